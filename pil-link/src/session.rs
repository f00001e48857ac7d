//! The firmware side of a PIL session as a plain state machine: bytes and the time in, reply
//! frames out. It knows nothing of UARTs or controllers, so the same code runs in the
//! firmware image and in host tests.
//!
//! ```text
//! AwaitHello --Hello--> Open --Stop--> Stopped
//!     |                  |  any link error, sequence gap, watchdog expiry,
//!     | Hello with a     |  a second Config
//!     | bad watchdog     v
//!     +------------> Faulted (latched: safe state, every frame answered with Fault)
//! ```
//!
//! A session nobody talks to ends: [`FirmwareSession::abandoned`] tells the firmware to
//! exit (which ends QEMU) when no `Hello` came within [`HELLO_WAIT_MS`] of boot, or when a
//! faulted session hears nothing for twice its watchdog plus [`ABANDON_GRACE_MS`], as when
//! the harness was killed.

use crate::message::{FaultCode, FaultReport, Hello, HelloAck, SafeOutputs, WATCHDOG_MS_RANGE};
use crate::wire::Writer;
use crate::{Decoder, Frame, FrameKind, PROTOCOL_VERSION, SequenceCheck};

/// What the session drives: the controller behind the link.
pub trait Target {
    /// Applies a `Config` payload (controller parameters for this run).
    fn configure(&mut self, payload: &[u8]) -> Result<(), FaultCode>;
    /// Runs one controller tick on a `Sensors` payload and writes the `Commands` payload.
    fn tick(&mut self, sensors: &[u8], commands: &mut Writer) -> Result<(), FaultCode>;
    /// Enters the safe state (zero torque, fault latched, power stage disabled) and returns
    /// what it wrote, read back from the board layer's outputs, so the report shows what is
    /// really output.
    fn enter_safe_state(&mut self) -> SafeOutputs;
}

/// How long after boot (time 0) the firmware waits for a `Hello` before it gives up.
pub const HELLO_WAIT_MS: u32 = 30_000;
/// Silence a faulted session tolerates beyond twice its watchdog before it gives up.
pub const ABANDON_GRACE_MS: u32 = 2_000;

/// Where the session is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SessionState {
    /// Waiting for the harness's `Hello`; noise is ignored and no watchdog runs.
    AwaitHello,
    /// Session open: frames must arrive in sequence within the watchdog period.
    Open,
    /// Safe state latched; only a reset (new boot) clears it.
    Faulted(FaultReport),
    /// The harness ended the run; `faulted` tells whether it ended in the safe state.
    Stopped {
        /// True when the run ended with a latched fault.
        faulted: bool,
    },
}

/// Firmware-side session. Feed it every received byte with [`FirmwareSession::on_byte`] and
/// call [`FirmwareSession::poll_watchdog`] while waiting; send whatever frame they return.
#[derive(Clone, Debug)]
pub struct FirmwareSession {
    decoder: Decoder,
    seq: SequenceCheck,
    state: SessionState,
    configured: bool,
    watchdog_ms: u32,
    last_frame_ms: u32,
    ticks_done: u32,
    firmware_version: u32,
}

impl FirmwareSession {
    /// A session waiting for `Hello`. `firmware_version` is packed
    /// `major << 16 | minor << 8 | patch` and reported in `HelloAck`.
    pub const fn new(firmware_version: u32) -> Self {
        Self {
            decoder: Decoder::new(),
            seq: SequenceCheck::new(0),
            state: SessionState::AwaitHello,
            configured: false,
            watchdog_ms: 0,
            last_frame_ms: 0,
            ticks_done: 0,
            firmware_version,
        }
    }

    /// Current state.
    pub const fn state(&self) -> SessionState {
        self.state
    }

    /// Sensor frames answered so far.
    pub const fn ticks_done(&self) -> u32 {
        self.ticks_done
    }

    /// Feeds one received byte at time `now_ms`; returns the frame to send, if any.
    pub fn on_byte<T: Target>(&mut self, byte: u8, now_ms: u32, target: &mut T) -> Option<Frame> {
        let decoded = self.decoder.push(byte);
        match self.state {
            SessionState::Stopped { .. } => None,
            // Before Hello the line may carry start-up noise: only an intact Hello counts.
            SessionState::AwaitHello => match decoded {
                Ok(Some(frame)) if frame.kind == FrameKind::Hello => {
                    self.open(&frame, now_ms, target)
                }
                _ => None,
            },
            SessionState::Faulted(report) => match decoded {
                Ok(None) => None,
                Ok(Some(frame)) => {
                    self.last_frame_ms = now_ms;
                    if frame.kind == FrameKind::Stop {
                        self.state = SessionState::Stopped { faulted: true };
                    }
                    fault_frame(&report)
                }
                Err(_) => fault_frame(&report),
            },
            SessionState::Open => match decoded {
                Ok(None) => None,
                Ok(Some(frame)) => {
                    self.last_frame_ms = now_ms;
                    self.on_frame(&frame, target)
                }
                Err(e) => self.latch(FaultCode::from_link_error(e), target),
            },
        }
    }

    /// Checks the watchdog at time `now_ms` (wrapping ms); returns the `Fault` frame to send
    /// when it has just expired.
    pub fn poll_watchdog<T: Target>(&mut self, now_ms: u32, target: &mut T) -> Option<Frame> {
        if self.state != SessionState::Open {
            return None;
        }
        if now_ms.wrapping_sub(self.last_frame_ms) > self.watchdog_ms {
            return self.latch(FaultCode::Timeout, target);
        }
        None
    }

    /// Whether nobody is driving this session any more (see the module docs): the firmware
    /// should then exit.
    pub fn abandoned(&self, now_ms: u32) -> bool {
        match self.state {
            SessionState::AwaitHello => now_ms > HELLO_WAIT_MS,
            SessionState::Faulted(_) => {
                let limit = self
                    .watchdog_ms
                    .saturating_mul(2)
                    .saturating_add(ABANDON_GRACE_MS);
                now_ms.wrapping_sub(self.last_frame_ms) > limit
            }
            SessionState::Open | SessionState::Stopped { .. } => false,
        }
    }

    fn open<T: Target>(&mut self, frame: &Frame, now_ms: u32, target: &mut T) -> Option<Frame> {
        let hello = Hello::decode(frame.payload()).ok()?;
        self.seq = SequenceCheck::new(frame.seq.wrapping_add(1));
        self.last_frame_ms = now_ms;
        if !WATCHDOG_MS_RANGE.contains(&hello.watchdog_ms) {
            // A watchdog of 0 or of days would let a dead host keep the outputs on.
            return self.latch(FaultCode::Protocol, target);
        }
        self.watchdog_ms = hello.watchdog_ms;
        self.state = SessionState::Open;
        let ack = HelloAck {
            protocol_version: PROTOCOL_VERSION,
            firmware_version: self.firmware_version,
            watchdog_ms: hello.watchdog_ms,
        };
        let mut w = Writer::new();
        ack.encode(&mut w).ok()?;
        Frame::new(FrameKind::HelloAck, frame.seq, w.as_slice()).ok()
    }

    fn on_frame<T: Target>(&mut self, frame: &Frame, target: &mut T) -> Option<Frame> {
        if self.seq.accept(frame.seq).is_err() {
            let reply = self.latch(FaultCode::OutOfSequence, target);
            if frame.kind == FrameKind::Stop {
                // The harness wants the run over: end it, still latched and reported.
                self.state = SessionState::Stopped { faulted: true };
            }
            return reply;
        }
        match frame.kind {
            // A second Config would reset the controller and clear a latched controller
            // fault without an operator: refused.
            FrameKind::Config if self.configured => self.latch(FaultCode::Protocol, target),
            FrameKind::Config => match target.configure(frame.payload()) {
                Ok(()) => {
                    self.configured = true;
                    Frame::new(FrameKind::ConfigAck, frame.seq, &[]).ok()
                }
                Err(code) => self.latch(code, target),
            },
            FrameKind::Sensors if self.configured => {
                let mut w = Writer::new();
                match target.tick(frame.payload(), &mut w) {
                    Ok(()) => {
                        self.ticks_done = self.ticks_done.wrapping_add(1);
                        Frame::new(FrameKind::Commands, frame.seq, w.as_slice()).ok()
                    }
                    Err(code) => self.latch(code, target),
                }
            }
            FrameKind::Stop => {
                self.state = SessionState::Stopped { faulted: false };
                Frame::new(FrameKind::Stop, frame.seq, &[]).ok()
            }
            _ => self.latch(FaultCode::Protocol, target),
        }
    }

    fn latch<T: Target>(&mut self, code: FaultCode, target: &mut T) -> Option<Frame> {
        let outputs = target.enter_safe_state();
        let report = FaultReport {
            code,
            expected_seq: self.seq.expected(),
            ticks_done: self.ticks_done,
            outputs,
        };
        self.state = SessionState::Faulted(report);
        fault_frame(&report)
    }
}

fn fault_frame(report: &FaultReport) -> Option<Frame> {
    let mut w = Writer::new();
    report.encode(&mut w).ok()?;
    Frame::new(FrameKind::Fault, report.expected_seq, w.as_slice()).ok()
}
