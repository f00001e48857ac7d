//! stiffdrive firmware: binds controller-core to a drive board's timer interrupts
//! (4 kHz current loop, 2 kHz velocity loop). On the host this binary is an empty `main`
//! so that `cargo test` and `cargo clippy --workspace` work without the ARM target.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod target {
    use cortex_m_rt::{entry, exception, ExceptionFrame};
    use cortex_m_semihosting::debug;
    // The defmt global logger: frames go out over semihosting (decoded by defmt-print).
    use defmt_semihosting as _;

    #[entry]
    fn main() -> ! {
        defmt::info!("stiffdrive firmware {=str} up", env!("CARGO_PKG_VERSION"));
        debug::exit(debug::EXIT_SUCCESS);
        loop {
            cortex_m::asm::bkpt();
        }
    }

    // SAFETY: cortex-m-rt requires the HardFault handler to be declared `unsafe fn`; it
    // only reads the stacked frame it is handed.
    #[allow(unsafe_code)]
    #[exception]
    unsafe fn HardFault(frame: &ExceptionFrame) -> ! {
        defmt::error!("HardFault at pc={=u32:#x}", frame.pc());
        debug::exit(debug::EXIT_FAILURE);
        loop {
            cortex_m::asm::bkpt();
        }
    }

    #[panic_handler]
    fn panic(info: &core::panic::PanicInfo) -> ! {
        defmt::error!("panic: {}", defmt::Display2Format(info));
        debug::exit(debug::EXIT_FAILURE);
        loop {
            cortex_m::asm::bkpt();
        }
    }
}

#[cfg(not(target_os = "none"))]
fn main() {
    println!("firmware: build for thumbv7em-none-eabihf (cargo fw-build); nothing to run on the host");
}
