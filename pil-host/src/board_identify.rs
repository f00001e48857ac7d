//! The host side of the board's `Identify` (`pil_link::board::identify`): one measurement
//! run on the board, its record collected from the `ScopeData` frames that follow the
//! reply. The record must be whole: every tick, numbered from 0 without a gap, in the
//! channels `pil_link::board::identify::CHANNELS`; a fault the board latched during the
//! run (a new entry in its fault history) fails it. The board streams while it records
//! and holds only what the link is behind; a run it ended early (its buffer overran on a
//! slow link, or a `Disable`) ends the stream with a mark, and fails at once, saying why.

use pil_link::board::client::{BoardClient, BoardError};
use pil_link::board::faults::LINK_FAULT_CODE;
use pil_link::board::identify::{is_cut_end, IdentifyRun, CHANNELS};
use pil_link::board::message::Request;
use pil_link::board::scope::{ScopeChunk, ScopeInfo, SCOPE_CHANNELS};
use pil_link::board::session::fault_name;
use pil_link::host::Stream;
use sim_engine::error::{HarnessError, Result};
use std::time::{Duration, Instant};

/// A measurement's record as the board sent it.
#[derive(Clone, Debug, PartialEq)]
pub struct BoardRecord {
    /// Ticks per second (the current-loop rate).
    pub rate_hz: u32,
    /// Per tick, the raw channels of `CHANNELS`: Q16.16 bits of excitation, current and
    /// torque reference, the encoder counter.
    pub samples: Vec<[i32; SCOPE_CHANNELS]>,
}

fn link(e: BoardError) -> HarnessError {
    match e {
        BoardError::Refused { message, .. } => {
            HarnessError::Backend(format!("board refused: {message}"))
        }
        other => HarnessError::Backend(format!("board identify: {other}")),
    }
}

/// Places chunk `c`'s samples at their numbers in `samples` (numbered from 0); false for a
/// chunk that does not continue the record (a gap, a repeat, beyond `wanted`).
fn place(samples: &mut Vec<[i32; SCOPE_CHANNELS]>, c: &ScopeChunk, wanted: usize) -> bool {
    if c.first as usize != samples.len() || samples.len() + usize::from(c.len) > wanted {
        return false;
    }
    samples.extend(c.samples().iter().map(|s| s.values));
    true
}

/// Runs `run` on the board and collects its record (module docs). The board sends at its
/// own pace: the wait is four times the run at its rate, and 10 s.
///
/// # Errors
/// Refused (enabled, a latched fault, settings or excitation out of range: the board's
/// message names the key), a link failure, a gap, other channels, a fault during the run.
pub fn run_identify(client: &mut BoardClient<Stream>, run: &IdentifyRun) -> Result<BoardRecord> {
    let faults_before = client.faults().map_err(link)?.total();
    let wanted = run.ticks as usize;
    let mut samples = Vec::with_capacity(wanted);
    let mut broken = false;
    // The ticks of a run the board ended early.
    let mut cut: Option<u32> = None;
    let body = client
        .request_with(&Request::Identify(*run), &mut |c| {
            if is_cut_end(&c, run.ticks) {
                cut = Some(c.first);
            }
            broken |= !place(&mut samples, &c, wanted);
        })
        .map_err(link)?;
    let info = ScopeInfo::decode(&body).map_err(|e| link(BoardError::Reply(e)))?;
    if info.channels != CHANNELS {
        return Err(HarnessError::Backend(format!(
            "board identify: the board records {:?}, not {CHANNELS:?}",
            info.channels
        )));
    }
    let rate_hz = info.rate_hz.max(1);
    let seconds = f64::from(run.ticks) / f64::from(rate_hz);
    let bar = sim_engine::progress::bar(wanted as u64, "identify (board)");
    let deadline = Instant::now() + Duration::from_secs_f64(4.0 * seconds + 10.0);
    let received = if cut.is_some() {
        Ok(())
    } else {
        client.scope_receive(deadline, &mut |c| {
            if is_cut_end(&c, run.ticks) {
                cut = Some(c.first);
            }
            broken |= !place(&mut samples, &c, wanted);
            bar.set_position(samples.len() as u64);
            !broken && cut.is_none() && samples.len() < wanted
        })
    };
    bar.finish_and_clear();
    received.map_err(link)?;
    if let Some(recorded) = cut {
        let history = client.faults().map_err(link)?;
        let overran = history.total() != faults_before
            && history.entries().last().map(|e| e.code) == Some(LINK_FAULT_CODE);
        let why = if overran {
            "the console link fell behind the record and the board's buffer overran: a \
             faster link, or fewer identify.prbs_periods"
        } else {
            "the drive was disabled or faulted"
        };
        return Err(HarnessError::Backend(format!(
            "board identify: the board ended the run after {recorded} of {wanted} ticks: {why}"
        )));
    }
    if broken || samples.len() != wanted {
        return Err(HarnessError::Backend(format!(
            "board identify: the record has a gap ({} of {wanted} samples in order)",
            samples.len()
        )));
    }
    let history = client.faults().map_err(link)?;
    if history.total() != faults_before {
        let last = history.entries().last().map_or(0, |e| e.code);
        return Err(HarnessError::Backend(format!(
            "board identify: the drive faulted during the measurement ({}); lower \
             identify.amplitude_pu or identify.reversal_torque_pu",
            fault_name(last)
        )));
    }
    Ok(BoardRecord { rate_hz, samples })
}
