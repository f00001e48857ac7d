//! The boards behind the board layer, chosen by cargo feature: `board-qemu` (default,
//! mps2-an386 under QEMU) or `board-stm32f4` (STM32F4-Discovery). [`active`] is the one
//! this image is built for; binaries use only its common items (`init`, `CurrentIoImpl`,
//! `VelocityIoImpl`, `Console`, `bind_interrupts!`, `CORE_CLOCK_HZ`).

#[cfg(all(feature = "board-qemu", not(feature = "board-stm32f4")))]
pub mod qemu;
#[cfg(all(feature = "board-qemu", not(feature = "board-stm32f4")))]
pub use qemu as active;

#[cfg(feature = "board-stm32f4")]
pub mod stm32f4;
#[cfg(feature = "board-stm32f4")]
pub use stm32f4 as active;

#[cfg(not(any(feature = "board-qemu", feature = "board-stm32f4")))]
compile_error!("select a board: feature `board-qemu` (default) or `board-stm32f4`");

/// End the program with a pass/fail status. Under QEMU this stops the emulator with exit
/// code 0 or 1 (semihosting; `probe-rs run` implements it too); if no debugger or
/// emulator handles semihosting it parks the core. The board layer's own, so a board's
/// bring-up can give up without reaching up into the runtime (`crate::rt` re-exports it).
pub fn exit(success: bool) -> ! {
    use cortex_m_semihosting::debug;
    debug::exit(if success {
        debug::EXIT_SUCCESS
    } else {
        debug::EXIT_FAILURE
    });
    loop {
        cortex_m::asm::bkpt();
    }
}
