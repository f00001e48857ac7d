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

/// The machine files' folder, `configs/machines/`.
pub fn machines_dir() -> PathBuf {
    configs_dir().join("machines")
}

/// Names of the scenarios under `configs/scenarios/`, sorted.
pub fn known_scenarios() -> Vec<String> {
    scenarios_in(&configs_dir().join("scenarios"))
}

/// The scenario names in the folder `dir`, sorted.
fn scenarios_in(dir: &Path) -> Vec<String> {
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

/// The value tree of `configs/scenarios/NAME.toml`, with its `extends` resolved; a name with
/// no file (or not a plain name) lists the known scenarios.
pub fn scenario_table(name: &str) -> Result<Table> {
    scenario_table_in(&configs_dir().join("scenarios"), name, &mut Vec::new())
}

/// How many scenarios an `extends` chain may hold: enough for any real use, and a bound on
/// a chain that loops.
const MAX_EXTENDS_DEPTH: usize = 8;

/// [`scenario_table`] from the scenario folder `dir`, `chain` holding the scenarios that
/// extend this one (to refuse a loop).
fn scenario_table_in(dir: &Path, name: &str, chain: &mut Vec<String>) -> Result<Table> {
    let path = dir.join(format!("{name}.toml"));
    if !is_scenario_in(dir, name) {
        return Err(HarnessError::UnknownScenario {
            name: name.to_string(),
            known: known_scenarios(),
        });
    }
    let mut doc = read_table(&path)?;
    let parent = match doc.get_mut("scenario").and_then(|s| s.as_table_mut()) {
        Some(spec) => spec.remove("extends"),
        None => None,
    };
    let Some(parent) = parent else {
        return Ok(doc);
    };
    let Some(parent) = parent.as_str().map(str::to_string) else {
        return Err(HarnessError::config(
            "scenario.extends",
            "must be the name of a scenario under configs/scenarios/",
        ));
    };
    if !is_scenario_in(dir, &parent) {
        return Err(HarnessError::config(
            "scenario.extends",
            format!(
                "no scenario `{parent}`: one of {}",
                scenarios_in(dir).join(", ")
            ),
        ));
    }
    chain.push(name.to_string());
    if chain.contains(&parent) || chain.len() > MAX_EXTENDS_DEPTH {
        chain.push(parent);
        return Err(HarnessError::config(
            "scenario.extends",
            format!(
                "a loop or a chain longer than {MAX_EXTENDS_DEPTH}: {}",
                chain.join(" extends ")
            ),
        ));
    }
    let mut base = scenario_table_in(dir, &parent, chain)?;
    merge_over(&mut base, doc);
    Ok(base)
}

/// Whether `name` is a plain name with a scenario file in `dir`.
fn is_scenario_in(dir: &Path, name: &str) -> bool {
    let plain = !name.is_empty()
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_');
    plain && dir.join(format!("{name}.toml")).is_file()
}

/// `over` laid on `base`: a table present in both is merged key by key, anything else
/// (values, arrays such as `[[scenario.load]]`) is replaced by `over`'s.
fn merge_over(base: &mut Table, over: Table) {
    for (key, value) in over {
        match (base.get_mut(&key), value) {
            (Some(toml::Value::Table(b)), toml::Value::Table(o)) => merge_over(b, o),
            (_, value) => {
                base.insert(key, value);
            }
        }
    }
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

/// Finds a machine file by path, or by name as `configs/machines/NAME.toml`.
pub fn config_path(name_or_path: &str) -> Result<PathBuf> {
    let p = Path::new(name_or_path);
    if p.is_file() {
        return Ok(p.to_path_buf());
    }
    let valid = !name_or_path.is_empty()
        && name_or_path
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_');
    let by_name = machines_dir().join(format!("{name_or_path}.toml"));
    if valid && by_name.is_file() {
        return Ok(by_name);
    }
    Err(HarnessError::io(
        p,
        "no such machine file (give a path, or a name under configs/machines/)",
    ))
}

/// Reads a TOML file into a value tree.
pub fn read_table(path: &Path) -> Result<Table> {
    Ok(machine_file::read(path)?)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;

    fn write(dir: &Path, name: &str, text: &str) {
        std::fs::write(dir.join(format!("{name}.toml")), text).unwrap();
    }

    #[test]
    fn extends_lays_the_scenario_over_its_parent() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path();
        write(
            dir,
            "base",
            "[scenario]\ndescription = \"b\"\nconfig = \"table1\"\nduration_s = 2.5\n\
             [scenario.profile]\nspeed_pu = 1.0\naccel_s = 1.0\n\
             [[scenario.load]]\nt_s = 1.5\ntorque_pu = 0.5\n\
             [scenario.set]\n\"drive.velocity_bandwidth_rad_s\" = 50.0\n",
        );
        write(
            dir,
            "twin",
            "[scenario]\nextends = \"base\"\ndescription = \"t\"\n\
             [[scenario.load]]\nt_s = 1.0\ntorque_pu = 0.25\n\
             [scenario.set]\n\"drive.accel_feedback.mode\" = \"off\"\n",
        );
        let t = scenario_table_in(dir, "twin", &mut Vec::new()).unwrap();
        let s = t["scenario"].as_table().unwrap();
        assert_eq!(s["description"].as_str(), Some("t"));
        assert_eq!(
            s["duration_s"].as_float(),
            Some(2.5),
            "kept from the parent"
        );
        assert!(!s.contains_key("extends"));
        // Tables merge key by key; arrays are replaced whole.
        let set = s["set"].as_table().unwrap();
        assert_eq!(set.len(), 2, "{set:?}");
        let load = s["load"].as_array().unwrap();
        assert_eq!(load.len(), 1);
        assert_eq!(load[0]["t_s"].as_float(), Some(1.0));
    }

    #[test]
    fn an_extends_loop_or_a_missing_parent_is_an_error() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path();
        write(dir, "a", "[scenario]\nextends = \"b\"\n");
        write(dir, "b", "[scenario]\nextends = \"a\"\n");
        let e = scenario_table_in(dir, "a", &mut Vec::new())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("scenario.extends") && e.contains("a extends b extends a"),
            "{e}"
        );
        write(dir, "c", "[scenario]\nextends = \"nosuch\"\n");
        let e = scenario_table_in(dir, "c", &mut Vec::new())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("scenario.extends") && e.contains("nosuch") && e.contains("a, b, c"),
            "{e}"
        );
        write(dir, "d", "[scenario]\nextends = 3\n");
        let e = scenario_table_in(dir, "d", &mut Vec::new())
            .unwrap_err()
            .to_string();
        assert!(e.contains("scenario.extends"), "{e}");
    }
}
