//! The settings the board console boots with: the settings sector's record, or the baked
//! drive, and the boot log's note of which and why (`super`'s module docs).

use core::fmt::Write as _;

use controller_core::DriveConfig;
use pil_link::board::message::Origin;
use pil_link::board::session::settings_crc;
use pil_link::board::store::{self, StoreError, RECORD_LEN};

use super::ConsoleBoard;

/// What the boot says of the settings it runs.
pub(super) type Note = heapless::String<128>;

/// The settings to run: the sector's record if it passes its checks and `design`, else
/// the baked drive; the boot log (and the note) says which and why.
pub(super) fn boot_settings<H: ConsoleBoard>(
    hw: &mut H,
    baked: DriveConfig,
) -> (DriveConfig, Origin, Note) {
    let mut sector = [0_u8; RECORD_LEN];
    hw.read_settings(&mut sector);
    let mut note = Note::new();
    match store::decode(&sector) {
        Ok(cfg) if cfg.pmsm.is_some() != baked.pmsm.is_some() => {
            defmt::warn!(
                "saved settings are for another motor than the board's: running the baked drive"
            );
            let _ = write!(note, "saved settings for another motor: baked");
        }
        Ok(cfg) => match controller_core::design(&cfg) {
            Ok(_) => {
                defmt::info!(
                    "drive: saved on the board (settings crc {=u32:08x}), in place of the baked {=str}",
                    settings_crc(&cfg),
                    crate::drive::NAME
                );
                let _ = write!(
                    note,
                    "saved on the board (settings crc {:08x})",
                    settings_crc(&cfg)
                );
                return (cfg, Origin::Saved, note);
            }
            Err(e) => {
                defmt::warn!(
                    "saved settings refused (drive.{=str}): running the baked drive",
                    e.param()
                );
                let _ = write!(note, "saved settings refused (drive.{}): baked", e.param());
            }
        },
        Err(StoreError::Empty) => {
            defmt::info!("no saved settings on the board");
            let _ = write!(note, "baked (no saved settings on the board)");
        }
        Err(e) => {
            defmt::warn!("{}: running the baked drive", defmt::Display2Format(&e));
            let _ = write!(note, "baked ({e})");
        }
    }
    defmt::info!("drive: {=str}", crate::drive::NAME);
    (baked, Origin::Baked, note)
}
