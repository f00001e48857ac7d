//! The harness side of the link (needs `std`): lock-step request/reply over any byte stream
//! with a read timeout (a Unix socket to QEMU's serial port, or a serial device: a board's
//! `/dev/ttyACM0`, or the pseudo-terminal QEMU gives its UART), and fault injection for
//! tests.

use crate::message::{FaultReport, Hello, HelloAck};
use crate::wire::Writer;
use crate::{Decoder, Frame, FrameKind, LinkError, MAX_FRAME};
use std::io::{self, Read, Write};
use std::os::unix::net::UnixStream;
use std::time::{Duration, Instant};

/// A byte stream whose reads can time out.
pub trait Transport: Read + Write {
    /// Sets the read timeout (`None` blocks).
    fn set_read_deadline(&mut self, timeout: Option<Duration>) -> io::Result<()>;
}

impl Transport for UnixStream {
    fn set_read_deadline(&mut self, timeout: Option<Duration>) -> io::Result<()> {
        self.set_read_timeout(timeout)
    }
}

/// A serial device: termios raw mode, reads that time out (the `serialport` crate).
impl Transport for serialport::TTYPort {
    fn set_read_deadline(&mut self, timeout: Option<Duration>) -> io::Result<()> {
        // No timeout is a long one: the device has no blocking mode of its own.
        serialport::SerialPort::set_timeout(self, timeout.unwrap_or(Duration::from_secs(3600)))
            .map_err(io::Error::from)
    }
}

/// Opens the serial device `path` at `baud` (8N1, no flow control, raw) as a link stream.
pub fn open_serial(path: &std::path::Path, baud: u32) -> io::Result<Stream> {
    let port = serialport::new(path.to_string_lossy(), baud)
        .timeout(Duration::from_secs(1))
        .open_native()
        .map_err(|e| io::Error::other(format!("serial device {}: {e}", path.display())))?;
    Ok(Stream::Serial(port))
}

/// The byte stream of a link: a Unix socket or a serial device.
pub enum Stream {
    /// A Unix socket (QEMU's UART on a socket chardev).
    Socket(UnixStream),
    /// A serial device (a board's port, or QEMU's UART on a pseudo-terminal).
    Serial(serialport::TTYPort),
}

impl Read for Stream {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        match self {
            Self::Socket(s) => s.read(buf),
            Self::Serial(s) => s.read(buf),
        }
    }
}

impl Write for Stream {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        match self {
            Self::Socket(s) => s.write(buf),
            Self::Serial(s) => s.write(buf),
        }
    }

    fn flush(&mut self) -> io::Result<()> {
        match self {
            Self::Socket(s) => s.flush(),
            Self::Serial(s) => s.flush(),
        }
    }
}

impl Transport for Stream {
    fn set_read_deadline(&mut self, timeout: Option<Duration>) -> io::Result<()> {
        match self {
            Self::Socket(s) => Transport::set_read_deadline(s, timeout),
            Self::Serial(s) => Transport::set_read_deadline(s, timeout),
        }
    }
}

impl Transport for std::net::TcpStream {
    fn set_read_deadline(&mut self, timeout: Option<Duration>) -> io::Result<()> {
        self.set_read_timeout(timeout)
    }
}

/// A fault to inject on the link, for testing that both sides detect it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Injection {
    /// The sensor frame is never sent (lost on the way to the firmware).
    DropRequest,
    /// One bit of the sensor frame is flipped (byte offset within the frame, from 0).
    CorruptRequest {
        /// Byte index within the encoded frame (taken modulo the frame length).
        byte: usize,
    },
    /// The sensor frame is sent this late.
    DelayRequest {
        /// Delay before sending, in ms.
        ms: u64,
    },
    /// The sensor frame is sent with the sequence number one too high (the one before it
    /// "lost" in a stream that does not wait for replies).
    SkipSequence,
    /// One bit of the firmware's reply is flipped before the harness decodes it.
    CorruptReply {
        /// Byte index within the reply (taken modulo its length).
        byte: usize,
    },
    /// The firmware's reply is discarded (lost on the way back).
    DropReply,
}

/// Inject `injection` on the sensor frame with index `at_tick` (0 = first).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FaultPlan {
    /// Index of the sensor frame to hit.
    pub at_tick: u64,
    /// What to do to it.
    pub injection: Injection,
}

impl core::str::FromStr for FaultPlan {
    type Err = String;

    /// `KIND@TICK[:ARG]`, KIND one of `drop`, `corrupt[:BYTE]`, `delay:MS`, `skip-seq`,
    /// `corrupt-reply[:BYTE]`, `drop-reply`. Example: `corrupt@1200:9`, `delay@500:400`.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let usage = "fault plan KIND@TICK[:ARG], KIND one of drop, corrupt, delay, skip-seq, \
                     corrupt-reply, drop-reply (delay needs :MS)";
        let (kind, rest) = s
            .split_once('@')
            .ok_or_else(|| format!("{usage}; got {s:?}"))?;
        let (tick, arg) = match rest.split_once(':') {
            Some((t, a)) => (t, Some(a)),
            None => (rest, None),
        };
        let at_tick: u64 = tick
            .parse()
            .map_err(|_| format!("{usage}; TICK {tick:?} is not a whole number"))?;
        let arg_num = |default: Option<u64>| -> Result<u64, String> {
            match (arg, default) {
                (Some(a), _) => a
                    .parse()
                    .map_err(|_| format!("{usage}; ARG {a:?} is not a whole number")),
                (None, Some(d)) => Ok(d),
                (None, None) => Err(format!("{usage}; {kind} needs :ARG")),
            }
        };
        // Default corrupted byte 9: inside the payload of every sensor frame.
        let injection = match kind {
            "drop" => Injection::DropRequest,
            "corrupt" => Injection::CorruptRequest {
                byte: usize::try_from(arg_num(Some(9))?).unwrap_or(usize::MAX),
            },
            "delay" => Injection::DelayRequest { ms: arg_num(None)? },
            "skip-seq" => Injection::SkipSequence,
            "corrupt-reply" => Injection::CorruptReply {
                byte: usize::try_from(arg_num(Some(9))?).unwrap_or(usize::MAX),
            },
            "drop-reply" => Injection::DropReply,
            other => return Err(format!("{usage}; unknown KIND {other:?}")),
        };
        Ok(Self { at_tick, injection })
    }
}

/// What went wrong on the harness side of the link.
#[derive(Debug)]
pub enum HostError {
    /// The harness detected a bad frame from the firmware (CRC, version, sequence, ...) or
    /// no reply within the deadline (`LinkError::Timeout`).
    Link(LinkError),
    /// The firmware reported that it latched its safe state.
    FirmwareFault(FaultReport),
    /// The firmware answered with a frame of the wrong kind.
    UnexpectedReply {
        /// Kind expected.
        expected: FrameKind,
        /// Kind received.
        received: FrameKind,
    },
    /// The stream closed (QEMU exited).
    Closed,
    /// An I/O error on the stream.
    Io(io::Error),
}

impl core::fmt::Display for HostError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Link(e) => write!(f, "harness detected a link fault: {e}"),
            Self::FirmwareFault(r) => {
                write!(
                    f,
                    "firmware latched its safe state: {} (expected frame {}, {} ticks done; outputs: \
                 torque bits {}, PWM voltage bits {}, enable pin {}, tick after the fault {})",
                    r.code.name(),
                    r.expected_seq,
                    r.ticks_done,
                    r.outputs.torque_cmd_bits,
                    r.outputs.pwm_voltage_bits,
                    if r.outputs.enable_pin { "high" } else { "low" },
                    if r.outputs.current_tick_ran {
                        "ran"
                    } else {
                        "did NOT run"
                    }
                )
            }
            Self::UnexpectedReply { expected, received } => {
                write!(f, "expected a {expected:?} frame, got {received:?}")
            }
            Self::Closed => write!(f, "the firmware closed the link"),
            Self::Io(e) => write!(f, "link I/O error: {e}"),
        }
    }
}

impl std::error::Error for HostError {}

impl From<io::Error> for HostError {
    fn from(e: io::Error) -> Self {
        Self::Io(e)
    }
}

/// Harness end of the link: sends one frame and waits for its reply (lock step).
pub struct HostLink<S: Transport> {
    stream: S,
    decoder: Decoder,
    next_seq: u16,
    reply_timeout: Duration,
    plan: Option<FaultPlan>,
    sensors_sent: u64,
    pending: std::collections::VecDeque<u8>,
}

impl<S: Transport> HostLink<S> {
    /// A link over `stream`; every reply must arrive within `reply_timeout`.
    pub fn new(stream: S, reply_timeout: Duration) -> Self {
        Self {
            stream,
            decoder: Decoder::new(),
            next_seq: 0,
            reply_timeout,
            plan: None,
            sensors_sent: 0,
            pending: std::collections::VecDeque::new(),
        }
    }

    /// Arms a fault injection.
    pub fn inject(&mut self, plan: FaultPlan) {
        self.plan = Some(plan);
    }

    /// Sensor frames sent so far.
    pub const fn sensors_sent(&self) -> u64 {
        self.sensors_sent
    }

    /// Opens the session; the firmware arms a watchdog of `watchdog_ms`.
    pub fn hello(&mut self, watchdog_ms: u32) -> Result<HelloAck, HostError> {
        let mut w = Writer::new();
        Hello { watchdog_ms }
            .encode(&mut w)
            .map_err(HostError::Link)?;
        let reply = self.request(FrameKind::Hello, w.as_slice(), FrameKind::HelloAck)?;
        HelloAck::decode(reply.payload()).map_err(HostError::Link)
    }

    /// Sends the controller configuration.
    pub fn configure(&mut self, payload: &[u8]) -> Result<(), HostError> {
        self.request(FrameKind::Config, payload, FrameKind::ConfigAck)
            .map(|_| ())
    }

    /// One tick: sends a `Sensors` payload, returns the `Commands` payload.
    pub fn tick(&mut self, sensors: &[u8]) -> Result<Frame, HostError> {
        let r = self.request(FrameKind::Sensors, sensors, FrameKind::Commands);
        self.sensors_sent += 1;
        r
    }

    /// Sends a frame of `kind` with the next sequence number, without waiting for a reply
    /// (the board console, [`crate::board::client`]); returns the sequence number used.
    pub fn send_next(&mut self, kind: FrameKind, payload: &[u8]) -> Result<u16, HostError> {
        let seq = self.next_seq;
        self.next_seq = seq.wrapping_add(1);
        self.send(kind, seq, payload)?;
        Ok(seq)
    }

    /// Writes `bytes` to the line as they are (tests: line noise, damaged frames).
    pub fn write_raw(&mut self, bytes: &[u8]) -> Result<(), HostError> {
        self.stream.write_all(bytes)?;
        self.stream.flush()?;
        Ok(())
    }

    /// The next frame from the firmware, whatever its kind, by `deadline`.
    pub fn receive(&mut self, deadline: Instant) -> Result<Frame, HostError> {
        self.read_frame(deadline, None)
    }

    /// Ends the session cleanly (the firmware acknowledges and exits).
    pub fn stop(&mut self) -> Result<(), HostError> {
        self.request(FrameKind::Stop, &[], FrameKind::Stop)
            .map(|_| ())
    }

    /// After a fault: proves the firmware latched its safe state and ends the session.
    ///
    /// If the firmware has not reported a fault itself (`already` is `None`, e.g. the harness
    /// caught a corrupted reply), the harness stays silent for up to `wait` so the firmware's
    /// watchdog must expire and report `Timeout`. Then it sends `Stop`; a latched firmware
    /// answers with its `Fault` report again and exits. Returns the last report received,
    /// `None` if the firmware never showed a latched fault.
    pub fn confirm_safe_state(
        &mut self,
        already: Option<FaultReport>,
        wait: Duration,
    ) -> Option<FaultReport> {
        self.plan = None;
        self.decoder.reset();
        let mut report = already;
        if report.is_none() {
            report = self.await_fault(Instant::now() + wait);
        }
        let seq = self.next_seq;
        self.next_seq = self.next_seq.wrapping_add(1);
        if self.send(FrameKind::Stop, seq, &[]).is_ok()
            && let Some(r) = self.await_fault(Instant::now() + wait)
        {
            report = Some(r);
        }
        report
    }

    fn await_fault(&mut self, deadline: Instant) -> Option<FaultReport> {
        while Instant::now() < deadline {
            match self.read_frame(deadline, None) {
                Ok(frame) if frame.kind == FrameKind::Fault => {
                    return FaultReport::decode(frame.payload()).ok();
                }
                Ok(_) | Err(HostError::Link(_)) => {}
                Err(_) => return None,
            }
        }
        None
    }

    fn injection_now(&self, kind: FrameKind) -> Option<Injection> {
        match self.plan {
            Some(p) if kind == FrameKind::Sensors && p.at_tick == self.sensors_sent => {
                Some(p.injection)
            }
            _ => None,
        }
    }

    fn request(
        &mut self,
        kind: FrameKind,
        payload: &[u8],
        expected: FrameKind,
    ) -> Result<Frame, HostError> {
        let injection = self.injection_now(kind);
        let mut seq = self.next_seq;
        if injection == Some(Injection::SkipSequence) {
            seq = seq.wrapping_add(1);
        }
        self.next_seq = seq.wrapping_add(1);
        match injection {
            Some(Injection::DropRequest) => {}
            Some(Injection::DelayRequest { ms }) => {
                std::thread::sleep(Duration::from_millis(ms));
                self.send(kind, seq, payload)?;
            }
            Some(Injection::CorruptRequest { byte }) => {
                let mut wire = self.encode(kind, seq, payload)?;
                let n = wire.len();
                if let Some(b) = wire.get_mut(byte % n.max(1)) {
                    *b ^= 0x10;
                }
                self.stream.write_all(&wire)?;
                self.stream.flush()?;
            }
            _ => self.send(kind, seq, payload)?,
        }
        let deadline = Instant::now() + self.reply_timeout;
        let mut frame = self.read_frame(deadline, injection)?;
        if injection == Some(Injection::DropReply) {
            // The reply was "lost": wait for another one, which never comes in lock step.
            frame = self.read_frame(deadline, None)?;
        }
        if frame.kind == FrameKind::Fault {
            let report = FaultReport::decode(frame.payload()).map_err(HostError::Link)?;
            return Err(HostError::FirmwareFault(report));
        }
        if frame.seq != seq {
            return Err(HostError::Link(LinkError::OutOfSequence {
                expected: seq,
                received: frame.seq,
            }));
        }
        if frame.kind != expected {
            return Err(HostError::UnexpectedReply {
                expected,
                received: frame.kind,
            });
        }
        Ok(frame)
    }

    fn encode(&self, kind: FrameKind, seq: u16, payload: &[u8]) -> Result<Vec<u8>, HostError> {
        let frame = Frame::new(kind, seq, payload).map_err(HostError::Link)?;
        let mut wire = [0_u8; MAX_FRAME];
        let n = frame.encode(&mut wire).map_err(HostError::Link)?;
        Ok(wire.get(..n).unwrap_or(&[]).to_vec())
    }

    fn send(&mut self, kind: FrameKind, seq: u16, payload: &[u8]) -> Result<(), HostError> {
        let wire = self.encode(kind, seq, payload)?;
        self.stream.write_all(&wire)?;
        self.stream.flush()?;
        Ok(())
    }

    /// Reads bytes until one frame completes (or an error), by `deadline`.
    fn read_frame(
        &mut self,
        deadline: Instant,
        injection: Option<Injection>,
    ) -> Result<Frame, HostError> {
        let mut received = 0_usize;
        loop {
            while let Some(mut byte) = self.pending.pop_front() {
                if let Some(Injection::CorruptReply { byte: at }) = injection {
                    // Flip a bit of byte `at` of the reply, taken modulo the shortest frame
                    // (header + CRC) so the hit always lands.
                    if received == at % (crate::HEADER_LEN + crate::CRC_LEN) {
                        byte ^= 0x10;
                    }
                }
                received += 1;
                if let Some(frame) = self.decoder.push(byte).map_err(HostError::Link)? {
                    return Ok(frame);
                }
            }
            let now = Instant::now();
            if now >= deadline {
                return Err(HostError::Link(LinkError::Timeout {
                    waited_ms: u32::try_from(self.reply_timeout.as_millis()).unwrap_or(u32::MAX),
                }));
            }
            self.stream.set_read_deadline(Some(deadline - now))?;
            let mut buf = [0_u8; 256];
            match self.stream.read(&mut buf) {
                Ok(0) => return Err(HostError::Closed),
                Ok(n) => self.pending.extend(buf.get(..n).unwrap_or(&[])),
                Err(e)
                    if matches!(
                        e.kind(),
                        io::ErrorKind::WouldBlock
                            | io::ErrorKind::TimedOut
                            | io::ErrorKind::Interrupted
                    ) => {}
                Err(e) => return Err(HostError::Io(e)),
            }
        }
    }
}
