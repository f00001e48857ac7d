//! One PIL run: the scenario (as for `run`) plus the firmware, QEMU and link settings, each
//! checked against the range the protocol and the firmware accept.

use sim_engine::error::{HarnessError, Result};
use std::ops::RangeInclusive;
use std::path::{Path, PathBuf};

/// The harness's reply deadlines it accepts, in ms.
pub const REPLY_TIMEOUT_MS: RangeInclusive<u64> = 1..=60_000;
/// The firmware link watchdog of a run that sets none, in ms.
pub const DEFAULT_WATCHDOG_MS: u32 = 1000;
/// The harness's reply deadline of a run that sets none, in ms.
pub const DEFAULT_REPLY_TIMEOUT_MS: u64 = 5000;

/// What one PIL run runs, and how.
#[derive(Clone, Debug)]
pub struct PilRun {
    /// Scenario name (a file under `configs/scenarios/`).
    pub scenario: String,
    /// Configuration (path, or name under `configs/`); `None`: the scenario's.
    pub config: Option<String>,
    /// `section.key=value` overrides.
    pub set: Vec<String>,
    /// Output directory.
    pub out: PathBuf,
    /// Firmware ELF to run; `None`: the `pil` image, built with cargo
    /// ([`crate::image::build_pil_image`]).
    pub elf: Option<PathBuf>,
    /// QEMU binary.
    pub qemu: PathBuf,
    /// A link fault to inject, `KIND@TICK[:ARG]` (see `pil_link::host::FaultPlan`).
    pub inject: Option<String>,
    /// Firmware link watchdog, in ms (within `pil_link::WATCHDOG_MS_RANGE`).
    pub watchdog_ms: u32,
    /// Harness deadline for each reply, in ms (within [`REPLY_TIMEOUT_MS`]).
    pub reply_timeout_ms: u64,
    /// Skip the bit-for-bit comparison with the host run.
    pub no_compare: bool,
    /// Where QEMU puts the firmware's UART: a Unix socket, or a pseudo-terminal opened as a
    /// serial device (the code path of a board's serial port).
    pub port: crate::LinkPort,
}

impl PilRun {
    /// `scenario` into `out` with every default.
    pub fn new(scenario: &str, out: &Path) -> Self {
        Self {
            scenario: scenario.to_string(),
            config: None,
            set: Vec::new(),
            out: out.to_path_buf(),
            elf: None,
            qemu: PathBuf::from(fw_runner::provision::QEMU_BINARY),
            inject: None,
            watchdog_ms: DEFAULT_WATCHDOG_MS,
            reply_timeout_ms: DEFAULT_REPLY_TIMEOUT_MS,
            no_compare: false,
            port: crate::LinkPort::Socket,
        }
    }

    /// The watchdog and reply deadline against the ranges the firmware and the harness
    /// accept: an error names the flag and its range.
    pub fn check(&self) -> Result<()> {
        let wd = &pil_link::WATCHDOG_MS_RANGE;
        if !wd.contains(&self.watchdog_ms) {
            return Err(HarnessError::config(
                "--watchdog-ms",
                format!(
                    "{} ms is outside the PIL protocol's watchdog range [{}, {}] ms (the \
                     firmware refuses such a Hello with a Protocol fault)",
                    self.watchdog_ms,
                    wd.start(),
                    wd.end()
                ),
            ));
        }
        if !REPLY_TIMEOUT_MS.contains(&self.reply_timeout_ms) {
            return Err(HarnessError::config(
                "--reply-timeout-ms",
                format!(
                    "{} ms is outside [{}, {}] ms",
                    self.reply_timeout_ms,
                    REPLY_TIMEOUT_MS.start(),
                    REPLY_TIMEOUT_MS.end()
                ),
            ));
        }
        Ok(())
    }
}
