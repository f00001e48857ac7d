//! `stiffdrive board` arguments: where the board is (`--qemu` or `--port PATH`) and the
//! actions, run in order in one session (`pil_host::board`); `identify --board`'s.

use pil_host::board::Machine;
use pil_host::board::{board_command, parse_actions, BoardTarget};
use sim_engine::Result;
use std::path::PathBuf;
use std::time::Duration;

/// The QEMU machines `board --qemu` runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum QemuMachine {
    /// mps2-an386 (Cortex-M4F): the `board` image.
    #[value(name = "mps2-an386")]
    Mps2An386,
    /// netduinoplus2 (STM32F405): the STM32F4 image.
    Netduinoplus2,
}

/// `stiffdrive board` arguments.
#[derive(Clone, Debug, clap::Args)]
#[command(group = clap::ArgGroup::new("where").required(true).args(["qemu", "port"]))]
pub struct BoardArgs {
    /// A board console image in QEMU, its serial port on a pseudo-terminal (opened as a
    /// serial device).
    #[arg(long)]
    pub qemu: bool,
    /// With `--qemu`: the machine. `mps2-an386` runs the `board` image (UART0);
    /// `netduinoplus2` (STM32F405) runs the STM32F4 image (USART2), where QEMU models no
    /// loop timers (no `enable`, no `scope`) and no flash controller (`save` fails).
    /// Default: mps2-an386.
    #[arg(long, value_enum, conflicts_with = "port")]
    pub machine: Option<QemuMachine>,
    /// A board's serial device, e.g. /dev/ttyACM0.
    #[arg(long, value_name = "PATH")]
    pub port: Option<PathBuf>,
    /// Baud rate of `--port`.
    #[arg(long, default_value_t = 115_200)]
    pub baud: u32,
    /// With `--qemu`: the image to run; default: build the machine's image with cargo
    /// (`cargo build -p firmware --release --target thumbv7em-none-eabihf --bin board`;
    /// on netduinoplus2 `cargo fw-build-stm32-dc`).
    // `requires = "qemu"` would always hold (a flag is present as its default, false);
    // one of --qemu and --port is required, so conflicting with --port is the same rule.
    #[arg(long, conflicts_with = "port")]
    pub elf: Option<PathBuf>,
    /// With `--qemu`: the machine file (path, or name under configs/) whose `[drive]` the
    /// built image carries, e.g. a `drive.toml` from `tune` or `commission`; default
    /// Table 1's.
    #[arg(long, conflicts_with_all = ["elf", "port"])]
    pub config: Option<String>,
    /// With `--qemu`: the QEMU binary.
    #[arg(long, default_value = "qemu-system-arm")]
    pub qemu_bin: PathBuf,
    /// Deadline for each reply (ms).
    #[arg(long, default_value_t = 2000, value_parser = clap::value_parser!(u64).range(1..=60_000))]
    pub reply_timeout_ms: u64,
    /// In order: status, get KEY, set KEY=VALUE, save, reset, faults, enable, disable,
    /// scope --seconds S --out DIR, calibrate. KEY is a machine file's `[drive]` key, e.g.
    /// drive.velocity_bandwidth_rad_s, or drive.pmsm.encoder_offset_elec_deg. `calibrate`
    /// calibrates a PMSM drive's motor on the board (as `identify --board` does first) and
    /// sets and saves the calibration; until then the board refuses to enable a PMSM drive.
    #[arg(
        required = true,
        trailing_var_arg = true,
        allow_hyphen_values = true,
        value_name = "ACTION"
    )]
    pub actions: Vec<String>,
}

impl BoardArgs {
    /// Runs the session these arguments ask for.
    ///
    /// # Errors
    /// A bad action, a refused or failed one (naming the key), a link failure.
    pub fn run(&self) -> Result<String> {
        let actions = parse_actions(&self.actions)?;
        let target = match &self.port {
            Some(path) => BoardTarget::Port {
                path: path.clone(),
                baud: self.baud,
            },
            None => BoardTarget::Qemu {
                machine: match self.machine {
                    None | Some(QemuMachine::Mps2An386) => Machine::Mps2An386,
                    Some(QemuMachine::Netduinoplus2) => Machine::Netduinoplus2,
                },
                elf: self.elf.clone(),
                drive: self
                    .config
                    .as_deref()
                    .map(machine_workflows::flash::drive_file)
                    .transpose()?,
                qemu: self.qemu_bin.clone(),
            },
        };
        board_command(
            &target,
            &actions,
            Duration::from_millis(self.reply_timeout_ms),
            &mut machine_workflows::calibrate::board::calibrate_action,
        )
    }
}

/// `identify --board --qemu | --port PATH` arguments.
#[derive(Clone, Debug, clap::Args)]
pub struct IdentifyBoardArgs {
    /// Measure on the board: the `board` image in QEMU (`--qemu`, built with the machine
    /// file) or a board's serial device (`--port PATH`).
    #[arg(long, requires = "board_where")]
    pub board: bool,
    /// With `--board`: the `board` image in QEMU.
    #[arg(long, requires = "board", group = "board_where")]
    pub qemu: bool,
    /// With `--board`: a board's serial device, e.g. /dev/ttyACM0.
    #[arg(long, value_name = "PATH", requires = "board", group = "board_where")]
    pub port: Option<PathBuf>,
    /// Baud rate of `--port`.
    #[arg(long, default_value_t = 115_200)]
    pub baud: u32,
    /// With `--qemu`: the QEMU binary.
    #[arg(long, default_value = "qemu-system-arm")]
    pub qemu_bin: PathBuf,
}

impl IdentifyBoardArgs {
    /// The board to measure on; `None` without `--board`.
    #[must_use]
    pub fn target(&self) -> Option<BoardTarget> {
        if !self.board {
            return None;
        }
        Some(match &self.port {
            Some(path) => BoardTarget::Port {
                path: path.clone(),
                baud: self.baud,
            },
            // `identify_board` sets the drive to its machine file.
            None => BoardTarget::Qemu {
                machine: Machine::Mps2An386,
                elf: None,
                drive: None,
                qemu: self.qemu_bin.clone(),
            },
        })
    }
}
