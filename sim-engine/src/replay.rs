//! `hil-harness replay`: plant-host's open-loop replay of a torque CSV.

use crate::config::config_path;
use crate::error::{HarnessError, Result};
use crate::output::{check_file_target, FileMark};
use std::path::Path;

/// What marks a file as this command's output: its first line is exactly plant-host's
/// output header ([`plant_host::REPLAY_OUTPUT_HEADER`]).
pub const REPLAY_MARK: FileMark = FileMark {
    what: "a replay CSV stiffdrive wrote",
    is_ours: is_replay_csv,
};

fn is_replay_csv(bytes: &[u8]) -> bool {
    let line = bytes.split(|b| *b == b'\n').next().unwrap_or_default();
    line.strip_suffix(b"\r").unwrap_or(line) == plant_host::REPLAY_OUTPUT_HEADER.as_bytes()
}

/// Runs plant-host's `replay`; on error nothing is written (plant-host writes atomically).
/// An existing file at `out` is replaced only if it is a replay CSV ([`REPLAY_MARK`]).
pub fn replay(config: &str, torque: &Path, out: &Path) -> Result<String> {
    check_file_target(out, &REPLAY_MARK)?;
    let cfg = config_path(config)?;
    let summary =
        plant_host::replay(&cfg, torque, out).map_err(|e| HarnessError::Backend(e.to_string()))?;
    Ok(format!(
        "replayed {} rows over {:.3} s ({} lost-motion edge crossings) -> {}",
        summary.rows,
        summary.duration_s,
        summary.edge_crossings,
        out.display()
    ))
}
