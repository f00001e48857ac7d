//! The one composer of a machine file: its TOML text into plant-host's [`PlantConfig`] (the
//! machine) and controller-core's [`DriveConfig`] (the drive that runs it).
//!
//! The harness, the tests and the firmware build (`firmware/build.rs`, which bakes the drive
//! into the image) all compose a file through [`compose`], so one file gives one drive
//! everywhere.
//!
//! A machine file has a `[drive]` table, read by controller-core, and the plant's tables
//! (`[plant]`, `[electrics]`, `[sensors]`, …), read by plant-host. The `[drive]` keys that
//! describe the machine ([`MACHINE_KEYS`]) default to the plant's values: the drive counts
//! what the encoder interpolator delivers (`encoder_cpr × sensors.encoder_interpolation`),
//! and its models use the plant's inertias and winding. Give them in `[drive]` only to model
//! a drive tuned for another machine.

use controller_core::DriveConfig;
use plant_host::PlantConfig;
use serde::de::DeserializeOwned;
use std::fmt;
use std::path::{Path, PathBuf};
use toml::{Table, Value};

/// Where the paper's Table 1 machine file lies below the workspace root: the drive an image
/// carries when no other is named.
pub const TABLE1_PATH: &str = "configs/machines/table1.toml";

/// The text of `configs/machines/table1.toml`: the paper's Table 1 machine and drive, the drive a
/// firmware image carries unless its build is given another file.
pub const TABLE1_TOML: &str = include_str!("../../configs/machines/table1.toml");

/// The `[drive]` keys that describe the machine, each defaulting to the plant's value.
pub const MACHINE_KEYS: [&str; 6] = [
    "base_speed_rpm",
    "encoder_cpr",
    "motor_inertia_s",
    "load_inertia_s",
    "winding_resistance_pu",
    "winding_inductance_pu_s",
];

/// A composed machine file: the plant and the drive, each validated by its owner.
#[derive(Debug, Clone, PartialEq)]
pub struct Machine {
    /// The simulated machine (plant-host).
    pub plant: PlantConfig,
    /// The drive (controller-core).
    pub drive: DriveConfig,
}

/// Why a machine file could not be composed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Error {
    /// The file could not be read.
    Io {
        /// The file.
        path: PathBuf,
        /// The operating system's message.
        reason: String,
    },
    /// The text is not TOML.
    Parse {
        /// The file, if the text came from one.
        path: Option<PathBuf>,
        /// The parser's message.
        reason: String,
    },
    /// A key that does not exist, has the wrong type, or is out of its range.
    Key {
        /// The dotted key, e.g. `drive.velocity_bandwidth_rad_s`.
        key: String,
        /// What is wrong and what is allowed.
        reason: String,
    },
}

impl Error {
    fn key(key: impl Into<String>, reason: impl Into<String>) -> Self {
        Self::Key {
            key: key.into(),
            reason: reason.into(),
        }
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Io { path, reason } => write!(f, "{}: {reason}", path.display()),
            Self::Parse {
                path: Some(path),
                reason,
            } => write!(f, "cannot parse {}: {reason}", path.display()),
            Self::Parse { path: None, reason } => write!(f, "cannot parse: {reason}"),
            Self::Key { key, reason } => write!(f, "bad configuration `{key}`: {reason}"),
        }
    }
}

impl std::error::Error for Error {}

/// The plant's value of each of [`MACHINE_KEYS`], in order.
fn machine_values(plant: &PlantConfig) -> [Value; 6] {
    let m = &plant.mechanics;
    let e = &plant.electrics;
    [
        Value::Float(m.base_speed_rpm),
        // The drive counts what the interpolator delivers.
        Value::Integer(i64::from(plant.counts_per_rev())),
        Value::Float(m.motor_inertia_s),
        Value::Float(m.load_inertia_s),
        Value::Float(e.winding_resistance_pu),
        Value::Float(e.winding_inductance_pu_s),
    ]
}

/// Deserializes `value` into `T`. An error names the key where it happened, below `prefix`
/// (`drive`, or `""` for a whole file), with serde's message: an unknown key and the allowed
/// ones, a missing key, a value of the wrong type.
pub fn typed<T: DeserializeOwned>(prefix: &str, value: Value) -> Result<T, Error> {
    serde_path_to_error::deserialize(value).map_err(|e| {
        let path = e.path().to_string();
        let key = match (prefix.is_empty(), path.as_str()) {
            (true, _) => path.clone(),
            (false, "" | ".") => prefix.to_string(),
            (false, p) => format!("{prefix}.{p}"),
        };
        Error::key(key, e.inner().message().to_string())
    })
}

/// The plant and the drive of a machine file's value tree (after any `--set`). The `[drive]`
/// table goes to controller-core, the rest to plant-host; a table neither knows is an error
/// naming it. Each half is validated by its owner's one range table.
pub fn compose(mut doc: Table) -> Result<Machine, Error> {
    let mut drive = match doc.remove("drive") {
        None => Table::new(),
        Some(Value::Table(t)) => t,
        Some(_) => return Err(Error::key("drive", "must be a table")),
    };
    let plant = PlantConfig::from_table(doc).map_err(|e| Error::key(e.key(), e.to_string()))?;
    for (key, value) in MACHINE_KEYS.into_iter().zip(machine_values(&plant)) {
        drive.entry(key).or_insert(value);
    }
    motor_table(&plant, &mut drive)?;
    let drive: DriveConfig = typed("drive", Value::Table(drive))?;
    drive
        .validate()
        .map_err(|e| Error::key(format!("drive.{}", e.param()), e.to_string()))?;
    Ok(Machine { plant, drive })
}

/// The `[drive.pmsm]` keys: those that describe the motor default to `[electrics]`; the
/// calibration's (`encoder_offset_elec_deg`, `encoder_reversed`) never do.
pub const PMSM_MACHINE_KEYS: [&str; 5] = [
    "pole_pairs",
    "d_inductance_pu_s",
    "q_inductance_pu_s",
    "flux_linkage_pu",
    "dc_bus_pu",
];

/// Every key of `[drive.pmsm]`, each of which may also be written straight in `[drive]`.
const PMSM_KEYS: [&str; 11] = [
    "pole_pairs",
    "d_inductance_pu_s",
    "q_inductance_pu_s",
    "flux_linkage_pu",
    "dc_bus_pu",
    "encoder_offset_elec_deg",
    "encoder_reversed",
    "angle_advance_ticks",
    "pwm_period_counts",
    "commutation_min_speed_pu",
    "commutation_trip_s",
];

/// The drive's motor kind follows the plant's (`electrics.motor`). For a PMSM, the
/// `[drive.pmsm]` table gathers its keys (given there or straight in `[drive]`, not both)
/// and takes the motor's values from `[electrics]` where not given. A DC machine's drive
/// has no PMSM key.
fn motor_table(plant: &PlantConfig, drive: &mut Table) -> Result<(), Error> {
    let e = &plant.electrics;
    if e.motor == plant_host::MotorKind::Dc {
        let flat = PMSM_KEYS.into_iter().find(|k| drive.contains_key(*k));
        if let Some(key) = flat.or(drive.contains_key("pmsm").then_some("pmsm")) {
            return Err(Error::key(
                format!("drive.{key}"),
                "a PMSM drive key, and this machine's motor is `dc` (electrics.motor)",
            ));
        }
        return Ok(());
    }
    let mut table = match drive.remove("pmsm") {
        None => Table::new(),
        Some(Value::Table(t)) => t,
        Some(_) => return Err(Error::key("drive.pmsm", "must be a table")),
    };
    for key in PMSM_KEYS {
        if let Some(v) = drive.remove(key) {
            if table.contains_key(key) {
                return Err(Error::key(
                    format!("drive.{key}"),
                    "given twice: in [drive] and in [drive.pmsm]; keep one",
                ));
            }
            table.insert(key.to_string(), v);
        }
    }
    let values = [
        e.pole_pairs.map(|p| Value::Integer(i64::from(p))),
        e.d_inductance_pu_s.map(Value::Float),
        e.q_inductance_pu_s.map(Value::Float),
        Some(Value::Float(e.flux_linkage_pu.unwrap_or(1.0))),
        e.dc_bus_pu.map(Value::Float),
    ];
    for (key, value) in PMSM_MACHINE_KEYS.into_iter().zip(values) {
        if let Some(v) = value {
            table.entry(key).or_insert(v);
        }
    }
    drive.insert("pmsm".to_string(), Value::Table(table));
    Ok(())
}

/// The value tree of a machine file's text.
pub fn parse(text: &str) -> Result<Table, Error> {
    text.parse::<Table>().map_err(|e| Error::Parse {
        path: None,
        reason: e.to_string(),
    })
}

/// Reads a TOML file into a value tree.
pub fn read(path: &Path) -> Result<Table, Error> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::Io {
        path: path.to_path_buf(),
        reason: e.to_string(),
    })?;
    text.parse::<Table>().map_err(|e| Error::Parse {
        path: Some(path.to_path_buf()),
        reason: e.to_string(),
    })
}

/// [`compose`] of a machine file's text.
pub fn from_text(text: &str) -> Result<Machine, Error> {
    compose(parse(text)?)
}

/// [`compose`] of a machine file.
pub fn load(path: &Path) -> Result<Machine, Error> {
    compose(read(path)?)
}

/// The paper's Table 1 machine and drive ([`TABLE1_TOML`]).
pub fn table1() -> Result<Machine, Error> {
    from_text(TABLE1_TOML)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;

    fn with(extra: &str) -> Result<Machine, Error> {
        let mut doc = parse(TABLE1_TOML).unwrap();
        for (k, v) in parse(extra).unwrap() {
            match (doc.get_mut(&k), v) {
                (Some(Value::Table(a)), Value::Table(b)) => a.extend(b),
                (_, v) => {
                    doc.insert(k, v);
                }
            }
        }
        compose(doc)
    }

    #[test]
    fn the_drive_counts_what_the_interpolator_delivers() {
        let base = table1().unwrap();
        assert_eq!(base.drive.encoder_cpr, base.plant.counts_per_rev());
        let m = with("[sensors]\nencoder_interpolation = 4\n").unwrap();
        assert_eq!(
            m.plant.counts_per_rev(),
            4 * base.plant.mechanics.encoder_cpr
        );
        assert_eq!(m.drive.encoder_cpr, m.plant.counts_per_rev());
    }

    #[test]
    fn machine_keys_default_to_the_plant_and_drive_keys_override_them() {
        let m = table1().unwrap();
        assert_eq!(
            m.drive.motor_inertia_s,
            m.plant.mechanics.motor_inertia_s as f32
        );
        assert_eq!(
            m.drive.winding_resistance_pu,
            m.plant.electrics.winding_resistance_pu as f32
        );
        let m = with("[drive]\nload_inertia_s = 0.5\n").unwrap();
        assert_eq!(m.drive.load_inertia_s, 0.5);
        assert_ne!(m.plant.mechanics.load_inertia_s, 0.5);
    }

    #[test]
    fn errors_name_the_key() {
        let e = with("[drive]\nvelocity_damping = 20\n").unwrap_err();
        assert!(
            matches!(&e, Error::Key { key, .. } if key == "drive.velocity_damping"),
            "{e}"
        );
        let e = with("[drive]\nvelocity_bandwith_rad_s = 5\n").unwrap_err();
        assert!(
            matches!(&e, Error::Key { key, .. } if key == "drive.velocity_bandwith_rad_s"),
            "{e}"
        );
        let e = with("[drivee]\nx = 1\n").unwrap_err();
        assert!(e.to_string().contains("drivee"), "{e}");
        let e = with("drive = 3\n").unwrap_err();
        assert!(
            matches!(&e, Error::Key { key, .. } if key == "drive"),
            "{e}"
        );
        assert!(matches!(
            from_text("[drive"),
            Err(Error::Parse { path: None, .. })
        ));
        let missing = Path::new("/nonexistent/machine.toml");
        assert!(matches!(load(missing), Err(Error::Io { path, .. }) if path == missing));
    }

    /// A PMSM machine's drive takes the motor keys from `[electrics]`, never the offset;
    /// flat `[drive]` PMSM keys join `[drive.pmsm]`; a DC machine refuses them.
    #[test]
    fn a_pmsm_drive_takes_the_motor_from_electrics_and_the_offset_only_from_the_file() {
        let text = include_str!("../../configs/machines/table1-pmsm.toml");
        let m = from_text(text).unwrap();
        let p = m.drive.pmsm.unwrap();
        assert_eq!(
            (p.pole_pairs, p.dc_bus_pu, p.flux_linkage_pu),
            (4, 2.0785, 1.0)
        );
        assert_eq!(p.d_inductance_pu_s, 5e-4);
        assert_eq!(p.encoder_offset_elec_deg, Some(23.0));
        let no_offset = text.replace("[drive.pmsm]\nencoder_offset_elec_deg = 23.0", "");
        let m = from_text(&no_offset).unwrap();
        assert_eq!(m.drive.pmsm.unwrap().encoder_offset_elec_deg, None);
        let flat = no_offset.replace(
            "current_bandwidth_rad_s = 1998.0",
            "current_bandwidth_rad_s = 1998.0\nencoder_offset_elec_deg = 5.0\npole_pairs = 5",
        );
        let p = from_text(&flat).unwrap().drive.pmsm.unwrap();
        assert_eq!((p.encoder_offset_elec_deg, p.pole_pairs), (Some(5.0), 5));
        let twice = format!("{text}encoder_reversed = true\n").replace(
            "current_bandwidth_rad_s = 1998.0",
            "current_bandwidth_rad_s = 1998.0\nencoder_reversed = false",
        );
        let e = from_text(&twice).unwrap_err();
        assert!(
            matches!(&e, Error::Key { key, .. } if key == "drive.encoder_reversed"),
            "{e}"
        );
        let e = with("[drive]\nencoder_offset_elec_deg = 5.0\n").unwrap_err();
        assert!(
            matches!(&e, Error::Key { key, .. } if key == "drive.encoder_offset_elec_deg"),
            "{e}"
        );
        let e = with("[drive.pmsm]\npole_pairs = 5\n").unwrap_err();
        assert!(
            matches!(&e, Error::Key { key, .. } if key == "drive.pmsm"),
            "{e}"
        );
        let e = from_text(&text.replace("dc_bus_pu = 2.0", "dc_bus_pu = -1.0")).unwrap_err();
        assert!(e.to_string().contains("dc_bus_pu"), "{e}");
    }
}
