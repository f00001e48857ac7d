//! A machine file's value tree into plant-host's `PlantConfig` and controller-core's
//! `DriveConfig`: each deserialized once, each validated by its owner's one validator.

use super::typed::typed;
use crate::error::{HarnessError, Result};
use controller_core::DriveConfig;
use plant_host::PlantConfig;
use toml::{Table, Value};

/// The `[drive]` keys that describe the machine, with the plant's value each defaults to:
/// set them in `[drive]` only to model a drive tuned for another machine.
fn machine_keys(plant: &PlantConfig) -> [(&'static str, Value); 6] {
    let m = &plant.mechanics;
    let e = &plant.electrics;
    [
        ("base_speed_rpm", Value::Float(m.base_speed_rpm)),
        // The drive counts what the interpolator delivers.
        (
            "encoder_cpr",
            Value::Integer(i64::from(plant.sensors.counts_per_rev())),
        ),
        ("motor_inertia_s", Value::Float(m.motor_inertia_s)),
        ("load_inertia_s", Value::Float(m.load_inertia_s)),
        ("winding_resistance_pu", Value::Float(e.winding_resistance_pu)),
        ("winding_inductance_pu_s", Value::Float(e.winding_inductance_pu_s)),
    ]
}

/// The plant and the drive of a (merged) machine file. The `[drive]` table goes to
/// controller-core, the rest to plant-host; a table neither knows is an error naming it.
pub fn machine(mut doc: Table) -> Result<(PlantConfig, DriveConfig)> {
    let mut drive = match doc.remove("drive") {
        None => Table::new(),
        Some(Value::Table(t)) => t,
        Some(_) => return Err(HarnessError::config("drive", "must be a table")),
    };
    let plant =
        PlantConfig::from_table(doc).map_err(|e| HarnessError::config(e.key(), e.to_string()))?;
    for (key, value) in machine_keys(&plant) {
        drive.entry(key).or_insert(value);
    }
    let drive: DriveConfig = typed("drive", Value::Table(drive))?;
    drive
        .validate()
        .map_err(|e| HarnessError::config(format!("drive.{}", e.param()), e.to_string()))?;
    Ok((plant, drive))
}
