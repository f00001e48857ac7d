//! The JSON Schema of a machine file (`configs/machines/*.toml`): plant-host's tables and
//! controller-core's `[drive]`, each generated from its type (schemars), with the bounds of
//! the owners' range tables (`plant_host::RANGES`, `controller_core::RANGES`) as
//! `minimum`/`maximum`. An editor with a TOML language server (taplo, Even Better TOML)
//! completes and checks a drive file against it: `hil-harness schema --out FILE`.
//!
//! And the schema of the grids file (`configs/grids.toml`, [`super::grids`]), with the
//! bounds of [`super::grids::RANGES`]: `hil-harness schema --grids`.

use super::grids::{GridsFile, MAX_VALUES, RANGES as GRID_RANGES};
use super::machine::MACHINE_KEYS;
use crate::error::{HarnessError, Result};
use serde_json::{Map, Value};

/// Follows `$ref`s (`#/$defs/Name`) in `root` from `node`.
fn resolved<'a>(root: &'a Value, mut node: &'a Value) -> &'a Value {
    while let Some(r) = node.get("$ref").and_then(Value::as_str) {
        let Some(name) = r.strip_prefix("#/$defs/") else {
            break;
        };
        match root.get("$defs").and_then(|d| d.get(name)) {
            Some(next) => node = next,
            None => break,
        }
    }
    node
}

/// The JSON pointers of every schema that holds the property at `path` (dotted), from
/// `at`: through `$ref`s, into each alternative of a `oneOf`/`anyOf` (a tagged enum).
fn holders(root: &Value, at: String, path: &[&str], out: &mut Vec<String>) {
    let Some(node) = root.pointer(&at) else {
        return;
    };
    let node = resolved(root, node);
    let here = pointer_of(root, node).unwrap_or(at);
    let Some((first, rest)) = path.split_first() else {
        out.push(here);
        return;
    };
    for alt in ["oneOf", "anyOf"] {
        if let Some(n) = node.get(alt).and_then(Value::as_array).map(Vec::len) {
            for i in 0..n {
                holders(root, format!("{here}/{alt}/{i}"), path, out);
            }
        }
    }
    if node.get("properties").and_then(|p| p.get(*first)).is_some() {
        holders(root, format!("{here}/properties/{first}"), rest, out);
    }
}

/// The JSON pointer of `node` inside `root`'s `$defs`, or `None` for an inline node.
fn pointer_of(root: &Value, node: &Value) -> Option<String> {
    let defs = root.get("$defs")?.as_object()?;
    defs.iter()
        .find(|(_, v)| std::ptr::eq(*v, node))
        .map(|(k, _)| format!("/$defs/{k}"))
}

/// Writes the bounds of one key into every schema that holds it.
fn bound(root: &mut Value, base: &str, key: &str, bounds: &[(&str, f64)]) -> Result<()> {
    let path: Vec<&str> = key.split('.').collect();
    let mut at = Vec::new();
    holders(root, base.to_string(), &path, &mut at);
    if at.is_empty() {
        return Err(HarnessError::Backend(format!(
            "schema: the range table's key `{key}` is not in the generated schema"
        )));
    }
    for p in at {
        if let Some(Value::Object(o)) = root.pointer_mut(&p) {
            for (name, v) in bounds {
                if v.is_finite() {
                    o.insert((*name).into(), Value::from(*v));
                }
            }
        }
    }
    Ok(())
}

fn to_value(schema: schemars::Schema) -> Result<Value> {
    serde_json::to_value(schema).map_err(|e| HarnessError::Backend(format!("schema: {e}")))
}

/// The schema of a machine file, every range bound in it.
pub fn machine_schema() -> Result<Value> {
    let mut root = to_value(schemars::schema_for!(plant_host::PlantConfig))?;
    let drive = to_value(schemars::schema_for!(controller_core::DriveConfig))?;
    let mut defs = root
        .get("$defs")
        .and_then(Value::as_object)
        .cloned()
        .unwrap_or_default();
    let mut drive_root = drive.as_object().cloned().unwrap_or_default();
    if let Some(Value::Object(d)) = drive_root.remove("$defs") {
        for (k, v) in d {
            if defs.insert(k.clone(), v).is_some() {
                return Err(HarnessError::Backend(format!(
                    "schema: plant and drive both define `{k}`"
                )));
            }
        }
    }
    drive_root.remove("$schema");
    if let Value::Object(o) = &mut root {
        o.insert("$defs".into(), Value::Object(defs));
        let props = o
            .entry("properties")
            .or_insert_with(|| Value::Object(Map::new()));
        if let Value::Object(p) = props {
            p.insert("drive".into(), Value::Object(drive_root));
        }
    }
    for r in plant_host::RANGES {
        let b = match r.allowed {
            plant_host::Allowed::Real { min, max } => vec![("minimum", min), ("maximum", max)],
            plant_host::Allowed::Integer { min, max } => {
                vec![("minimum", min as f64), ("maximum", max as f64)]
            }
            plant_host::Allowed::Words(_) | plant_host::Allowed::Bool => continue,
        };
        bound(&mut root, "", r.key, &b)?;
    }
    // The machine keys of `[drive]` default to the plant's values (`machine`).
    if let Some(Value::Array(req)) = root.pointer_mut("/properties/drive/required") {
        req.retain(|k| !k.as_str().is_some_and(|k| MACHINE_KEYS.contains(&k)));
    }
    // An f32 bound as the decimal it was written as (0.1, not 0.10000000149).
    let decimal = |v: f32| format!("{v}").parse::<f64>().unwrap_or(f64::from(v));
    for r in controller_core::RANGES {
        let low = if r.min_exclusive {
            "exclusiveMinimum"
        } else {
            "minimum"
        };
        let b = [(low, decimal(r.min)), ("maximum", decimal(r.max))];
        bound(&mut root, "/properties/drive", r.key, &b)?;
    }
    Ok(root)
}

/// What marks a file as this command's output: JSON whose root is titled `PlantConfig`
/// with a `$schema` and a `drive` property titled `DriveConfig` (what `machine_schema`
/// writes, in this version and the earlier ones).
pub const SCHEMA_MARK: crate::output::FileMark = crate::output::FileMark {
    what: "a machine-file JSON Schema stiffdrive wrote",
    is_ours: is_machine_schema,
};

fn is_machine_schema(bytes: &[u8]) -> bool {
    serde_json::from_slice::<Value>(bytes).is_ok_and(|v| {
        v.get("$schema").is_some()
            && v.get("title").and_then(Value::as_str) == Some("PlantConfig")
            && v.pointer("/properties/drive/title").and_then(Value::as_str) == Some("DriveConfig")
    })
}

/// The schema of the grids file, every list's bounds in it: `minItems`/`maxItems` on the
/// list, `minimum` (or `exclusiveMinimum`) and `maximum` on its values.
pub fn grids_schema() -> Result<Value> {
    let mut root = to_value(schemars::schema_for!(GridsFile))?;
    for r in GRID_RANGES {
        let (list, field) = match r.key.split_once('.') {
            Some((list, field)) => (list, vec![field]),
            None => (r.key, Vec::new()),
        };
        let at = format!("/$defs/Grid/properties/{list}");
        if let Some(Value::Object(o)) = root.pointer_mut(&at) {
            o.insert("minItems".into(), Value::from(1));
            o.insert("maxItems".into(), Value::from(MAX_VALUES));
        }
        let low = if r.min_exclusive {
            "exclusiveMinimum"
        } else {
            "minimum"
        };
        let bounds = [(low, r.min), ("maximum", r.max)];
        let mut holders_of = Vec::new();
        holders(&root, format!("{at}/items"), &field, &mut holders_of);
        if holders_of.is_empty() {
            return Err(HarnessError::Backend(format!(
                "schema: the grid key `{}` is not in the generated schema",
                r.key
            )));
        }
        for p in holders_of {
            if let Some(Value::Object(o)) = root.pointer_mut(&p) {
                for (name, v) in bounds {
                    o.insert(name.into(), Value::from(v));
                }
            }
        }
    }
    Ok(root)
}

/// What marks a file as `schema --grids`'s output: JSON whose root is titled `GridsFile`
/// with a `$schema`.
pub const GRIDS_SCHEMA_MARK: crate::output::FileMark = crate::output::FileMark {
    what: "a grids-file JSON Schema stiffdrive wrote",
    is_ours: is_grids_schema,
};

fn is_grids_schema(bytes: &[u8]) -> bool {
    serde_json::from_slice::<Value>(bytes).is_ok_and(|v| {
        v.get("$schema").is_some() && v.get("title").and_then(Value::as_str) == Some("GridsFile")
    })
}

/// Which file `hil-harness schema` describes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SchemaOf {
    /// A machine file (`configs/machines/*.toml`).
    Machine,
    /// The grids file (`configs/grids.toml`).
    Grids,
}

impl SchemaOf {
    /// Where `schema` writes without `--out`, from the working directory.
    #[must_use]
    pub fn default_out(self) -> &'static str {
        match self {
            Self::Machine => "configs/machine.schema.json",
            Self::Grids => "configs/grids.schema.json",
        }
    }
}

/// `hil-harness schema [--grids] --out FILE`: writes the schema as pretty JSON (an existing
/// file only if it is a schema of the same kind stiffdrive wrote; see [`SCHEMA_MARK`],
/// [`GRIDS_SCHEMA_MARK`]).
pub fn write_schema(of: SchemaOf, out: &std::path::Path) -> Result<String> {
    let (mark, schema, what) = match of {
        SchemaOf::Machine => (
            &SCHEMA_MARK,
            machine_schema as fn() -> Result<Value>,
            "machine",
        ),
        SchemaOf::Grids => (
            &GRIDS_SCHEMA_MARK,
            grids_schema as fn() -> Result<Value>,
            "grids",
        ),
    };
    crate::output::check_file_target(out, mark)?;
    let text = serde_json::to_string_pretty(&schema()?)
        .map_err(|e| HarnessError::Backend(format!("schema: {e}")))?;
    crate::output::write_file(out, (text + "\n").as_bytes(), mark)?;
    Ok(format!("{what}-file JSON Schema -> {}", out.display()))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn every_range_is_in_the_schema_and_the_committed_schema_is_current() {
        let s = machine_schema().unwrap();
        let drive = &s["properties"]["drive"];
        assert_eq!(
            resolved(
                &s,
                &s["$defs"]["AccelFeedbackConfig"]["properties"]["gain_fraction"]
            )["maximum"],
            20.0
        );
        let required: Vec<&str> = drive["required"]
            .as_array()
            .unwrap()
            .iter()
            .filter_map(Value::as_str)
            .collect();
        assert!(required.contains(&"current_rate_hz"), "{required:?}");
        assert!(!required.contains(&"motor_inertia_s"), "{required:?}");
        let text = serde_json::to_string_pretty(&s).unwrap() + "\n";
        let committed =
            std::fs::read_to_string(crate::config::configs_dir().join("machine.schema.json"))
                .unwrap();
        assert!(
            committed == text,
            "configs/machine.schema.json is stale: run `cargo run --release -- schema`"
        );
    }

    #[test]
    fn the_grids_schema_holds_the_ranges_and_the_committed_one_is_current() {
        let s = grids_schema().unwrap();
        let grid = &s["$defs"]["Grid"]["properties"];
        assert_eq!(grid["gains"]["minItems"], 1);
        assert_eq!(grid["gains"]["items"]["maximum"], 20.0);
        assert_eq!(grid["bandwidths_rad_s"]["items"]["exclusiveMinimum"], 0.0);
        let filters = s["$defs"]["GridFilter"]["oneOf"].as_array().unwrap();
        assert_eq!(filters.len(), 2);
        for f in filters {
            assert_eq!(f["properties"]["corner_hz"]["maximum"], 500.0, "{f}");
        }
        let text = serde_json::to_string_pretty(&s).unwrap() + "\n";
        let committed =
            std::fs::read_to_string(crate::config::configs_dir().join("grids.schema.json"))
                .unwrap();
        assert!(
            committed == text,
            "configs/grids.schema.json is stale: run `cargo run --release -- schema --grids`"
        );
        assert!(is_grids_schema(text.as_bytes()));
        assert!(!is_machine_schema(text.as_bytes()));
    }

    #[test]
    fn a_key_the_schema_lacks_is_an_error() {
        let mut s = machine_schema().unwrap();
        assert!(bound(&mut s, "", "plant.no_such_key", &[("minimum", 0.0)]).is_err());
    }
}
