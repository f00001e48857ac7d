//! What `tune` and `commission` write: drive files, each the machine file with its whole
//! `[drive]` table replaced by the design's `controller_core::DriveConfig`, every key stated
//! (also those that would default from the plant, and no `[drive.notch]` table when the
//! design has none), so that `run --config`, `flash --config` and the firmware build's
//! `STIFFDRIVE_DRIVE` compose exactly the drive that was verified, whatever the file's own
//! `[drive]` said ([`drive_file`]); and `tune.md`, which shows that table.

use super::damping::StepFit;
use super::TuneResult;
use controller_core::DriveConfig;
use sim_engine::error::{HarnessError, Result};
use std::fmt::Write as _;
use toml::{Table, Value};

fn toml_error(e: impl std::fmt::Display) -> HarnessError {
    HarnessError::config("tune", e.to_string())
}

/// Every float of the drive is an `f32`: written in its shortest decimal form (0.1, not
/// the f64 value of the nearest f32, 0.10000000149011612) when that reads back to the same
/// f32 through the f64 a TOML reader makes of it; else as the f32's exact value.
fn shortest_f32(v: &mut Value) {
    match v {
        Value::Float(f) => {
            let x = *f as f32;
            if let Ok(short) = x.to_string().parse::<f64>() {
                if short as f32 == x {
                    *f = short;
                }
            }
        }
        Value::Table(t) => t.iter_mut().for_each(|(_, v)| shortest_f32(v)),
        Value::Array(a) => a.iter_mut().for_each(shortest_f32),
        _ => {}
    }
}

/// `drive` as a TOML table, the form `[drive]` is read in: every key, a `None` left out.
pub fn drive_table(drive: &DriveConfig) -> Result<Table> {
    let mut v = Value::try_from(drive).map_err(toml_error)?;
    shortest_f32(&mut v);
    match v {
        Value::Table(t) => Ok(t),
        other => Err(toml_error(format!(
            "the drive serialized as {}",
            other.type_str()
        ))),
    }
}

/// The whole tuned `[drive]` table, as `tune.md` shows it.
pub fn drive_toml(drive: &DriveConfig) -> Result<String> {
    let mut doc = Table::new();
    doc.insert("drive".into(), Value::Table(drive_table(drive)?));
    toml::to_string(&doc).map_err(toml_error)
}

/// The settings CRC of `drive`: CRC-32 of its settings record, the number the board logs
/// at boot (`settings crc …`, `pil_link::board::session::settings_crc`); 0 when the drive
/// has no settings record.
#[must_use]
pub fn settings_crc(drive: &DriveConfig) -> u32 {
    pil_link::board::session::settings_crc(drive)
}

/// The machine file `doc` with its `[drive]` table replaced whole by `drive` (every key
/// stated, [`drive_table`]): nothing of the file's own `[drive]` is kept.
pub fn with_drive(mut doc: Table, drive: &DriveConfig) -> Result<Table> {
    doc.insert("drive".into(), Value::Table(drive_table(drive)?));
    Ok(doc)
}

/// A drive file's text: each line of `header` as a comment (its first line says what the
/// file is and whether it was verified), the settings CRC, then `doc` with `drive`
/// ([`with_drive`]). It composes back to `drive` exactly.
pub fn drive_file(doc: Table, drive: &DriveConfig, header: &str) -> Result<String> {
    let body = toml::to_string(&with_drive(doc, drive)?).map_err(toml_error)?;
    let mut s = String::new();
    for line in header.lines() {
        let _ = writeln!(s, "# {line}");
    }
    let _ = writeln!(
        s,
        "# settings crc {:08x}: the board logs it at boot for the drive it runs.",
        settings_crc(drive)
    );
    Ok(s + &body)
}

fn damping_text(f: &StepFit, tolerance: f64) -> String {
    let diff = (f.fitted.damping() - f.smallest_damping).abs();
    format!(
        "## Damping in the nonlinear loop\n\n{} load steps between {:.2} and {:.2} pu, {:.2} s apart, \
         from {:.2} s on the `fig6` move (the load held from before the ramp ends, so the gears \
         stay engaged: smallest shaft torque {:.3} pu; largest torque reference {:.3} pu). The \
         mean of their load-speed error responses (the steps off with the sign turned) is \
         fitted with the matrix-pencil method; its dominant oscillatory mode: **ζ = {:.3} at \
         {:.2} Hz**. The linear model's pole nearest to it: ζ = {:.3} at {:.2} Hz ({}). The \
         model's smallest damping, {:.3}, is {:.3} from the fitted one: {} (tolerance \
         {tolerance}). The same fit on the linear model's own step response gives ζ = {:.3}: \
         the part of the difference that is the method's.\n",
        f.steps,
        f.load_pu[0],
        f.load_pu[1],
        (f.window_s[1] - f.window_s[0]) / f.steps.max(1) as f64,
        f.window_s[0],
        f.min_shaft_torque_pu,
        f.max_torque_pu,
        f.fitted.damping(),
        f.fitted.hz(),
        f.nearest_pole_damping,
        f.nearest_pole_hz,
        if f.nearest_is_smallest {
            "the least damped pole"
        } else {
            "not the least damped pole"
        },
        f.smallest_damping,
        diff,
        if diff <= tolerance { "within" } else { "outside" },
        f.fitted_to_model_damping,
    )
}

/// `DIR/tune.md`: every number from `r`; `images` are the Bode plot and the pole map.
#[must_use]
pub fn markdown(r: &TuneResult, drive_toml: &str, images: &[String; 2]) -> String {
    let d = &r.design;
    let mut s = format!(
        "# tune: `{}`\n\n{} candidates judged on the linear model, {} met the constraints; {} \
         refused in the nonlinear loop before this one.\n\n## Design\n\n```toml\n{}```\n\n",
        r.config,
        r.judged,
        r.feasible,
        r.refused.len(),
        drive_toml
    );
    let _ = writeln!(
        s,
        "Predicted (linear model): smallest damping {:.3} engaged, {} apart; velocity-loop phase \
         margin {:.1}°, gain margin {:.1} dB; quantization torque noise {:.4} pu RMS; weakest \
         stiffness over ω_v … 10·ω_v {:.4e} pu per pu·s.\n",
        d.damping[0],
        if d.damping[1].is_finite() {
            format!("{:.3}", d.damping[1])
        } else {
            "(no lost motion)".into()
        },
        d.margins[0],
        d.margins[1],
        d.noise_pu,
        d.stiffness
    );
    if let Some(b) = d.notch_band_damping {
        let _ = writeln!(
            s,
            "The drive has a notch on the torque reference: the damping figures above are of \
             the poles outside its band; inside it (the resonance it leaves to the machine, \
             and its own poles) the smallest damping is {b:.4}.\n"
        );
    }
    if let Some(b) = d.resonance_band_damping {
        let _ = writeln!(
            s,
            "The machine damps its own resonance less than the floor: the engaged damping \
             above is of the poles outside ±{:.0} % of that resonance; inside it the \
             smallest damping is {b:.4}, held to the machine's own (docs/tuning.md).\n",
            100.0 * super::RESONANCE_BAND_SHARE
        );
    }
    let _ = writeln!(
        s,
        "![Bode plot of the velocity loop]({})\n\n![Closed-loop poles]({})\n",
        images[0], images[1]
    );
    let _ = writeln!(
        s,
        "| verification | stable | oscillation verdict | faulted | shaft-torque ripple (pu) | \
         torque chatter (pu) |\n|---|---|---|---|---|---|"
    );
    for v in &r.verification {
        let _ = writeln!(
            s,
            "| {} | {} | {} at {:.1} Hz | {} | {:.4} | {:.4} |",
            v.scenario,
            v.stable,
            v.oscillation.word(),
            v.oscillation_freq_hz,
            v.faulted,
            v.shaft_torque_ripple_rms_pu,
            v.limit_cycle_torque_pu
        );
    }
    let _ = write!(
        s,
        "\n{}",
        super::summary::markdown(&r.per_bandwidth, &r.constraints)
    );
    if let Some(f) = &r.step {
        let _ = write!(s, "\n{}", damping_text(f, super::DAMPING_TOLERANCE));
    } else if r.no_oscillatory_mode {
        let _ = write!(
            s,
            "\n## Damping in the nonlinear loop\n\nThe load speed error after the `fig6` move's \
             load steps has no decaying oscillatory mode that the fit finds, so no damping is \
             fitted to it: the mode the model names least damped does not show there. The \
             model's smallest damping is {:.3}.\n",
            r.design.damping[0]
        );
    }
    s
}

/// One design of a [`Comparison`].
#[derive(Debug, Clone, serde::Serialize)]
pub struct Entry {
    /// Its velocity bandwidth \[rad/s\].
    pub bandwidth_rad_s: f64,
    /// Its AFB, as `tune` labels it.
    pub afb: String,
    /// Its figures and objective on `fig6`.
    pub score: super::objective::Score,
}

impl Entry {
    fn of(t: &super::Tuned) -> Self {
        let c = &t.result.design.candidate;
        Self {
            bandwidth_rad_s: c.bandwidth_rad_s,
            afb: c.afb.label(),
            score: t.result.score,
        }
    }
}

/// Both designs of a pair by the objective, against the default drive.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Comparison {
    /// The default drive's figures and the budgets.
    pub reference: super::objective::Reference,
    /// The best design with AFB.
    pub with_afb: Entry,
    /// The best design without AFB.
    pub without_afb: Entry,
    /// "with AFB" or "without AFB": the lower objective.
    pub chosen: &'static str,
    /// J without AFB − J with AFB: how much AFB lowers the objective on this machine
    /// (negative: it does not help).
    pub afb_gain: f64,
}

impl Comparison {
    /// The comparison of `p`'s two designs (the reference is the AFB search's; both
    /// searches run the same default drive).
    #[must_use]
    pub fn of(p: &super::pair::Pair) -> Self {
        Self {
            reference: p.with.result.reference,
            with_afb: Entry::of(&p.with),
            without_afb: Entry::of(&p.without),
            chosen: if p.afb_chosen() {
                "with AFB"
            } else {
                "without AFB"
            },
            afb_gain: p.without.result.score.objective - p.with.result.score.objective,
        }
    }
}

fn opt(x: Option<f64>) -> String {
    x.map_or_else(|| "-".into(), |v| format!("{v:.4}"))
}

/// One row of the comparison table.
fn figures_row(
    s: &mut String,
    name: &str,
    bw: &str,
    afb: &str,
    j: f64,
    f: &super::objective::Figures,
) {
    let _ = writeln!(
        s,
        "| {name} | {bw} | {afb} | {j:.3} | {} | {} | {} | {:.4} | {} |",
        opt(f.peak_droop_pu),
        opt(f.peak_shaft_torque_pu),
        opt(f.recovery_s),
        f.torque_noise_rms_pu,
        f.stable && !f.faulted
    );
}

/// `tune.md`'s section on the choice: the objective and budgets in words and numbers, the
/// default drive and both designs, which was chosen and by how much AFB helps.
#[must_use]
pub fn comparison_markdown(
    p: &super::pair::Pair,
    c: &Comparison,
    names: &super::PairFiles,
) -> String {
    let r = &c.reference;
    let mut s = format!(
        "\n## Choice by the objective\n\n{}\n\n| design | bandwidth (rad/s) | AFB | J | peak \
         droop (pu) | peak shaft torque (pu) | recovery (s) | torque noise (pu RMS) | stable, \
         no fault |\n|---|---|---|---|---|---|---|---|---|\n",
        r.describe()
    );
    let d = &r.default_drive;
    figures_row(
        &mut s,
        "default drive (the file's `[drive]`)",
        "-",
        "-",
        r.objective(d),
        d,
    );
    for (name, e) in [("with AFB", &c.with_afb), ("without AFB", &c.without_afb)] {
        let bw = format!("{}", e.bandwidth_rad_s);
        figures_row(
            &mut s,
            name,
            &bw,
            &e.afb,
            e.score.objective,
            &e.score.figures,
        );
    }
    let scored = |t: &super::Tuned| {
        let n = t.result.scored.len();
        let within = t
            .result
            .scored
            .iter()
            .filter(|x| x.score.within_budget)
            .count();
        format!("{n} run in the loop, {within} within the budgets")
    };
    let gain = c.afb_gain;
    let _ = writeln!(
        s,
        "\n**Chosen: {}** (`{}`; the best of the other kind is `{}`{}). {}\n\n\
         Candidates scored: with AFB {}; without AFB {}.",
        c.chosen,
        names.chosen,
        names.runner_up,
        if names.model_only {
            ": both on the identified model, not verified on the machine as files"
        } else {
            ""
        },
        if gain > 0.0 {
            format!(
                "AFB helps on this machine: it lowers J by {gain:.3} ({:.1} % of the no-AFB \
                 design's).",
                100.0 * gain / c.without_afb.score.objective
            )
        } else {
            format!(
                "AFB does not help on this machine: the no-AFB design's J is lower or equal \
                 by {:.3}.",
                -gain
            )
        },
        scored(&p.with),
        scored(&p.without)
    );
    let (chosen, _) = p.chosen();
    let j = chosen.result.score.objective;
    let default = r.objective(d);
    if j >= default {
        let _ = writeln!(
            s,
            "\n**The chosen design does not beat the machine file's own drive** (J {j:.3} \
             against {default:.3}): with the bandwidths searched here, keeping the file's \
             `[drive]` is better by this objective."
        );
    }
    s
}
