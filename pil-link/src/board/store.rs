//! The settings sector's record: what `Save` writes and the boot reads back.
//!
//! ```text
//! offset  size  field
//! 0       4     magic "SDRV" (0x5652_4453 little endian)
//! 4       2     record version (STORE_VERSION)
//! 6       2     settings length (settings::LEN)
//! 8       LEN   the DriveConfig in pil-link's settings encoding
//! 8+LEN   4     CRC-32 over bytes 0..8+LEN
//! ```
//! A record that fails any check is not used: the firmware then runs its baked drive and
//! its boot log says why ([`StoreError`]).

use crate::settings;
use crate::wire::Writer;
use crate::{LinkError, crc32};
use controller_core::DriveConfig;

/// "SDRV", little endian.
pub const MAGIC: u32 = 0x5652_4453;
/// Version of the record layout; bump it when the layout or the settings encoding changes.
pub const STORE_VERSION: u16 = 4;
/// Bytes of a record.
pub const RECORD_LEN: usize = 8 + settings::LEN + 4;

/// Why a record is not used.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StoreError {
    /// No record (the magic is missing: a blank sector).
    Empty,
    /// The CRC does not match the bytes (a torn or corrupted write).
    BadCrc {
        /// CRC carried by the record.
        stored: u32,
        /// CRC of its bytes.
        computed: u32,
    },
    /// Another record version.
    BadVersion {
        /// Version found.
        found: u16,
    },
    /// The settings do not decode.
    Settings(LinkError),
}

impl core::fmt::Display for StoreError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            Self::Empty => write!(f, "no saved settings"),
            Self::BadCrc { stored, computed } => write!(
                f,
                "saved settings have a bad CRC ({stored:08x}, bytes give {computed:08x})"
            ),
            Self::BadVersion { found } => write!(
                f,
                "saved settings are record version {found}, this firmware reads {STORE_VERSION}"
            ),
            Self::Settings(e) => write!(f, "saved settings do not decode: {e}"),
        }
    }
}

/// Why writing the settings sector failed: the board's answer to `Save`, which the
/// console reports as `save failed: ...`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SaveError {
    /// Settings cannot be saved while the drive is enabled (writing the sector may hold up
    /// the control loops).
    Enabled,
    /// The record could not be encoded.
    Encode,
    /// The flash controller stayed locked after its unlock keys.
    Locked,
    /// The flash controller stayed busy past the bounded wait (in the step named).
    Timeout(&'static str),
    /// The flash controller flagged an error (in the step named; its status register).
    Flash {
        /// `erase` or `program`.
        step: &'static str,
        /// The status register's error flags.
        status: u32,
    },
    /// The erase did not leave the sector blank: the first offset that is not.
    NotBlank {
        /// Byte offset into the sector.
        offset: u32,
    },
    /// The sector did not read back what was written: the first offset that differs.
    Verify {
        /// Byte offset into the sector.
        offset: u32,
    },
}

impl core::fmt::Display for SaveError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            Self::Enabled => write!(f, "refused while the drive is enabled (disable it first)"),
            Self::Encode => write!(f, "the settings record does not encode"),
            Self::Locked => write!(f, "the flash controller stays locked after its unlock keys"),
            Self::Timeout(step) => write!(f, "{step}: the flash controller stays busy"),
            Self::Flash { step, status } => {
                write!(
                    f,
                    "{step}: the flash controller flags an error (status {status:#010x})"
                )
            }
            Self::NotBlank { offset } => write!(
                f,
                "erase: the sector is not blank at byte {offset} after its erase"
            ),
            Self::Verify { offset } => write!(
                f,
                "the settings sector does not read back what was written (byte {offset})"
            ),
        }
    }
}

/// The record of `cfg`.
///
/// # Errors
/// The settings codec's error (never for a `DriveConfig`).
pub fn encode(cfg: &DriveConfig) -> Result<[u8; RECORD_LEN], LinkError> {
    let mut w = Writer::new();
    w.u32(MAGIC)?
        .u16(STORE_VERSION)?
        .u16(settings::LEN as u16)?;
    settings::encode(cfg, &mut w)?;
    let crc = crc32(w.as_slice());
    w.u32(crc)?;
    let mut out = [0_u8; RECORD_LEN];
    let src = w.as_slice();
    let dst = out
        .get_mut(..src.len())
        .ok_or(LinkError::BufferTooSmall { needed: src.len() })?;
    dst.copy_from_slice(src);
    Ok(out)
}

/// The settings of a record (`bytes` may be longer: the rest of the sector).
///
/// # Errors
/// [`StoreError`] naming the first check that failed.
pub fn decode(bytes: &[u8]) -> Result<DriveConfig, StoreError> {
    let word = |at: usize| -> Option<u32> {
        let b: [u8; 4] = bytes.get(at..at + 4)?.try_into().ok()?;
        Some(u32::from_le_bytes(b))
    };
    if word(0) != Some(MAGIC) {
        return Err(StoreError::Empty);
    }
    let body_len = 8 + settings::LEN;
    let body = bytes.get(..body_len).ok_or(StoreError::Empty)?;
    let stored = word(body_len).ok_or(StoreError::Empty)?;
    let computed = crc32(body);
    if stored != computed {
        return Err(StoreError::BadCrc { stored, computed });
    }
    let found = word(4).map_or(0, |w| (w & 0xFFFF) as u16);
    if found != STORE_VERSION || word(4).map(|w| w >> 16) != Some(settings::LEN as u32) {
        return Err(StoreError::BadVersion { found });
    }
    settings::decode(body.get(8..).unwrap_or(&[])).map_err(StoreError::Settings)
}
