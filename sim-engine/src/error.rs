//! One error type for the harness: every variant says what went wrong and where, so the
//! command line can print a clear message and exit non-zero.

use std::fmt;
use std::path::PathBuf;

/// Everything that can stop a harness command.
#[derive(Debug)]
pub enum HarnessError {
    /// A scenario name with no file under `configs/scenarios/`.
    UnknownScenario {
        /// The name asked for.
        name: String,
        /// The scenarios that do exist.
        known: Vec<String>,
    },
    /// A configuration key that does not exist, or a value out of its range.
    Config {
        /// Dotted key, e.g. `drive.velocity_bandwidth_rad_s`.
        key: String,
        /// What is wrong and what is allowed.
        reason: String,
    },
    /// A file or directory could not be read or written.
    Io {
        /// The path involved.
        path: PathBuf,
        /// The operating system's message.
        reason: String,
    },
    /// An `--out` path that holds something stiffdrive did not write, or cannot hold its
    /// output (a file where a directory goes, a symbolic link, a path through a file).
    /// Nothing was changed.
    OutputInTheWay {
        /// The output path asked for.
        out: PathBuf,
        /// What is in the way, naming its path.
        reason: String,
    },
    /// A TOML file that does not parse.
    Parse {
        /// The file.
        path: PathBuf,
        /// The parser's message.
        reason: String,
    },
    /// A plot could not be drawn.
    Plot(String),
    /// Anything raised by a component crate (plant, controller, PIL link).
    Backend(String),
    /// `tune` or `commission` found no design that meets the constraints (for `commission`
    /// also: none beats the machine file's own drive on the machine): what was tried and
    /// which constraint failed (exit code [`NO_DESIGN_EXIT_CODE`]). Not a bad input.
    NoDesign(String),
    /// `commission` found a design that beats the file's own drive on the machine, but it
    /// failed the rest of the criterion (a placed notch that does not help) (exit code
    /// [`NOT_PASSED_EXIT_CODE`]): every file is written, `commission.md` says why and not to
    /// flash it. Not a bad input.
    NotPassed(String),
}

/// The exit code of a `tune` or `commission` that found no design meeting the constraints
/// (every other error exits 1, a command-line usage error 2).
pub const NO_DESIGN_EXIT_CODE: u8 = 3;
/// The exit code of a `commission` whose chosen design did not pass on the machine.
pub const NOT_PASSED_EXIT_CODE: u8 = 4;

impl fmt::Display for HarnessError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::UnknownScenario { name, known } => write!(
                f,
                "unknown scenario `{name}`; known scenarios: {}",
                known.join(", ")
            ),
            Self::Config { key, reason } => write!(f, "bad configuration `{key}`: {reason}"),
            Self::Io { path, reason } => write!(f, "{}: {reason}", path.display()),
            Self::OutputInTheWay { out, reason } => write!(
                f,
                "refusing to write to `{}`: {reason}; nothing was changed",
                out.display()
            ),
            Self::Parse { path, reason } => write!(f, "cannot parse {}: {reason}", path.display()),
            Self::Plot(reason) => write!(f, "plot failed: {reason}"),
            Self::Backend(reason) => write!(f, "{reason}"),
            Self::NoDesign(reason) => write!(f, "no design: {reason}"),
            Self::NotPassed(reason) => write!(f, "not passed: {reason}"),
        }
    }
}

impl std::error::Error for HarnessError {}

impl HarnessError {
    /// An I/O error on `path`.
    pub fn io(path: impl Into<PathBuf>, err: impl fmt::Display) -> Self {
        Self::Io {
            path: path.into(),
            reason: err.to_string(),
        }
    }

    /// The process exit code for this error: [`NO_DESIGN_EXIT_CODE`] for
    /// [`HarnessError::NoDesign`], [`NOT_PASSED_EXIT_CODE`] for [`HarnessError::NotPassed`],
    /// 1 for every other.
    #[must_use]
    pub fn exit_code(&self) -> u8 {
        match self {
            Self::NoDesign(_) => NO_DESIGN_EXIT_CODE,
            Self::NotPassed(_) => NOT_PASSED_EXIT_CODE,
            _ => 1,
        }
    }

    /// A configuration error on `key`.
    pub fn config(key: impl Into<String>, reason: impl Into<String>) -> Self {
        Self::Config {
            key: key.into(),
            reason: reason.into(),
        }
    }
}

impl From<machine_file::Error> for HarnessError {
    fn from(e: machine_file::Error) -> Self {
        match e {
            machine_file::Error::Io { path, reason } => Self::Io { path, reason },
            machine_file::Error::Parse { path, reason } => Self::Parse {
                path: path.unwrap_or_default(),
                reason,
            },
            machine_file::Error::Key { key, reason } => Self::Config { key, reason },
        }
    }
}

/// Result alias for the harness.
pub type Result<T> = std::result::Result<T, HarnessError>;
