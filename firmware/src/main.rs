//! stiffdrive firmware: controller-core in a 4 kHz current-loop interrupt and a 2 kHz
//! velocity-loop interrupt, driven by hardware timers, the current loop at the higher
//! priority.
//!
//! On the STM32F4 board (`board-stm32f4`) this is the board console image
//! (`firmware::board_console`): it starts disabled, holding position, and serves
//! `stiffdrive board --port` on USART2 until reset. On the three-phase board
//! (`board-stm32f4-3ph`) it is the PMSM drive of `firmware::pmsm_image`.
//!
//! Under QEMU (`cargo fw-run`) it is the demo run: the drive enables itself, runs the
//! Table 1 controller on the virtual motor for a 1 s move, asks for a dump of the trend
//! buffer (written to the UART as CSV once it froze), checks the loops ran at their rates
//! without a fault, and exits 0 (1 on any failure, panic or HardFault). On the host this
//! binary is an empty `main` (so `cargo test` and `cargo clippy --workspace` work without
//! the ARM target).
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(all(
    target_os = "none",
    feature = "board-stm32f4",
    not(feature = "board-stm32f4-3ph")
))]
mod stm32 {
    use cortex_m_rt::entry;
    use firmware::board_console::{current_loop, run, uart_rx, velocity_loop};
    use firmware::boards::stm32f4::BoardConsole;

    firmware::bind_interrupts!(current: current_loop, velocity: velocity_loop, command: uart_rx);

    #[entry]
    fn main() -> ! {
        run(BoardConsole)
    }
}

/// The three-phase board (`board-stm32f4-3ph`): the PMSM drive, its current loop on ADC1's
/// end of conversion (`firmware::pmsm_image`).
#[cfg(all(target_os = "none", feature = "board-stm32f4-3ph"))]
mod stm32_3ph {
    use cortex_m_rt::entry;
    use firmware::pmsm_image::{command, current_loop, run, velocity_loop};

    firmware::bind_three_phase_interrupts!(
        current: current_loop,
        velocity: velocity_loop,
        command: command
    );

    #[entry]
    fn main() -> ! {
        run()
    }
}

#[cfg(all(target_os = "none", not(feature = "board-stm32f4")))]
mod target {
    use core::fmt::Write;
    use core::sync::atomic::{AtomicBool, Ordering};

    use controller_core::per_unit::count_signed;
    use controller_core::{Counts, DriveConfig, Profile, ProfileConfig, ProfileKind, Pu, Setpoint};
    use cortex_m_rt::entry;
    use firmware::app::{App, SetpointSource, DEFAULT_TRACE};
    use firmware::board::EncoderCounter;
    use firmware::boards::active as board;
    use firmware::isr::Loops;
    use firmware::rt::exit;
    use firmware::trace::{TraceSample, TraceState};

    use board::inverter::VirtualInverter;

    static LOOPS: Loops<board::CurrentIoImpl, board::VelocityIoImpl, GatedMove> = Loops::new();
    /// The loops of a PMSM drive (the baked file's `[drive.pmsm]`): its current tick on the
    /// virtual three-phase stage.
    static PMSM_LOOPS: Loops<VirtualInverter, board::VelocityIoImpl, GatedMove> = Loops::new();
    /// Set once a PMSM drive is installed in [`PMSM_LOOPS`] (before the timers start).
    static PMSM: AtomicBool = AtomicBool::new(false);
    static DUMP_REQUESTED: AtomicBool = AtomicBool::new(false);
    /// The move runs while set (by `e`); otherwise the setpoint holds where it is.
    static MOVE_GO: AtomicBool = AtomicBool::new(false);

    /// The profile, advanced only while the drive is told to move: a drive enabled later
    /// starts its move then, from where the shaft is, instead of chasing a setpoint that
    /// ran ahead or jumping back to where it was at power-up.
    struct GatedMove {
        /// The move from position 0, as built.
        base: Profile,
        /// The move in progress (`base` shifted to the start position).
        profile: Profile,
        hold: Setpoint,
        moving: bool,
        counter_bits: u8,
    }

    impl SetpointSource for GatedMove {
        fn next_setpoint(&mut self) -> Setpoint {
            let go = MOVE_GO.load(Ordering::Relaxed);
            if go && !self.moving {
                // Start from the present position, in the frame the core uses after its
                // reset at enable: the raw counter read as signed.
                let raw = board::encoder().count();
                let start = count_signed(raw, self.counter_bits);
                self.profile = self.base.with_start_position(Counts::from_num(start));
            }
            if !go && self.moving {
                // Disabled: hold where the move had got to.
                self.hold.velocity_pu = Pu::ZERO;
                self.hold.acceleration_pu_s = Pu::ZERO;
            }
            self.moving = go;
            if go {
                self.hold = self.profile.next();
            }
            self.hold
        }
    }

    fn current_loop() {
        if PMSM.load(Ordering::Relaxed) {
            let _ = PMSM_LOOPS.pmsm_isr();
        } else {
            let _ = LOOPS.current_isr();
        }
    }

    fn velocity_loop() {
        if PMSM.load(Ordering::Relaxed) {
            let _ = PMSM_LOOPS.velocity_isr();
        } else {
            let _ = LOOPS.velocity_isr();
        }
    }

    /// Run `f` on the installed drive's app (thread mode, the UART command).
    fn with_app<R>(f: impl FnOnce(&mut App) -> R) -> Option<R> {
        if PMSM.load(Ordering::Relaxed) {
            PMSM_LOOPS.with_app(f)
        } else {
            LOOPS.with_app(f)
        }
    }

    fn command() {
        match board::read_command() {
            Some(b'd') => DUMP_REQUESTED.store(true, Ordering::Relaxed),
            Some(b'e') => enable(true),
            Some(b'x') => enable(false),
            Some(b'r') => {
                with_app(|app| app.reset());
            }
            _ => {}
        }
    }

    fn enable(on: bool) {
        with_app(|app| app.set_enable_request(on));
        MOVE_GO.store(on, Ordering::Relaxed);
    }

    firmware::bind_interrupts!(current: current_loop, velocity: velocity_loop, command: command);

    /// The demo move: 0.5 pu in 0.4 s (1.2 pu of torque on J_total = 0.98 s, inside the
    /// 2 pu limit), 0.2 s at speed, back to rest in 0.4 s.
    const MOVE: ProfileConfig = ProfileConfig {
        kind: ProfileKind::Trapezoid,
        peak_velocity_pu: 0.5,
        accel_time_s: 0.4,
        hold_time_s: 0.2,
        decel_time_s: 0.4,
        start_delay_s: 0.01,
    };
    /// QEMU run length [current ticks]: 1.2 s at 4 kHz.
    const RUN_TICKS: u32 = 4800;
    /// How close to the move's end position the virtual motor must stop, as a fraction of a
    /// revolution (1/512 rev = 0.70°: 8 counts of Table 1's 4096), so that a drive with a finer
    /// encoder is held to the same angle.
    const END_TOLERANCE_PER_REV: u32 = 512;
    /// Tick at which the QEMU run asks for a dump itself (0.5 s, at speed).
    const SELF_DUMP_TICK: u32 = 2000;

    #[entry]
    fn main() -> ! {
        let Some(mut core) = cortex_m::Peripherals::take() else {
            exit(false)
        };
        let cfg = baked_settings();
        let b = board::init(&mut core, &cfg);
        defmt::info!(
            "stiffdrive firmware {=str} on {=str}: current loop {=u32} Hz, velocity loop {=u32} Hz",
            env!("CARGO_PKG_VERSION"),
            board::NAME,
            cfg.current_rate_hz,
            cfg.velocity_rate_hz
        );
        defmt::info!("drive: {=str}", firmware::drive::NAME);
        let (app, motion) = app_and_motion(&cfg);
        let mem = firmware::rt::memory_use();
        defmt::info!(
            "image: {=u32} bytes of flash, {=u32} bytes of static RAM",
            mem.flash_bytes,
            mem.static_ram_bytes
        );
        if cfg.pmsm.is_some() {
            // The baked file's PMSM behind the virtual three-phase stage.
            let Some(stage) = board::inverter::virtual_pmsm_config(&cfg) else {
                defmt::error!(
                    "the drive has [drive.pmsm] but the baked machine file's motor is not a \
                     PMSM (electrics.motor)"
                );
                exit(false)
            };
            PMSM_LOOPS.install(app, VirtualInverter::new(stage), b.velocity_io, motion);
            PMSM.store(true, Ordering::Relaxed);
            defmt::info!("PMSM drive on the virtual three-phase stage");
        } else {
            LOOPS.install(app, b.current_io, b.velocity_io, motion);
        }
        let console = b.console;
        // The demo enables at once.
        enable(true);
        board::start(&mut core.NVIC, cfg.current_rate_hz, cfg.velocity_rate_hz);
        run(console)
    }

    /// The drive baked at build time (`firmware::drive`); an image whose settings do not decode
    /// stays in its safe state (outputs never enabled) and reports it.
    fn baked_settings() -> DriveConfig {
        match firmware::drive::baked() {
            Ok(cfg) => cfg,
            Err(e) => {
                defmt::error!("baked drive settings: {}", defmt::Debug2Format(&e));
                exit(false)
            }
        }
    }

    /// The app for `cfg` and the gated demo move; exits on bad settings.
    fn app_and_motion(cfg: &DriveConfig) -> (App, GatedMove) {
        let bits = board::Encoder::COUNTER_BITS;
        let app = if cfg.pmsm.is_some() {
            App::new_pmsm(cfg, bits, DEFAULT_TRACE)
        } else {
            App::new(cfg, bits, DEFAULT_TRACE)
        };
        let app = match app {
            Ok(app) => app,
            Err(e) => {
                defmt::error!("bad settings: {}", defmt::Debug2Format(&e));
                exit(false)
            }
        };
        let profile = match Profile::new(&MOVE, cfg) {
            Ok(p) => p,
            Err(e) => {
                defmt::error!("bad profile: {}", defmt::Display2Format(&e));
                exit(false)
            }
        };
        let motion = GatedMove {
            base: profile,
            profile,
            hold: Setpoint::default(),
            moving: false,
            counter_bits: cfg.counter_bits,
        };
        (app, motion)
    }

    /// Thread mode with the loops running: serve dump requests (and, under QEMU, ask for
    /// one dump itself and finish the run after `RUN_TICKS`).
    fn run(mut console: board::Console) -> ! {
        let mut dumps = 0_u32;
        let mut self_dump_asked = false;
        let (mut fault_logged, mut warning_logged) = (false, false);
        loop {
            cortex_m::asm::wfi();
            let ticks = with_app(|app| app.ticks()).unwrap_or(0);
            // When and why the drive tripped, once per latch; the I²t warning once per rise.
            match with_app(|app| app.fault_record()).flatten() {
                Some((fault, tick)) if !fault_logged => {
                    fault_logged = true;
                    defmt::error!(
                        "fault latched: {=str} (code {=u8}) at current tick {=u32}",
                        fault.name(),
                        fault.code(),
                        tick
                    );
                }
                Some(_) => {}
                None => fault_logged = false,
            }
            let warm = with_app(|app| app.thermal_warning()).unwrap_or(false);
            if warm && !warning_logged {
                defmt::warn!(
                    "I2t warning: winding at its thermal warning level, tick {=u32}",
                    ticks
                );
            }
            warning_logged = warm;
            if ticks >= SELF_DUMP_TICK && !self_dump_asked {
                self_dump_asked = true;
                DUMP_REQUESTED.store(true, Ordering::Relaxed);
            }
            if DUMP_REQUESTED.swap(false, Ordering::Relaxed) {
                defmt::info!("dump requested at tick {=u32}", ticks);
                with_app(|app| app.request_dump());
            }
            if let Some(n) = dump(&mut console) {
                dumps += 1;
                defmt::info!(
                    "trace dump {=u32}: {=usize} samples on the console",
                    dumps,
                    n
                );
            }
            if ticks >= RUN_TICKS {
                board::stop();
                finish(dumps);
            }
        }
    }

    /// Write a frozen trend buffer to the console as CSV; `None` if none is frozen.
    fn dump(console: &mut board::Console) -> Option<usize> {
        let channels = with_app(|app| app.trace().config().channels)?;
        let mut count = 0;
        let sink = |index: usize, sample: &TraceSample| {
            if index == 0 {
                let _ = write!(console, "tick");
                for c in channels {
                    let _ = write!(console, ",{}", c.name());
                }
                let _ = writeln!(console);
            }
            let _ = write!(console, "{}", sample.tick);
            for v in sample.values {
                let _ = write!(console, ",{v}");
            }
            let _ = writeln!(console);
            count = index + 1;
        };
        let state = if PMSM.load(Ordering::Relaxed) {
            PMSM_LOOPS.dump_trace(sink)
        } else {
            LOOPS.dump_trace(sink)
        }?;
        if let TraceState::Frozen {
            cause,
            trigger_tick,
        } = state
        {
            let _ = writeln!(
                console,
                "# end of trace: {count} samples, trigger {cause:?} at tick {trigger_tick}, \
                 per-unit columns are Q16.16 bits"
            );
        }
        Some(count)
    }

    /// QEMU: check the run and exit with its status.
    fn finish(dumps: u32) -> ! {
        let status = with_app(|app| (app.ticks(), app.fault()));
        let Some((ticks, fault)) = status else {
            exit(false)
        };
        let overruns = if PMSM.load(Ordering::Relaxed) {
            PMSM_LOOPS.overruns()
        } else {
            LOOPS.overruns()
        };
        // The move's end position: 0.5 pu for (0.4/2 + 0.2 + 0.4/2) s at the baked drive's
        // counts per pu·s. The motor must have got there and stopped.
        let Ok(cfg) = firmware::drive::baked() else {
            exit(false)
        };
        let cpps = controller_core::per_unit::counts_per_pu_s(cfg.encoder_cpr, cfg.base_speed_rpm);
        let end_counts = (0.5 * 0.6 * cpps) as i32;
        let final_error = board::motor_counts() as i32 - end_counts;
        defmt::info!(
            "run done: {=u32} current ticks, {=u32} velocity overruns, {=u32} dumps, fault {}, \
             motor at {=i32} counts of {=i32} ({=i32} off)",
            ticks,
            overruns,
            dumps,
            defmt::Debug2Format(&fault),
            board::motor_counts() as i32,
            end_counts,
            final_error
        );
        exit(
            fault.is_none()
                && overruns == 0
                && dumps >= 1
                && ticks >= RUN_TICKS
                && final_error.unsigned_abs() <= (cfg.encoder_cpr / END_TOLERANCE_PER_REV).max(1),
        )
    }
}

#[cfg(not(target_os = "none"))]
fn main() {
    println!(
        "firmware: build for thumbv7em-none-eabihf (cargo fw-build); nothing to run on the host"
    );
}
