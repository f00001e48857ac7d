//! Crash check (`cargo fw-crash-check`, QEMU): executes a permanently undefined instruction
//! from the velocity-loop interrupt while the loops run, so the fault escalates to
//! HardFault. The HardFault handler must log the faulting pc and exit with status 1; the
//! runner's `--expect-crash` turns exactly that (status 1 and a `HardFault` line) into a
//! pass, and anything else (exit 0, a hang, no log) into a failure.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod target {
    use core::sync::atomic::{AtomicU32, Ordering};

    use cortex_m_rt::entry;
    use firmware::boards::active as board;

    static TICKS: AtomicU32 = AtomicU32::new(0);

    fn current_loop() {
        TICKS.fetch_add(1, Ordering::Relaxed);
    }

    fn velocity_loop() {
        if TICKS.load(Ordering::Relaxed) >= 100 {
            defmt::info!("fw-crash: executing UDF in the velocity-loop interrupt");
            cortex_m::asm::udf();
        }
    }

    fn command() {
        let _ = board::read_command();
    }

    firmware::bind_interrupts!(current: current_loop, velocity: velocity_loop, command: command);

    #[entry]
    fn main() -> ! {
        let Some(mut core) = cortex_m::Peripherals::take() else {
            firmware::rt::exit(false)
        };
        let Ok(cfg) = firmware::drive::baked() else {
            defmt::error!("fw-crash: baked drive settings do not decode");
            // Exit 0 is the failure case here (the runner expects the crash's status 1).
            firmware::rt::exit(true)
        };
        let _board = board::init(&mut core, &cfg);
        board::start(&mut core.NVIC, cfg.current_rate_hz, cfg.velocity_rate_hz);
        loop {
            cortex_m::asm::wfi();
            if TICKS.load(Ordering::Relaxed) > 1000 {
                defmt::error!("fw-crash: no fault happened");
                // Exit 0 here is the failure case: the runner expects status 1.
                firmware::rt::exit(true);
            }
        }
    }
}

#[cfg(not(target_os = "none"))]
fn main() {
    println!("fw-crash: runs in QEMU: cargo fw-crash-check");
}
