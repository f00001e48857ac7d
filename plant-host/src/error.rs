//! Typed errors. Every configuration error names the offending key and its allowed range, so a
//! user can fix the file without reading the source.

use std::fmt;
use std::path::PathBuf;

/// A configuration problem: bad TOML, a missing, unknown, mistyped, non-finite or
/// out-of-range key. [`ConfigError::key`] gives the dotted key (or table) it is about.
#[derive(Debug, Clone, PartialEq)]
pub enum ConfigError {
    /// The text is not valid TOML.
    Syntax {
        /// The TOML parser's message.
        message: String,
    },
    /// A table this crate requires is missing (`[plant]`, `[electrics]`).
    MissingTable {
        /// Table name.
        table: &'static str,
    },
    /// A table this crate owns is present but is not a table.
    NotATable {
        /// Table name.
        table: &'static str,
    },
    /// A top-level table that is not one of plant-host's.
    UnknownTable {
        /// Table name.
        table: String,
    },
    /// A required key is missing.
    Missing {
        /// `table.key`.
        key: String,
        /// The allowed range, as text with units.
        allowed: String,
    },
    /// A key this crate does not know, inside one of its own tables.
    Unknown {
        /// `table.key`.
        key: String,
        /// The keys that table accepts.
        allowed: String,
    },
    /// A key of the wrong TOML type.
    WrongType {
        /// `table.key`.
        key: String,
        /// What was expected, with the allowed range.
        allowed: String,
    },
    /// A NaN or infinite number.
    NotFinite {
        /// `table.key`.
        key: String,
        /// The allowed range.
        allowed: String,
    },
    /// Keys each in range whose combination is not allowed.
    Inconsistent {
        /// The keys involved, `table.key`, the one most to blame first.
        keys: Vec<&'static str>,
        /// What is wrong and how to fix it.
        message: String,
    },
    /// A value outside its allowed range.
    OutOfRange {
        /// `table.key`.
        key: String,
        /// The value found, as written.
        value: String,
        /// The allowed range.
        allowed: String,
    },
}

impl ConfigError {
    /// The dotted key the error is about (`plant.motor_inertia_s`), the table for a table
    /// error (`plant`), the first of the keys for an inconsistent combination, and "" for a
    /// TOML syntax error.
    pub fn key(&self) -> &str {
        match self {
            Self::Syntax { .. } => "",
            Self::MissingTable { table } | Self::NotATable { table } => table,
            Self::UnknownTable { table } => table,
            Self::Inconsistent { keys, .. } => keys.first().copied().unwrap_or(""),
            Self::Missing { key, .. }
            | Self::Unknown { key, .. }
            | Self::WrongType { key, .. }
            | Self::NotFinite { key, .. }
            | Self::OutOfRange { key, .. } => key,
        }
    }
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Syntax { message } => write!(f, "invalid TOML: {message}"),
            Self::MissingTable { table } => write!(f, "missing table [{table}]"),
            Self::NotATable { table } => write!(f, "`{table}` must be a table ([{table}])"),
            Self::UnknownTable { table } => write!(
                f,
                "unknown table `[{table}]` (plant-host reads [plant], [electrics], [sensors], \
                 [lost_motion])"
            ),
            Self::Missing { key, allowed } => {
                write!(f, "missing key `{key}` (allowed: {allowed})")
            }
            Self::Unknown { key, allowed } => {
                write!(f, "unknown key `{key}` (allowed keys: {allowed})")
            }
            Self::WrongType { key, allowed } => {
                write!(f, "`{key}` has the wrong type (allowed: {allowed})")
            }
            Self::NotFinite { key, allowed } => {
                write!(f, "`{key}` is not finite (allowed: {allowed})")
            }
            Self::Inconsistent { keys, message } => write!(f, "{}: {message}", keys.join(", ")),
            Self::OutOfRange {
                key,
                value,
                allowed,
            } => write!(f, "`{key}` = {value} is out of range (allowed: {allowed})"),
        }
    }
}

impl std::error::Error for ConfigError {}

/// Any failure of the plant's file-level operations (config, replay).
#[derive(Debug, Clone, PartialEq)]
pub enum PlantError {
    /// The configuration is invalid.
    Config(ConfigError),
    /// A file could not be read or written.
    Io {
        /// The file.
        path: PathBuf,
        /// The OS message.
        message: String,
    },
    /// The torque CSV is malformed.
    Csv {
        /// The file.
        path: PathBuf,
        /// 1-based line number (0 when the whole file is at fault).
        line: usize,
        /// What is wrong and what is allowed.
        message: String,
    },
    /// A step length is not finite and non-negative.
    BadStep {
        /// The requested step in seconds.
        dt_s: f64,
    },
    /// A load time series is malformed.
    BadSeries {
        /// 0-based index of the offending point.
        index: usize,
        /// What is wrong.
        message: String,
    },
    /// A torque or voltage input is not finite.
    BadInput {
        /// The offending value.
        value: f64,
    },
    /// The inverter cannot be built (bus, dead time or PWM frequency).
    BadInverter {
        /// Which setting, its value and what is allowed.
        message: String,
    },
}

impl fmt::Display for PlantError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Config(e) => write!(f, "config: {e}"),
            Self::Io { path, message } => write!(f, "{}: {message}", path.display()),
            Self::Csv {
                path,
                line,
                message,
            } => write!(f, "{}:{line}: {message}", path.display()),
            Self::BadStep { dt_s } => {
                write!(f, "step dt_s = {dt_s} must be finite and >= 0")
            }
            Self::BadSeries { index, message } => {
                write!(f, "load time series point {index}: {message}")
            }
            Self::BadInput { value } => write!(f, "plant input {value} must be finite"),
            Self::BadInverter { message } => write!(f, "inverter: {message}"),
        }
    }
}

impl std::error::Error for PlantError {}

impl From<ConfigError> for PlantError {
    fn from(e: ConfigError) -> Self {
        Self::Config(e)
    }
}
