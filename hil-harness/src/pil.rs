//! `hil-harness pil` arguments: the scenario (as for `run`) plus the firmware, QEMU and
//! link settings of a [`pil_host::PilRun`], which checks each against its range.

use crate::cli::ScenarioArgs;
use pil_host::{PilRun, DEFAULT_REPLY_TIMEOUT_MS, DEFAULT_WATCHDOG_MS};
use std::path::PathBuf;

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
    #[arg(long, default_value_t = DEFAULT_WATCHDOG_MS)]
    pub watchdog_ms: u32,
    /// Harness deadline for each reply (ms, 1 to 60000).
    #[arg(long, default_value_t = DEFAULT_REPLY_TIMEOUT_MS)]
    pub reply_timeout_ms: u64,
    /// Skip the bit-for-bit comparison with the host run.
    #[arg(long)]
    pub no_compare: bool,
    /// Where QEMU puts the firmware's UART: `socket` (a Unix socket) or `pty` (a
    /// pseudo-terminal the harness opens as a serial device, as it would a board's port).
    #[arg(long, default_value = "socket", value_name = "socket|pty")]
    pub link: pil_host::LinkPort,
}

impl PilArgs {
    /// The run these arguments ask for.
    pub fn to_run(&self) -> PilRun {
        PilRun {
            scenario: self.run.scenario.clone(),
            config: self.run.config.clone(),
            set: self.run.set.clone(),
            out: self.run.out.clone(),
            elf: self.elf.clone(),
            qemu: self.qemu.clone(),
            inject: self.inject.clone(),
            watchdog_ms: self.watchdog_ms,
            reply_timeout_ms: self.reply_timeout_ms,
            no_compare: self.no_compare,
            port: self.link,
        }
    }
}
