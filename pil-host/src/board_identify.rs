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

pub(crate) fn link(e: BoardError) -> HarnessError {
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
    stream_record(
        client,
        &Request::Identify(*run),
        &Streamed {
            samples: run.ticks,
            per_tick: 1,
            channels: CHANNELS,
            what: "identify",
            shorter: "fewer identify.prbs_periods",
            lower: "lower identify.amplitude_pu or identify.reversal_torque_pu",
        },
    )
}

/// What a streamed record is: its length, its channels, how the errors name it.
pub(crate) struct Streamed {
    /// Samples of the whole record.
    pub samples: u32,
    /// Samples a current tick takes.
    pub per_tick: u32,
    /// The channels the board must record.
    pub channels: &'static str,
    /// The command, as the errors name it.
    pub what: &'static str,
    /// How to make the run shorter (an overrun's remedy).
    pub shorter: &'static str,
    /// How to excite less (a fault's remedy).
    pub lower: &'static str,
}

/// Sends `request` and collects the record the board streams after its reply (module
/// docs); the wait is four times the run at its rate, and 10 s.
pub(crate) fn stream_record(
    client: &mut BoardClient<Stream>,
    request: &Request<'_>,
    rec: &Streamed,
) -> Result<BoardRecord> {
    let what = rec.what;
    let faults_before = client.faults().map_err(link)?.total();
    let wanted = rec.samples as usize;
    let mut samples = Vec::with_capacity(wanted);
    let mut broken = false;
    // The samples of a run the board ended early.
    let mut cut: Option<u32> = None;
    let body = client
        .request_with(request, &mut |c| {
            if is_cut_end(&c, rec.samples) {
                cut = Some(c.first);
            }
            broken |= !place(&mut samples, &c, wanted);
        })
        .map_err(link)?;
    let info = ScopeInfo::decode(&body).map_err(|e| link(BoardError::Reply(e)))?;
    if info.channels != rec.channels {
        return Err(HarnessError::Backend(format!(
            "board {what}: the board records {:?}, not {:?}",
            info.channels, rec.channels
        )));
    }
    let rate_hz = info.rate_hz.max(1);
    let seconds = f64::from(rec.samples / rec.per_tick.max(1)) / f64::from(rate_hz);
    let bar = sim_engine::progress::bar(wanted as u64, &format!("{what} (board)"));
    let deadline = Instant::now() + Duration::from_secs_f64(4.0 * seconds + 10.0);
    let received = if cut.is_some() {
        Ok(())
    } else {
        client.scope_receive(deadline, &mut |c| {
            if is_cut_end(&c, rec.samples) {
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
            format!(
                "the console link fell behind the record and the board's buffer overran: a \
                 faster link, or {}",
                rec.shorter
            )
        } else {
            "the drive was disabled or faulted".to_string()
        };
        let per_tick = rec.per_tick.max(1);
        return Err(HarnessError::Backend(format!(
            "board {what}: the board ended the run after {} of {} ticks: {why}",
            recorded / per_tick,
            rec.samples / per_tick
        )));
    }
    if broken || samples.len() != wanted {
        return Err(HarnessError::Backend(format!(
            "board {what}: the record has a gap ({} of {wanted} samples in order)",
            samples.len()
        )));
    }
    let history = client.faults().map_err(link)?;
    if history.total() != faults_before {
        let last = history.entries().last().map_or(0, |e| e.code);
        return Err(HarnessError::Backend(format!(
            "board {what}: the drive faulted during the measurement ({}); {}",
            fault_name(last),
            rec.lower
        )));
    }
    Ok(BoardRecord { rate_hz, samples })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;
    use controller_core::{ConfigError, DriveConfig};
    use pil_link::board::faults::{FaultEntry, FaultHistory};
    use pil_link::board::identify::IdentifyError;
    use pil_link::board::message::Origin;
    use pil_link::board::scope::{ScopeSample, CHUNK_SAMPLES};
    use pil_link::board::session::{BoardSession, Drive};
    use pil_link::board::store::{SaveError, RECORD_LEN};
    use pil_link::wire::Writer;
    use pil_link::{Frame, FrameKind, MAX_FRAME};
    use std::io::{Read, Write};
    use std::os::unix::net::UnixStream;

    /// A board whose measurement ends after two chunks, as the firmware's console ends a
    /// run cut short (`firmware/src/board_console/`): the samples recorded, an overrun's
    /// link fault in the history (or none: a disable), then the empty mark.
    struct CutBoard {
        history: FaultHistory,
        enabled: bool,
        started: bool,
    }

    impl Drive for CutBoard {
        fn apply(&mut self, _: &DriveConfig) -> std::result::Result<(), ConfigError> {
            Ok(())
        }
        fn enabled(&self) -> bool {
            self.enabled
        }
        fn set_enabled(&mut self, on: bool) {
            self.enabled = on;
        }
        fn fault_code(&self) -> u8 {
            0
        }
        fn save(&mut self, _: &[u8; RECORD_LEN]) -> std::result::Result<(), SaveError> {
            Ok(())
        }
        fn fault_history(&self) -> FaultHistory {
            self.history
        }
        fn scope(&mut self, _: bool) -> ScopeInfo<'_> {
            ScopeInfo {
                rate_hz: 1000,
                channels: "a,b,c,d",
            }
        }
        fn enter_safe_state(&mut self) {}
        fn identify(
            &mut self,
            cfg: &DriveConfig,
            _: &DriveConfig,
            _: &IdentifyRun,
        ) -> std::result::Result<ScopeInfo<'_>, IdentifyError> {
            (self.enabled, self.started) = (true, true);
            Ok(ScopeInfo {
                rate_hz: cfg.current_rate_hz,
                channels: CHANNELS,
            })
        }
    }

    fn send(sock: &mut UnixStream, kind: FrameKind, payload: &[u8]) {
        send_frame(sock, &Frame::new(kind, 0, payload).unwrap());
    }

    fn send_frame(sock: &mut UnixStream, frame: &Frame) {
        let mut wire = [0_u8; MAX_FRAME];
        let n = frame.encode(&mut wire).unwrap();
        sock.write_all(&wire[..n]).unwrap();
    }

    fn chunk_payload(c: &ScopeChunk) -> Vec<u8> {
        let mut w = Writer::new();
        c.encode(&mut w).unwrap();
        w.as_slice().to_vec()
    }

    /// Serves the console on `sock` until the host hangs up.
    fn serve(mut sock: UnixStream, overrun: bool) {
        let drive = machine_file::table1().expect("table1 composes").drive;
        let mut session = BoardSession::new(drive, Origin::Baked, 0x0001_0000, "table1");
        let mut board = CutBoard {
            history: FaultHistory::new(),
            enabled: false,
            started: false,
        };
        let mut buf = [0_u8; 256];
        while let Ok(n @ 1..) = sock.read(&mut buf) {
            for &b in &buf[..n] {
                if let Some(reply) = session.on_byte(b, &mut board) {
                    send_frame(&mut sock, &reply);
                }
                if std::mem::take(&mut board.started) {
                    for first in [0, 8] {
                        let mut c = ScopeChunk::new(first);
                        for n in first..first + CHUNK_SAMPLES as u32 {
                            c.push(ScopeSample {
                                tick: n,
                                values: [0; SCOPE_CHANNELS],
                            });
                        }
                        send(&mut sock, FrameKind::ScopeData, &chunk_payload(&c));
                    }
                    if overrun {
                        board.history.push(FaultEntry {
                            ms: 1,
                            code: LINK_FAULT_CODE,
                        });
                    }
                    board.enabled = false;
                    let mark = ScopeChunk::new(16);
                    send(&mut sock, FrameKind::ScopeData, &chunk_payload(&mark));
                }
            }
        }
    }

    /// identify's default frequency-response run: 32 periods of 8191 ticks.
    const DEFAULT_RUN: IdentifyRun = IdentifyRun {
        amplitude_pu: 0.3,
        prbs_bits: 13,
        prbs_hold_ticks: 1,
        prbs_periods: 32,
        velocity_bandwidth_rad_s: 15.0,
        load_pu: 0.8,
        reverse_every_ticks: 0,
        ticks: 262_112,
    };

    fn cut_run(overrun: bool) -> (String, Duration) {
        let (host, board) = UnixStream::pair().unwrap();
        let server = std::thread::spawn(move || serve(board, overrun));
        let mut client = BoardClient::new(Stream::Socket(host), Duration::from_secs(5));
        let t0 = Instant::now();
        let err = run_identify(&mut client, &DEFAULT_RUN).unwrap_err();
        let took = t0.elapsed();
        drop(client);
        server.join().unwrap();
        (err.to_string(), took)
    }

    #[test]
    fn a_run_the_board_cut_short_fails_at_once_naming_why() {
        // The link fell a ring behind: the history's link fault says so.
        let (msg, took) = cut_run(true);
        assert!(
            msg.contains("ended the run after 16 of 262112 ticks")
                && msg.contains("fell behind")
                && msg.contains("identify.prbs_periods"),
            "{msg}"
        );
        // At the mark, not at the stream's deadline (four times the 65.5 s run).
        assert!(took < Duration::from_secs(5), "{took:?}");
        // Without the link fault: the drive was disabled.
        let (msg, took) = cut_run(false);
        assert!(
            msg.contains("after 16 of 262112 ticks") && msg.contains("disabled"),
            "{msg}"
        );
        assert!(took < Duration::from_secs(5), "{took:?}");
    }
}
