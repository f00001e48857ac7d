//! Resolving what one run uses: the scenario file's value tree with the `scenario.*`
//! overrides, then the config file's value tree (by path or name under `configs/`) with the
//! scenario's `set` table and the command line's other `--set`s, each deserialized once
//! into its owner's type.

use super::files::{config_path, read_table, scenario_of, scenario_table};
use super::machine::machine;
use super::overrides;
use super::scenario::ScenarioSpec;
use crate::engine::metrics::{MachineBands, MetricWindows};
use crate::error::{HarnessError, Result};
use controller_core::{AfbMode, DriveConfig};
use plant_host::PlantConfig;
use std::path::PathBuf;

/// Everything one closed-loop run needs.
#[derive(Clone, Debug)]
pub struct RunConfig {
    /// Scenario name.
    pub name: String,
    /// The scenario (after `scenario.*` overrides).
    pub scenario: ScenarioSpec,
    /// The plant.
    pub plant: PlantConfig,
    /// The drive.
    pub drive: DriveConfig,
    /// The config file used.
    pub config_path: PathBuf,
    /// Where this run's regulator gains come from when it is a comparison "without AFB":
    /// the AFB run whose design it borrows ([`GainsOf`]); `None` = its own design.
    pub gains_of: Option<GainsOf>,
}

impl RunConfig {
    /// The scenario's metric windows with this machine's bands and count-rate tone
    /// ([`MachineBands`]).
    pub fn metric_windows(&self) -> MetricWindows {
        let m = &self.plant.mechanics;
        let d = m.derived();
        let hz = |rad_s: f64| rad_s / (2.0 * std::f64::consts::PI);
        let mut w = self
            .scenario
            .metric_windows(f64::from(self.drive.torque_limit_pu));
        w.machine = Some(MachineBands {
            counts_per_s_per_pu: m.base_speed_rpm / 60.0 * f64::from(self.plant.counts_per_rev()),
            velocity_bandwidth_hz: hz(f64::from(self.drive.velocity_bandwidth_rad_s)),
            resonance_band_hz: (
                0.7 * hz(d.anti_resonance_rad_s),
                1.4 * hz(d.resonance_rad_s),
            ),
        });
        w
    }
}

/// The AFB run a comparison run takes its regulator gains from. "The same gains without
/// AFB" means bit-identical gains: the run builds its controller with
/// `Controller::from_gains(design(AFB drive) with Ka = 0, carrying its own drive)`
/// ([`crate::engine::runner::regulator_gains`]), never by designing its own.
#[derive(Clone, Debug, PartialEq)]
pub struct GainsOf {
    /// What the gains are: a scenario name (`scenario.comparison.gains_of`) or the
    /// experiment's name for its AFB design (sweep, stiffness, Sec. II map).
    pub source: String,
    /// The AFB run's drive; its `design()` with Ka = 0 gives the gains.
    pub drive: DriveConfig,
}

/// Makes `cfg` (acceleration feedback off) a comparison run at the gains of `afb_drive`
/// (acceleration feedback on). The two drives may differ only in `[drive.accel_feedback]`:
/// anything else would not be "the same drive without AFB".
pub fn borrow_gains(cfg: &mut RunConfig, source: &str, afb_drive: &DriveConfig) -> Result<()> {
    let key = "scenario.comparison.gains_of";
    if cfg.drive.accel_feedback.mode != AfbMode::Off {
        return Err(HarnessError::config(
            key,
            format!("a run at the gains of {source} must have drive.accel_feedback.mode = \"off\""),
        ));
    }
    if afb_drive.accel_feedback.mode == AfbMode::Off {
        return Err(HarnessError::config(
            key,
            format!("{source} has acceleration feedback off: there are no AFB gains to borrow"),
        ));
    }
    let mut same = afb_drive.to_owned();
    same.accel_feedback = cfg.drive.accel_feedback;
    if same != cfg.drive {
        return Err(HarnessError::config(
            key,
            format!(
                "the drive of {} differs from that of {source} in more than \
                 [drive.accel_feedback]; a comparison without AFB must be the same drive",
                cfg.name
            ),
        ));
    }
    cfg.gains_of = Some(GainsOf {
        source: source.to_string(),
        drive: *afb_drive,
    });
    Ok(())
}

/// Loads scenario `name` and its config (or `config_override`), applying the scenario's
/// `set` table and then `sets` (`section.key=value`).
pub fn resolve(name: &str, config_override: Option<&str>, sets: &[String]) -> Result<RunConfig> {
    resolve_with(name, config_override, sets, true, true)
}

/// Scenario `name` on the machine `config` as the file describes it, then `sets`: the
/// scenario's `set` table (which tunes the shipped machine for its experiment) is not
/// applied, so the run has the file's plant and drive.
pub fn resolve_on_machine(name: &str, config: &str, sets: &[String]) -> Result<RunConfig> {
    resolve_with(name, Some(config), sets, true, false)
}

/// [`resolve`]; `borrow` = false for the AFB run a comparison names (it must design its
/// own gains, so a chain or a cycle of `gains_of` is an error, not a recursion).
fn resolve_with(
    name: &str,
    config_override: Option<&str>,
    sets: &[String],
    borrow: bool,
    scenario_set: bool,
) -> Result<RunConfig> {
    let (scenario_sets, config_sets): (Vec<String>, Vec<String>) = sets
        .iter()
        .cloned()
        .partition(|s| s.trim_start().starts_with("scenario."));
    let mut scenario_doc = scenario_table(name)?;
    overrides::apply_all(&mut scenario_doc, &scenario_sets)?;
    let scenario = scenario_of(scenario_doc)?;

    let config_path = config_path(config_override.unwrap_or(&scenario.config))?;
    let mut doc = read_table(&config_path)?;
    for (key, value) in scenario.set.iter().filter(|_| scenario_set) {
        overrides::set(&mut doc, key, value.clone())?;
    }
    overrides::apply_all(&mut doc, &config_sets)?;
    let (plant, drive) = machine(doc)?;
    let mut cfg = RunConfig {
        name: name.to_string(),
        scenario,
        plant,
        drive,
        config_path,
        gains_of: None,
    };
    if let Some(c) = cfg.scenario.comparison.clone() {
        if !borrow {
            return Err(HarnessError::config(
                "scenario.comparison.gains_of",
                format!("{name} itself borrows its gains; name the AFB run that designs them"),
            ));
        }
        // The AFB run under the same config file and command-line settings (scenario.*
        // settings belong to this scenario only).
        let afb = resolve_with(
            &c.gains_of,
            config_override,
            &config_sets,
            false,
            scenario_set,
        )
        .map_err(|e| match e {
            HarnessError::UnknownScenario { .. } => {
                HarnessError::config("scenario.comparison.gains_of", e.to_string())
            }
            other => other,
        })?;
        borrow_gains(&mut cfg, &c.gains_of, &afb.drive)?;
    }
    Ok(cfg)
}
