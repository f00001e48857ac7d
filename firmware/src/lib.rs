//! stiffdrive firmware library: everything the firmware images share, so the main firmware
//! (timer interrupts), the instruction benchmark `fw-bench`, the loop-in-the-loop image
//! `fw-lil` and the processor-in-the-loop image `pil` run the exact same tick code.
//!
//! * [`board`]: the board layer (embedded-hal PWM, enable, fault pins; current and encoder
//!   readers) and the per-loop I/O traits the ticks use.
//! * [`app`]: [`app::App`] holds the controller and the trend buffer; its
//!   `on_current_tick` / `on_velocity_tick` are what the 4 kHz and 2 kHz interrupts call.
//! * [`isr`]: the interrupt glue (`Loops`: where the app, I/O and profile live between
//!   interrupts; the handler bodies).
//! * [`trace`]: the trend buffer (fixed-size capture of chosen signals, dumped on request).
//! * [`virtual_motor`]: the power stage and motor of boards that have none (QEMU);
//!   [`virtual_pmsm`]: the three-phase inverter and PMSM there, for a PMSM drive.
//! * [`identify`]: the board console's measurement record (`Identify`, `Calibrate`), written
//!   per current tick, streamed from thread mode; [`calibrate`]: a PMSM's motor calibration
//!   run on the three-phase stage.
//! * [`drive`]: the drive settings baked at build time (`STIFFDRIVE_DRIVE`, else `configs/machines/table1.toml`).
//! * [`lil`]: the loop-in-the-loop record format and its reference run.
//! * [`ring`]: the UART receive ring of the link images; [`console`]: the board console's
//!   drive (settings sector, fault history, scope tap) of the `board` image.
//! * `board_console`: the board console image on any board (session loop, loop interrupt
//!   bodies, settings sector behind a trait), target builds only.
//! * `pmsm_image`: the PMSM drive on the three-phase STM32F4 board (`board-stm32f4-3ph`).
//! * `boards::qemu` / `boards::stm32f4`, `rt`: the hardware edge, target builds only.
//!
//! The library builds on the host too (`cargo test -p firmware`), where the hardware
//! modules are left out.
#![cfg_attr(not(test), no_std)]

pub mod app;
pub mod board;
pub mod calibrate;
pub mod console;
pub mod drive;
pub mod identify;
pub mod isr;
pub mod lil;
pub mod ring;
pub mod synthetic;
pub mod trace;
pub mod virtual_motor;
pub mod virtual_pmsm;

#[cfg(target_os = "none")]
pub mod board_console;
#[cfg(target_os = "none")]
pub mod boards;
#[cfg(all(target_os = "none", feature = "board-stm32f4-3ph"))]
pub mod pmsm_image;
#[cfg(all(target_os = "none", feature = "board-qemu"))]
pub mod rig;
#[cfg(target_os = "none")]
pub mod rt;

#[cfg(target_os = "none")]
pub use defmt;

/// `major << 16 | minor << 8 | patch` of this crate, as the link protocols report it.
#[must_use]
pub fn version() -> u32 {
    let mut parts = env!("CARGO_PKG_VERSION")
        .split('.')
        .map(|p| p.parse::<u32>().unwrap_or(0));
    let mut v = 0;
    for _ in 0..3 {
        v = (v << 8) | (parts.next().unwrap_or(0) & 0xFF);
    }
    v
}
