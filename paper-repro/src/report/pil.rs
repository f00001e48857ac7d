//! The REPORT.md section of a PIL run: a function of the typed comparison and link report,
//! read back from the run directory with their own types (a missing or malformed file is an
//! error, never a `NAN` or `"?"`).

use pil_host::compare::Comparison;
use pil_host::{pil_command, LinkReport, PilRun};
use serde::de::DeserializeOwned;
use sim_engine::error::{HarnessError, Result};
use std::path::Path;

/// A PIL run's comparison and link statistics.
#[derive(Clone, Debug)]
pub struct PilSection {
    /// `pil-comparison.json`.
    pub comparison: Comparison,
    /// `pil.json`.
    pub link: LinkReport,
}

fn read_json<T: DeserializeOwned>(path: &Path) -> Result<T> {
    let text = std::fs::read_to_string(path).map_err(|e| HarnessError::io(path, e))?;
    serde_json::from_str(&text).map_err(|e| HarnessError::io(path, e))
}

impl PilSection {
    /// Reads `pil-comparison.json` and `pil.json` from a run directory written by `pil`.
    pub fn read(dir: &Path) -> Result<Self> {
        Ok(Self {
            comparison: read_json(&dir.join("pil-comparison.json"))?,
            link: read_json(&dir.join("pil.json"))?,
        })
    }

    /// The Markdown section.
    pub fn markdown(&self) -> String {
        pil_host::comparison_markdown(&self.comparison, &self.link)
    }
}

/// The REPORT.md section for a PIL run directory.
pub fn report_section(dir: &Path) -> Result<String> {
    PilSection::read(dir).map(|s| s.markdown())
}

/// The REPORT.md section for the PIL run in `dir`, or, if there is none, a paragraph
/// saying how to produce it (the PIL run needs QEMU and the ARM image, which `reproduce`
/// may not have).
pub fn report_section_or_hint(dir: &Path) -> String {
    report_section(dir).unwrap_or_else(|e| {
        format!(
            "## Processor in the loop\n\nNo PIL run in `{}` ({e}). Produce it with \
             `cargo run --release -- pil --scenario fig6 --out {}` \
             (needs qemu-system-arm and the thumbv7em-none-eabihf target); it compares \
             every controller output of the firmware in QEMU with the host run, bit for bit.\n",
            dir.display(),
            dir.display()
        )
    })
}

/// For `reproduce`: runs `fig6` through the firmware into `dir` (building the image) and
/// returns the REPORT.md section; if that is impossible here (no QEMU, no ARM target, a
/// link fault), returns a section that says why and how to run it.
pub fn run_for_report(dir: &Path) -> String {
    let args = PilRun::new("fig6", dir);
    match pil_command(&args) {
        Ok(_) => report_section_or_hint(dir),
        Err(e) => format!(
            "## Processor in the loop\n\nThe PIL run of `fig6` did not complete here: {e}.\n\n{}",
            report_section_or_hint(dir)
        ),
    }
}
