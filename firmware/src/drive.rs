//! The drive the firmware runs: the machine file named by `STIFFDRIVE_DRIVE` at build time
//! (else `configs/machines/table1.toml`), baked by `build.rs` (composed by `machine_file::compose`,
//! validated by `design()`, encoded with pil-link's settings codec) and decoded here at
//! start-up. There is no second spelling of the settings in the firmware.

use controller_core::DriveConfig;
use pil_link::LinkError;

/// The baked drive settings ([`pil_link::settings`] payload, [`pil_link::settings::LEN`]
/// bytes).
pub static BAKED: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/drive_settings.bin"));

/// Which drive is baked: the machine file's path (from the workspace root) and the CRC-32
/// of its settings, logged at boot.
pub static NAME: &str = include_str!(concat!(env!("OUT_DIR"), "/drive_name.txt"));

/// The baked drive. An `Err` (a corrupt image) must put the drive in its safe state, outputs
/// off; it never panics.
///
/// # Errors
/// The settings codec's error for a payload it cannot decode.
pub fn baked() -> Result<DriveConfig, LinkError> {
    pil_link::settings::decode(BAKED)
}

/// The reference PMSM drive, `configs/machines/table1-pmsm.toml` whatever
/// `STIFFDRIVE_DRIVE` names (`build.rs`): `fw-bench`'s second drive and the host tests' PMSM.
pub static REFERENCE_PMSM: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/pmsm_settings.bin"));

/// The reference PMSM drive ([`REFERENCE_PMSM`]).
///
/// # Errors
/// The settings codec's error for a payload it cannot decode.
pub fn reference_pmsm() -> Result<DriveConfig, LinkError> {
    pil_link::settings::decode(REFERENCE_PMSM)
}

/// The machine behind the `board` image's virtual motor: the baked machine file's motor
/// inertia \[s\] and its load behind the shaft (`build.rs`, from the file's `[plant]`).
#[must_use]
pub fn coupling() -> (f32, crate::virtual_motor::Coupling) {
    include!(concat!(env!("OUT_DIR"), "/virtual_machine.rs"))
}

/// The PMSM behind the QEMU images' virtual inverter: the baked machine file's
/// `[electrics]` (`build.rs`); `None` for a DC motor.
#[must_use]
pub fn pmsm_machine() -> Option<crate::virtual_pmsm::PmsmMachine> {
    include!(concat!(env!("OUT_DIR"), "/virtual_pmsm.rs"))
}
