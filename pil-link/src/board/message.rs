//! Board console payloads. A request is `BOARD_VERSION u8 | op u8 | arguments`; its reply
//! (same sequence number) is `BOARD_VERSION u8 | op u8 | status u8 | body`, status 0 for
//! done (the body as below) or a [`Refusal`] code (the body the firmware's message, UTF-8).
//!
//! | op            | request arguments        | body when done                              |
//! |---------------|--------------------------|---------------------------------------------|
//! | `Status`      |                          | [`StatusReport`]                            |
//! | `Get`         | key (text)               | value f64                                   |
//! | `Set`         | value f64, key (text)    | value f64 as stored                         |
//! | `Save`        |                          |                                             |
//! | `Reset`       |                          | (then the board resets)                     |
//! | `Faults`      |                          | [`FaultHistory`](super::faults::FaultHistory) |
//! | `Enable`      |                          |                                             |
//! | `Disable`     |                          |                                             |
//! | `ScopeStart`  |                          | [`ScopeInfo`](super::scope::ScopeInfo); then `ScopeData` frames      |
//! | `ScopeStop`   |                          |                                             |
//! | `Identify`    | [`IdentifyRun`]          | [`ScopeInfo`](super::scope::ScopeInfo); then the record in `ScopeData` frames |
//! | `Calibrate`   | [`CalibrationSettings`] ([`super::calibrate::encode`]) | [`ScopeInfo`](super::scope::ScopeInfo); then the record in `ScopeData` frames |
//!
//! A `ScopeData` frame is a [`ScopeChunk`](super::scope::ScopeChunk). Values travel as raw bits (`f64::to_bits`).

use super::BOARD_VERSION;
use super::identify::IdentifyRun;
use crate::wire::{Reader, Writer};
use crate::{FrameKind, LinkError};
use controller_core::foc::calibration::CalibrationSettings;

/// What a request asks for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum Op {
    /// Firmware version, drive, enabled, latched fault.
    Status = 1,
    /// Read one setting.
    Get = 2,
    /// Write one setting (drive disabled only).
    Set = 3,
    /// Store the running settings in the board's settings sector.
    Save = 4,
    /// System reset after the answer.
    Reset = 5,
    /// The fault history.
    Faults = 6,
    /// Power stage on (no latched fault).
    Enable = 7,
    /// Power stage off.
    Disable = 8,
    /// Start streaming scope samples.
    ScopeStart = 9,
    /// Stop streaming scope samples.
    ScopeStop = 10,
    /// Run a measurement and stream its record ([`super::identify`]).
    Identify = 11,
    /// Run a PMSM's motor calibration and stream its record ([`super::calibrate`]).
    Calibrate = 12,
}

impl Op {
    /// Decodes an op byte.
    #[must_use]
    pub const fn from_byte(b: u8) -> Option<Self> {
        Some(match b {
            1 => Self::Status,
            2 => Self::Get,
            3 => Self::Set,
            4 => Self::Save,
            5 => Self::Reset,
            6 => Self::Faults,
            7 => Self::Enable,
            8 => Self::Disable,
            9 => Self::ScopeStart,
            10 => Self::ScopeStop,
            11 => Self::Identify,
            12 => Self::Calibrate,
            _ => return None,
        })
    }
}

/// A console request.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Request<'a> {
    /// See [`Op::Status`].
    Status,
    /// See [`Op::Get`]: the key, `drive.<key>`.
    Get(&'a str),
    /// See [`Op::Set`]: the key and its new value.
    Set(&'a str, f64),
    /// See [`Op::Save`].
    Save,
    /// See [`Op::Reset`].
    Reset,
    /// See [`Op::Faults`].
    Faults,
    /// See [`Op::Enable`].
    Enable,
    /// See [`Op::Disable`].
    Disable,
    /// See [`Op::ScopeStart`].
    ScopeStart,
    /// See [`Op::ScopeStop`].
    ScopeStop,
    /// See [`Op::Identify`].
    Identify(IdentifyRun),
    /// See [`Op::Calibrate`].
    Calibrate(CalibrationSettings),
}

/// Why a request was refused (the reply's status byte).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum Refusal {
    /// The request speaks another board protocol version.
    Version = 1,
    /// The payload does not parse (unknown op, bad key text, wrong length).
    Malformed = 2,
    /// No setting has this key.
    UnknownKey = 3,
    /// The setting is not part of this drive (e.g. a notch key without a notch).
    NotPresent = 4,
    /// Settings cannot change while the drive is enabled.
    Enabled = 5,
    /// The value is out of its range, or the settings it gives fail validation.
    Invalid = 6,
    /// A fault is latched (enable refused).
    Faulted = 7,
    /// The settings sector could not be written.
    Storage = 8,
    /// A PMSM drive without its motor calibration (enable or a measurement refused).
    Uncalibrated = 9,
}

impl Refusal {
    /// Decodes a status byte (`None` for 0, done, or an unknown code).
    #[must_use]
    pub const fn from_byte(b: u8) -> Option<Self> {
        Some(match b {
            1 => Self::Version,
            2 => Self::Malformed,
            3 => Self::UnknownKey,
            4 => Self::NotPresent,
            5 => Self::Enabled,
            6 => Self::Invalid,
            7 => Self::Faulted,
            8 => Self::Storage,
            9 => Self::Uncalibrated,
            _ => return None,
        })
    }
}

impl<'a> Request<'a> {
    /// The request's op.
    #[must_use]
    pub const fn op(&self) -> Op {
        match self {
            Self::Status => Op::Status,
            Self::Get(_) => Op::Get,
            Self::Set(..) => Op::Set,
            Self::Save => Op::Save,
            Self::Reset => Op::Reset,
            Self::Faults => Op::Faults,
            Self::Enable => Op::Enable,
            Self::Disable => Op::Disable,
            Self::ScopeStart => Op::ScopeStart,
            Self::ScopeStop => Op::ScopeStop,
            Self::Identify(_) => Op::Identify,
            Self::Calibrate(_) => Op::Calibrate,
        }
    }

    /// Writes the request payload.
    ///
    /// # Errors
    /// `BufferTooSmall` for a key longer than a payload.
    pub fn encode(&self, w: &mut Writer) -> Result<(), LinkError> {
        w.u8(BOARD_VERSION)?.u8(self.op() as u8)?;
        match *self {
            Self::Get(key) => {
                w.bytes(key.as_bytes())?;
            }
            Self::Set(key, value) => {
                w.bytes(&value.to_bits().to_le_bytes())?
                    .bytes(key.as_bytes())?;
            }
            Self::Identify(run) => run.encode(w)?,
            Self::Calibrate(settings) => super::calibrate::encode(&settings, w)?,
            _ => {}
        }
        Ok(())
    }

    /// Parses a request payload. The op is returned with the refusal when it is known, so
    /// the reply can name it.
    ///
    /// # Errors
    /// [`Refusal::Version`] or [`Refusal::Malformed`].
    pub fn decode(payload: &'a [u8]) -> Result<Self, (Option<Op>, Refusal)> {
        let mut r = Reader::new(FrameKind::BoardRequest, payload);
        let version = r.u8().map_err(|_| (None, Refusal::Malformed))?;
        let op = r.u8().ok().and_then(Op::from_byte);
        if version != BOARD_VERSION {
            return Err((op, Refusal::Version));
        }
        let op = op.ok_or((None, Refusal::Malformed))?;
        let bad = (Some(op), Refusal::Malformed);
        let request = match op {
            Op::Get => Self::Get(key_text(r.rest()).ok_or(bad)?),
            Op::Set => {
                let value = f64::from_bits(
                    r.u32()
                        .and_then(|lo| r.u32().map(|hi| u64::from(lo) | u64::from(hi) << 32))
                        .map_err(|_| bad)?,
                );
                Self::Set(key_text(r.rest()).ok_or(bad)?, value)
            }
            Op::Status => Self::Status,
            Op::Save => Self::Save,
            Op::Reset => Self::Reset,
            Op::Faults => Self::Faults,
            Op::Enable => Self::Enable,
            Op::Disable => Self::Disable,
            Op::ScopeStart => Self::ScopeStart,
            Op::ScopeStop => Self::ScopeStop,
            Op::Identify => Self::Identify(IdentifyRun::decode(&mut r).map_err(|_| bad)?),
            Op::Calibrate => Self::Calibrate(super::calibrate::decode(&mut r).map_err(|_| bad)?),
        };
        r.finish().map_err(|_| bad)?;
        Ok(request)
    }
}

/// A key as text: UTF-8, not empty.
fn key_text(bytes: &[u8]) -> Option<&str> {
    core::str::from_utf8(bytes).ok().filter(|k| !k.is_empty())
}

/// Starts a reply payload: version, op, status (0 = done, else the refusal).
///
/// # Errors
/// Never for a fresh writer.
pub fn reply_head(
    w: &mut Writer,
    op: Option<Op>,
    refusal: Option<Refusal>,
) -> Result<(), LinkError> {
    w.u8(BOARD_VERSION)?
        .u8(op.map_or(0, |o| o as u8))?
        .u8(refusal.map_or(0, |r| r as u8))?;
    Ok(())
}

/// A parsed reply: its op, and the body when done or the refusal with its message.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Reply<'a> {
    /// The op answered (0 when the request was too malformed to have one).
    pub op: u8,
    /// `Ok(body)` when done, `Err((refusal, message))` when refused.
    pub result: Result<&'a [u8], (Refusal, &'a str)>,
}

impl<'a> Reply<'a> {
    /// Parses a reply payload.
    ///
    /// # Errors
    /// `BadPayload` for a payload too short or with an unknown status, `BadVersion` for
    /// another board protocol version.
    pub fn decode(payload: &'a [u8]) -> Result<Self, LinkError> {
        let mut r = Reader::new(FrameKind::BoardReply, payload);
        let version = r.u8()?;
        if version != BOARD_VERSION {
            return Err(LinkError::BadVersion { received: version });
        }
        let op = r.u8()?;
        let status = r.u8()?;
        let rest = r.rest();
        let result = match status {
            0 => Ok(rest),
            code => {
                let refusal = Refusal::from_byte(code).ok_or(LinkError::BadPayload {
                    kind: FrameKind::BoardReply as u8,
                    len: u8::try_from(payload.len()).unwrap_or(u8::MAX),
                })?;
                Err((refusal, core::str::from_utf8(rest).unwrap_or("")))
            }
        };
        Ok(Self { op, result })
    }
}

/// What `Status` answers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StatusReport<'a> {
    /// `major << 16 | minor << 8 | patch` of the firmware.
    pub firmware_version: u32,
    /// Power stage enabled.
    pub enabled: bool,
    /// Latched fault (controller-core's fault code; 0 none).
    pub fault_code: u8,
    /// CRC-32 of the running settings (pil-link's settings encoding), as the boot log names
    /// a drive.
    pub settings_crc: u32,
    /// Where the running settings come from.
    pub origin: Origin,
    /// The baked drive as the boot log names it (its machine file and settings CRC).
    pub baked_name: &'a str,
}

/// Where the running settings come from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum Origin {
    /// Baked into the image at build time.
    Baked = 0,
    /// Read from the settings sector at boot.
    Saved = 1,
    /// Changed by `Set` since boot (not saved yet).
    Changed = 2,
}

impl Origin {
    /// How a status line says it.
    #[must_use]
    pub const fn describe(self) -> &'static str {
        match self {
            Self::Baked => "the baked drive",
            Self::Saved => "saved on the board",
            Self::Changed => "changed since boot, not saved",
        }
    }
}

impl<'a> StatusReport<'a> {
    /// Writes the body.
    ///
    /// # Errors
    /// `BufferTooSmall` if the name does not fit.
    pub fn encode(&self, w: &mut Writer) -> Result<(), LinkError> {
        w.u32(self.firmware_version)?
            .u8(u8::from(self.enabled))?
            .u8(self.fault_code)?
            .u32(self.settings_crc)?
            .u8(self.origin as u8)?
            .bytes(self.baked_name.as_bytes())?;
        Ok(())
    }

    /// Parses the body.
    ///
    /// # Errors
    /// `BadPayload` when it does not parse.
    pub fn decode(body: &'a [u8]) -> Result<Self, LinkError> {
        let mut r = Reader::new(FrameKind::BoardReply, body);
        let bad = LinkError::BadPayload {
            kind: FrameKind::BoardReply as u8,
            len: u8::try_from(body.len()).unwrap_or(u8::MAX),
        };
        Ok(Self {
            firmware_version: r.u32()?,
            enabled: r.u8()? != 0,
            fault_code: r.u8()?,
            settings_crc: r.u32()?,
            origin: match r.u8()? {
                0 => Origin::Baked,
                1 => Origin::Saved,
                2 => Origin::Changed,
                _ => return Err(bad),
            },
            baked_name: core::str::from_utf8(r.rest()).map_err(|_| bad)?,
        })
    }
}

/// Writes an f64 as its bits.
///
/// # Errors
/// `BufferTooSmall`.
pub fn put_f64(w: &mut Writer, v: f64) -> Result<(), LinkError> {
    w.bytes(&v.to_bits().to_le_bytes())?;
    Ok(())
}

/// Reads an f64 body.
///
/// # Errors
/// `BadPayload` when the body is not 8 bytes.
pub fn get_f64(body: &[u8]) -> Result<f64, LinkError> {
    let mut r = Reader::new(FrameKind::BoardReply, body);
    let lo = r.u32()?;
    let hi = r.u32()?;
    r.finish()?;
    Ok(f64::from_bits(u64::from(lo) | u64::from(hi) << 32))
}
