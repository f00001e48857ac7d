//! The firmware side of the board console as a plain state machine: bytes in, reply frames
//! out, the drive behind the [`Drive`] trait. No UART, no interrupts, no panics: the same
//! code runs in the board image and in host tests (and the fuzz test).
//!
//! The session owns the running settings. `Set` changes one key on a copy, checks it
//! against its range ([`super::keys`]) and the whole copy with controller-core's `design`
//! (the validation and the gains the controller is then built with), and only then hands
//! it to the drive; anything refused leaves the settings and the drive as they were. `Set`
//! is refused while the drive is enabled.
//!
//! A PMSM drive without its motor calibration (`[drive.pmsm]` with no
//! `encoder_offset_elec_deg`) refuses `Enable` and `Identify` ([`ConsoleError::Uncalibrated`],
//! naming the command that measures it); `Calibrate` ([`super::calibrate`]) runs on it.
//!
//! Safe state: a frame that fails its checks (CRC, length, version, kind) while the drive
//! is enabled turns the drive off ([`Drive::enter_safe_state`]): the console that drives it
//! is no longer trusted. A corrupt frame never changes a setting, enabled or not.

use super::calibrate::{self, CalibrateError};
use super::faults::FaultHistory;
use super::identify::{IdentifyError, IdentifyRun};
use super::keys::{self, KeyError};
use super::message::{Origin, Refusal, Request, StatusReport, put_f64, reply_head};
use super::scope::ScopeInfo;
use super::store::{self, RECORD_LEN, SaveError};
use crate::wire::Writer;
use crate::{Decoder, Frame, FrameKind, crc32, settings};
use controller_core::foc::calibration::Calibration;
use controller_core::{ConfigError, DriveConfig};
use core::fmt::Write as _;

/// The drive behind the console.
pub trait Drive {
    /// Rebuilds the controller for `cfg` (only called while disabled, with settings
    /// `design` accepted).
    ///
    /// # Errors
    /// What the board refuses of `cfg` (e.g. a counter width its encoder lacks).
    fn apply(&mut self, cfg: &DriveConfig) -> Result<(), ConfigError>;
    /// Whether the power stage is enabled.
    fn enabled(&self) -> bool;
    /// Switches the power stage on or off.
    fn set_enabled(&mut self, on: bool);
    /// The latched fault's code (controller-core's `fault_code`; 0 none).
    fn fault_code(&self) -> u8;
    /// Writes a settings record to the settings sector and reads it back.
    ///
    /// # Errors
    /// Why the sector does not hold the record.
    fn save(&mut self, record: &[u8; RECORD_LEN]) -> Result<(), SaveError>;
    /// The fault history.
    fn fault_history(&self) -> FaultHistory;
    /// Starts or stops the scope stream; returns its rate and channels.
    fn scope(&mut self, on: bool) -> ScopeInfo<'_>;
    /// Power stage off after a link fault, recorded in the fault history.
    fn enter_safe_state(&mut self);
    /// Starts the measurement `run` on the settings `cfg` (the running settings changed
    /// as [`IdentifyRun::drive_config`] says, `design` passed; only called while disabled
    /// and without a latched fault), the power stage on for its ticks; back to `running`
    /// after them. Returns the record's rate and channels.
    ///
    /// # Errors
    /// What the board cannot run (too long, no measurements on this board, the
    /// excitation refused).
    fn identify(
        &mut self,
        cfg: &DriveConfig,
        running: &DriveConfig,
        run: &IdentifyRun,
    ) -> Result<ScopeInfo<'_>, IdentifyError> {
        let _ = (cfg, running, run);
        Err(IdentifyError::Unsupported)
    }
    /// Starts the motor calibration `seq` on the PMSM drive `cfg` (the running settings;
    /// only called while disabled and without a latched fault), the power stage on for its
    /// ticks. Returns the record's rate and channels
    /// ([`super::calibrate::CHANNELS`]).
    ///
    /// # Errors
    /// What the board cannot run (no calibration on this board, the drive's modulator
    /// refused).
    fn calibrate(
        &mut self,
        cfg: &DriveConfig,
        seq: &Calibration,
    ) -> Result<ScopeInfo<'_>, CalibrateError> {
        let _ = (cfg, seq);
        Err(CalibrateError::Unsupported)
    }
}

/// The command that calibrates a PMSM drive on the board, as the refusals name it.
pub const CALIBRATE_COMMAND: &str = "stiffdrive identify --board --config FILE";

/// The firmware's console session.
#[derive(Clone, Debug)]
pub struct BoardSession {
    decoder: Decoder,
    cfg: DriveConfig,
    origin: Origin,
    firmware_version: u32,
    baked_name: &'static str,
    reset_requested: bool,
    link_errors: u32,
}

/// Why a request was refused, typed; its message (the reply's body) names the key.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ConsoleError<'a> {
    /// Another board protocol version.
    Version,
    /// A payload that does not parse.
    Malformed,
    /// No setting has this key.
    UnknownKey(&'a str),
    /// The key's setting is not part of this drive.
    NotPresent(&'static str),
    /// `Set` of this key while the drive is enabled.
    Enabled(&'static str),
    /// The value is outside the key's own range (the error names the key and the range).
    OutOfRange(ConfigError),
    /// The settings with the value fail validation (`error` names the key and its range).
    Invalid {
        /// The key set.
        key: &'static str,
        /// The value refused.
        value: f64,
        /// What `design` or the drive said.
        error: ConfigError,
    },
    /// Enable with a latched fault (its code).
    Faulted(u8),
    /// The settings sector failed.
    Storage(SaveError),
    /// `Identify` while the drive is enabled.
    RunWhileEnabled,
    /// `Identify` refused by the settings or the board.
    Identify(IdentifyError),
    /// `Calibrate` refused.
    Calibrate(CalibrateError),
    /// `Enable` or `Identify` of a PMSM drive without its motor calibration.
    Uncalibrated,
}

impl ConsoleError<'_> {
    /// The reply's status code.
    #[must_use]
    pub const fn refusal(&self) -> Refusal {
        match self {
            Self::Version => Refusal::Version,
            Self::Malformed => Refusal::Malformed,
            Self::UnknownKey(_) => Refusal::UnknownKey,
            Self::NotPresent(_) => Refusal::NotPresent,
            Self::Enabled(_) => Refusal::Enabled,
            Self::OutOfRange(_) | Self::Invalid { .. } => Refusal::Invalid,
            Self::Faulted(_) => Refusal::Faulted,
            Self::Storage(_) => Refusal::Storage,
            Self::RunWhileEnabled => Refusal::Enabled,
            Self::Identify(_) => Refusal::Invalid,
            Self::Calibrate(CalibrateError::Enabled) => Refusal::Enabled,
            Self::Calibrate(_) => Refusal::Invalid,
            Self::Uncalibrated => Refusal::Uncalibrated,
        }
    }
}

impl core::fmt::Display for ConsoleError<'_> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let p = keys::PREFIX;
        match *self {
            Self::Version => write!(
                f,
                "request of another board protocol version; this firmware speaks {}",
                super::BOARD_VERSION
            ),
            Self::Malformed => write!(f, "malformed request"),
            Self::UnknownKey(key) => write!(
                f,
                "{key}: no such setting (the keys are the machine file's [drive] keys)"
            ),
            Self::NotPresent(key) => write!(f, "{p}{key}: not part of this drive"),
            Self::Enabled(key) => write!(
                f,
                "{p}{key}: refused while the drive is enabled (disable it first); drive unchanged"
            ),
            Self::OutOfRange(e) => write!(f, "{p}{e}; drive unchanged"),
            Self::Invalid { key, value, error } => {
                write!(f, "{p}{key} = {value} refused, drive unchanged: {p}{error}")
            }
            Self::Faulted(code) => write!(
                f,
                "fault latched ({}): reset the board to clear it",
                fault_name(code)
            ),
            Self::Storage(e) => write!(f, "save failed: {e}"),
            Self::RunWhileEnabled => write!(
                f,
                "identify: refused while the drive is enabled (disable it first; the \
                 measurement is its own enable)"
            ),
            Self::Identify(e) => write!(f, "{e}"),
            Self::Calibrate(e) => write!(f, "{e}"),
            Self::Uncalibrated => write!(
                f,
                "{p}pmsm.encoder_offset_elec_deg is not set: the PMSM drive runs only once \
                 its motor is calibrated; run `{CALIBRATE_COMMAND}` or `stiffdrive board \
                 ... calibrate` (both save it on the board)"
            ),
        }
    }
}

impl BoardSession {
    /// A session over the running settings `cfg` (from `origin`); `firmware_version` packed
    /// `major << 16 | minor << 8 | patch`, `baked_name` as the boot log names the baked drive.
    #[must_use]
    pub const fn new(
        cfg: DriveConfig,
        origin: Origin,
        firmware_version: u32,
        baked_name: &'static str,
    ) -> Self {
        Self {
            decoder: Decoder::new(),
            cfg,
            origin,
            firmware_version,
            baked_name,
            reset_requested: false,
            link_errors: 0,
        }
    }

    /// The running settings.
    #[must_use]
    pub const fn settings(&self) -> &DriveConfig {
        &self.cfg
    }

    /// Where the running settings come from.
    #[must_use]
    pub const fn origin(&self) -> Origin {
        self.origin
    }

    /// A `Reset` was answered: the firmware resets once the reply is out.
    #[must_use]
    pub const fn reset_requested(&self) -> bool {
        self.reset_requested
    }

    /// Frames that failed their checks so far.
    #[must_use]
    pub const fn link_errors(&self) -> u32 {
        self.link_errors
    }

    /// Feeds one received byte; returns the reply to send, if one is due.
    pub fn on_byte<D: Drive>(&mut self, byte: u8, drive: &mut D) -> Option<Frame> {
        match self.decoder.push(byte) {
            Ok(None) => None,
            Ok(Some(frame)) if frame.kind == FrameKind::BoardRequest => {
                self.on_request(&frame, drive)
            }
            // Frames of the PIL protocol, or of the firmware's own direction: not for us.
            Ok(Some(_)) => None,
            Err(_) => {
                self.link_errors = self.link_errors.wrapping_add(1);
                if drive.enabled() {
                    drive.enter_safe_state();
                }
                None
            }
        }
    }

    fn on_request<D: Drive>(&mut self, frame: &Frame, drive: &mut D) -> Option<Frame> {
        let mut body = Writer::new();
        let (op, outcome) = match Request::decode(frame.payload()) {
            Ok(request) => (Some(request.op()), self.serve(request, drive, &mut body)),
            Err((op, Refusal::Version)) => (op, Err(ConsoleError::Version)),
            Err((op, _)) => (op, Err(ConsoleError::Malformed)),
        };
        let mut w = Writer::new();
        match outcome {
            Ok(()) => {
                reply_head(&mut w, op, None).ok()?;
                w.bytes(body.as_slice()).ok()?;
            }
            Err(e) => {
                reply_head(&mut w, op, Some(e.refusal())).ok()?;
                // A message too long for the payload is cut; the code still says what it is.
                let _ = write!(w, "{e}");
            }
        }
        Frame::new(FrameKind::BoardReply, frame.seq, w.as_slice()).ok()
    }

    fn serve<'r, D: Drive>(
        &mut self,
        request: Request<'r>,
        drive: &mut D,
        out: &mut Writer,
    ) -> Result<(), ConsoleError<'r>> {
        // Every body fits a payload; should one not, the request reads as malformed.
        let full = |_| ConsoleError::Malformed;
        match request {
            Request::Status => self.status(drive).encode(out).map_err(full),
            Request::Get(key) => {
                let value = keys::get(&self.cfg, key).map_err(|e| key_error(key, e))?;
                put_f64(out, value).map_err(full)
            }
            Request::Set(key, value) => {
                let stored = self.set(key, value, drive)?;
                put_f64(out, stored).map_err(full)
            }
            Request::Save => self.save(drive),
            Request::Reset => {
                drive.set_enabled(false);
                self.reset_requested = true;
                Ok(())
            }
            Request::Faults => drive.fault_history().encode(out).map_err(full),
            Request::Enable if !calibrated(&self.cfg) => Err(ConsoleError::Uncalibrated),
            Request::Enable => match drive.fault_code() {
                0 => {
                    drive.set_enabled(true);
                    Ok(())
                }
                code => Err(ConsoleError::Faulted(code)),
            },
            Request::Disable => {
                drive.set_enabled(false);
                Ok(())
            }
            Request::ScopeStart => drive.scope(true).encode(out).map_err(full),
            Request::ScopeStop => {
                drive.scope(false);
                Ok(())
            }
            Request::Identify(run) => {
                if drive.enabled() {
                    return Err(ConsoleError::RunWhileEnabled);
                }
                match drive.fault_code() {
                    0 => {}
                    code => return Err(ConsoleError::Faulted(code)),
                }
                if !calibrated(&self.cfg) {
                    return Err(ConsoleError::Uncalibrated);
                }
                let cfg = run
                    .drive_config(&self.cfg)
                    .map_err(ConsoleError::Identify)?;
                drive
                    .identify(&cfg, &self.cfg, &run)
                    .map_err(ConsoleError::Identify)?
                    .encode(out)
                    .map_err(full)
            }
            Request::Calibrate(settings) => {
                let refused = ConsoleError::Calibrate;
                if drive.enabled() {
                    return Err(refused(CalibrateError::Enabled));
                }
                match drive.fault_code() {
                    0 => {}
                    code => return Err(ConsoleError::Faulted(code)),
                }
                let seq = calibrate::sequence(&self.cfg, &settings).map_err(refused)?;
                drive
                    .calibrate(&self.cfg, &seq)
                    .map_err(refused)?
                    .encode(out)
                    .map_err(full)
            }
        }
    }

    fn status<D: Drive>(&self, drive: &D) -> StatusReport<'static> {
        StatusReport {
            firmware_version: self.firmware_version,
            enabled: drive.enabled(),
            fault_code: drive.fault_code(),
            settings_crc: settings_crc(&self.cfg),
            origin: self.origin,
            baked_name: self.baked_name,
        }
    }

    /// `Set`: the key on a copy, the copy through `design`, then the drive; the value as
    /// stored.
    fn set<'r, D: Drive>(
        &mut self,
        key: &'r str,
        value: f64,
        drive: &mut D,
    ) -> Result<f64, ConsoleError<'r>> {
        let static_key = keys::static_key(key).ok_or(ConsoleError::UnknownKey(key))?;
        if drive.enabled() {
            return Err(ConsoleError::Enabled(static_key));
        }
        let mut next = self.cfg;
        keys::set(&mut next, key, value).map_err(|e| key_error(key, e))?;
        let invalid = |error| ConsoleError::Invalid {
            key: static_key,
            value,
            error,
        };
        controller_core::design(&next).map_err(invalid)?;
        drive.apply(&next).map_err(invalid)?;
        self.cfg = next;
        self.origin = Origin::Changed;
        keys::get(&self.cfg, key).map_err(|e| key_error(key, e))
    }

    fn save<D: Drive>(&mut self, drive: &mut D) -> Result<(), ConsoleError<'static>> {
        let record =
            store::encode(&self.cfg).map_err(|_| ConsoleError::Storage(SaveError::Encode))?;
        drive.save(&record).map_err(ConsoleError::Storage)?;
        self.origin = Origin::Saved;
        Ok(())
    }
}

/// Whether `cfg` may run: a DC drive, or a PMSM drive with its measured encoder offset.
#[must_use]
pub fn calibrated(cfg: &DriveConfig) -> bool {
    cfg.pmsm.is_none_or(|p| p.encoder_offset_elec_deg.is_some())
}

/// CRC-32 of `cfg` in pil-link's settings encoding: how the boot log names a drive.
#[must_use]
pub fn settings_crc(cfg: &DriveConfig) -> u32 {
    let mut w = Writer::new();
    match settings::encode(cfg, &mut w) {
        Ok(()) => crc32(w.as_slice()),
        Err(_) => 0,
    }
}

/// The name of controller-core's fault `code` (or the link fault).
#[must_use]
pub fn fault_name(code: u8) -> &'static str {
    if code == super::faults::LINK_FAULT_CODE {
        return "console link";
    }
    match controller_core::words::fault_from_code(code) {
        Ok(Some(f)) => f.name(),
        Ok(None) => "none",
        Err(_) => "unknown",
    }
}

fn key_error(key: &str, e: KeyError) -> ConsoleError<'_> {
    match e {
        KeyError::Unknown => ConsoleError::UnknownKey(key),
        KeyError::NotPresent(r) => ConsoleError::NotPresent(r.key),
        KeyError::Invalid(e) => ConsoleError::OutOfRange(e),
    }
}
