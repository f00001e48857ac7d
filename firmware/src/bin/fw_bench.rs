//! Instruction budget of the control interrupts (`cargo fw-bench`, QEMU with
//! `-icount shift=0,sleep=off`).
//!
//! The real interrupt code paths run from the real timer interrupts (TIMER0 at 4 kHz, TIMER1
//! at 2 kHz, the current loop at the higher priority) through the same `Loops` glue and
//! `App` as the firmware, on synthetic sensor inputs that follow the motion profile. Each
//! handler reads SysTick (core clock) around the tick body. Under `-icount shift=0` QEMU
//! executes one instruction per virtual nanosecond, so one SysTick count at 25 MHz is 40
//! instructions; the windows start at a dithered phase (a varying spin before each one) so
//! the ±1 count quantization averages out over the 2,000 current and 1,000 velocity ticks.
//! The figures are INSTRUCTIONS executed, not cycles (QEMU has no cycle model and no DWT
//! cycle counter), net of the measuring code (calibrated with empty windows).
//!
//! Prints `current_tick_instructions: N`, `velocity_tick_instructions: N`, the budget check,
//! a per-block table (each block of the core timed alone on the bare controller's signals,
//! and the firmware glue as the interrupt body minus the core), the period with a
//! torque-reference notch configured (a third controller, the bare one plus `BENCH_NOTCH`,
//! fed the same inputs: its current tick's difference added to the period), the image's
//! flash and RAM use, and exits 1 if one 4 kHz period (current tick plus half a velocity
//! tick) of the baked drive exceeds `PERIOD_BUDGET` (660) instructions (the period with the
//! notch is reported, with a warning when it is over), if a fault latched in the firmware
//! or the notched controller (the fault path is shorter and would flatter the figures) or
//! if any measurement was disturbed.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
#[path = "fw_bench/blocks.rs"]
mod blocks;
#[cfg(target_os = "none")]
#[path = "fw_bench/pmsm.rs"]
mod pmsm;
#[cfg(target_os = "none")]
#[path = "fw_bench/pmsm_blocks.rs"]
mod pmsm_blocks;
#[cfg(target_os = "none")]
#[path = "fw_bench/report.rs"]
mod report;
#[cfg(target_os = "none")]
#[path = "fw_bench/stack.rs"]
mod stack;
#[cfg(target_os = "none")]
#[path = "fw_bench/window.rs"]
mod window;

#[cfg(target_os = "none")]
mod target {
    use core::sync::atomic::{AtomicBool, AtomicI32, AtomicU32, Ordering};

    use controller_core::{
        Controller, CurrentInputs, DriveConfig, NotchConfig, Profile, ProfileConfig, ProfileKind,
        Pu, Setpoint, VelocityInputs,
    };
    use cortex_m::peripheral::syst::SystClkSource;
    use cortex_m::peripheral::SYST;
    use cortex_m_rt::entry;
    use firmware::app::{App, DEFAULT_TRACE};
    use firmware::board::{CurrentLoopIo, VelocityLoopIo};
    use firmware::boards::active as board;
    use firmware::isr::{Loops, TaskLocal};
    use firmware::rt::{exit, memory_use, paint_stack, stack_high_water_bytes};
    use firmware::synthetic::{SyntheticCurrentIo, SyntheticSensors, SyntheticVelocityIo};

    use crate::blocks::{current_blocks, velocity_blocks};
    use crate::report::{self, Results};
    use crate::stack::{self, StackMark};
    use crate::window::{
        calibrate, cycle_window_arm_current, cycle_window_arm_velocity, cycle_window_preempt,
        dither, elapsed, per_call, tally, timed,
    };

    /// Budget of one 4 kHz period: current tick + half a velocity tick [instructions]: the
    /// 600 measured for the drive before the overcurrent, I²t and stall protections, plus
    /// 10 %, so a regression of that size fails the bench.
    pub(crate) const PERIOD_BUDGET: u32 = 660;
    /// Gate of the traced worst-case period [estimated Cortex-M4 cycles]: the worst current
    /// tick plus half the worst velocity tick, each with exception entry and exit; checked
    /// by the runner (`fw-runner --cycles`). The 1,054 measured for the DC drive plus 10 %,
    /// as the instruction budget's margin.
    pub(crate) const PERIOD_CYCLE_BUDGET: u32 = 1160;
    /// Current ticks before measuring (start-up: estimator priming).
    pub(crate) const WARMUP_TICKS: u32 = 100;
    /// Measured current ticks (and half as many velocity ticks).
    pub(crate) const MEASURED_TICKS: u32 = 2000;

    pub(crate) static LOOPS: Loops<SyntheticCurrentIo, SyntheticVelocityIo, Profile> = Loops::new();
    /// The sensor generator and its own copy of the profile (the motion it follows).
    static SENSORS: TaskLocal<(SyntheticSensors, Profile, Setpoint)> = TaskLocal::new();

    static CURRENT_TICKS: AtomicU32 = AtomicU32::new(0);
    static CURRENT_COUNTS: AtomicU32 = AtomicU32::new(0);
    pub(crate) static CURRENT_SAMPLES: AtomicU32 = AtomicU32::new(0);
    pub(crate) static CURRENT_OVERHEAD: AtomicU32 = AtomicU32::new(0);
    static VELOCITY_TICKS: AtomicU32 = AtomicU32::new(0);
    static VELOCITY_COUNTS: AtomicU32 = AtomicU32::new(0);
    pub(crate) static VELOCITY_SAMPLES: AtomicU32 = AtomicU32::new(0);
    pub(crate) static VELOCITY_OVERHEAD: AtomicU32 = AtomicU32::new(0);
    pub(crate) static DISTURBED: AtomicU32 = AtomicU32::new(0);
    /// Longest single window [SysTick counts].
    pub(crate) static CURRENT_MAX: AtomicU32 = AtomicU32::new(0);
    pub(crate) static VELOCITY_MAX: AtomicU32 = AtomicU32::new(0);
    /// A second, bare controller fed the same inputs: the core's share of the figures.
    static BARE: TaskLocal<(Controller, Profile)> = TaskLocal::new();
    pub(crate) static BARE_CURRENT_COUNTS: AtomicU32 = AtomicU32::new(0);
    pub(crate) static BARE_VELOCITY_COUNTS: AtomicU32 = AtomicU32::new(0);
    pub(crate) static BARE_PROFILE_COUNTS: AtomicU32 = AtomicU32::new(0);
    /// The notch of the third controller: near the shipped machine's engaged resonance (the
    /// instructions of a notch step do not depend on its coefficients).
    pub(crate) const BENCH_NOTCH: NotchConfig = NotchConfig {
        centre_hz: 65.0,
        width_hz: 20.0,
        depth_db: 20.0,
    };
    /// The bare controller with [`BENCH_NOTCH`] configured, fed the same inputs: what a
    /// configured notch adds to the core's ticks.
    pub(crate) static NOTCHED: TaskLocal<Controller> = TaskLocal::new();
    pub(crate) static NOTCHED_CURRENT_COUNTS: AtomicU32 = AtomicU32::new(0);
    /// The commanded acceleration of the last velocity tick (raw Q16.16), for the AFB block.
    static LAST_ACCEL_CMD: AtomicI32 = AtomicI32::new(0);

    /// Velocity tick (after the measurement) that checks the priorities.
    const PREEMPTION_CHECK_TICK: u32 = (WARMUP_TICKS + MEASURED_TICKS) / 2 + 10;
    /// Current ticks that ran inside the stretched velocity interrupt.
    pub(crate) static PREEMPTIONS: AtomicU32 = AtomicU32::new(0);
    /// Stack marks of the current and the velocity interrupt (see `fw_bench/stack.rs`).
    pub(crate) static CURRENT_STACK: StackMark = StackMark::new();
    pub(crate) static VELOCITY_STACK: StackMark = StackMark::new();
    /// The velocity interrupt is running (a current tick then nests in it).
    static IN_VELOCITY: AtomicBool = AtomicBool::new(false);

    /// Check that the current loop preempts the velocity loop: stay in the velocity
    /// interrupt for 600 µs (2.4 current periods, timed on SysTick) and count the current
    /// ticks that ran meanwhile. With the priorities right that is 2 or 3; with them wrong,
    /// 0. Runs once, after the measured ticks.
    fn preemption_check() {
        let before = CURRENT_TICKS.load(Ordering::Relaxed);
        let counts = board::CORE_CLOCK_HZ / 1_000_000 * 600;
        let start = SYST::get_current();
        while elapsed(start, SYST::get_current()) < counts {}
        let ran = CURRENT_TICKS.load(Ordering::Relaxed).wrapping_sub(before);
        PREEMPTIONS.store(ran, Ordering::Relaxed);
    }

    fn measuring(tick: u32) -> bool {
        (WARMUP_TICKS..WARMUP_TICKS + MEASURED_TICKS).contains(&tick)
    }

    fn current_loop() {
        if crate::pmsm::ACTIVE.load(Ordering::Relaxed) {
            crate::pmsm::current_loop();
            return;
        }
        cycle_window_preempt();
        let tick = CURRENT_TICKS.fetch_add(1, Ordering::Relaxed);
        if measuring(tick) {
            let isr = || LOOPS.current_isr();
            let w = timed(
                tick,
                &CURRENT_OVERHEAD,
                cycle_window_arm_current,
                || (),
                isr,
            );
            CURRENT_STACK.record(
                w.sp,
                stack::depth(w.sp),
                IN_VELOCITY.load(Ordering::Relaxed),
            );
            tally(w.counts(), &CURRENT_COUNTS, &CURRENT_MAX, &CURRENT_SAMPLES);
            let mut io = SyntheticCurrentIo;
            let inputs = CurrentInputs {
                encoder_count: io.encoder_count(),
                current_pu: io.current_pu().unwrap_or_default(),
            };
            dither(tick % 13);
            let bare = BARE.with(|(c, _)| {
                let t0 = SYST::get_current();
                let out = core::hint::black_box(c.current_tick(core::hint::black_box(inputs)));
                let t1 = SYST::get_current();
                BARE_CURRENT_COUNTS.fetch_add(elapsed(t0, t1), Ordering::Relaxed);
                out.current_ref_pu.saturating_sub(out.accel_fb_pu)
            });
            dither(tick % 19);
            let _ = NOTCHED.with(|c| {
                let t0 = SYST::get_current();
                let out = core::hint::black_box(c.current_tick(core::hint::black_box(inputs)));
                let t1 = SYST::get_current();
                NOTCHED_CURRENT_COUNTS.fetch_add(elapsed(t0, t1), Ordering::Relaxed);
                out
            });
            let a_cmd = LAST_ACCEL_CMD.load(Ordering::Relaxed);
            current_blocks(
                tick,
                inputs.encoder_count,
                inputs.current_pu,
                Pu::from_bits(a_cmd),
                bare.unwrap_or_default(),
            );
        } else {
            let _ = LOOPS.current_isr();
            let mut io = SyntheticCurrentIo;
            let inputs = CurrentInputs {
                encoder_count: io.encoder_count(),
                current_pu: io.current_pu().unwrap_or_default(),
            };
            let _ = BARE.with(|(c, _)| c.current_tick(inputs));
            let _ = NOTCHED.with(|c| c.current_tick(inputs));
        }
        // Next sensor values: outside the measured window.
        let _ = SENSORS.with(|(sensors, profile, setpoint)| {
            if tick % 2 == 1 {
                *setpoint = profile.next();
            }
            sensors.advance(setpoint);
        });
    }

    fn velocity_loop() {
        if crate::pmsm::ACTIVE.load(Ordering::Relaxed) {
            crate::pmsm::velocity_loop();
            return;
        }
        IN_VELOCITY.store(true, Ordering::Relaxed);
        velocity_loop_body();
        IN_VELOCITY.store(false, Ordering::Relaxed);
    }

    fn velocity_loop_body() {
        let tick = VELOCITY_TICKS.fetch_add(1, Ordering::Relaxed);
        if tick == PREEMPTION_CHECK_TICK {
            preemption_check();
        }
        if measuring(tick * 2) {
            let before = || CURRENT_TICKS.load(Ordering::Relaxed);
            let isr = || LOOPS.velocity_isr();
            let w = timed(
                tick,
                &VELOCITY_OVERHEAD,
                cycle_window_arm_velocity,
                before,
                isr,
            );
            let velocity_depth = stack::depth(w.sp);
            dither(tick % 13);
            let _ = BARE
                .with(|(c, profile)| {
                    let t0 = SYST::get_current();
                    let setpoint = core::hint::black_box(profile.next());
                    let t1 = SYST::get_current();
                    BARE_PROFILE_COUNTS.fetch_add(elapsed(t0, t1), Ordering::Relaxed);
                    let inputs = VelocityInputs {
                        encoder_count: SyntheticVelocityIo.encoder_count(),
                        setpoint,
                        fault_input: false,
                    };
                    let t0 = SYST::get_current();
                    let out = core::hint::black_box(c.velocity_tick(core::hint::black_box(inputs)));
                    let t1 = SYST::get_current();
                    BARE_VELOCITY_COUNTS.fetch_add(elapsed(t0, t1), Ordering::Relaxed);
                    LAST_ACCEL_CMD.store(setpoint.acceleration_pu_s.to_bits(), Ordering::Relaxed);
                    (out, setpoint)
                })
                .map(|(out, setpoint)| {
                    notched_velocity_tick(setpoint);
                    let e = out.velocity_cmd_pu.saturating_sub(out.velocity_est_pu);
                    velocity_blocks(tick, e, setpoint.acceleration_pu_s, out.accel_fb_pu);
                });
            if CURRENT_TICKS.load(Ordering::Relaxed) == w.before {
                VELOCITY_STACK.record(w.sp, velocity_depth, false);
                tally(
                    w.counts(),
                    &VELOCITY_COUNTS,
                    &VELOCITY_MAX,
                    &VELOCITY_SAMPLES,
                );
            } else {
                // Preempted by the current loop: the window holds both ticks.
                DISTURBED.fetch_add(1, Ordering::Relaxed);
            }
        } else {
            let _ = LOOPS.velocity_isr();
            let setpoint = BARE.with(|(c, profile)| {
                let setpoint = profile.next();
                let _ = c.velocity_tick(VelocityInputs {
                    encoder_count: SyntheticVelocityIo.encoder_count(),
                    setpoint,
                    fault_input: false,
                });
                setpoint
            });
            if let Some(setpoint) = setpoint {
                notched_velocity_tick(setpoint);
            }
        }
    }

    /// The notched controller's velocity tick on the bare one's inputs (not timed: the
    /// notch runs in the current tick only).
    fn notched_velocity_tick(setpoint: Setpoint) {
        let _ = NOTCHED.with(|c| {
            c.velocity_tick(VelocityInputs {
                encoder_count: SyntheticVelocityIo.encoder_count(),
                setpoint,
                fault_input: false,
            })
        });
    }

    fn command() {
        let _ = board::read_command();
    }

    firmware::bind_interrupts!(current: current_loop, velocity: velocity_loop, command: command);

    /// The motion the synthetic drive follows: 0.5 pu in 0.25 s, then at speed.
    pub(crate) const MOVE: ProfileConfig = ProfileConfig {
        kind: ProfileKind::Trapezoid,
        peak_velocity_pu: 0.5,
        accel_time_s: 0.25,
        hold_time_s: f32::INFINITY,
        decel_time_s: 0.25,
        start_delay_s: 0.0,
    };

    #[entry]
    fn main() -> ! {
        paint_stack();
        let Some(mut core) = cortex_m::Peripherals::take() else {
            exit(false)
        };
        let Ok(cfg) = firmware::drive::baked() else {
            defmt::error!("baked drive settings do not decode");
            exit(false)
        };
        // The board brings up its console and outputs; the drive I/O here is synthetic.
        let _board = board::init(&mut core, &cfg);
        install(&cfg);
        start_systick(&mut core.SYST);
        let calibration = calibrate();
        board::start(&mut core.NVIC, cfg.current_rate_hz, cfg.velocity_rate_hz);
        stack::note_main_sp();
        while CURRENT_TICKS.load(Ordering::Relaxed) < WARMUP_TICKS + MEASURED_TICKS + 60 {
            cortex_m::asm::wfi();
        }
        board::stop();
        let results = results(calibration);
        report::print(&results);
        let baked = report::verdict(&results);
        // The second drive, the reference PMSM, through the same interrupts.
        let pmsm = crate::pmsm::run(&mut core.NVIC, calibration);
        if baked && pmsm {
            defmt::info!("PASS: both drives within budget");
        }
        exit(baked && pmsm)
    }

    /// The app and its synthetic I/O in the loops, the bare controller and its block bench,
    /// the sensor generator; the drive told to enable. Exits on bad settings.
    fn install(cfg: &DriveConfig) {
        let (app, profile, generator) = match (
            App::new(cfg, cfg.counter_bits, DEFAULT_TRACE),
            Profile::new(&MOVE, cfg),
        ) {
            (Ok(app), Ok(profile)) => (app, profile, profile),
            _ => {
                defmt::error!("bad settings");
                exit(false)
            }
        };
        let notched = DriveConfig {
            notch: Some(BENCH_NOTCH),
            ..*cfg
        };
        match (Controller::new(cfg), Controller::new(&notched)) {
            (Ok(c), Ok(n)) => {
                crate::blocks::install(c.blocks(), n.blocks().notch);
                let _ = BARE.install((c, profile));
                let _ = NOTCHED.install(n);
            }
            _ => exit(false),
        }
        let _ = SENSORS.install((
            SyntheticSensors::new(cfg.counter_bits),
            generator,
            Setpoint::default(),
        ));
        LOOPS.install(app, SyntheticCurrentIo, SyntheticVelocityIo, profile);
        LOOPS.with_app(|app| app.set_enable_request(true));
    }

    /// SysTick free-running on the core clock over its full 24 bits.
    fn start_systick(syst: &mut SYST) {
        syst.set_clock_source(SystClkSource::Core);
        syst.set_reload(0x00FF_FFFF);
        syst.clear_current();
        syst.enable_counter();
    }

    /// The figures of the stopped run (before anything else uses the stack).
    fn results(calibration: u32) -> Results {
        let current = per_call(&CURRENT_COUNTS, &CURRENT_OVERHEAD, &CURRENT_SAMPLES);
        let velocity = per_call(&VELOCITY_COUNTS, &VELOCITY_OVERHEAD, &VELOCITY_SAMPLES);
        let period = current + velocity / 2;
        let bare_current = per_call(&BARE_CURRENT_COUNTS, &CURRENT_OVERHEAD, &CURRENT_SAMPLES);
        let notched_current =
            per_call(&NOTCHED_CURRENT_COUNTS, &CURRENT_OVERHEAD, &CURRENT_SAMPLES);
        let period_with_notch = (period + notched_current).saturating_sub(bare_current);
        let fault = LOOPS
            .with_app(|app| app.fault())
            .flatten()
            .or(NOTCHED.with(|c| c.fault()).flatten());
        let mem = memory_use();
        let stack = stack_high_water_bytes();
        Results {
            calibration,
            current,
            velocity,
            period,
            notched_current,
            period_with_notch,
            fault,
            mem,
            stack,
        }
    }
}

#[cfg(not(target_os = "none"))]
fn main() {
    println!("fw-bench: runs in QEMU: cargo fw-bench");
}
