//! Typed payloads of the session frames (everything except the per-tick sensor and command
//! payloads, whose layout belongs to the controller and lives in [`crate::tick`]).

use crate::wire::{Reader, Writer};
use crate::{FrameKind, LinkError};

/// H→F `Hello`: opens a session.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Hello {
    /// The firmware latches a `Timeout` fault when no complete frame arrives for this long
    /// once the session is open (ms of the target's SysTick time).
    pub watchdog_ms: u32,
}

impl Hello {
    /// Payload bytes.
    pub fn encode(&self, w: &mut Writer) -> Result<(), LinkError> {
        w.u32(self.watchdog_ms).map(|_| ())
    }

    /// Parses a `Hello` payload.
    pub fn decode(payload: &[u8]) -> Result<Self, LinkError> {
        let mut r = Reader::new(FrameKind::Hello, payload);
        let watchdog_ms = r.u32()?;
        r.finish()?;
        Ok(Self { watchdog_ms })
    }
}

/// F→H `HelloAck`: the firmware's identity.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HelloAck {
    /// Protocol version the firmware speaks (equal to the harness's, or it would not parse).
    pub protocol_version: u8,
    /// Firmware crate version, packed `major << 16 | minor << 8 | patch`.
    pub firmware_version: u32,
    /// Watchdog the firmware armed (ms); echoes `Hello::watchdog_ms`.
    pub watchdog_ms: u32,
}

impl HelloAck {
    /// Payload bytes.
    pub fn encode(&self, w: &mut Writer) -> Result<(), LinkError> {
        w.u8(self.protocol_version)?
            .u32(self.firmware_version)?
            .u32(self.watchdog_ms)
            .map(|_| ())
    }

    /// Parses a `HelloAck` payload.
    pub fn decode(payload: &[u8]) -> Result<Self, LinkError> {
        let mut r = Reader::new(FrameKind::HelloAck, payload);
        let out = Self {
            protocol_version: r.u8()?,
            firmware_version: r.u32()?,
            watchdog_ms: r.u32()?,
        };
        r.finish()?;
        Ok(out)
    }
}

/// Why the firmware latched its safe state. Wire values are stable across versions.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum FaultCode {
    /// A frame failed its CRC.
    BadCrc = 1,
    /// A frame of another protocol version arrived.
    BadVersion = 2,
    /// A length byte exceeded the maximum payload.
    BadLength = 3,
    /// An intact frame of unknown kind arrived.
    UnknownKind = 4,
    /// A sequence gap, repeat or reorder (a lost frame).
    OutOfSequence = 5,
    /// No frame within the watchdog period (a lost or late frame, or a dead harness).
    Timeout = 6,
    /// A payload did not fit its frame kind.
    BadPayload = 7,
    /// A frame arrived that the session state does not allow (e.g. sensors before config).
    Protocol = 8,
    /// The controller refused its configuration.
    Config = 9,
}

impl FaultCode {
    /// Decodes a wire byte; unknown codes are a `BadPayload` of a `Fault` frame.
    pub fn from_byte(b: u8, len: u8) -> Result<Self, LinkError> {
        Ok(match b {
            1 => Self::BadCrc,
            2 => Self::BadVersion,
            3 => Self::BadLength,
            4 => Self::UnknownKind,
            5 => Self::OutOfSequence,
            6 => Self::Timeout,
            7 => Self::BadPayload,
            8 => Self::Protocol,
            9 => Self::Config,
            _ => {
                return Err(LinkError::BadPayload {
                    kind: FrameKind::Fault as u8,
                    len,
                })
            }
        })
    }

    /// The fault a link error latches.
    pub const fn from_link_error(e: LinkError) -> Self {
        match e {
            LinkError::BadCrc { .. } => Self::BadCrc,
            LinkError::BadVersion { .. } => Self::BadVersion,
            LinkError::BadLength { .. } => Self::BadLength,
            LinkError::UnknownKind { .. } => Self::UnknownKind,
            LinkError::OutOfSequence { .. } => Self::OutOfSequence,
            LinkError::Timeout { .. } => Self::Timeout,
            LinkError::BadPayload { .. } | LinkError::BufferTooSmall { .. } => Self::BadPayload,
        }
    }

    /// Short name for logs and summaries.
    pub const fn name(self) -> &'static str {
        match self {
            Self::BadCrc => "BadCrc",
            Self::BadVersion => "BadVersion",
            Self::BadLength => "BadLength",
            Self::UnknownKind => "UnknownKind",
            Self::OutOfSequence => "OutOfSequence",
            Self::Timeout => "Timeout",
            Self::BadPayload => "BadPayload",
            Self::Protocol => "Protocol",
            Self::Config => "Config",
        }
    }
}

/// F→H `Fault`: the firmware is latched in its safe state. It sends one when it detects the
/// fault and answers every later frame with the same report.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FaultReport {
    /// Why the fault latched.
    pub code: FaultCode,
    /// Sequence number the firmware expected next when it latched.
    pub expected_seq: u16,
    /// Number of sensor frames the firmware answered before the fault.
    pub ticks_done: u32,
    /// Torque (current) reference the firmware now commands, raw bits of the controller's
    /// fixed-point type (0 in the safe state).
    pub torque_cmd_bits: i32,
    /// Voltage the firmware now commands, raw bits (0 in the safe state).
    pub voltage_cmd_bits: i32,
}

impl FaultReport {
    /// Payload bytes.
    pub fn encode(&self, w: &mut Writer) -> Result<(), LinkError> {
        w.u8(self.code as u8)?
            .u16(self.expected_seq)?
            .u32(self.ticks_done)?
            .i32(self.torque_cmd_bits)?
            .i32(self.voltage_cmd_bits)
            .map(|_| ())
    }

    /// Parses a `Fault` payload.
    pub fn decode(payload: &[u8]) -> Result<Self, LinkError> {
        let len = u8::try_from(payload.len()).unwrap_or(u8::MAX);
        let mut r = Reader::new(FrameKind::Fault, payload);
        let code = FaultCode::from_byte(r.u8()?, len)?;
        let out = Self {
            code,
            expected_seq: r.u16()?,
            ticks_done: r.u32()?,
            torque_cmd_bits: r.i32()?,
            voltage_cmd_bits: r.i32()?,
        };
        r.finish()?;
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn fault_report_round_trip_and_bad_code() {
        let f = FaultReport {
            code: FaultCode::OutOfSequence,
            expected_seq: 41,
            ticks_done: 40,
            torque_cmd_bits: 0,
            voltage_cmd_bits: 0,
        };
        let mut w = Writer::new();
        f.encode(&mut w).unwrap();
        assert_eq!(FaultReport::decode(w.as_slice()), Ok(f));
        let mut bad = w.as_slice().to_vec();
        bad[0] = 200;
        assert!(matches!(
            FaultReport::decode(&bad),
            Err(LinkError::BadPayload { .. })
        ));
        assert!(FaultReport::decode(&w.as_slice()[..5]).is_err());
    }

    #[test]
    fn hello_rejects_trailing_bytes() {
        assert_eq!(Hello::decode(&[1, 0, 0, 0]), Ok(Hello { watchdog_ms: 1 }));
        assert!(Hello::decode(&[1, 0, 0, 0, 9]).is_err());
    }
}
