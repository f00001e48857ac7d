//! Frame format and a byte-at-a-time decoder.
//!
//! ```text
//! offset  size  field
//! 0       2     sync 0xA5 0x5A
//! 2       1     protocol version (PROTOCOL_VERSION)
//! 3       1     kind (FrameKind)
//! 4       2     sequence number, little endian, wrapping
//! 6       1     payload length n (0..=MAX_PAYLOAD)
//! 7       n     payload (raw fixed-point bits, little endian)
//! 7+n     4     CRC-32/ISO-HDLC over bytes 2..7+n, little endian
//! ```
//! The layout of bytes 0..7 is frozen across versions, so a peer can always read the
//! version of a frame it does not understand and report `BadVersion` instead of garbage.

use crate::LinkError;
use crate::crc::Crc32;

/// Two sync bytes open every frame; the decoder hunts for them after noise or an error.
pub const SYNC: [u8; 2] = [0xA5, 0x5A];
/// Version of this protocol. Bump it whenever a payload layout changes.
pub const PROTOCOL_VERSION: u8 = 9;
/// Largest payload, in bytes.
pub const MAX_PAYLOAD: usize = 240;
/// Bytes before the payload: sync (2), version, kind, sequence (2), length.
pub const HEADER_LEN: usize = 7;
/// Bytes of CRC after the payload.
pub const CRC_LEN: usize = 4;
/// Largest frame on the wire, in bytes.
pub const MAX_FRAME: usize = HEADER_LEN + MAX_PAYLOAD + CRC_LEN;

/// What a frame carries. Direction: H = harness, F = firmware.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum FrameKind {
    /// H→F: open a session (watchdog period).
    Hello = 0x01,
    /// F→H: session accepted (protocol and firmware version).
    HelloAck = 0x02,
    /// H→F: controller parameters for this run.
    Config = 0x03,
    /// F→H: parameters accepted.
    ConfigAck = 0x04,
    /// H→F: sampled sensors for one tick.
    Sensors = 0x05,
    /// F→H: the controller's commands for that tick.
    Commands = 0x06,
    /// F→H: the link or the controller is faulted; the firmware holds its safe state.
    Fault = 0x07,
    /// H→F: end of the run; the firmware exits.
    Stop = 0x08,
    /// H→F: a board console request ([`crate::board`]; board protocol version first).
    BoardRequest = 0x10,
    /// F→H: the answer to a board console request (same sequence number).
    BoardReply = 0x11,
    /// F→H: scope samples streamed between `ScopeStart` and `ScopeStop`.
    ScopeData = 0x12,
}

impl FrameKind {
    /// Decodes a kind byte.
    pub const fn from_byte(kind: u8) -> Result<Self, LinkError> {
        Ok(match kind {
            0x01 => Self::Hello,
            0x02 => Self::HelloAck,
            0x03 => Self::Config,
            0x04 => Self::ConfigAck,
            0x05 => Self::Sensors,
            0x06 => Self::Commands,
            0x07 => Self::Fault,
            0x08 => Self::Stop,
            0x10 => Self::BoardRequest,
            0x11 => Self::BoardReply,
            0x12 => Self::ScopeData,
            _ => return Err(LinkError::UnknownKind { kind }),
        })
    }
}

/// One decoded (or to-be-encoded) frame. Plain data, no allocation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Frame {
    /// What the frame carries.
    pub kind: FrameKind,
    /// Sequence number (wrapping).
    pub seq: u16,
    len: u8,
    payload: [u8; MAX_PAYLOAD],
}

impl Frame {
    /// A frame with the given payload; `BufferTooSmall` if it exceeds [`MAX_PAYLOAD`].
    pub fn new(kind: FrameKind, seq: u16, payload: &[u8]) -> Result<Self, LinkError> {
        let mut frame = Self {
            kind,
            seq,
            len: 0,
            payload: [0; MAX_PAYLOAD],
        };
        let dst = frame
            .payload
            .get_mut(..payload.len())
            .ok_or(LinkError::BufferTooSmall {
                needed: payload.len(),
            })?;
        dst.copy_from_slice(payload);
        // payload.len() <= MAX_PAYLOAD = 192 here, so it fits a u8.
        frame.len = payload.len() as u8;
        Ok(frame)
    }

    /// The payload bytes.
    pub fn payload(&self) -> &[u8] {
        self.payload.get(..usize::from(self.len)).unwrap_or(&[])
    }

    /// Bytes this frame occupies on the wire.
    pub fn wire_len(&self) -> usize {
        HEADER_LEN + usize::from(self.len) + CRC_LEN
    }

    /// Writes the frame into `out`, returning the number of bytes written.
    ///
    /// ```
    /// use pil_link::{Decoder, Frame, FrameKind, MAX_FRAME};
    /// let frame = Frame::new(FrameKind::Sensors, 7, &[1, 2, 3]).unwrap();
    /// let mut wire = [0_u8; MAX_FRAME];
    /// let n = frame.encode(&mut wire).unwrap();
    /// let mut decoder = Decoder::new();
    /// let decoded: Vec<_> = wire[..n].iter().filter_map(|&b| decoder.push(b).transpose()).collect();
    /// assert_eq!(decoded, vec![Ok(frame)]);
    /// ```
    pub fn encode(&self, out: &mut [u8]) -> Result<usize, LinkError> {
        let n = self.wire_len();
        let dst = out
            .get_mut(..n)
            .ok_or(LinkError::BufferTooSmall { needed: n })?;
        let [s0, s1] = SYNC;
        let [q0, q1] = self.seq.to_le_bytes();
        let header = [s0, s1, PROTOCOL_VERSION, self.kind as u8, q0, q1, self.len];
        let body_end = n - CRC_LEN;
        let (body, tail) = dst.split_at_mut(body_end);
        let (head, payload) = body.split_at_mut(HEADER_LEN);
        head.copy_from_slice(&header);
        payload.copy_from_slice(self.payload());
        // The CRC covers everything after the sync pair: version, kind, seq, len, payload.
        let crc = crate::crc32(body.get(SYNC.len()..).unwrap_or(&[]));
        tail.copy_from_slice(&crc.to_le_bytes());
        Ok(n)
    }
}

/// Where the decoder is within a frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum State {
    Sync0,
    Sync1,
    Version,
    Kind,
    SeqLo,
    SeqHi,
    Len,
    Payload,
    Crc,
}

/// Byte-at-a-time frame decoder (no allocation, bounded work per byte), suited to a UART
/// receive loop. After any error it hunts for the next sync pair.
#[derive(Clone, Debug)]
pub struct Decoder {
    state: State,
    version: u8,
    kind: u8,
    seq: u16,
    len: u8,
    index: usize,
    payload: [u8; MAX_PAYLOAD],
    crc_bytes: [u8; CRC_LEN],
    crc: Crc32,
    skipped: u32,
}

impl Default for Decoder {
    fn default() -> Self {
        Self::new()
    }
}

impl Decoder {
    /// A decoder hunting for the first sync pair.
    pub const fn new() -> Self {
        Self {
            state: State::Sync0,
            version: 0,
            kind: 0,
            seq: 0,
            len: 0,
            index: 0,
            payload: [0; MAX_PAYLOAD],
            crc_bytes: [0; CRC_LEN],
            crc: Crc32::new(),
            skipped: 0,
        }
    }

    /// Bytes discarded while hunting for a sync pair (noise between frames).
    pub const fn skipped_bytes(&self) -> u32 {
        self.skipped
    }

    /// True between frames (nothing of a frame has been received).
    pub fn is_idle(&self) -> bool {
        self.state == State::Sync0
    }

    /// Drops a partly received frame and hunts for the next sync pair.
    pub fn reset(&mut self) {
        self.state = State::Sync0;
    }

    /// Feeds one byte. Returns `Ok(Some(frame))` when a frame completes, `Ok(None)` while
    /// one is in progress, `Err` when the frame just completed (or its length byte) is bad.
    pub fn push(&mut self, byte: u8) -> Result<Option<Frame>, LinkError> {
        let [s0, s1] = SYNC;
        match self.state {
            State::Sync0 => {
                if byte == s0 {
                    self.state = State::Sync1;
                } else {
                    self.skipped = self.skipped.wrapping_add(1);
                }
            }
            State::Sync1 => {
                if byte == s1 {
                    self.crc = Crc32::new();
                    self.state = State::Version;
                } else if byte != s0 {
                    // 0xA5 0xA5 0x5A is still a sync pair: stay in Sync1 on a repeated 0xA5.
                    self.skipped = self.skipped.wrapping_add(2);
                    self.state = State::Sync0;
                } else {
                    self.skipped = self.skipped.wrapping_add(1);
                }
            }
            State::Version => {
                self.crc.push(byte);
                self.version = byte;
                self.state = State::Kind;
            }
            State::Kind => {
                self.crc.push(byte);
                self.kind = byte;
                self.state = State::SeqLo;
            }
            State::SeqLo => {
                self.crc.push(byte);
                self.seq = u16::from(byte);
                self.state = State::SeqHi;
            }
            State::SeqHi => {
                self.crc.push(byte);
                self.seq |= u16::from(byte) << 8;
                self.state = State::Len;
            }
            State::Len => {
                self.crc.push(byte);
                if usize::from(byte) > MAX_PAYLOAD {
                    self.state = State::Sync0;
                    return Err(LinkError::BadLength { len: byte });
                }
                self.len = byte;
                self.index = 0;
                self.state = if byte == 0 {
                    State::Crc
                } else {
                    State::Payload
                };
            }
            State::Payload => {
                self.crc.push(byte);
                if let Some(slot) = self.payload.get_mut(self.index) {
                    *slot = byte;
                }
                self.index += 1;
                if self.index >= usize::from(self.len) {
                    self.index = 0;
                    self.state = State::Crc;
                }
            }
            State::Crc => {
                if let Some(slot) = self.crc_bytes.get_mut(self.index) {
                    *slot = byte;
                }
                self.index += 1;
                if self.index >= CRC_LEN {
                    self.state = State::Sync0;
                    return self.finish().map(Some);
                }
            }
        }
        Ok(None)
    }

    /// Checks a complete frame: CRC first (so line noise reads as `BadCrc`), then version
    /// and kind of an intact frame.
    fn finish(&self) -> Result<Frame, LinkError> {
        let received = u32::from_le_bytes(self.crc_bytes);
        let computed = self.crc.value();
        if received != computed {
            return Err(LinkError::BadCrc { computed, received });
        }
        if self.version != PROTOCOL_VERSION {
            return Err(LinkError::BadVersion {
                received: self.version,
            });
        }
        let kind = FrameKind::from_byte(self.kind)?;
        let payload = self
            .payload
            .get(..usize::from(self.len))
            .ok_or(LinkError::BadLength { len: self.len })?;
        Frame::new(kind, self.seq, payload)
    }
}

/// Checks that frames arrive with consecutive (wrapping) sequence numbers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SequenceCheck {
    expected: u16,
}

impl SequenceCheck {
    /// Expects `first` next.
    pub const fn new(first: u16) -> Self {
        Self { expected: first }
    }

    /// The sequence number expected next.
    pub const fn expected(&self) -> u16 {
        self.expected
    }

    /// Accepts `seq` if it is the expected one and advances; otherwise `OutOfSequence`
    /// (and stays, so the caller can latch the fault with both numbers).
    pub fn accept(&mut self, seq: u16) -> Result<(), LinkError> {
        if seq != self.expected {
            return Err(LinkError::OutOfSequence {
                expected: self.expected,
                received: seq,
            });
        }
        self.expected = self.expected.wrapping_add(1);
        Ok(())
    }
}
