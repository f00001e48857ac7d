//! `hil-harness pil` arguments: the scenario (as for `run`) plus the firmware, QEMU and
//! link settings, each checked against the range the protocol and the firmware accept.

use crate::cli::ScenarioArgs;
use sim_engine::error::{HarnessError, Result};
use std::path::{Path, PathBuf};

/// The harness's reply deadlines it accepts, in ms.
pub const REPLY_TIMEOUT_MS: std::ops::RangeInclusive<u64> = 1..=60_000;

/// `hil-harness pil` arguments.
#[derive(Clone, Debug, clap::Args)]
pub struct PilArgs {
    /// The scenario, its config, overrides and output directory, as for `run`.
    #[command(flatten)]
    pub run: ScenarioArgs,
    /// Firmware ELF to run; default: build the `pil` image with cargo
    /// (`cargo build -p firmware --release --target thumbv7em-none-eabihf --bin pil`).
    #[arg(long)]
    pub elf: Option<PathBuf>,
    /// QEMU binary.
    #[arg(long, default_value = "qemu-system-arm")]
    pub qemu: PathBuf,
    /// Inject a link fault, `KIND@TICK[:ARG]` with KIND one of drop, corrupt, delay (ARG =
    /// ms), skip-seq, corrupt-reply, drop-reply; TICK counts sensor frames from 0.
    #[arg(long, value_name = "KIND@TICK[:ARG]")]
    pub inject: Option<String>,
    /// Firmware link watchdog: no frame for this long latches its safe state (ms, 1 to
    /// 1000: the firmware refuses others).
    #[arg(long, default_value_t = 1000)]
    pub watchdog_ms: u32,
    /// Harness deadline for each reply (ms, 1 to 60000).
    #[arg(long, default_value_t = 5000)]
    pub reply_timeout_ms: u64,
    /// Skip the bit-for-bit comparison with the host run.
    #[arg(long)]
    pub no_compare: bool,
}

impl PilArgs {
    /// Arguments for `scenario` into `out` with every default.
    pub fn new(scenario: &str, out: &Path) -> Self {
        Self {
            run: ScenarioArgs {
                scenario: scenario.to_string(),
                config: None,
                set: Vec::new(),
                out: out.to_path_buf(),
            },
            elf: None,
            qemu: PathBuf::from("qemu-system-arm"),
            inject: None,
            watchdog_ms: 1000,
            reply_timeout_ms: 5000,
            no_compare: false,
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
