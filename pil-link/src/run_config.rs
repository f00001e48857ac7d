//! The whole `Config` payload: the drive settings ([`crate::settings`], [`settings::LEN`]
//! bytes) followed by the run's identification excitation, if any (controller-core's
//! [`ExcitationConfig`], every field, `f32` as raw IEEE bits):
//!
//! ```text
//! tag 0 (no excitation)                                           1 byte
//! tag 1 (PRBS)  | injection u8 | amplitude_pu f32 | bits u8 | hold_ticks u16 | periods u16
//!                                                                 11 bytes
//! tag 2 (chirp) | injection u8 | amplitude_pu f32 | start_hz f32 | end_hz f32 | duration_s f32
//!                                                                 18 bytes
//! injection: 0 torque reference, 1 velocity reference
//! ```
//!
//! The firmware applies the excitation with `Controller::with_excitation`, whose checks
//! (ranges, Nyquist) refuse a bad one with a `Config` fault.

use crate::settings;
use crate::wire::{Reader, Writer};
use crate::{FrameKind, LinkError};
use controller_core::DriveConfig;
use controller_core::excitation::{ExcitationConfig, Injection, Waveform};

const TAG_NONE: u8 = 0;
const TAG_PRBS: u8 = 1;
const TAG_CHIRP: u8 = 2;

/// Longest `Config` payload (drive settings and a chirp), in bytes.
pub const MAX_LEN: usize = settings::LEN + 18;
// The longest payload fits a frame.
const _: () = assert!(MAX_LEN <= crate::MAX_PAYLOAD);

/// Payload bytes of a run's drive settings and excitation.
///
/// ```
/// use controller_core::excitation::{ExcitationConfig, Injection, Waveform};
/// use pil_link::{run_config, wire::Writer};
/// # let cfg: controller_core::DriveConfig = toml::from_str(include_str!(concat!(
/// #     env!("CARGO_MANIFEST_DIR"), "/../controller-core/doc/example-drive.toml"))).unwrap();
/// let e = ExcitationConfig {
///     waveform: Waveform::Prbs { bits: 9, hold_ticks: 2, periods: 3 },
///     amplitude_pu: 0.05,
///     injection: Injection::TorqueReference,
/// };
/// let mut w = Writer::new();
/// run_config::encode(&cfg, Some(&e), &mut w).unwrap();
/// assert_eq!(run_config::decode(w.as_slice()), Ok((cfg, Some(e))));
/// ```
pub fn encode(
    drive: &DriveConfig,
    excitation: Option<&ExcitationConfig>,
    w: &mut Writer,
) -> Result<(), LinkError> {
    settings::encode(drive, w)?;
    let Some(e) = excitation else {
        return w.u8(TAG_NONE).map(|_| ());
    };
    let ExcitationConfig {
        waveform,
        amplitude_pu,
        injection,
    } = *e;
    let tag = match waveform {
        Waveform::Prbs { .. } => TAG_PRBS,
        Waveform::Chirp { .. } => TAG_CHIRP,
    };
    let injection = match injection {
        Injection::TorqueReference => 0,
        Injection::VelocityReference => 1,
    };
    w.u8(tag)?.u8(injection)?.u32(amplitude_pu.to_bits())?;
    match waveform {
        Waveform::Prbs {
            bits,
            hold_ticks,
            periods,
        } => w.u8(bits)?.u16(hold_ticks)?.u16(periods)?,
        Waveform::Chirp {
            start_hz,
            end_hz,
            duration_s,
        } => w
            .u32(start_hz.to_bits())?
            .u32(end_hz.to_bits())?
            .u32(duration_s.to_bits())?,
    };
    Ok(())
}

/// Parses a `Config` payload: the drive settings and the excitation, if any.
pub fn decode(payload: &[u8]) -> Result<(DriveConfig, Option<ExcitationConfig>), LinkError> {
    let bad = LinkError::BadPayload {
        kind: FrameKind::Config as u8,
        len: u8::try_from(payload.len()).unwrap_or(u8::MAX),
    };
    let (drive, rest) = match (payload.get(..settings::LEN), payload.get(settings::LEN..)) {
        (Some(drive), Some(rest)) => (drive, rest),
        // Too short for the settings: their own decoder names the truncation.
        _ => (payload, &[][..]),
    };
    let drive = settings::decode(drive)?;
    // Errors of the excitation section name the whole payload's length.
    let mut r = Reader::new(FrameKind::Config, rest);
    let excitation = excitation(&mut r, bad).map_err(|_| bad)?;
    r.finish().map_err(|_| bad)?;
    Ok((drive, excitation))
}

fn excitation(r: &mut Reader<'_>, bad: LinkError) -> Result<Option<ExcitationConfig>, LinkError> {
    let tag = r.u8()?;
    if tag == TAG_NONE {
        return Ok(None);
    }
    let injection = match r.u8()? {
        0 => Injection::TorqueReference,
        1 => Injection::VelocityReference,
        _ => return Err(bad),
    };
    let amplitude_pu = f32::from_bits(r.u32()?);
    let waveform = match tag {
        TAG_PRBS => Waveform::Prbs {
            bits: r.u8()?,
            hold_ticks: r.u16()?,
            periods: r.u16()?,
        },
        TAG_CHIRP => Waveform::Chirp {
            start_hz: f32::from_bits(r.u32()?),
            end_hz: f32::from_bits(r.u32()?),
            duration_s: f32::from_bits(r.u32()?),
        },
        _ => return Err(bad),
    };
    Ok(Some(ExcitationConfig {
        waveform,
        amplitude_pu,
        injection,
    }))
}
