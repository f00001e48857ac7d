//! Runtime edge shared by every firmware image: the defmt logger, panic and HardFault
//! handlers, and the exit path. Both handlers first switch the power stage off
//! (`emergency_stop`: plain register writes, no locks), then log. Under QEMU a panic or HardFault logs and exits with a
//! non-zero semihosting status, so a crash fails CI; on the board the same status reaches
//! `probe-rs run` (which implements semihosting exit), and the log goes out over RTT.

use cortex_m_rt::{exception, ExceptionFrame};

// The defmt global logger of the selected board.
#[cfg(feature = "board-stm32f4")]
use defmt_rtt as _;
#[cfg(all(feature = "board-qemu", not(feature = "board-stm32f4")))]
use defmt_semihosting as _;

/// End the program with a pass/fail status (the board layer's: `boards::exit`, which
/// the boards' own bring-up calls too).
pub use crate::boards::exit;

// SAFETY: cortex-m-rt requires the HardFault handler to be declared `unsafe fn`; it only
// reads the stacked frame it is handed.
#[allow(unsafe_code)]
#[exception]
unsafe fn HardFault(frame: &ExceptionFrame) -> ! {
    crate::boards::active::emergency_stop();
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
    crate::boards::active::emergency_stop();
    defmt::error!("panic: {}", defmt::Display2Format(info));
    exit(false)
}

/// Memory use of the image, from the cortex-m-rt linker symbols.
#[derive(Clone, Copy, Debug)]
pub struct MemoryUse {
    /// Flash: vector table, code, read-only data and the initial values of `.data` [bytes].
    pub flash_bytes: u32,
    /// Static RAM: `.data`, `.bss`, `.uninit` [bytes] (the stack comes on top).
    pub static_ram_bytes: u32,
}

extern "C" {
    static __vector_table: u32;
    static __sidata: u32;
    static __sdata: u32;
    static __edata: u32;
    static __sheap: u32;
    static _stack_start: u32;
}

fn symbol_address(sym: *const u32) -> u32 {
    sym as usize as u32
}

/// The image's flash and static RAM use.
pub fn memory_use() -> MemoryUse {
    let vt = symbol_address(&raw const __vector_table);
    let sidata = symbol_address(&raw const __sidata);
    let sdata = symbol_address(&raw const __sdata);
    let edata = symbol_address(&raw const __edata);
    let sheap = symbol_address(&raw const __sheap);
    MemoryUse {
        flash_bytes: sidata.wrapping_sub(vt) + edata.wrapping_sub(sdata),
        static_ram_bytes: sheap.wrapping_sub(sdata),
    }
}

/// Pattern painted into the free stack to find its high-water mark.
const STACK_PAINT: u32 = 0xA5A5_A5A5;
/// Words just below the current stack pointer left unpainted (the painter's own frame).
const PAINT_GUARD_WORDS: usize = 64;

/// Paint the unused stack (from the end of static RAM up to just below the current stack
/// pointer) so [`stack_high_water_bytes`] can later see how deep the stack went. Call early
/// in `main`, before interrupts run.
pub fn paint_stack() {
    let bottom = symbol_address(&raw const __sheap) as usize;
    let sp = cortex_m::register::msp::read() as usize;
    let top = sp.saturating_sub(PAINT_GUARD_WORDS * 4);
    let mut addr = bottom;
    while addr + 4 <= top {
        // SAFETY: [__sheap, sp − guard) is RAM between the last static and the live stack,
        // owned by nobody (no heap in this firmware), word aligned (cortex-m-rt aligns
        // __sheap to 4); writing it cannot alias a live object.
        #[allow(unsafe_code)]
        unsafe {
            core::ptr::write_volatile(addr as *mut u32, STACK_PAINT);
        }
        addr += 4;
    }
}

/// Deepest stack use since [`paint_stack`] [bytes]: from the top of RAM down to the lowest
/// word no longer holding the paint.
pub fn stack_high_water_bytes() -> u32 {
    let bottom = symbol_address(&raw const __sheap) as usize;
    let top = symbol_address(&raw const _stack_start) as usize;
    let mut addr = bottom;
    while addr + 4 <= top {
        // SAFETY: reads of RAM inside [__sheap, _stack_start), word aligned (see paint_stack).
        #[allow(unsafe_code)]
        let word = unsafe { core::ptr::read_volatile(addr as *const u32) };
        if word != STACK_PAINT {
            break;
        }
        addr += 4;
    }
    (top - addr) as u32
}
