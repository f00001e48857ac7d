//! The host side of the board's `Calibrate` (`pil_link::board::calibrate`): a PMSM's motor
//! calibration run by the board in its current-loop interrupt, its record collected from
//! the `ScopeData` frames that follow the reply (two samples a tick), whole, as an
//! `Identify` record is ([`crate::board_identify`]: every sample in order, a run the board
//! cut short or a fault during it fails the command).

use crate::board_identify::{stream_record, Streamed};
use controller_core::foc::calibration::{Calibration, CalibrationSettings};
use pil_link::board::calibrate::{CalibrationRow, CHANNELS, SAMPLES_PER_TICK};
use pil_link::board::client::BoardClient;
use pil_link::board::message::Request;
use pil_link::host::Stream;
use sim_engine::error::{HarnessError, Result};

/// A calibration's record as the board took it.
#[derive(Clone, Debug, PartialEq)]
pub struct BoardCalibration {
    /// Ticks per second (the current-loop rate).
    pub rate_hz: u32,
    /// Every tick, in order.
    pub rows: Vec<CalibrationRow>,
}

/// Runs the calibration `settings` on the board and collects its record.
///
/// # Errors
/// Settings the sequencer refuses (naming the setting); the board's refusal (enabled, a
/// latched fault, not a PMSM drive, another current-loop rate: its message names why); a
/// link failure, a gap, a fault during the run, a row of no stage.
pub fn run_calibrate(
    client: &mut BoardClient<Stream>,
    settings: &CalibrationSettings,
) -> Result<BoardCalibration> {
    let seq = Calibration::new(settings)
        .map_err(|e| HarnessError::config("calibration", e.to_string()))?;
    let record = stream_record(
        client,
        &Request::Calibrate(*settings),
        &Streamed {
            samples: seq.total_ticks().saturating_mul(SAMPLES_PER_TICK),
            per_tick: SAMPLES_PER_TICK,
            channels: CHANNELS,
            what: "calibrate",
            shorter: "a shorter calibration",
            lower: "a lower calibration current",
        },
    )?;
    let rows = record
        .samples
        .chunks_exact(SAMPLES_PER_TICK as usize)
        .enumerate()
        .map(|(k, pair)| {
            match pair {
                [first, second] => CalibrationRow::from_samples(first, second),
                _ => None,
            }
            .ok_or_else(|| HarnessError::Backend(format!("board calibrate: tick {k} has no stage")))
        })
        .collect::<Result<Vec<_>>>()?;
    Ok(BoardCalibration {
        rate_hz: record.rate_hz,
        rows,
    })
}
