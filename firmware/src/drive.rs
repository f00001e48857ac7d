//! The drive the firmware runs: `configs/table1.toml`, baked at build time (`build.rs`:
//! composed, validated by `design()`, encoded with pil-link's settings codec) and decoded
//! here at start-up. There is no second spelling of the settings in the firmware.

use controller_core::DriveConfig;
use pil_link::LinkError;

/// The baked drive settings ([`pil_link::settings`] payload, [`pil_link::settings::LEN`]
/// bytes).
pub static BAKED: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/drive_settings.bin"));

/// The baked drive. An `Err` (a corrupt image) must put the drive in its safe state, outputs
/// off; it never panics.
///
/// # Errors
/// The settings codec's error for a payload it cannot decode.
pub fn baked() -> Result<DriveConfig, LinkError> {
    pil_link::settings::decode(BAKED)
}
