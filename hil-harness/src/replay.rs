//! `hil-harness replay`: plant-host's open-loop replay of a torque CSV.

use crate::config::config_path;
use crate::error::{HarnessError, Result};
use std::path::Path;

/// Runs plant-host's `replay`; on error nothing is written (plant-host writes atomically).
pub fn replay(config: &str, torque: &Path, out: &Path) -> Result<String> {
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
