//! `hil-harness commission --config CFG --out DIR`: from measurement to a verified design,
//! as a drive engineer commissions a machine whose parameters nobody gave them.
//!
//! 1. **Identify** the machine of `CFG` in the closed loop ([`super::identify`]): the
//!    estimator reads only the recorded signals. `DIR/identify/` gets its files.
//! 2. **The identified machine file**, `DIR/identified.toml`: `CFG` (with `--set` applied)
//!    with its `[plant]` table replaced by the identified one. Everything the drive knows of
//!    the machine now comes from the measurement.
//! 3. **Tune** on the identified file ([`super::tune`]), with AFB (`DIR/tune/`), and the
//!    no-AFB design by the same constraints, for the comparison ([`tune::pair`]).
//! 4. **Verify on the machine itself**: both drives run `fig6` (a move with a load step)
//!    against the plant of `CFG`, not the identified one. The commissioning passes by
//!    [`tune::pair::CRITERION`]: the AFB design is stable, does not fault, and leaves less
//!    shaft-torque ripple after the load step than the no-AFB design. `DIR/commission.md` and `DIR/commission.json`
//!    hold the figures; the command fails (after writing them) when it does not pass.
//!
//! Everything is staged: on an error before the verification nothing is written.

mod write;

use crate::config::{config_path, overrides, read_table, resolve, RunConfig};
use crate::error::{HarnessError, Result};
use crate::experiments::identify::{self, lost_motion::identified_mechanics};
use crate::experiments::tune::{self, Constraints};
use crate::output::Staging;
use std::path::Path;
use toml::Value;

/// The verification of one drive on the machine itself.
pub use crate::experiments::tune::pair::LoopRun as OnMachine;

/// What `commission` found.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Commissioning {
    /// The machine file.
    pub config: String,
    /// The AFB design and the no-AFB design, verified on the machine.
    pub runs: [OnMachine; 2],
    /// The AFB design passed (stable, no fault, less ripple than the no-AFB design).
    pub passed: bool,
}

/// `CFG` with `sets` applied and its `[plant]` table replaced by the identified one.
fn identified_file(
    config: &str,
    sets: &[String],
    base: &RunConfig,
    ident: &identify::Identification,
) -> Result<String> {
    let mut doc = read_table(&config_path(config)?)?;
    overrides::apply_all(&mut doc, sets)?;
    // The measurement's own settings are not part of the machine.
    doc.remove("identify");
    let plant = identified_mechanics(base, &ident.fit.fit, ident.lost_motion.backlash_deg);
    let table = Value::try_from(plant)
        .map_err(|e| HarnessError::Backend(format!("identified.toml: {e}")))?;
    doc.insert("plant".into(), table);
    let body = toml::to_string(&doc)
        .map_err(|e| HarnessError::Backend(format!("identified.toml: {e}")))?;
    Ok(format!(
        "# `hil-harness commission`: {} with the [plant] table `identify` measured.\n{body}",
        base.config_path.display()
    ))
}

/// `design`'s drive (tuned on the identified machine) running `scenario` against the
/// machine of `config` itself.
fn on_machine(
    scenario: &str,
    config: &str,
    sets: &[String],
    identified: &str,
    label: &'static str,
    design: &tune::Candidate,
) -> Result<OnMachine> {
    let mut cfg = resolve(scenario, Some(identified), &[])?;
    let machine = resolve(scenario, Some(config), sets)?;
    cfg.plant = machine.plant;
    cfg.config_path = machine.config_path;
    OnMachine::run(cfg, label, design)
}

/// `hil-harness commission`.
pub fn commission(
    config: &str,
    sets: &[String],
    target_bandwidth: Option<f64>,
    constraints: &Constraints,
    out: &Path,
) -> Result<String> {
    // A bad bandwidth is reported before the identification.
    tune::bandwidths(target_bandwidth)?;
    let (base, spec) = identify::load(config, sets)?;
    let ident = identify::identify_machine(&base, &spec)?;
    let staging = Staging::new(out)?;
    let dir = staging.dir();
    let id_dir = staging.path("identify/identify.md")?;
    let id_dir = id_dir.parent().unwrap_or(dir);
    identify::write::write_all(id_dir, &base, &spec, &ident)?;
    let identified = staging.write(
        "identified.toml",
        &identified_file(config, sets, &base, &ident)?,
    )?;
    let identified = identified.display().to_string();

    let pair = tune::pair::design_both(&identified, target_bandwidth, constraints)?;
    let (mut with, without) = (pair.with, pair.without.result);
    with.result.config = "identified.toml".into();
    let tune_md = staging.path("tune/tune.md")?;
    tune::write_design(tune_md.parent().unwrap_or(dir), &with)?;

    let runs = [
        on_machine(
            "fig6",
            config,
            sets,
            &identified,
            "tuned with AFB",
            &with.result.design.candidate,
        )?,
        on_machine(
            "fig6",
            config,
            sets,
            &identified,
            "tuned without AFB",
            &without.design.candidate,
        )?,
    ];
    let [a, b] = &runs;
    let passed = tune::pair::afb_passes(a, b);
    let c = Commissioning {
        config: base.config_path.display().to_string(),
        runs,
        passed,
    };
    write::write_all(&staging, &c, &base, &ident, &with)?;
    staging.commit()?;
    let line = format!(
        "commission {}: {}; on the machine: ripple {:.4} pu with AFB, {:.4} pu without -> {}",
        c.config,
        tune::summary_line(&with, &out.join("tune")),
        c.runs[0].shaft_torque_ripple_rms_pu,
        c.runs[1].shaft_torque_ripple_rms_pu,
        out.display()
    );
    if c.passed {
        Ok(line)
    } else {
        Err(HarnessError::Backend(format!(
            "{line}: the AFB design did not pass on the machine (commission.md)"
        )))
    }
}
