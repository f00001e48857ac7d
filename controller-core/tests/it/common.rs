//! Test support: the paper's Table 1 drive and plant from `configs/machines/table1.toml`, composed by the one
//! composer of a machine file (`machine_file::compose`) that the harness and the firmware
//! build use.
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use controller_core::DriveConfig;

/// The text of `configs/machines/table1.toml`.
pub const TABLE1_TOML: &str = machine_file::TABLE1_TOML;

/// The drive of a machine file's text.
pub fn drive_of(text: &str) -> DriveConfig {
    try_drive_of(text).expect("[drive] composes")
}

/// [`drive_of`], with the error as text naming the key.
pub fn try_drive_of(text: &str) -> Result<DriveConfig, String> {
    machine_file::from_text(text)
        .map(|m| m.drive)
        .map_err(|e| e.to_string())
}

/// The paper's Table 1 drive (`configs/machines/table1.toml`).
pub fn table1() -> DriveConfig {
    drive_of(TABLE1_TOML)
}

/// A number of a table of `configs/machines/table1.toml` (e.g. `("plant", "anti_resonance_hz")`).
pub fn table1_number(table: &str, key: &str) -> f64 {
    let doc: toml::Table = TABLE1_TOML.parse().unwrap();
    match doc.get(table).and_then(|t| t.get(key)) {
        Some(toml::Value::Float(x)) => *x,
        Some(toml::Value::Integer(n)) => *n as f64,
        other => panic!("{table}.{key}: {other:?}"),
    }
}

/// The Table 1 plant of `configs/machines/table1.toml` (lost motion 0.5°, RL winding,
/// 0.18 ms computational delay, 12-bit current ADC), as the harness runs it.
pub fn table1_plant() -> plant_host::PlantConfig {
    machine_file::from_text(TABLE1_TOML)
        .expect("table1 composes")
        .plant
}
