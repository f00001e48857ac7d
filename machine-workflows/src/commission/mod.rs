//! `hil-harness commission --config CFG --out DIR`: from measurement to a verified design,
//! as a drive engineer commissions a machine whose parameters nobody gave them.
//!
//! 1. **Identify** the machine of `CFG` in the closed loop ([`super::identify`]): the
//!    estimator reads only the recorded signals. `DIR/identify/` gets its files. On a PMSM
//!    machine this starts with the motor calibration ([`super::identify::motor`]).
//! 2. **The identified machine file**, `DIR/identified.toml`: `CFG` (with `--set` applied)
//!    with its `[plant]` table replaced by the identified one; for a PMSM also the measured
//!    motor in `[electrics]` and the calibration in the drive's `winding_resistance_pu` and
//!    `[drive.pmsm]`. Everything the drive knows of the machine now comes from the
//!    measurement. The machine file's own drive, where it is the reference below, runs with
//!    the same calibration (a PMSM drive runs with no other).
//! 3. **Tune** on the identified file ([`super::tune`]), with AFB and without by the same
//!    constraints ([`tune::pair`]), each chosen by the objective; `DIR/tune/` as `tune`
//!    writes it.
//!    **The automatic notch** ([`notch`]): when no candidate meets the constraints because
//!    the least-damped mode of the best one is the identified resonance, a notch is placed
//!    on it, `DIR/notched.toml` is `identified.toml` with that `[drive.notch]`, and both
//!    designs are tuned on it instead (so `tune/drive.toml` carries the notch). Otherwise
//!    nothing changes.
//! 4. **Verify on the machine itself**: the first [`ON_MACHINE_PER_KIND`] designs of each
//!    kind that the model ranks within its budgets run `fig6` on the machine; of each kind,
//!    the one the machine ranks first that passes `tune`'s verification on the model
//!    becomes that kind's design ([`tune::retarget`]); `commission.md` puts each one's
//!    prediction beside the machine's figures. Then both drives run `fig6` (a move with a load step)
//!    against the plant of `CFG`, not the identified one, and are scored by `tune`'s
//!    objective ([`tune::objective`]) against `CFG`'s own drive on the machine. The machine
//!    chooses: of the two designs stable, without a fault and within the noise budget there,
//!    one no worse than `CFG`'s own drive in peak droop and peak shaft torque before one
//!    that is worse, then the lower objective on the machine, is `DIR/tune/drive.toml`, the
//!    other `DIR/tune/runner-up.toml` (the model's choice stands only when neither
//!    qualifies). The commissioning passes by [`CRITERION`] (the chosen design qualifies,
//!    is no worse than the file's own drive in peak droop and peak shaft torque, and its
//!    objective on the machine is lower) and, with a notch
//!    placed, by [`NOTCH_CRITERION`] (less ripple than the chosen design with the notch
//!    taken out, run too for the comparison).
//!    `DIR/drive.toml` is `CFG` as given with the chosen `[drive]` (what `run --config` and
//!    `flash --config` take on this machine), `DIR/runner-up.toml` with the other kind's.
//!    `DIR/commission.md` and `DIR/commission.json` hold the figures and the notch
//!    decision with its reason; the command fails (after writing them) when it does not
//!    pass: with the no-design code, and without `drive.toml` and `runner-up.toml`, when
//!    no design tried beats the file's own drive on the machine (keep that drive).
//!
//! Everything is staged: on an error before the verification nothing is written.

mod files;
mod no_design;
pub mod notch;
mod on_machine;
mod spread;
mod write;

use crate::identify;
use crate::tune::{self, Constraints};
pub use files::WrittenFile;
use files::{drive_files, identified_doc, machine_doc, render, with_notch};
use notch::Decision;
use on_machine::{both_on_machine, try_on_machine, verification_base};
pub use on_machine::{Tried, ON_MACHINE_PER_KIND};
use sim_engine::config::{resolve, RunConfig};
use sim_engine::error::{HarnessError, Result};
use sim_engine::output::Staging;
pub use spread::{shifted, Spread, STEP_OFFSETS_S};
use std::path::Path;
use toml::Table;

/// The verification of one drive on the machine itself.
pub use crate::tune::pair::LoopRun as OnMachine;

/// The second criterion with a notch placed, fixed before any run.
pub const NOTCH_CRITERION: &str =
    "less shaft-torque ripple than the same chosen design with the notch taken out";

/// The criterion on the machine itself, fixed before any run.
pub const CRITERION: &str = "the chosen design (of the two, the one stable without a fault \
    and within the torque-noise budget on the machine, no worse than the machine file's own \
    drive in peak droop and peak shaft torque before one that is worse, then the lower \
    objective there, against the machine file's own drive on the machine) is stable without \
    a fault, within the budget, no worse than the file's own drive in peak droop and in peak \
    shaft torque, and its objective on the machine is lower than the file's own drive's (3); \
    worse means worse beyond the noise: a design is worse than the file's own drive in a \
    figure only by more than that figure's run-to-run spread, measured as its range over the \
    file's own drive run with the load step moved by -0.1 to +0.1 s every 20 ms";

/// The machine file's own drive judged on the identified model by the linear constraints
/// the designs must meet (as `tune` judges each candidate).
#[derive(Clone, Debug, serde::Serialize)]
pub struct ReferenceDrive {
    /// Its figures on the linear model of the identified machine.
    pub judged: tune::Judged,
    /// The constraints it fails, each with its figure and the bound (empty: it meets them).
    pub fails: Vec<String>,
}

/// What `commission` found.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Commissioning {
    /// The machine file.
    pub config: String,
    /// Every design tried on the machine, the model's prediction beside the machine's
    /// figures ([`ON_MACHINE_PER_KIND`] of each kind).
    pub tried: Vec<Tried>,
    /// The AFB design and the no-AFB design, verified on the machine.
    pub runs: [OnMachine; 2],
    /// Which of `runs` was chosen (the lower objective on the model it was tuned on):
    /// "with AFB" or "without AFB".
    pub chosen: &'static str,
    /// The machine file's own drive on the machine, and the budget: the reference of the
    /// objective on the machine.
    pub reference: tune::objective::Reference,
    /// The objective of `runs` on the machine.
    pub objective: [f64; 2],
    /// Whether a notch was placed, where and why ([`notch`]).
    pub notch: Decision,
    /// With a notch placed: the chosen design with the notch taken out, on the machine.
    pub without_notch: Option<OnMachine>,
    /// The chosen design passed ([`CRITERION`] and, with a notch placed,
    /// [`NOTCH_CRITERION`]).
    pub passed: bool,
    /// No design tried beats the file's own drive on the machine ([`CRITERION`] without
    /// the notch's part): the commissioning has no design, as when none meets the
    /// constraints on the model, and `drive.toml` is not written.
    pub no_design: bool,
    /// The machine file's own drive on the identified model, by the linear constraints.
    pub reference_drive: ReferenceDrive,
    /// The run-to-run spread of the file's own drive's figures on the machine, over the
    /// load step's timing: the noise a design must be worse by to count as worse.
    pub spread: Spread,
    /// The AFB design's gains without its AFB, on the machine: what the AFB itself adds on
    /// top of the bandwidth.
    pub same_gains_without_afb: Option<OnMachine>,
    /// Every machine file written, with its drive's settings CRC.
    pub files: Vec<WrittenFile>,
}

/// What [`identify_into`] gives.
struct Identified {
    /// The machine as the identification ran it.
    base: RunConfig,
    ident: identify::Identification,
    /// `identified.toml`'s tree, its staged path and its entry.
    doc: Table,
    path: String,
    file: WrittenFile,
}

/// Identifies the machine into the staging directory: `identify/` and `identified.toml`
/// (steps 1 and 2).
fn identify_into(
    staging: &Staging,
    config: &str,
    sets: &[String],
    machine: &Table,
) -> Result<Identified> {
    let (base, spec) = identify::load(config, sets)?;
    let ident = identify::identify_machine(&base, &spec)?;
    let id_md = staging.path("identify/identify.md")?;
    identify::write::write_all(
        id_md.parent().unwrap_or(staging.dir()),
        &base,
        &spec,
        &ident,
    )?;
    let doc = identified_doc(machine.clone(), &base, &ident)?;
    let header = format!(
        "{} with the [plant] table `identify` measured: the model the designs are tuned on.",
        base.config_path.display()
    );
    let (text, drive) = render("identified.toml", &header, &doc)?;
    let path = staging.write("identified.toml", &text)?;
    let file = WrittenFile::new(
        "identified.toml",
        &drive,
        false,
        "the machine file with the identified [plant] (the file's own [drive] on it)".into(),
    );
    Ok(Identified {
        base,
        ident,
        doc,
        path: path.display().to_string(),
        file,
    })
}

/// `hil-harness commission`.
pub fn commission(
    config: &str,
    sets: &[String],
    target_bandwidth: Option<f64>,
    constraints: &Constraints,
    out: &Path,
) -> Result<String> {
    // One bar over the stages (hidden when stderr is not a terminal); `tune`'s own bar
    // shows the linear judging within its stage.
    let pb = sim_engine::progress::bar(STAGES.len() as u64, "commission");
    let stage = |i: usize| {
        pb.set_position(i as u64);
        pb.set_message(STAGES.get(i).copied().unwrap_or("commission"));
    };
    let result = run_stages(config, sets, target_bandwidth, constraints, out, &stage);
    pb.finish_and_clear();
    result
}

/// The stages the progress bar names.
const STAGES: [&str; 5] = ["identify", "judge", "tune", "on the machine", "write"];

/// The notch decision ([`notch::decide`]) on the identified file and the file both designs
/// are tuned on: `identified.toml` with the candidates already judged on it, or with a notch
/// placed `notched.toml` (written, its entry given) and nothing judged yet.
fn place_notch(
    staging: &Staging,
    id: &Identified,
    judged: Vec<tune::Judged>,
    constraints: &Constraints,
) -> Result<Placed> {
    let fig6 = resolve("fig6", Some(&id.path), &[])?;
    let decision = notch::decide(&fig6, id.ident.fit.fit.resonance_hz(), &judged, constraints)?;
    Ok(match &decision.notch {
        None => Placed {
            decision,
            tuned_on: id.path.clone(),
            name: "identified.toml",
            judged: Some(judged),
            file: None,
        },
        Some(n) => {
            let header = format!(
                "identified.toml with the notch commission placed ({}); every [drive] key \
                 stated.",
                decision.reason
            );
            let (doc, drive) = with_notch(id.doc.clone(), n)?;
            let text = tune::output::drive_file(
                doc,
                &drive,
                &format!("NOT verified on the machine (a model only): `hil-harness commission`: {header}"),
            )?;
            let path = staging.write("notched.toml", &text)?.display().to_string();
            let file = WrittenFile::new(
                "notched.toml",
                &drive,
                false,
                "identified.toml with the notch placed: the model the designs are tuned on".into(),
            );
            Placed {
                decision,
                tuned_on: path,
                name: "notched.toml",
                judged: None,
                file: Some(file),
            }
        }
    })
}

/// What [`place_notch`] decided and where the designs are tuned.
struct Placed {
    decision: Decision,
    /// The file tuned on (staged path) and its name in the output folder.
    tuned_on: String,
    name: &'static str,
    /// The candidates judged on it already (without a notch).
    judged: Option<Vec<tune::Judged>>,
    /// `notched.toml`'s entry, when written.
    file: Option<WrittenFile>,
}

/// `commission`'s copies of `tune`'s drive files in `DIR/tune/`: the identified model with
/// each design, named so as not to be taken for the drive to flash.
pub const MODEL_FILES: tune::PairFiles = tune::PairFiles {
    chosen: "model-chosen.toml",
    runner_up: "model-runner-up.toml",
    model_only: true,
};

/// The machine file's own drive (`own`) on the identified model the designs were tuned on
/// (`tuned_on`), judged by `constraints` as each candidate is.
fn judge_reference(
    own: &RunConfig,
    tuned_on: &str,
    constraints: &Constraints,
) -> Result<ReferenceDrive> {
    let mut cfg = resolve("fig6", Some(tuned_on), &[])?;
    cfg.drive = own.drive;
    let judged = tune::judge_drive(&cfg, constraints)?;
    let mut fails: Vec<String> = no_design::misses(&judged, constraints)
        .into_iter()
        .map(|(s, _)| s)
        .collect();
    let own_damping = tune::machine_resonance_damping(&cfg);
    if let Some(b) = judged.resonance_band_damping {
        if b < own_damping {
            fails.push(format!(
                "damping near the machine's resonance {b:.3} (needs ≥ the machine's own \
                 {own_damping:.3})"
            ));
        }
    }
    if let Some(b) = judged.notch_band_damping {
        let floor = tune::NOTCH_BAND_DAMPING_SHARE * own_damping;
        if b < floor {
            fails.push(format!(
                "damping in the notch's band {b:.3} (needs ≥ {floor:.3})"
            ));
        }
    }
    if fails.is_empty() && !judged.feasible {
        fails.push("a band-damping rule of `tune` (docs/tuning.md)".into());
    }
    Ok(ReferenceDrive { judged, fails })
}

/// The two designs on the model `placed` holds, or why there are not two
/// (`HarnessError::NoDesign`): with the design with AFB alone, the account names it and the
/// command that writes it, since `commission` chooses between the two kinds on the machine.
fn designs_on_model(
    placed: &Placed,
    target_bandwidth: Option<f64>,
    constraints: &Constraints,
    out: &Path,
) -> Result<tune::pair::Pair> {
    match tune::pair::designs_from(
        &placed.tuned_on,
        placed.judged.clone(),
        target_bandwidth,
        constraints,
    )? {
        tune::pair::Designs::Both(p) => Ok(*p),
        tune::pair::Designs::WithAfbOnly { with, without_afb } => {
            let c = &with.result.design.candidate;
            Err(HarnessError::NoDesign(format!(
                "{without_afb}; a design with AFB does meet them ({} at {} rad/s), but \
                 `commission` chooses between a design with AFB and one without on the machine \
                 and has only one: `stiffdrive tune --config {} --out DIR` writes it alone, \
                 verified on the identified model",
                c.afb.label(),
                c.bandwidth_rad_s,
                out.join(placed.name).display()
            )))
        }
    }
}

fn run_stages(
    config: &str,
    sets: &[String],
    target_bandwidth: Option<f64>,
    constraints: &Constraints,
    out: &Path,
    stage: &dyn Fn(usize),
) -> Result<String> {
    tune::objective::check_budget(constraints.max_torque_noise_pu)?;
    let grid = sim_engine::config::tune_grid()?;
    let bws = tune::bandwidths(&grid, target_bandwidth)?;
    let machine = machine_doc(config, sets)?;
    let staging = Staging::new(out)?;
    stage(0);
    let id = identify_into(&staging, config, sets, &machine)?;
    stage(1);
    let judged = tune::judge_grid(&id.path, &tune::candidates(&grid, &bws), constraints)?;
    let all_judged = judged.clone();
    let placed = place_notch(&staging, &id, judged, constraints)?;
    let (base, ident) = (&id.base, &id.ident);
    stage(2);
    let pair = match designs_on_model(&placed, target_bandwidth, constraints, out) {
        Ok(p) => p,
        Err(HarnessError::NoDesign(reason)) => {
            return no_design_on_model(staging, out, base, &all_judged, constraints, &reason)
        }
        Err(e) => return Err(e),
    };
    let mut pair = pair;
    let m = verification_base(config, sets, &placed.tuned_on)?;
    // The file's own drive, with a PMSM's calibration: what the machine runs it with.
    let mut own = resolve("fig6", Some(config), sets)?;
    if let Some(m) = &ident.motor {
        own.drive = identify::motor::calibrated(&own.drive, m)?;
    }
    let spread = Spread::measure(&own)?;
    let [droop_spread, shaft_spread, ..] = spread.range;
    let reference = tune::objective::Reference::of(&own, constraints.max_torque_noise_pu)?
        .with_spread([droop_spread, shaft_spread]);
    let reference_drive = judge_reference(&own, &placed.tuned_on, constraints)?;
    stage(3);
    let tried = try_on_machine(&m, &placed.tuned_on, &mut pair, &reference, constraints)?;
    pair.with.result.config = placed.name.into();
    pair.without.result.config = placed.name.into();
    let (runs, objective) = both_on_machine(&m, &mut pair, &reference, &tried)?;
    let tune_md = staging.path("tune/tune.md")?;
    tune::write_pair_as(
        tune_md.parent().unwrap_or(staging.dir()),
        &pair,
        &MODEL_FILES,
    )?;
    let afb = pair.afb_chosen();
    let (without_notch, same_gains_without_afb) =
        on_machine::comparisons(&m, &pair, placed.decision.notch.is_some())?;
    let c_run = if afb { &runs[0] } else { &runs[1] };
    let c_j = if afb { objective[0] } else { objective[1] };
    let (beats_the_file, passed) =
        on_machine::verdict(&reference, c_run, c_j, without_notch.as_ref());
    let no_design = !beats_the_file;
    let drives = if no_design {
        Vec::new()
    } else {
        drive_files(&machine, &base.config_path, &pair, passed)?
    };
    let files = files::listed(&id.file, placed.file.as_ref(), &pair, placed.name, &drives);
    let c = Commissioning {
        config: base.config_path.display().to_string(),
        tried,
        runs,
        chosen: if afb { "with AFB" } else { "without AFB" },
        reference,
        objective,
        notch: placed.decision,
        without_notch,
        passed,
        no_design,
        reference_drive,
        spread,
        same_gains_without_afb,
        files,
    };
    stage(4);
    write::write_all(&staging, &c, base, ident, &pair)?;
    for (name, text, _) in &drives {
        staging.write(name, text)?;
    }
    staging.commit()?;
    finish(&c, &pair, out)
}

/// No design meets the constraints on the model (`reason`, naming the file tuned on where
/// it is staged): the identification stands on its own, so it is kept with a
/// `commission.md` of the closest designs (`all_judged`) and what each misses, and the
/// command exits with the no-design code.
fn no_design_on_model(
    staging: Staging,
    out: &Path,
    base: &RunConfig,
    all_judged: &[tune::Judged],
    constraints: &Constraints,
    reason: &str,
) -> Result<String> {
    // The user finds the file tuned on under `out`.
    let staged = staging.dir().display().to_string();
    let reason = reason.replace(&staged, &out.display().to_string());
    let md = no_design::markdown(
        &base.config_path.display().to_string(),
        all_judged,
        constraints,
        &reason,
    );
    staging.write("commission.md", &md)?;
    staging.commit()?;
    Err(HarnessError::NoDesign(format!(
        "{reason}; the identification is in {} (identify/, identified.toml), the \
         closest designs and what each misses in {}",
        out.display(),
        out.join("commission.md").display()
    )))
}

/// The command's line, or its error when the commissioning did not pass.
fn finish(c: &Commissioning, pair: &tune::pair::Pair, out: &Path) -> Result<String> {
    let notch = c.notch.notch.map_or_else(
        || "no notch".to_string(),
        |n| format!("notch at {:.1} Hz", n.centre_hz),
    );
    let line = format!(
        "commission {}: {}; {notch}; on the machine: J {:.3} with AFB, {:.3} without \
         (the file's own drive 3), ripple {:.4} pu with AFB ({}), {:.4} pu without ({}) -> {}",
        c.config,
        tune::pair_line(pair, &out.join("tune")),
        c.objective[0],
        c.objective[1],
        c.runs[0].shaft_torque_ripple_rms_pu,
        c.runs[0].verdict(),
        c.runs[1].shaft_torque_ripple_rms_pu,
        c.runs[1].verdict(),
        out.display()
    );
    if c.passed {
        Ok(line)
    } else if c.no_design {
        Err(HarnessError::NoDesign(format!(
            "{line}: none of the {} designs tried beats the machine file's own drive on the \
             machine; keep that drive (the identification is in identify/ and \
             identified.toml, every design tried in commission.md)",
            c.tried.len()
        )))
    } else {
        Err(HarnessError::NotPassed(format!(
            "{line}: the chosen design did not pass on the machine (commission.md)"
        )))
    }
}
