//! Runtime edge shared by every firmware image: the defmt logger, panic and HardFault
//! handlers, and the exit path. Under QEMU a panic or HardFault logs and exits with a
//! non-zero semihosting status, so a crash fails CI; on the board the same status reaches
//! `probe-rs run` (which implements semihosting exit), and the log goes out over RTT.

use cortex_m_rt::{exception, ExceptionFrame};
use cortex_m_semihosting::debug;

// The defmt global logger of the selected board.
#[cfg(all(feature = "board-qemu", not(feature = "board-stm32f4")))]
use defmt_semihosting as _;
#[cfg(feature = "board-stm32f4")]
use defmt_rtt as _;

/// End the program with a pass/fail status. Under QEMU this stops the emulator with exit
/// code 0 or 1; if no debugger or emulator handles semihosting it parks the core.
pub fn exit(success: bool) -> ! {
    debug::exit(if success {
        debug::EXIT_SUCCESS
    } else {
        debug::EXIT_FAILURE
    });
    loop {
        cortex_m::asm::bkpt();
    }
}

// SAFETY: cortex-m-rt requires the HardFault handler to be declared `unsafe fn`; it only
// reads the stacked frame it is handed.
#[allow(unsafe_code)]
#[exception]
unsafe fn HardFault(frame: &ExceptionFrame) -> ! {
    defmt::error!(
        "HardFault at pc={=u32:#x} lr={=u32:#x} xpsr={=u32:#x}",
        frame.pc(),
        frame.lr(),
        frame.xpsr()
    );
    exit(false)
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    defmt::error!("panic: {}", defmt::Display2Format(info));
    exit(false)
}
