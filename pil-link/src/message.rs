//! Typed payloads of the session frames (everything except the per-tick sensor and command
//! payloads, whose layout belongs to the controller and lives in [`crate::tick`]).

use crate::wire::{Reader, Writer};
use crate::{FrameKind, LinkError};

/// The link watchdogs the firmware accepts, in ms: a `Hello` outside this range is refused
/// with a `Protocol` fault, so no host can switch the watchdog off by asking for years.
pub const WATCHDOG_MS_RANGE: core::ops::RangeInclusive<u32> = 1..=1000;

/// H→F `Hello`: opens a session.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Hello {
    /// The firmware latches a `Timeout` fault when no complete frame arrives for this long
    /// once the session is open (ms of the target's SysTick time), within
    /// [`WATCHDOG_MS_RANGE`].
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
                });
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
            LinkError::UnsupportedMotor => Self::Config,
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

/// What the safe-state entry wrote, read back from the board layer's outputs (the values
/// that reach the PWM and the enable pin), not from the controller's intentions.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SafeOutputs {
    /// Whether the current-loop interrupt ran after the fault latched. If it did not, the
    /// other fields are what the outputs held before, and the safe state is not shown.
    pub current_tick_ran: bool,
    /// Torque (current) reference of that tick, raw Q16.16 bits (0 in the safe state;
    /// `i32::MIN`, never safe, when the tick did not run).
    pub torque_cmd_bits: i32,
    /// Voltage written to the PWM, raw Q16.16 bits (0, i.e. 50 % duty, in the safe state).
    pub pwm_voltage_bits: i32,
    /// Level written to the power stage's enable pin (low in the safe state).
    pub enable_pin: bool,
}

impl SafeOutputs {
    /// Whether these outputs are the safe state: the power stage off (enable pin low, zero
    /// PWM voltage) and, if the controller ran after the fault, zero torque from it. (Before
    /// any configuration no controller runs, and the stage off is the whole safe state.)
    pub const fn are_safe(&self) -> bool {
        !self.enable_pin
            && self.pwm_voltage_bits == 0
            && (!self.current_tick_ran || self.torque_cmd_bits == 0)
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
    /// The outputs after the safe-state entry, as the board layer wrote them.
    pub outputs: SafeOutputs,
}

impl FaultReport {
    /// Payload bytes.
    pub fn encode(&self, w: &mut Writer) -> Result<(), LinkError> {
        let o = &self.outputs;
        w.u8(self.code as u8)?
            .u16(self.expected_seq)?
            .u32(self.ticks_done)?
            .u8(u8::from(o.current_tick_ran))?
            .i32(o.torque_cmd_bits)?
            .i32(o.pwm_voltage_bits)?
            .u8(u8::from(o.enable_pin))
            .map(|_| ())
    }

    /// Parses a `Fault` payload.
    pub fn decode(payload: &[u8]) -> Result<Self, LinkError> {
        let len = u8::try_from(payload.len()).unwrap_or(u8::MAX);
        let mut r = Reader::new(FrameKind::Fault, payload);
        let code = FaultCode::from_byte(r.u8()?, len)?;
        let flag = |b: u8| match b {
            0 => Ok(false),
            1 => Ok(true),
            _ => Err(LinkError::BadPayload {
                kind: FrameKind::Fault as u8,
                len,
            }),
        };
        let expected_seq = r.u16()?;
        let ticks_done = r.u32()?;
        let outputs = SafeOutputs {
            current_tick_ran: flag(r.u8()?)?,
            torque_cmd_bits: r.i32()?,
            pwm_voltage_bits: r.i32()?,
            enable_pin: flag(r.u8()?)?,
        };
        let out = Self {
            code,
            expected_seq,
            ticks_done,
            outputs,
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
            outputs: SafeOutputs {
                current_tick_ran: true,
                torque_cmd_bits: -3,
                pwm_voltage_bits: 7,
                enable_pin: true,
            },
        };
        assert!(!f.outputs.are_safe(), "torque, voltage and enable are on");
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
        // An enable byte other than 0 or 1 is a bad payload, not "on".
        let mut bad_flag = w.as_slice().to_vec();
        *bad_flag.last_mut().unwrap() = 2;
        assert!(FaultReport::decode(&bad_flag).is_err());
    }

    #[test]
    fn only_the_stage_off_and_zero_torque_from_a_tick_that_ran_are_safe() {
        let safe = SafeOutputs {
            current_tick_ran: true,
            ..SafeOutputs::default()
        };
        assert!(safe.are_safe());
        let not_run = SafeOutputs {
            torque_cmd_bits: i32::MIN,
            ..SafeOutputs::default()
        };
        assert!(not_run.are_safe(), "no controller ran, the stage is off");
        for unsafe_one in [
            SafeOutputs {
                enable_pin: true,
                ..not_run
            },
            SafeOutputs {
                pwm_voltage_bits: 5,
                ..not_run
            },
            SafeOutputs {
                torque_cmd_bits: 1,
                ..safe
            },
            SafeOutputs {
                pwm_voltage_bits: -1,
                ..safe
            },
            SafeOutputs {
                enable_pin: true,
                ..safe
            },
        ] {
            assert!(!unsafe_one.are_safe(), "{unsafe_one:?}");
        }
    }

    #[test]
    fn hello_rejects_trailing_bytes() {
        assert_eq!(Hello::decode(&[1, 0, 0, 0]), Ok(Hello { watchdog_ms: 1 }));
        assert!(Hello::decode(&[1, 0, 0, 0, 9]).is_err());
    }
}
