//! `commission.md` and `commission.json`.

use super::Commissioning;
use crate::identify::{write::estimates, Identification};
use crate::tune::pair::Pair;
use sim_engine::config::RunConfig;
use sim_engine::error::{HarnessError, Result};
use sim_engine::output::Staging;
use std::fmt::Write as _;

/// The simulated machine's own value of an identified `[plant]` key (a real machine has
/// none: it is shown only to judge the measurement).
fn file_value(base: &RunConfig, name: &str) -> Option<f64> {
    let m = &base.plant.mechanics;
    let e = &base.plant.electrics;
    match name {
        "winding_resistance_pu" if e.motor != plant_host::MotorKind::Dc => {
            Some(e.winding_resistance_pu)
        }
        "d_inductance_pu_s" => e.d_inductance_pu_s,
        "q_inductance_pu_s" => e.q_inductance_pu_s,
        "encoder_offset_elec_deg" => e.encoder_offset_elec_deg,
        "pole_pairs" => e.pole_pairs.map(f64::from),
        "motor_inertia_s" => Some(m.motor_inertia_s),
        "load_inertia_s" => Some(m.load_inertia_s),
        "anti_resonance_hz" => Some(m.anti_resonance_hz),
        "shaft_damping_ratio" => Some(m.shaft_damping_ratio),
        "backlash_deg" => Some(m.backlash_deg),
        _ => None,
    }
}

/// `commission.md`, section by section.
fn markdown(c: &Commissioning, base: &RunConfig, ident: &Identification, pair: &Pair) -> String {
    let mut md = identified(c, base, ident);
    tuned(&mut md, c, pair);
    reference_drive(&mut md, c, pair);
    on_the_machine(&mut md, c);
    spread_table(&mut md, c);
    credit(&mut md, c, pair);
    tried_table(&mut md, c);
    verdict(&mut md, c, pair);
    files_table(&mut md, c);
    md
}

/// The heading and section 1: the identified `[plant]` keys beside the simulated machine's
/// own values.
fn identified(c: &Commissioning, base: &RunConfig, ident: &Identification) -> String {
    let mut md = format!(
        "# Commissioning of {}\n\n## 1. Identified ([identify/identify.md](identify/identify.md))\n\n\
         | parameter | identified | standard error | the simulated machine's file | unit |\n\
         |---|---|---|---|---|\n",
        c.config
    );
    for e in estimates(base, ident) {
        let truth = file_value(base, e.name).map_or_else(|| "-".into(), |v| format!("{v:.6}"));
        let _ = writeln!(
            md,
            "| {} | {:.6} | {:.2e} | {truth} | {} |",
            e.name, e.value, e.std_error, e.unit
        );
    }
    md.push_str(if ident.motor.is_some() {
        "\n`identified.toml` is the machine file with that `[plant]` table, the measured motor \
         in `[electrics]` and the calibration in the drive's `winding_resistance_pu` and \
         `[drive.pmsm]`; every drive below runs with that calibration.\n\n"
    } else {
        "\n`identified.toml` is the machine file with that `[plant]` table.\n\n"
    });
    md
}

/// Section 2: the design chosen on the identified model, and where its files are.
fn tuned(md: &mut String, c: &Commissioning, pair: &Pair) {
    let (chosen, other) = pair.chosen();
    let d = &chosen.result.design;
    let _ = write!(
        md,
        "{}## 2. Tuned on the identified machine ([tune/tune.md](tune/tune.md))\n\n\
         Chosen {} (J {:.3} on the identified model; {} J {:.3}; the file's own drive \
         3) by the objective on the machine, where both designs ran (section 3): {} rad/s, {}; smallest damping {:.3} (engaged){}, phase margin \
         {:.1} deg, gain margin {:.1} dB, quantization torque noise {:.3} pu RMS. \
         {} The files written, each with the settings CRC of its drive, are listed in \
         section 4.\n\n",
        notch_text(c),
        c.chosen,
        chosen.result.score.objective,
        if pair.afb_chosen() {
            "without AFB"
        } else {
            "with AFB"
        },
        other.result.score.objective,
        d.candidate.bandwidth_rad_s,
        d.candidate.afb.label(),
        d.damping[0],
        d.notch_band_damping.map_or_else(String::new, |b| format!(
            " outside the notch's band and {b:.4} inside it (the resonance left to the \
             machine: at least {:.0} % of its own damping)",
            100.0 * crate::tune::NOTCH_BAND_DAMPING_SHARE
        )),
        d.margins[0],
        d.margins[1],
        d.noise_pu,
        if c.no_design {
            format!(
                "The designs as tuned are in `tune/{}` and `tune/{}`: the identified model \
                 with each drive, not verified on the machine as files.",
                super::MODEL_FILES.chosen,
                super::MODEL_FILES.runner_up
            )
        } else {
            format!(
                "`drive.toml` is the machine file as given with that drive and \
                 `runner-up.toml` with the other, each with every `[drive]` key stated \
                 (`tune/{}` and `tune/{}`: the same drives in the identified model, not \
                 verified on the machine as files).",
                super::MODEL_FILES.chosen,
                super::MODEL_FILES.runner_up
            )
        },
    );
}

/// Section 3's table: both designs (and the runs set beside them) on the machine itself.
fn on_the_machine(md: &mut String, c: &Commissioning) {
    let _ = write!(
        md,
        "\n## 3. On the machine itself: `fig6` against the plant of the machine file\n\n\
         {}\n\n\
         | {} J on the machine | peak droop (pu) | peak shaft torque (pu) | recovery (s) | \
         torque noise (pu RMS) | torque noise / the file's drive's |\n|{}---|---|---|---|---|---|\n",
        c.reference.describe(),
        super::OnMachine::HEADER,
        super::OnMachine::RULE,
    );
    let f = |x: Option<f64>| x.map_or_else(|| "-".into(), |v| format!("{v:.4}"));
    let own_noise = c.reference.default_drive.torque_noise_rms_pu;
    for r in c
        .runs
        .iter()
        .chain(&c.without_notch)
        .chain(&c.same_gains_without_afb)
    {
        let g = &r.figures;
        let _ = writeln!(
            md,
            "|{} {:.3} | {} | {} | {} | {:.4} | {} |",
            r.row(),
            c.reference.objective(g),
            f(g.peak_droop_pu),
            f(g.peak_shaft_torque_pu),
            f(g.recovery_s),
            g.torque_noise_rms_pu,
            ratio(g.torque_noise_rms_pu, own_noise)
        );
    }
}

/// `x / of` as "8.5×", or "-" when `of` is not a positive number.
fn ratio(x: f64, of: f64) -> String {
    if of > 0.0 && x.is_finite() {
        format!("{:.2}×", x / of)
    } else {
        "-".into()
    }
}

/// The machine file's own drive beside the two designs on the identified model, by the
/// linear constraints the designs must meet.
fn reference_drive(md: &mut String, c: &Commissioning, pair: &Pair) {
    let k = &pair.with.result.constraints;
    let _ = write!(
        md,
        "### The machine file's own drive, judged as the designs are\n\nOn the linear model \
         of the identified machine, by the constraints every design must meet (smallest \
         damping ≥ {}, phase margin ≥ {} deg, gain margin ≥ {} dB, quantization torque \
         noise ≤ {} pu RMS):\n\n| drive | bandwidth (rad/s) | AFB | damping engaged | \
         damping apart | phase margin (deg) | gain margin (dB) | quantization noise (pu RMS) \
         | meets the constraints |\n|---|---|---|---|---|---|---|---|---|\n",
        k.min_damping, k.min_phase_margin_deg, k.min_gain_margin_db, k.max_noise_pu
    );
    let (chosen, other) = pair.chosen();
    let r = &c.reference_drive;
    for (name, j, meets) in [
        ("the file's own `[drive]`", &r.judged, r.fails.is_empty()),
        (
            "chosen",
            &chosen.result.design,
            chosen.result.design.feasible,
        ),
        (
            "runner-up",
            &other.result.design,
            other.result.design.feasible,
        ),
    ] {
        let apart = if j.damping[1].is_finite() {
            format!("{:.3}", j.damping[1])
        } else {
            "(no lost motion)".into()
        };
        let _ = writeln!(
            md,
            "| {name} | {} | {} | {:.3} | {apart} | {:.1} | {:.1} | {:.4} | {} |",
            j.candidate.bandwidth_rad_s,
            j.candidate.afb.label(),
            j.damping[0],
            j.margins[0],
            j.margins[1],
            j.noise_pu,
            if meets { "yes" } else { "no" }
        );
    }
    if r.fails.is_empty() {
        let _ = writeln!(
            md,
            "\nThe file's own drive meets the constraints the designs must meet."
        );
    } else {
        let _ = writeln!(
            md,
            "\n**The file's own drive fails the constraints the designs must meet**: {}. \
             It stays the reference of the objective (J = 3) all the same.",
            r.fails.join("; ")
        );
    }
}

/// The file's own drive over the load step's timing: each figure's spread, the noise a
/// design must be worse by to count as worse.
fn spread_table(md: &mut String, c: &Commissioning) {
    let f = |x: Option<f64>| x.map_or_else(|| "-".into(), |v| format!("{v:.4}"));
    let [d, s, r, n] = c.spread.range;
    let _ = write!(
        md,
        "\n### Worse means worse beyond the noise\n\nThe file's own drive ran `fig6` on the \
         machine with the load step moved by each offset below. A design counts as worse than \
         the file's own drive in peak droop or peak shaft torque only by more than that \
         figure's spread (its range over these runs), a rule fixed before any run.\n\n\
         | load step offset (s) | peak droop (pu) | peak shaft torque (pu) | recovery (s) | \
         torque noise (pu RMS) |\n|---|---|---|---|---|\n"
    );
    for (dt, g) in c.spread.offsets_s.iter().zip(&c.spread.runs) {
        let _ = writeln!(
            md,
            "| {dt:+.2} | {} | {} | {} | {:.4} |",
            f(g.peak_droop_pu),
            f(g.peak_shaft_torque_pu),
            f(g.recovery_s),
            g.torque_noise_rms_pu
        );
    }
    let _ = writeln!(
        md,
        "| **spread** | **{d:.2e}** | **{s:.2e}** | {r:.2e} | {n:.2e} |"
    );
}

/// What AFB itself adds to the chosen design, and what its torque noise costs.
fn credit(md: &mut String, c: &Commissioning, pair: &Pair) {
    let (chosen, _) = pair.chosen();
    let bw = chosen.result.design.candidate.bandwidth_rad_s;
    let own_bw = c.reference_drive.judged.candidate.bandwidth_rad_s;
    let j = |r: &super::OnMachine| c.reference.objective(&r.figures);
    let c_run = if pair.afb_chosen() {
        &c.runs[0]
    } else {
        &c.runs[1]
    };
    let _ = write!(md, "\n### Credit and price\n\n");
    let afb_run = &c.runs[0];
    let chosen_afb = pair.afb_chosen();
    match &c.same_gains_without_afb {
        Some(n) => {
            let (ja, jn) = (j(afb_run), j(n));
            let _ = writeln!(
                md,
                "**Credit.** {}The AFB design ({} rad/s, {}) with its AFB turned off at the \
                 same gains (last row above): J {jn:.3} against {ja:.3} with AFB. AFB itself \
                 lowers J by {:.3}; the rest of that design's gain over the file's own drive \
                 (J 3 → {jn:.3}) is its bandwidth's and estimator's (against the file's \
                 {own_bw} rad/s).",
                if chosen_afb {
                    String::new()
                } else {
                    format!(
                        "The chosen design has no AFB: all of its gain over the file's own \
                         drive (J 3 → {:.3}) is its bandwidth's and estimator's ({bw} rad/s \
                         against the file's {own_bw} rad/s). ",
                        j(c_run)
                    )
                },
                afb_run.bandwidth_rad_s,
                afb_run.afb,
                jn - ja
            );
        }
        None => {
            let _ = writeln!(
                md,
                "**Credit.** No design with AFB: all of the chosen design's gain over the \
                 file's own drive (J 3 → {:.3}) is its bandwidth's and estimator's ({bw} rad/s \
                 against the file's {own_bw} rad/s).",
                j(c_run)
            );
        }
    }
    let own = c.reference.default_drive.torque_noise_rms_pu;
    let _ = writeln!(
        md,
        "\n**Price.** Its torque noise on the machine: {:.4} pu RMS, {} the file's own \
         drive's {own:.4} pu (budget {:.4} pu).",
        c_run.figures.torque_noise_rms_pu,
        ratio(c_run.figures.torque_noise_rms_pu, own),
        c.reference.max_torque_noise_pu
    );
}

/// Every machine file written, with its drive's settings CRC.
fn files_table(md: &mut String, c: &Commissioning) {
    let _ = write!(
        md,
        "\n## 4. Files\n\nEach machine file written, with the settings CRC of the drive it \
         composes to (the board logs `settings crc …` at boot for the drive it runs, so a \
         user can check what runs). Every drive file states every `[drive]` key. {}\n\n\
         | file | settings crc | verified on the machine | what |\n|---|---|---|---|\n",
        if c.passed {
            "The one to flash is `drive.toml`."
        } else {
            "None of them is to be flashed: the commissioning did not pass."
        }
    );
    for f in &c.files {
        let _ = writeln!(
            md,
            "| `{}` | `{}` | {} | {} |",
            f.name,
            f.settings_crc,
            if f.verified_on_machine {
                "yes"
            } else {
                "no (a model only)"
            },
            f.what
        );
    }
}

/// The designs tried on the machine: the identified model's prediction beside the machine.
fn tried_table(md: &mut String, c: &Commissioning) {
    let f = |x: Option<f64>| x.map_or_else(|| "-".into(), |v| format!("{v:.4}"));
    let _ = write!(
        md,
        "\n### Predicted and measured\n\nThe first {} designs of each kind within the budgets \
         on the identified model, run on the machine; of each kind, the one the machine ranks \
         first (within the budgets and no worse than the file's own drive, then the lower J \
         there) that also passes `tune`'s verification is taken.\n\n\
         | kind | bandwidth (rad/s) | design | J model | J machine | peak droop model / \
         machine (pu) | peak shaft torque model / machine (pu) | recovery model / machine \
         (s) | torque noise model / machine (pu RMS) | on the machine | taken |\n\
         |---|---|---|---|---|---|---|---|---|---|---|\n",
        super::ON_MACHINE_PER_KIND
    );
    for t in &c.tried {
        let (p, m) = (&t.model.figures, &t.machine.figures);
        let _ = writeln!(
            md,
            "| {} | {} | {} | {:.3} | {:.3} | {} / {} | {} / {} | {} / {} | {:.4} / {:.4} | {} \
             | {} |",
            t.kind,
            t.candidate.bandwidth_rad_s,
            t.candidate.afb.label(),
            t.model.objective,
            t.objective,
            f(p.peak_droop_pu),
            f(m.peak_droop_pu),
            f(p.peak_shaft_torque_pu),
            f(m.peak_shaft_torque_pu),
            f(p.recovery_s),
            f(m.recovery_s),
            p.torque_noise_rms_pu,
            m.torque_noise_rms_pu,
            match t.qualifies {
                2 => "qualifies, no worse",
                1 => "qualifies, worse than the file's drive",
                _ => "out of budget",
            },
            if t.taken { "yes" } else { "" }
        );
    }
}

/// The notch section: whether one was placed, why (the figures of the best candidate
/// without it) and where.
fn notch_text(c: &Commissioning) -> String {
    let d = &c.notch;
    let mut s = format!(
        "## Notch\n\n{}: {}.\n",
        if d.notch.is_some() {
            "**A notch was placed**"
        } else {
            "No notch was placed"
        },
        d.reason
    );
    if let Some(t) = &d.trigger {
        let _ = write!(
            s,
            "\nWithout a notch, {} of {} candidates met the constraints. The best damped \
             ({} rad/s, {}): smallest damping {:.3} (floor {:.2}) at {:.1} Hz; phase margin \
             {:.1} deg, gain margin {:.1} dB. Identified resonance: {:.1} Hz.\n",
            t.feasible,
            t.judged,
            t.bandwidth_rad_s,
            t.afb,
            t.least_damped.0,
            t.min_damping,
            t.least_damped.1,
            t.margins[0],
            t.margins[1],
            t.resonance_hz
        );
    }
    if let Some(n) = &d.notch {
        let _ = write!(
            s,
            "\n`[drive.notch]`: centre {:.2} Hz, width {:.2} Hz, depth {:.1} dB \
             ([notched.toml](notched.toml); both designs below are tuned on it, and \
             `tune/model-chosen.toml` carries it). On the machine, the chosen design is also run \
             with the notch taken out (last row below).\n",
            n.centre_hz, n.width_hz, n.depth_db
        );
    }
    s + "\n"
}

/// Writes `commission.md` and `commission.json` into the staging directory.
pub fn write_all(
    staging: &Staging,
    c: &Commissioning,
    base: &RunConfig,
    ident: &Identification,
    pair: &Pair,
) -> Result<()> {
    staging.write("commission.md", &markdown(c, base, ident, pair))?;
    let json = serde_json::to_string_pretty(c)
        .map_err(|e| HarnessError::Backend(format!("commission.json: {e}")))?;
    staging.write("commission.json", &(json + "\n"))?;
    Ok(())
}

/// The file's own drive on the machine, the chosen design against it, and the verdict.
fn verdict(md: &mut String, c: &Commissioning, pair: &Pair) {
    let f = |x: Option<f64>| x.map_or_else(|| "-".into(), |v| format!("{v:.4}"));
    let g = &c.reference.default_drive;
    let _ = writeln!(
        md,
        "\nThe machine file's own drive on the machine: peak droop {} pu, peak shaft torque {} \
         pu, recovery {} s, torque noise {:.4} pu RMS (J {:.3}).",
        f(g.peak_droop_pu),
        f(g.peak_shaft_torque_pu),
        f(g.recovery_s),
        g.torque_noise_rms_pu,
        c.reference.objective(g)
    );
    let jc = if pair.afb_chosen() {
        c.objective[0]
    } else {
        c.objective[1]
    };
    if jc >= c.reference.objective(g) {
        let _ = writeln!(
            md,
            "\nThe chosen design does not beat the machine file's own drive on the machine \
             (J {jc:.3}): at the bandwidths searched, the file's `[drive]` is better by this \
             objective."
        );
    }
    for line in c
        .runs
        .iter()
        .chain(&c.without_notch)
        .filter_map(super::OnMachine::moved_by_verdict)
    {
        let _ = writeln!(md, "\n{line}.");
    }
    let _ = writeln!(
        md,
        "\n**{}** (criteria, fixed before the run: {}; with a notch placed, also {}).\n\n{}",
        if c.passed {
            "Passed"
        } else if c.no_design {
            "No design"
        } else {
            "Failed"
        },
        super::CRITERION,
        super::NOTCH_CRITERION,
        if c.passed {
            "The drive to flash is `drive.toml` (`cargo run --release -- flash \
             --config DIR/drive.toml`)."
        } else if c.no_design {
            "None of the designs tried beats the machine file's own drive on the machine \
             (table above): keep that drive. No drive file for the machine is written; \
             `tune/` holds the designs as tuned on the identified model, models only."
        } else {
            "`drive.toml` did not pass on the machine: do not flash it."
        }
    );
}
