//! Machines no shipped config describes, written as files for the tests: Table 1's file
//! with some keys replaced, so every other key keeps the shipped value.
#![allow(dead_code, clippy::unwrap_used)]

use std::path::Path;
use toml::{Table, Value};

/// `configs/machines/table1.toml` with each `(table, key, value)` of `keys` set (a missing table is
/// created), written to `dir/name`; returns the file's path.
pub fn machine_file(dir: &Path, name: &str, keys: &[(&str, &str, Value)]) -> String {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/machines/table1.toml");
    let mut doc: Table = std::fs::read_to_string(root).unwrap().parse().unwrap();
    for (table, key, value) in keys {
        let t = doc
            .entry(*table)
            .or_insert_with(|| Value::Table(Table::new()));
        t.as_table_mut()
            .unwrap()
            .insert((*key).into(), value.clone());
    }
    let path = dir.join(name);
    std::fs::write(&path, toml::to_string(&doc).unwrap()).unwrap();
    path.display().to_string()
}

/// `[plant]` keys with float values, for [`machine_file`].
pub fn plant(keys: &[(&'static str, f64)]) -> Vec<(&'static str, &'static str, Value)> {
    keys.iter()
        .map(|(k, v)| ("plant", *k, Value::Float(*v)))
        .collect()
}
