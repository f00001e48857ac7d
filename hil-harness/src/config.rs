//! Resolving what one run uses: the config file (by path or name under `configs/`), the
//! scenario's `set` overrides, then the command line's `--set`, parsed into plant-host's
//! `PlantConfig` and controller-core's `DriveConfig`.

use crate::drive::{drive_config, MachineDefaults};
use crate::error::{HarnessError, Result};
use crate::overrides;
use crate::scenario::{configs_dir, ScenarioFile, ScenarioSpec};
use controller_core::{AfbMode, DriveConfig};
use plant_host::PlantConfig;
use std::path::{Path, PathBuf};
use toml::Table;

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

/// The AFB run a comparison run takes its regulator gains from. "The same gains without
/// AFB" means bit-identical gains: the run builds its controller with
/// `Controller::with_gains(own drive, design(AFB drive) with Ka = 0)`
/// ([`crate::runner::regulator_gains`]), never by designing its own.
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

/// Finds a config by path, or by name as `configs/NAME.toml`.
pub fn config_path(name_or_path: &str) -> Result<PathBuf> {
    let p = Path::new(name_or_path);
    if p.is_file() {
        return Ok(p.to_path_buf());
    }
    // Project configs first, then the harness's own test-stand plants.
    for dir in [
        configs_dir(),
        configs_dir().join("scenarios").join("plants"),
    ] {
        let by_name = dir.join(format!("{name_or_path}.toml"));
        if by_name.is_file() {
            return Ok(by_name);
        }
    }
    Err(HarnessError::io(
        p,
        "no such config file (give a path or a name under configs/)",
    ))
}

/// Reads a TOML file into a table.
pub fn read_table(path: &Path) -> Result<Table> {
    let text = std::fs::read_to_string(path).map_err(|e| HarnessError::io(path, e))?;
    text.parse::<Table>().map_err(|e| HarnessError::Parse {
        path: path.to_path_buf(),
        reason: e.to_string(),
    })
}

/// The machine values the drive takes from the plant unless `[drive]` overrides them.
pub fn machine_defaults(plant: &PlantConfig) -> MachineDefaults {
    MachineDefaults {
        base_speed_rpm: plant.mechanics.base_speed_rpm as f32,
        // The drive counts what the interpolator delivers.
        encoder_cpr: plant.counts_per_rev(),
        motor_inertia_s: plant.mechanics.motor_inertia_s as f32,
        load_inertia_s: plant.mechanics.load_inertia_s as f32,
        winding_resistance_pu: plant.electrics.winding_resistance_pu as f32,
        winding_inductance_pu_s: plant.electrics.winding_inductance_pu_s as f32,
    }
}

/// The tables a machine config may hold: plant-host's and the drive's.
pub const CONFIG_TABLES: [&str; 5] = ["plant", "electrics", "sensors", "lost_motion", "drive"];

/// Parses plant and drive from a (merged) document. A top-level key that is not one of
/// [`CONFIG_TABLES`] (a misspelt table) is an error: nothing would read it.
pub fn plant_and_drive(doc: &Table) -> Result<(PlantConfig, DriveConfig)> {
    if let Some(k) = doc.keys().find(|k| !CONFIG_TABLES.contains(&k.as_str())) {
        return Err(HarnessError::config(
            k.as_str(),
            format!(
                "unknown table `[{k}]`: nothing reads it (a config has {})",
                CONFIG_TABLES.map(|t| format!("[{t}]")).join(", ")
            ),
        ));
    }
    let mut plant_tables = doc.clone();
    plant_tables.remove("drive");
    let plant = PlantConfig::from_table(plant_tables).map_err(plant_error)?;
    let drive = drive_config(doc, &machine_defaults(&plant))?;
    Ok((plant, drive))
}

fn plant_error(e: plant_host::ConfigError) -> HarnessError {
    HarnessError::config(e.key(), e.to_string())
}

/// Loads scenario `name` and its config (or `config_override`), applying the scenario's
/// `set` table and then `sets` (`section.key=value`).
pub fn resolve(name: &str, config_override: Option<&str>, sets: &[String]) -> Result<RunConfig> {
    resolve_with(name, config_override, sets, true)
}

/// [`resolve`]; `borrow` = false for the AFB run a comparison names (it must design its
/// own gains, so a chain or a cycle of `gains_of` is an error, not a recursion).
fn resolve_with(
    name: &str,
    config_override: Option<&str>,
    sets: &[String],
    borrow: bool,
) -> Result<RunConfig> {
    // Validates the name and lists the known scenarios if it does not exist.
    crate::scenario::load_scenario(name)?;
    let scenario_path = configs_dir().join("scenarios").join(format!("{name}.toml"));
    let mut scenario_doc = read_table(&scenario_path)?;

    let (scenario_sets, config_sets): (Vec<String>, Vec<String>) = sets
        .iter()
        .cloned()
        .partition(|s| s.trim_start().starts_with("scenario."));
    overrides::apply_all(&mut scenario_doc, &scenario_sets)?;
    let file: ScenarioFile = scenario_doc
        .clone()
        .try_into()
        .map_err(|e: toml::de::Error| {
            HarnessError::config(format!("scenario ({name})"), e.message().to_string())
        })?;
    let scenario = file.scenario;
    scenario.validate()?;

    let config_path = config_path(config_override.unwrap_or(&scenario.config))?;
    let mut doc = read_table(&config_path)?;
    for (key, value) in &scenario.set {
        overrides::set(&mut doc, key, value.clone())?;
    }
    overrides::apply_all(&mut doc, &config_sets)?;
    let (plant, drive) = plant_and_drive(&doc)?;
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
        let afb =
            resolve_with(&c.gains_of, config_override, &config_sets, false).map_err(
                |e| match e {
                    HarnessError::UnknownScenario { .. } => {
                        HarnessError::config("scenario.comparison.gains_of", e.to_string())
                    }
                    other => other,
                },
            )?;
        borrow_gains(&mut cfg, &c.gains_of, &afb.drive)?;
    }
    Ok(cfg)
}
