//! The board console image (`board`, QEMU mps2-an386): the drive firmware as a board runs
//! it, the 4 kHz and 2 kHz loop interrupts on the virtual motor, started disabled and held
//! at rest, with the board console of `stiffdrive board` on UART0 (pil-link's board frames,
//! `pil_link::board`).
//!
//! The image is `firmware::board_console` (shared with the STM32F4 image, `src/main.rs`)
//! bound to this board: its settings sector is `boards::qemu::SETTINGS_SECTOR`, which
//! QEMU keeps across the system reset of `Reset`.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(all(target_os = "none", feature = "board-qemu"))]
mod target {
    use cortex_m_rt::entry;
    use firmware::board_console::{current_loop, run, uart_rx, velocity_loop};
    use firmware::boards::qemu::BoardConsole;

    firmware::bind_interrupts!(current: current_loop, velocity: velocity_loop, command: uart_rx);

    #[entry]
    fn main() -> ! {
        run(BoardConsole)
    }
}

#[cfg(not(all(target_os = "none", feature = "board-qemu")))]
fn main() {
    println!(
        "board: the board console image runs in QEMU under `stiffdrive board --qemu`; build it \
         with cargo build -p firmware --release --target thumbv7em-none-eabihf --bin board"
    );
}
