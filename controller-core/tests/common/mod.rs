//! Test support: the paper's Table 1 drive from `configs/table1.toml`, composed the way the
//! harness and the firmware compose it: the `[drive]` table, with the machine keys it omits
//! taken from `[plant]` (base speed, inertias, encoder) and `[electrics]` (winding).
//! `firmware/build.rs` bakes the firmware's drive through this same module
//! ([`try_drive_of`]), so the tests and the image compose the file one way.
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use controller_core::DriveConfig;

/// The text of `configs/table1.toml`.
pub const TABLE1_TOML: &str = include_str!("../../../configs/table1.toml");

/// Machine keys of `[drive]` and the table of the file that supplies each when absent.
pub const MACHINE_KEYS: [(&str, &str); 6] = [
    ("base_speed_rpm", "plant"),
    ("motor_inertia_s", "plant"),
    ("load_inertia_s", "plant"),
    ("encoder_cpr", "plant"),
    ("winding_resistance_pu", "electrics"),
    ("winding_inductance_pu_s", "electrics"),
];

/// The `[drive]` table of a configuration text with the machine keys filled in.
pub fn drive_table(text: &str) -> toml::Table {
    try_drive_table(text).expect("configuration parses")
}

/// [`drive_table`], with the parse error as text.
pub fn try_drive_table(text: &str) -> Result<toml::Table, String> {
    let doc: toml::Table = text.parse().map_err(|e| format!("{e}"))?;
    let mut drive = match doc.get("drive") {
        Some(toml::Value::Table(t)) => t.clone(),
        Some(_) => return Err("drive: must be a table".into()),
        None => toml::Table::new(),
    };
    for (key, from) in MACHINE_KEYS {
        if !drive.contains_key(key) {
            if let Some(v) = doc.get(from).and_then(|t| t.get(key)) {
                drive.insert(key.into(), v.clone());
            }
        }
    }
    Ok(drive)
}

/// The drive of a configuration text.
pub fn drive_of(text: &str) -> DriveConfig {
    try_drive_of(text).expect("[drive] deserializes")
}

/// [`drive_of`], with the error as text naming the `[drive]` key.
pub fn try_drive_of(text: &str) -> Result<DriveConfig, String> {
    try_drive_table(text)?
        .try_into()
        .map_err(|e: toml::de::Error| format!("[drive]: {e}"))
}

/// The paper's Table 1 drive (`configs/table1.toml`).
pub fn table1() -> DriveConfig {
    drive_of(TABLE1_TOML)
}

/// A number of a table of `configs/table1.toml` (e.g. `("plant", "anti_resonance_hz")`).
pub fn table1_number(table: &str, key: &str) -> f64 {
    let doc: toml::Table = TABLE1_TOML.parse().unwrap();
    match doc.get(table).and_then(|t| t.get(key)) {
        Some(toml::Value::Float(x)) => *x,
        Some(toml::Value::Integer(n)) => *n as f64,
        other => panic!("{table}.{key}: {other:?}"),
    }
}
