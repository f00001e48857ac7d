//! `flash --config FILE`: the image of the board for that machine file's motor, carrying its
//! drive, written to the board through a debug probe by probe-rs (defmt over RTT, as
//! `cargo fw-flash` does for the default drive):
//! - a DC motor: the STM32F4-Discovery's bridge ([`DISCOVERY`]);
//! - a PMSM (`[electrics] motor = "pmsm"`): the NUCLEO-F446RE with X-NUCLEO-IHM08M1
//!   ([`THREE_PHASE`]), whose image has no console, so the drive must carry its measured
//!   `[drive.pmsm] encoder_offset_elec_deg` and a current loop of whole PWM periods.
//!
//! The file is composed and its drive designed on the host first, so a bad file is refused
//! naming its key before anything is built. Without probe-rs, or without a probe, the command
//! fails with probe-rs's own message and the exact command to run once a probe is there.

use controller_core::DriveConfig;
use pil_host::image::{build_board_image, build_three_phase_image};
use sim_engine::config::config_path;
use sim_engine::error::{HarnessError, Result};
use std::path::{Path, PathBuf};
use std::process::Command;

/// A board `flash` writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Board {
    /// What the board is.
    pub name: &'static str,
    /// Its chip, as probe-rs names it.
    pub chip: &'static str,
}

/// The DC drive's board: the STM32F4-Discovery (its bridge drives one winding).
pub const DISCOVERY: Board = Board {
    name: "STM32F4-Discovery",
    chip: "STM32F407VGTx",
};

/// The PMSM drive's board: the NUCLEO-F446RE with the X-NUCLEO-IHM08M1 inverter.
pub const THREE_PHASE: Board = Board {
    name: "NUCLEO-F446RE with X-NUCLEO-IHM08M1",
    chip: "STM32F446RETx",
};

/// The probe-rs program: `$STIFFDRIVE_PROBE_RS`, else `probe-rs` on the `PATH`.
fn probe_rs() -> PathBuf {
    std::env::var_os("STIFFDRIVE_PROBE_RS").map_or_else(|| "probe-rs".into(), PathBuf::from)
}

/// The command that writes `elf` to `board` and runs it.
fn probe_command(board: Board, elf: &Path) -> String {
    format!("probe-rs run --chip {} {}", board.chip, elf.display())
}

/// `flash`: build the image of the board for `config`'s motor (a path or a name under
/// `configs/`) and, unless `build_only`, run it on the board through probe-rs.
pub fn flash(config: &str, build_only: bool) -> Result<String> {
    let (path, drive) = drive_of(config)?;
    let (board, elf) = if drive.pmsm.is_some() {
        // No console on this board to calibrate through: the image must carry the offset.
        controller_core::Controller::new(&drive)
            .map_err(|e| HarnessError::config(format!("drive.{}", e.param()), e.to_string()))?;
        (THREE_PHASE, build_three_phase_image(&path, &drive)?)
    } else {
        (DISCOVERY, build_board_image(&path)?)
    };
    let run = probe_command(board, &elf);
    if build_only {
        return Ok(format!(
            "built the {} image for {}: {}\nflash it with: {run}",
            board.name,
            path.display(),
            elf.display()
        ));
    }
    let program = probe_rs();
    let status = Command::new(&program)
        .args(["run", "--chip", board.chip])
        .arg(&elf)
        .status();
    match status {
        Ok(s) if s.success() => Ok(format!("{} ran {}", program.display(), elf.display())),
        Ok(s) => Err(HarnessError::Backend(format!(
            "probe-rs failed ({s}; its message is above). The image is built; with the board's \
             ST-LINK connected, run: {run}"
        ))),
        Err(e) => Err(HarnessError::Backend(format!(
            "cannot run {}: {e}. Install probe-rs (`cargo install --locked probe-rs-tools`), \
             connect the board's ST-LINK, then run: {run}",
            program.display()
        ))),
    }
}

/// The machine file `config` (path, or name under configs/) as an absolute path, checked to
/// give a drive (`controller_core::design`) before any image is built: what `flash` and
/// `board --qemu --config` bake.
///
/// # Errors
/// A missing file, a bad machine file, or a drive `design` refuses (naming the key).
pub fn drive_file(config: &str) -> Result<PathBuf> {
    drive_of(config).map(|(path, _)| path)
}

/// [`drive_file`] with the drive it composes.
fn drive_of(config: &str) -> Result<(PathBuf, DriveConfig)> {
    let path = config_path(config)?;
    let path = path
        .canonicalize()
        .map_err(|e| HarnessError::io(&path, e))?;
    let drive = machine_file::load(&path)?.drive;
    controller_core::design(&drive)
        .map_err(|e| HarnessError::config(format!("drive.{}", e.param()), e.to_string()))?;
    Ok((path, drive))
}
