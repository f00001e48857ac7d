//! `board ... scope --seconds S --out DIR`: the board's scope stream for S seconds of
//! samples (at the trace rate the board reports) into DIR/scope.csv and DIR/scope.png|svg.
//! The CSV has the firmware's sample counter, which must have no gap; per-unit channels are
//! raw Q16.16 bits, as in the firmware's trace dump. DIR is written through a staging
//! directory (`sim_engine::output`): never over what stiffdrive did not write.

use pil_link::board::client::{BoardClient, BoardError};
use pil_link::board::message::Request;
use pil_link::board::scope::ScopeSample;
use pil_link::host::Stream;
use sim_engine::error::{HarnessError, Result};
use sim_engine::output::Staging;
use sim_engine::plot::{self, Figure, Panel, Series};
use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// A scope recording.
#[derive(Clone, Debug, PartialEq)]
pub struct Scope {
    /// Seconds of samples, at the board's trace rate.
    pub seconds: f64,
    /// Output directory.
    pub out: PathBuf,
}

fn link(e: BoardError) -> HarnessError {
    HarnessError::Backend(format!("board scope: {e}"))
}

/// Records the scope; returns the line to print.
///
/// # Errors
/// A link failure, a gap in the sample counter, an `--out` that cannot be written.
pub fn scope(client: &mut BoardClient<Stream>, s: &Scope) -> Result<String> {
    let staging = Staging::new(&s.out)?;
    let (rate_hz, channels) = client.scope_start().map_err(link)?;
    let wanted = (s.seconds * f64::from(rate_hz)).ceil() as usize;
    let bar = sim_engine::progress::bar(wanted as u64, "scope");
    let mut samples: Vec<(u32, ScopeSample)> = Vec::with_capacity(wanted);
    // The board sends at its own pace: allow four times the recording, and some.
    let deadline = Instant::now() + Duration::from_secs_f64(4.0 * s.seconds + 5.0);
    let received = client.scope_receive(deadline, &mut |chunk| {
        for (i, sample) in chunk.samples().iter().enumerate() {
            samples.push((chunk.first.wrapping_add(i as u32), *sample));
        }
        bar.set_position(samples.len().min(wanted) as u64);
        samples.len() < wanted
    });
    bar.finish_and_clear();
    client
        .request_with(&Request::ScopeStop, &mut |_| {})
        .map_err(link)?;
    received.map_err(link)?;
    samples.truncate(wanted);
    let gaps = gaps(&samples);
    staging.write("scope.csv", &csv(&samples, &channels, rate_hz))?;
    plot::save(
        &figure(&samples, &channels, rate_hz),
        &staging.path("scope")?,
    )?;
    staging.commit()?;
    if gaps > 0 {
        return Err(HarnessError::Backend(format!(
            "board scope: {gaps} gap(s) in the sample counter ({} samples written to {})",
            samples.len(),
            s.out.join("scope.csv").display()
        )));
    }
    Ok(format!(
        "scope: {} samples at {rate_hz} Hz ({:.3} s), no gap, in {}",
        samples.len(),
        samples.len() as f64 / f64::from(rate_hz.max(1)),
        s.out.join("scope.csv").display()
    ))
}

/// Places where the counter does not go up by one.
fn gaps(samples: &[(u32, ScopeSample)]) -> usize {
    samples
        .windows(2)
        .filter(|w| matches!(w, [a, b] if b.0 != a.0.wrapping_add(1)))
        .count()
}

fn csv(samples: &[(u32, ScopeSample)], channels: &[String], rate_hz: u32) -> String {
    let mut text = format!("sample,time_s,tick,{}\n", channels.join(","));
    let first = samples.first().map_or(0, |s| s.0);
    for (n, s) in samples {
        let t = f64::from(n.wrapping_sub(first)) / f64::from(rate_hz.max(1));
        let _ = write!(text, "{n},{t:.6},{}", s.tick);
        for v in s.values {
            let _ = write!(text, ",{v}");
        }
        text.push('\n');
    }
    text
}

fn figure(samples: &[(u32, ScopeSample)], channels: &[String], rate_hz: u32) -> Figure {
    let first = samples.first().map_or(0, |s| s.0);
    let panels = channels
        .iter()
        .enumerate()
        .map(|(i, name)| {
            // Per-unit channels are Q16.16 bits: plotted in per unit.
            let scale = if name.ends_with("_pu") { 65536.0 } else { 1.0 };
            let points = samples
                .iter()
                .map(|(n, s)| {
                    let t = f64::from(n.wrapping_sub(first)) / f64::from(rate_hz.max(1));
                    (t, f64::from(s.values.get(i).copied().unwrap_or(0)) / scale)
                })
                .collect();
            Panel {
                title: name.clone(),
                y_label: if scale > 1.0 {
                    "pu".into()
                } else {
                    "counts".into()
                },
                series: vec![Series::line(name.clone(), points)],
                ..Panel::default()
            }
        })
        .collect();
    Figure {
        x_label: "time since the scope started [s]".into(),
        panels,
    }
}
