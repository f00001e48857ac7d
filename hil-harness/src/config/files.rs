//! Where the configuration files are, and reading one into a TOML value tree.

use super::scenario::ScenarioSpec;
use super::typed::typed;
use crate::error::{HarnessError, Result};
use std::path::{Path, PathBuf};
use toml::Table;

/// The `configs/` directory: `$STIFFDRIVE_CONFIGS`, else the first `configs/scenarios`
/// found from the working directory upwards, else the one in this source tree.
pub fn configs_dir() -> PathBuf {
    if let Some(dir) = std::env::var_os("STIFFDRIVE_CONFIGS") {
        return PathBuf::from(dir);
    }
    if let Ok(cwd) = std::env::current_dir() {
        for dir in cwd.ancestors() {
            let c = dir.join("configs");
            if c.join("scenarios").is_dir() {
                return c;
            }
        }
    }
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join("configs")
}

/// Names of the scenarios under `configs/scenarios/`, sorted.
pub fn known_scenarios() -> Vec<String> {
    let dir = configs_dir().join("scenarios");
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .map(|rd| {
            rd.filter_map(|e| e.ok())
                .filter_map(|e| {
                    let p = e.path();
                    (p.extension().is_some_and(|x| x == "toml"))
                        .then(|| p.file_stem().map(|s| s.to_string_lossy().into_owned()))
                        .flatten()
                })
                .collect()
        })
        .unwrap_or_default();
    names.sort();
    names
}

/// The value tree of `configs/scenarios/NAME.toml`; a name with no file (or not a plain
/// name) lists the known scenarios.
pub fn scenario_table(name: &str) -> Result<Table> {
    let valid = !name.is_empty()
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_');
    let path = configs_dir().join("scenarios").join(format!("{name}.toml"));
    if !valid || !path.is_file() {
        return Err(HarnessError::UnknownScenario {
            name: name.to_string(),
            known: known_scenarios(),
        });
    }
    read_table(&path)
}

/// The scenario of a scenario file's value tree, validated.
pub fn scenario_of(doc: Table) -> Result<ScenarioSpec> {
    let file: super::scenario::ScenarioFile = typed("", toml::Value::Table(doc))?;
    file.scenario.validate()?;
    Ok(file.scenario)
}

/// Loads and validates `configs/scenarios/NAME.toml`.
pub fn load_scenario(name: &str) -> Result<ScenarioSpec> {
    scenario_of(scenario_table(name)?)
}

/// Finds a config by path, or by name as `configs/NAME.toml` (then the harness's own
/// test-stand plants, `configs/scenarios/plants/NAME.toml`).
pub fn config_path(name_or_path: &str) -> Result<PathBuf> {
    let p = Path::new(name_or_path);
    if p.is_file() {
        return Ok(p.to_path_buf());
    }
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

/// Reads a TOML file into a value tree.
pub fn read_table(path: &Path) -> Result<Table> {
    Ok(machine_file::read(path)?)
}
