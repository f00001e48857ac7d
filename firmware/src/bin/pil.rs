//! Processor-in-the-loop image (`pil`, QEMU mps2-an386): the firmware's real interrupt code
//! path, driven tick by tick by `hil-harness pil` over UART0 with the `pil-link` protocol.
//!
//! Per `Sensors` frame the link loop (thread mode) fills the link board's mailboxes, pends
//! the TIMER0 (current loop) or TIMER1 (velocity loop) interrupt, and the very handlers the
//! drive firmware binds run `Loops::current_isr` (a PMSM drive: `Loops::pmsm_isr`) /
//! `velocity_isr`; the outputs go back in a `Commands` frame. Lock step: nothing here depends on how fast QEMU runs.
//!
//! A bad, lost (sequence gap or silence) or late frame latches the safe state: the link
//! board's fault input goes active, so the controller latches `Fault::External`, the enable
//! output drops and the voltage is zero; every later frame is answered with a `Fault` frame.
//! The harness's `Stop` ends the run: semihosting exit 0 after a clean run, 1 if faulted.
//!
//! Time base: SysTick every 10 ms of QEMU's virtual clock (which follows the host clock
//! when `-icount` is not given), for the link watchdog only. A faster SysTick costs QEMU
//! more than it buys here. The idle loop sleeps in WFI until a UART byte or SysTick.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(all(target_os = "none", feature = "board-qemu"))]
#[path = "../pil_board.rs"]
mod pil_board;

#[cfg(all(target_os = "none", feature = "board-qemu"))]
mod target {
    use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

    use controller_core::excitation::ExcitationParams;
    use controller_core::{CurrentOutputs, PmsmOutputs, VelocityOutputs};
    use cortex_m::peripheral::syst::SystClkSource;
    use cortex_m::peripheral::NVIC;
    use cortex_m_rt::{entry, exception};
    use firmware::app::{App, DEFAULT_TRACE};
    use firmware::boards::qemu::{enable_interrupts, Irq, Uart0, SYSCLK_HZ};
    use firmware::isr::Loops;
    use firmware::rt::exit;
    use pil_link::tick::{Applied, Commands, Sensors};
    use pil_link::wire::Writer;
    use pil_link::{
        run_config, FaultCode, FirmwareSession, Frame, SafeOutputs, SessionState, Target, MAX_FRAME,
    };

    use firmware::ring::ByteRing;

    use super::pil_board::{
        LinkCurrentIo, LinkSetpoint, LinkVelocityIo, APPLIED, CURRENT_IN, CURRENT_ISR_TICKS,
        CURRENT_OUT, LINK_FAULT, PMSM_IN, PMSM_OUT, VELOCITY_IN, VELOCITY_OUT,
    };

    static LOOPS: Loops<LinkCurrentIo, LinkVelocityIo, LinkSetpoint> = Loops::new();
    static RX: ByteRing = ByteRing::new();
    /// The configured drive is a PMSM: TIMER0 runs `Loops::pmsm_isr`.
    static PMSM: AtomicBool = AtomicBool::new(false);
    /// Milliseconds of virtual time since boot (advanced by SysTick in 10 ms steps).
    static NOW_MS: AtomicU32 = AtomicU32::new(0);
    const SYSTICK_MS: u32 = 10;
    /// How long the image stays up after its last reply, before it ends QEMU. On a serial
    /// device (QEMU's UART on a pseudo-terminal) QEMU's exit hangs the line up, and a hang-up
    /// discards the bytes the harness has not read yet: the `Stop` reply among them. A
    /// socket keeps them. The harness is already waiting for the reply when it is sent.
    const STOP_LINGER_MS: u32 = 200;

    /// Waits `ms` on the SysTick clock, asleep between ticks.
    fn linger(ms: u32) {
        let start = NOW_MS.load(Ordering::Relaxed);
        while NOW_MS.load(Ordering::Relaxed).wrapping_sub(start) < ms {
            cortex_m::asm::wfi();
        }
    }

    fn current_loop() {
        if PMSM.load(Ordering::Relaxed) {
            let out = LOOPS.pmsm_isr();
            CURRENT_ISR_TICKS.fetch_add(1, Ordering::Relaxed);
            critical_section::with(|cs| PMSM_OUT.borrow(cs).set(out));
        } else {
            let out = LOOPS.current_isr();
            CURRENT_ISR_TICKS.fetch_add(1, Ordering::Relaxed);
            critical_section::with(|cs| CURRENT_OUT.borrow(cs).set(out));
        }
    }

    fn velocity_loop() {
        let out = LOOPS.velocity_isr();
        critical_section::with(|cs| VELOCITY_OUT.borrow(cs).set(out));
    }

    fn uart_rx() {
        while let Some(b) = Uart0.read_byte() {
            RX.push(b);
        }
    }

    firmware::bind_interrupts!(current: current_loop, velocity: velocity_loop, command: uart_rx);

    #[exception]
    fn SysTick() {
        NOW_MS.fetch_add(SYSTICK_MS, Ordering::Relaxed);
    }

    /// Pends a loop interrupt and returns what its handler left in `slot`. The pended
    /// handler preempts thread mode at once (DSB/ISB make the pend take effect before we
    /// look); a few retries cover a handler that is still being entered.
    fn run_isr<T: Copy>(
        irq: Irq,
        slot: &'static critical_section::Mutex<core::cell::Cell<Option<T>>>,
    ) -> Option<T> {
        critical_section::with(|cs| slot.borrow(cs).set(None));
        NVIC::pend(irq);
        cortex_m::asm::dsb();
        cortex_m::asm::isb();
        for _ in 0..16 {
            if let Some(out) = critical_section::with(|cs| slot.borrow(cs).get()) {
                return Some(out);
            }
            cortex_m::asm::nop();
        }
        None
    }

    /// What the board layer applied in the last current tick, with the interrupt count and
    /// the excitation's latest sample.
    fn applied() -> Applied {
        let mut applied = critical_section::with(|cs| APPLIED.borrow(cs).get());
        applied.isr_ticks = CURRENT_ISR_TICKS.load(Ordering::Relaxed);
        applied.excitation_bits = LOOPS
            .with_app(|app| app.excitation_pu().to_bits())
            .unwrap_or(0);
        applied
    }

    /// The fields a refused excitation names (the `Config` payload's excitation section).
    const EXCITATION_NAMES: ExcitationParams = ExcitationParams {
        amplitude_pu: "excitation.amplitude_pu",
        start_or_bits: "excitation.start_hz/bits",
        end_or_hold: "excitation.end_hz/hold_ticks",
        duration_or_periods: "excitation.duration_s/periods",
    };

    /// The controller behind the link: the firmware's `App` in the `Loops` the interrupts
    /// share, exactly as the drive image installs it.
    struct PilTarget;

    impl Target for PilTarget {
        fn configure(&mut self, payload: &[u8]) -> Result<(), FaultCode> {
            let (cfg, excitation) =
                run_config::decode(payload).map_err(|_| FaultCode::BadPayload)?;
            // The link board delivers counts already wrapped at the configured width.
            let pmsm = cfg.pmsm.is_some();
            let app = if pmsm {
                App::new_pmsm(&cfg, cfg.counter_bits, DEFAULT_TRACE)
            } else {
                App::new(&cfg, cfg.counter_bits, DEFAULT_TRACE)
            };
            let app = app.and_then(|app| match excitation {
                Some(e) => app.with_excitation(&e, EXCITATION_NAMES),
                None => Ok(app),
            });
            let app = match app {
                Ok(app) => app,
                Err(e) => {
                    defmt::error!("pil: settings refused: {}", defmt::Debug2Format(&e));
                    return Err(FaultCode::Config);
                }
            };
            PMSM.store(pmsm, Ordering::Relaxed);
            LOOPS.install(app, LinkCurrentIo, LinkVelocityIo, LinkSetpoint);
            LOOPS.with_app(|app| app.set_enable_request(true));
            defmt::info!(
                "pil: configured, current loop {=u32} Hz, velocity loop {=u32} Hz",
                cfg.current_rate_hz,
                cfg.velocity_rate_hz
            );
            if let Some(e) = excitation {
                defmt::info!("pil: excitation {}", defmt::Debug2Format(&e));
            }
            Ok(())
        }

        fn tick(&mut self, sensors: &[u8], commands: &mut Writer) -> Result<(), FaultCode> {
            let reply = match Sensors::decode(sensors).map_err(|_| FaultCode::BadPayload)? {
                Sensors::Current(inputs) => {
                    critical_section::with(|cs| CURRENT_IN.borrow(cs).set(inputs));
                    let out: CurrentOutputs =
                        run_isr(Irq::Timer0, &CURRENT_OUT).ok_or(FaultCode::Protocol)?;
                    Commands::Current(out, applied())
                }
                Sensors::Velocity(inputs) => {
                    critical_section::with(|cs| VELOCITY_IN.borrow(cs).set(Some(inputs)));
                    let out: VelocityOutputs =
                        run_isr(Irq::Timer1, &VELOCITY_OUT).ok_or(FaultCode::Protocol)?;
                    Commands::Velocity(out)
                }
                Sensors::Pmsm(inputs) => {
                    critical_section::with(|cs| PMSM_IN.borrow(cs).set(inputs));
                    let out: PmsmOutputs =
                        run_isr(Irq::Timer0, &PMSM_OUT).ok_or(FaultCode::Protocol)?;
                    Commands::Pmsm(out, applied())
                }
            };
            reply.encode(commands).map_err(|_| FaultCode::BadPayload)
        }

        fn enter_safe_state(&mut self) -> SafeOutputs {
            // Fault input active: one velocity tick latches the controller's
            // `Fault::External` (it must run before the enable request drops, since a held
            // app skips the controller). Then operator enable off, and one current tick
            // commands and applies zero with the enable pin low. (The
            // `test-unsafe-keep-outputs-on` build skips this on purpose, so the PIL tests
            // can show that such a firmware fails the safe-state check.)
            let keep_on = cfg!(feature = "test-unsafe-keep-outputs-on");
            if !keep_on {
                LINK_FAULT.store(true, Ordering::Relaxed);
            }
            let _ = run_isr(Irq::Timer1, &VELOCITY_OUT);
            if !keep_on {
                LOOPS.with_app(|app| app.set_enable_request(false));
            }
            // The torque the tick commands (a PMSM: its q current reference).
            let out = if PMSM.load(Ordering::Relaxed) {
                run_isr(Irq::Timer0, &PMSM_OUT).map(|o| o.current_ref.q)
            } else {
                run_isr(Irq::Timer0, &CURRENT_OUT).map(|o| o.current_ref_pu)
            };
            // What the board layer wrote to the PWM (a PMSM: the duties' spread) and the
            // enable pin, not what the controller meant to write.
            let applied = critical_section::with(|cs| APPLIED.borrow(cs).get());
            let outputs = SafeOutputs {
                current_tick_ran: out.is_some(),
                // Unknown when the tick did not run: say so with a value that is never safe.
                torque_cmd_bits: out.map_or(i32::MIN, |t| t.to_bits()),
                pwm_voltage_bits: applied.voltage_bits,
                enable_pin: applied.enabled,
            };
            defmt::warn!(
                "pil: safe state: fault {}, current ref {=i32}, PWM voltage {=i32}, enable pin {=bool}, tick ran {=bool}",
                defmt::Debug2Format(&LOOPS.with_app(|app| app.fault()).flatten()),
                outputs.torque_cmd_bits,
                outputs.pwm_voltage_bits,
                outputs.enable_pin,
                outputs.current_tick_ran
            );
            outputs
        }
    }

    fn send(frame: &Frame) {
        let mut wire = [0_u8; MAX_FRAME];
        if let Ok(n) = frame.encode(&mut wire) {
            Uart0.write_bytes(wire.get(..n).unwrap_or(&[]));
        }
    }

    #[entry]
    fn main() -> ! {
        let Some(mut core) = cortex_m::Peripherals::take() else {
            exit(false)
        };
        core.SYST.set_clock_source(SystClkSource::Core);
        core.SYST.set_reload(SYSCLK_HZ / 1000 * SYSTICK_MS - 1);
        core.SYST.clear_current();
        core.SYST.enable_interrupt();
        core.SYST.enable_counter();
        Uart0.init();
        // The loop timers stay stopped: only the link pends their interrupts.
        enable_interrupts(&mut core.NVIC);
        defmt::info!(
            "pil: stiffdrive firmware {=str}, pil-link protocol {=u8}, waiting for Hello on UART0",
            env!("CARGO_PKG_VERSION"),
            pil_link::PROTOCOL_VERSION
        );

        let mut session = FirmwareSession::new(firmware::version());
        let mut target = PilTarget;
        loop {
            while let Some(byte) = RX.pop() {
                let now = NOW_MS.load(Ordering::Relaxed);
                if let Some(frame) = session.on_byte(byte, now, &mut target) {
                    send(&frame);
                }
                if let SessionState::Stopped { faulted } = session.state() {
                    defmt::info!(
                        "pil: stopped after {=u32} ticks, faulted {=bool}, {=u32} bytes lost",
                        session.ticks_done(),
                        faulted,
                        RX.overflows()
                    );
                    linger(STOP_LINGER_MS);
                    exit(!faulted);
                }
            }
            let now = NOW_MS.load(Ordering::Relaxed);
            if let Some(frame) = session.poll_watchdog(now, &mut target) {
                defmt::warn!("pil: watchdog expired");
                send(&frame);
            }
            if session.abandoned(now) {
                // Nobody drives the link (the harness died): exit, which ends QEMU.
                defmt::warn!(
                    "pil: no harness on the link at {=u32} ms ({}): exiting",
                    now,
                    defmt::Debug2Format(&session.state())
                );
                exit(false);
            }
            // Sleep until the next byte or SysTick; checked with interrupts masked so a byte
            // arriving between the check and WFI still wakes us (WFI wakes on pending).
            cortex_m::interrupt::free(|_| {
                if RX.is_empty() {
                    cortex_m::asm::wfi();
                }
            });
        }
    }
}

#[cfg(not(all(target_os = "none", feature = "board-qemu")))]
fn main() {
    println!(
        "pil: the processor-in-the-loop image runs in QEMU under `hil-harness pil`; \
         build it with cargo build -p firmware --release --target thumbv7em-none-eabihf --bin pil"
    );
}
