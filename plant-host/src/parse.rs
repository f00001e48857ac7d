//! Reading a [`PlantConfig`] from a machine file's value tree: serde does the reading
//! (`deny_unknown_fields` throughout), `serde_path_to_error` gives the key of a failure, and
//! the range table ([`RANGES`]) turns it into a [`ConfigError`] that names the key and what
//! it allows. Then [`PlantConfig::validate`] checks the values.

use crate::config::{Allowed, PlantConfig, RANGES, range_of};
use crate::error::{ConfigError, PlantError};
use serde_path_to_error::Segment;
use std::path::Path;
use toml::{Table, Value};

impl PlantConfig {
    /// The plant's settings from a machine file's value tree with the tables of other
    /// owners (`[drive]`) already removed: `[plant]`, `[electrics]`, `[sensors]`,
    /// `[lost_motion]`. Any other top-level table is an error naming it; then every key is
    /// read and validated ([`Self::validate`]).
    pub fn from_table(table: Table) -> Result<Self, ConfigError> {
        if let Some(k) = table.keys().find(|k| !Self::TABLES.contains(&k.as_str())) {
            return Err(ConfigError::UnknownTable { table: k.clone() });
        }
        let raw = Value::Table(table);
        let config: Self = serde_path_to_error::deserialize(raw.clone()).map_err(|e| {
            let path: Vec<&str> = e
                .path()
                .iter()
                .filter_map(|s| match s {
                    Segment::Map { key } => Some(key.as_str()),
                    _ => None,
                })
                .collect();
            classify(&raw, &path)
        })?;
        config.validate()?;
        Ok(config)
    }

    /// The plant's settings from the text of a machine file, ignoring its `[drive]` table
    /// (controller-core's).
    pub fn from_machine_toml(text: &str) -> Result<Self, ConfigError> {
        let mut table: Table = text
            .parse()
            .map_err(|e: toml::de::Error| ConfigError::Syntax {
                message: e.message().to_string(),
            })?;
        table.remove("drive");
        Self::from_table(table)
    }

    /// Reads a machine file ([`Self::from_machine_toml`]).
    pub fn from_machine_file(path: &Path) -> Result<Self, PlantError> {
        let text = std::fs::read_to_string(path).map_err(|e| PlantError::Io {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
        Ok(Self::from_machine_toml(&text)?)
    }
}

/// The error serde met at `path` (table keys), told from the value found there and the
/// range table: a missing table or key, a table that is not one, an unknown key, a value
/// that is not finite, out of range or of the wrong type.
fn classify(raw: &Value, path: &[&str]) -> ConfigError {
    let table_of = |name: &str| raw.get(name);
    match path {
        // The root: a required table is absent.
        [] => {
            let missing = PlantConfig::TABLES
                .into_iter()
                .find(|t| table_required(t) && table_of(t).is_none());
            ConfigError::MissingTable {
                table: missing.unwrap_or("plant"),
            }
        }
        // A table: it is not one, or a required key of it is absent.
        [table] => {
            let name = PlantConfig::TABLES
                .into_iter()
                .find(|t| t == table)
                .unwrap_or("plant");
            match table_of(name) {
                Some(Value::Table(t)) => missing_key(name, t),
                _ => ConfigError::NotATable { table: name },
            }
        }
        [table, key, ..] => {
            let dotted = format!("{table}.{key}");
            let value = table_of(table).and_then(|t| t.get(key));
            bad_value(dotted, table, value)
        }
    }
}

/// Whether a table has a required key (so the table itself is required).
fn table_required(table: &str) -> bool {
    RANGES.iter().any(|r| r.required && r.table() == table)
}

/// The first required key of `table` that `t` lacks.
fn missing_key(table: &'static str, t: &Table) -> ConfigError {
    match RANGES
        .iter()
        .find(|r| r.required && r.table() == table && !t.contains_key(r.name()))
    {
        Some(r) => ConfigError::Missing {
            key: r.key.to_string(),
            allowed: r.describe(),
        },
        None => ConfigError::Missing {
            key: table.to_string(),
            allowed: "a table with the keys of the range table".into(),
        },
    }
}

/// A key serde refused: unknown, or a value of the wrong kind for its range.
fn bad_value(key: String, table: &str, value: Option<&Value>) -> ConfigError {
    let Some(range) = range_of(&key) else {
        let known: Vec<&str> = RANGES
            .iter()
            .filter(|r| r.table() == table)
            .map(|r| r.name())
            .collect();
        return ConfigError::Unknown {
            key,
            allowed: known.join(", "),
        };
    };
    let allowed = range.describe();
    match (range.allowed, value) {
        (_, Some(Value::Float(x))) if !x.is_finite() => ConfigError::NotFinite { key, allowed },
        (Allowed::Integer { .. }, Some(Value::Integer(i))) => ConfigError::OutOfRange {
            key,
            value: i.to_string(),
            allowed,
        },
        (Allowed::Words(_), Some(Value::String(s))) => ConfigError::OutOfRange {
            key,
            value: format!("\"{s}\""),
            allowed,
        },
        _ => ConfigError::WrongType { key, allowed },
    }
}
