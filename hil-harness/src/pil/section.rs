//! The REPORT.md section of a PIL run: a function of the typed comparison and link report,
//! read back from the run directory with their own types (a missing or malformed file is an
//! error, never a `NAN` or `"?"`).

use super::compare::Comparison;
use super::session::LinkReport;
use super::{pil_command, PilArgs};
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
        let (c, l) = (&self.comparison, &self.link);
        let scenario = &c.scenario;
        let verdict = if c.bit_identical {
            "**bit-identical**: the firmware binary on the Cortex-M4F controls the simulated \
             machine exactly as the host build of controller-core does"
        } else {
            "**NOT bit-identical**"
        };
        let mut text = format!(
            "## Processor in the loop: `{scenario}` through the firmware in QEMU\n\n\
             Command: `cargo run --release -- pil --scenario {scenario} --out DIR`.\n\
             The firmware's `pil` image (version {}) runs in QEMU mps2-an386 \
             (Cortex-M4F); every controller tick the harness sends the sampled encoder count \
             and current (or the velocity setpoint) in a CRC-32 framed `pil-link` frame over \
             UART0, the firmware pends its TIMER0/TIMER1 interrupt, whose handler runs the \
             drive's interrupt body, and returns the commands; the harness then advances the \
             plant. Lock step, so QEMU's speed does not matter.\n\n\
             | quantity | value |\n|---|---|\n\
             | current ticks compared | {} |\n\
             | velocity ticks compared | {} |\n\
             | output values compared (raw fixed-point bits) | {} |\n\
             | mismatches | {} |\n\
             | controller inputs identical | {} |\n\
             | trace (plant states included) identical | {} |\n\
             | link frames | {} |\n\
             | mean wall time per frame (QEMU round trip + plant step) | {:.0} µs |\n\
             | wall time of the closed loop | {:.1} s |\n\n\
             Verdict: {verdict}.\n",
            l.firmware_version,
            c.current_ticks,
            c.velocity_ticks,
            c.values_compared,
            c.mismatches,
            c.inputs_identical,
            c.trace_identical,
            l.frames,
            l.round_trip_us,
            l.wall_time_s,
        );
        if let Some(m) = &c.first_mismatch {
            text.push_str(&format!(
                "\nFirst mismatch: {} tick {}, `{}`: host bits {}, firmware bits {}\n",
                m.tick_loop, m.index, m.field, m.host_bits, m.pil_bits
            ));
        }
        text
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
    let args = PilArgs::new("fig6", dir);
    match pil_command(&args) {
        Ok(_) => report_section_or_hint(dir),
        Err(e) => format!(
            "## Processor in the loop\n\nThe PIL run of `fig6` did not complete here: {e}.\n\n{}",
            report_section_or_hint(dir)
        ),
    }
}
