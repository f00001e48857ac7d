//! `flash --config FILE`: the STM32F4 board's image carrying that machine file's drive,
//! written to the board through a debug probe by probe-rs (defmt over RTT, as
//! `cargo fw-flash` does for the default drive).
//!
//! The file is composed and its drive designed on the host first, so a bad file is refused
//! naming its key before anything is built. Without probe-rs, or without a probe, the command
//! fails with probe-rs's own message and the exact command to run once a probe is there.

use pil_host::image::build_board_image;
use sim_engine::config::config_path;
use sim_engine::error::{HarnessError, Result};
use std::path::{Path, PathBuf};
use std::process::Command;

/// The chip of the STM32F4-Discovery board, as probe-rs names it.
pub const CHIP: &str = "STM32F407VGTx";

/// The probe-rs program: `$STIFFDRIVE_PROBE_RS`, else `probe-rs` on the `PATH`.
fn probe_rs() -> PathBuf {
    std::env::var_os("STIFFDRIVE_PROBE_RS").map_or_else(|| "probe-rs".into(), PathBuf::from)
}

/// The command that writes `elf` to the board and runs it.
fn probe_command(elf: &Path) -> String {
    format!("probe-rs run --chip {CHIP} {}", elf.display())
}

/// `flash`: build the board image for `config` (a path or a name under `configs/`) and, unless
/// `build_only`, run it on the board through probe-rs.
pub fn flash(config: &str, build_only: bool) -> Result<String> {
    let path = drive_file(config)?;
    let elf = build_board_image(&path)?;
    let run = probe_command(&elf);
    if build_only {
        return Ok(format!(
            "built the STM32F4 image for {}: {}\nflash it with: {run}",
            path.display(),
            elf.display()
        ));
    }
    let program = probe_rs();
    let status = Command::new(&program)
        .args(["run", "--chip", CHIP])
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
    let path = config_path(config)?;
    let path = path
        .canonicalize()
        .map_err(|e| HarnessError::io(&path, e))?;
    let machine = machine_file::load(&path)?;
    controller_core::design(&machine.drive)
        .map_err(|e| HarnessError::config(format!("drive.{}", e.param()), e.to_string()))?;
    Ok(path)
}
