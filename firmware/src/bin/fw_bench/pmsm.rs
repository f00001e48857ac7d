//! The bench's second drive: the reference PMSM (`configs/machines/table1-pmsm.toml`,
//! `firmware::drive::reference_pmsm`), run after the baked drive in the same image through
//! the same timer interrupts, `Loops` glue and `App` (its current interrupt
//! `Loops::pmsm_isr`), on synthetic sensors: the encoder follows the motion profile, the
//! two phase currents are the drive's last q-current reference at its own electrical angle
//! (`SyntheticSensors::advance_pmsm`). The windows, the dither and the stack marks are the
//! DC drive's; the runner's cycle trace starts a new group at `cycle_window_next_group`.
//!
//! Targets, reported as met or missed: one period at the drive's rates (current +
//! velocity/ratio) within [`PERIOD_TARGET`] instructions (1.4 × the DC drive's 650), and
//! the worst period of a 20 kHz current loop (current interrupt + a tenth of the 2 kHz
//! velocity interrupt, [`VELOCITY_SHARE`]) within [`PERIOD_CYCLE_TARGET`] cycles (15 % of a
//! 168 MHz Cortex-M4). The PMSM tick misses both today (docs/benchmarks.md says where its
//! instructions go), so the gates are regression budgets over today's figures, as the DC
//! drive's are: [`PERIOD_BUDGET`] instructions here, and [`PERIOD_CYCLE_BUDGET`] cycles,
//! which the runner checks.

use core::sync::atomic::{AtomicBool, AtomicI32, AtomicU32, Ordering};

use controller_core::foc::AngleCoefficients;
use controller_core::{Controller, DriveConfig, PmsmInputs, Profile, Pu, Setpoint, VelocityInputs};
use cortex_m::peripheral::{NVIC, SYST};
use firmware::app::{App, DEFAULT_TRACE};
use firmware::board::three_phase::PmsmLoopIo;
use firmware::board::VelocityLoopIo;
use firmware::boards::active as board;
use firmware::isr::{Loops, TaskLocal};
use firmware::rt::exit;
use firmware::synthetic::{SyntheticPmsmIo, SyntheticSensors, SyntheticVelocityIo};

use crate::pmsm_blocks::{self as blocks, BLOCKS};
use crate::report::{print_ticks, Sums};
use crate::stack::{self, StackMark, SPAN_BYTES};
use crate::target::{MEASURED_TICKS, MOVE, WARMUP_TICKS};
use crate::window::{
    cycle_window_arm_current, cycle_window_arm_velocity, cycle_window_next_group,
    cycle_window_preempt, dither, elapsed, per_call, tally, timed,
};

/// Target of one period at the drive's rates [instructions]: 1.4 × the DC drive's 650.
/// Reported, not gated.
const PERIOD_TARGET: u32 = 910;
/// Target of the traced worst period of a 20 kHz current loop [estimated cycles]: 15 % of
/// a 168 MHz Cortex-M4's 8,400 cycles per period. Reported by the runner, not gated.
const PERIOD_CYCLE_TARGET: u32 = 1260;
/// Gate of one period at the drive's rates [instructions]: today's figure and about 1.5 %,
/// as the DC drive's 660 over its 650.
const PERIOD_BUDGET: u32 = 1400;
/// Gate of the traced worst period of a 20 kHz current loop [estimated cycles]: today's
/// worst and about 5 %. Checked by the runner.
const PERIOD_CYCLE_BUDGET: u32 = 1720;
/// Current ticks per velocity tick of that period: 20 kHz / 2 kHz.
const VELOCITY_SHARE: u32 = 10;

static LOOPS: Loops<SyntheticPmsmIo, SyntheticVelocityIo, Profile> = Loops::new();
/// The sensor generator, its profile and setpoint, the drive's angle, the last i_q*.
static SENSORS: TaskLocal<(SyntheticSensors, Profile, Setpoint, AngleCoefficients)> =
    TaskLocal::new();
/// The last q-current reference the app's tick set (raw Q16.16).
static IQ_REF: AtomicI32 = AtomicI32::new(0);
/// A bare controller fed the same inputs: the core's share.
static BARE: TaskLocal<(Controller, Profile)> = TaskLocal::new();
/// The PMSM phase is running (the handlers dispatch on it).
pub(crate) static ACTIVE: AtomicBool = AtomicBool::new(false);
/// Current ticks per velocity tick of the drive.
static RATIO: AtomicU32 = AtomicU32::new(2);

static CURRENT_TICKS: AtomicU32 = AtomicU32::new(0);
static CURRENT_COUNTS: AtomicU32 = AtomicU32::new(0);
static CURRENT_SAMPLES: AtomicU32 = AtomicU32::new(0);
static CURRENT_OVERHEAD: AtomicU32 = AtomicU32::new(0);
static CURRENT_MAX: AtomicU32 = AtomicU32::new(0);
static VELOCITY_TICKS: AtomicU32 = AtomicU32::new(0);
static VELOCITY_COUNTS: AtomicU32 = AtomicU32::new(0);
static VELOCITY_SAMPLES: AtomicU32 = AtomicU32::new(0);
static VELOCITY_OVERHEAD: AtomicU32 = AtomicU32::new(0);
static VELOCITY_MAX: AtomicU32 = AtomicU32::new(0);
static DISTURBED: AtomicU32 = AtomicU32::new(0);
static BARE_CURRENT_COUNTS: AtomicU32 = AtomicU32::new(0);
static BARE_VELOCITY_COUNTS: AtomicU32 = AtomicU32::new(0);
static BARE_PROFILE_COUNTS: AtomicU32 = AtomicU32::new(0);
static CURRENT_STACK: StackMark = StackMark::new();
static VELOCITY_STACK: StackMark = StackMark::new();
static IN_VELOCITY: AtomicBool = AtomicBool::new(false);

fn measuring(tick: u32) -> bool {
    (WARMUP_TICKS..WARMUP_TICKS + MEASURED_TICKS).contains(&tick)
}

/// The bare controller's inputs of this tick: what the app's tick read.
fn inputs() -> PmsmInputs {
    let mut io = SyntheticPmsmIo;
    PmsmInputs {
        encoder_count: io.encoder_count(),
        phase_current_pu: io.phase_currents_pu().unwrap_or_default(),
    }
}

/// The current-loop handler's body in the PMSM phase (out of line: the DC phase's
/// handler frame, part of its stack figure, stays its own).
#[inline(never)]
pub(crate) fn current_loop() {
    cycle_window_preempt();
    let tick = CURRENT_TICKS.fetch_add(1, Ordering::Relaxed);
    let out = if measuring(tick) {
        let isr = || LOOPS.pmsm_isr();
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
        let out = w.out;
        let inputs = inputs();
        dither(tick % 13);
        let bare = BARE.with(|(c, _)| {
            let t0 = SYST::get_current();
            let o = core::hint::black_box(c.pmsm_tick(core::hint::black_box(inputs)));
            let t1 = SYST::get_current();
            BARE_CURRENT_COUNTS.fetch_add(elapsed(t0, t1), Ordering::Relaxed);
            o
        });
        let speed = SENSORS
            .with(|(_, _, setpoint, _)| setpoint.velocity_pu)
            .unwrap_or_default();
        if let Some(o) = bare {
            blocks::current_blocks(tick, inputs, &o, speed);
        }
        out
    } else {
        let out = LOOPS.pmsm_isr();
        let inputs = inputs();
        let _ = BARE.with(|(c, _)| c.pmsm_tick(inputs));
        out
    };
    if let Some(o) = out {
        IQ_REF.store(o.current_ref.q.to_bits(), Ordering::Relaxed);
    }
    // Next sensor values: outside the measured window.
    let ratio = RATIO.load(Ordering::Relaxed).max(1);
    let i_q = Pu::from_bits(IQ_REF.load(Ordering::Relaxed));
    let _ = SENSORS.with(|(sensors, profile, setpoint, angle)| {
        if tick % ratio == ratio - 1 {
            *setpoint = profile.next();
        }
        sensors.advance_pmsm(setpoint, angle, i_q);
    });
}

/// The velocity-loop handler's body in the PMSM phase (out of line, as `current_loop`).
#[inline(never)]
pub(crate) fn velocity_loop() {
    IN_VELOCITY.store(true, Ordering::Relaxed);
    velocity_body();
    IN_VELOCITY.store(false, Ordering::Relaxed);
}

fn bare_velocity_tick(timed: bool) {
    let _ = BARE.with(|(c, profile)| {
        let t0 = SYST::get_current();
        let setpoint = core::hint::black_box(profile.next());
        let t1 = SYST::get_current();
        let inputs = VelocityInputs {
            encoder_count: SyntheticVelocityIo.encoder_count(),
            setpoint,
            fault_input: false,
        };
        let t2 = SYST::get_current();
        let _ = core::hint::black_box(c.velocity_tick(core::hint::black_box(inputs)));
        let t3 = SYST::get_current();
        if timed {
            BARE_PROFILE_COUNTS.fetch_add(elapsed(t0, t1), Ordering::Relaxed);
            BARE_VELOCITY_COUNTS.fetch_add(elapsed(t2, t3), Ordering::Relaxed);
        }
    });
}

fn velocity_body() {
    let tick = VELOCITY_TICKS.fetch_add(1, Ordering::Relaxed);
    let ratio = RATIO.load(Ordering::Relaxed).max(1);
    if !measuring(tick * ratio) {
        let _ = LOOPS.velocity_isr();
        bare_velocity_tick(false);
        return;
    }
    let before = || CURRENT_TICKS.load(Ordering::Relaxed);
    let isr = || LOOPS.velocity_isr();
    let w = timed(
        tick,
        &VELOCITY_OVERHEAD,
        cycle_window_arm_velocity,
        before,
        isr,
    );
    let depth = stack::depth(w.sp);
    dither(tick % 13);
    bare_velocity_tick(true);
    if CURRENT_TICKS.load(Ordering::Relaxed) == w.before {
        VELOCITY_STACK.record(w.sp, depth, false);
        tally(
            w.counts(),
            &VELOCITY_COUNTS,
            &VELOCITY_MAX,
            &VELOCITY_SAMPLES,
        );
    } else {
        DISTURBED.fetch_add(1, Ordering::Relaxed);
    }
}

/// Install the PMSM drive's app, bare controller and sensor generator; false on bad
/// settings.
fn install(cfg: &DriveConfig) -> bool {
    let (Ok(app), Ok(profile), Ok(bare)) = (
        App::new_pmsm(cfg, cfg.counter_bits, DEFAULT_TRACE),
        Profile::new(&MOVE, cfg),
        Controller::new(cfg),
    ) else {
        return false;
    };
    let Some(foc) = bare.foc().copied() else {
        return false;
    };
    let angle = foc.angle;
    RATIO.store(firmware::lil::words::tick_ratio(cfg), Ordering::Relaxed);
    let _ = BARE.install((bare, profile));
    // The first tick's values (the sensors still hold the first drive's last ones).
    let mut sensors = SyntheticSensors::new(cfg.counter_bits);
    sensors.advance_pmsm(&Setpoint::default(), &angle, Pu::ZERO);
    blocks::install(foc, SyntheticVelocityIo.encoder_count());
    let _ = SENSORS.install((sensors, profile, Setpoint::default(), angle));
    LOOPS.install(app, SyntheticPmsmIo, SyntheticVelocityIo, profile);
    LOOPS.with_app(|app| app.set_enable_request(true));
    true
}

/// Run the PMSM phase on the running SysTick, print its figures; whether it passed.
pub(crate) fn run(nvic: &mut NVIC, calibration: u32) -> bool {
    let Ok(cfg) = firmware::drive::reference_pmsm() else {
        defmt::error!("FAIL: the reference PMSM drive's settings do not decode");
        exit(false)
    };
    if !install(&cfg) {
        defmt::error!("FAIL: the reference PMSM drive's settings are refused");
        return false;
    }
    cycle_window_next_group();
    ACTIVE.store(true, Ordering::Relaxed);
    board::start(nvic, cfg.current_rate_hz, cfg.velocity_rate_hz);
    while CURRENT_TICKS.load(Ordering::Relaxed) < WARMUP_TICKS + MEASURED_TICKS + 60 {
        cortex_m::asm::wfi();
    }
    board::stop();
    ACTIVE.store(false, Ordering::Relaxed);
    report(&cfg, calibration)
}

/// The PMSM phase's lines and verdict.
fn report(cfg: &DriveConfig, calibration: u32) -> bool {
    let ratio = RATIO.load(Ordering::Relaxed).max(1);
    let current = per_call(&CURRENT_COUNTS, &CURRENT_OVERHEAD, &CURRENT_SAMPLES);
    let velocity = per_call(&VELOCITY_COUNTS, &VELOCITY_OVERHEAD, &VELOCITY_SAMPLES);
    let period = current + velocity / ratio;
    defmt::info!(
        "fw-bench, second drive: the reference PMSM ({=str}: current loop {=u32} Hz, velocity loop {=u32} Hz; FOC current tick App::on_pmsm_tick) on synthetic phase currents at the drive's angle; calibration {=u32}",
        "configs/machines/table1-pmsm.toml",
        cfg.current_rate_hz,
        cfg.velocity_rate_hz,
        calibration
    );
    let current_sums = Sums {
        samples: &CURRENT_SAMPLES,
        overhead: &CURRENT_OVERHEAD,
        max: &CURRENT_MAX,
    };
    let velocity_sums = Sums {
        samples: &VELOCITY_SAMPLES,
        overhead: &VELOCITY_OVERHEAD,
        max: &VELOCITY_MAX,
    };
    print_ticks(
        (current, &current_sums),
        (velocity, &velocity_sums),
        &DISTURBED,
    );
    defmt::info!(
        "pmsm_period_instructions: {=u32} (current + velocity/{=u32} at the drive's rates; target {=u32} = 1.4 × the DC drive's 650: {=str}; regression budget {=u32})",
        period,
        ratio,
        PERIOD_TARGET,
        if period <= PERIOD_TARGET { "met" } else { "MISSED" },
        PERIOD_BUDGET
    );
    defmt::info!(
        "pmsm_period_20khz_instructions: {=u32} (a 20 kHz current loop: current + velocity/{=u32})",
        current + velocity / VELOCITY_SHARE,
        VELOCITY_SHARE
    );
    defmt::info!(
        "of which controller-core alone: Controller::pmsm_tick {=u32}, Controller::velocity_tick {=u32}, Profile::next {=u32}",
        per_call(&BARE_CURRENT_COUNTS, &CURRENT_OVERHEAD, &CURRENT_SAMPLES),
        per_call(&BARE_VELOCITY_COUNTS, &VELOCITY_OVERHEAD, &VELOCITY_SAMPLES),
        per_call(&BARE_PROFILE_COUNTS, &VELOCITY_OVERHEAD, &VELOCITY_SAMPLES)
    );
    defmt::info!("per-block instructions of Controller::pmsm_tick (each step timed alone on the bare controller's signals):");
    for (b, name) in BLOCKS {
        defmt::info!(
            "pmsm block {=str}: {=u32}",
            name,
            blocks::per_block(b, &CURRENT_OVERHEAD, &CURRENT_SAMPLES)
        );
    }
    for (name, mark) in [("current", &CURRENT_STACK), ("velocity", &VELOCITY_STACK)] {
        let (body, above, whole) = mark.get();
        defmt::info!(
            "stack_{=str}_interrupt_bytes: {=u32} (worst tick; painted stack: {=u32} used by the tick's body below the handler's stack pointer, {=u32} above it)",
            name,
            whole,
            body,
            above
        );
    }
    // Read by the runner for this group of windows.
    defmt::info!("period_velocity_share: {=u32}", VELOCITY_SHARE);
    defmt::info!("period_cycle_budget: {=u32}", PERIOD_CYCLE_BUDGET);
    defmt::info!("period_cycle_target: {=u32}", PERIOD_CYCLE_TARGET);
    verdict(period)
}

fn verdict(period: u32) -> bool {
    let fault = LOOPS.with_app(|app| app.fault()).flatten();
    let ratio = RATIO.load(Ordering::Relaxed).max(1);
    let complete = CURRENT_SAMPLES.load(Ordering::Relaxed) == MEASURED_TICKS
        && VELOCITY_SAMPLES.load(Ordering::Relaxed) >= MEASURED_TICKS / ratio - 1
        && LOOPS.overruns() == 0;
    let body = CURRENT_STACK.get().0.max(VELOCITY_STACK.get().0);
    if fault.is_some() {
        defmt::error!(
            "FAIL: the PMSM drive faulted ({}): the figures would not be the full path",
            defmt::Debug2Format(&fault)
        );
        false
    } else if !complete {
        defmt::error!("FAIL: PMSM measurement incomplete or disturbed");
        false
    } else if body == 0 || body >= SPAN_BYTES {
        defmt::error!("FAIL: a PMSM interrupt's stack mark is outside the painted span");
        false
    } else if period > PERIOD_BUDGET {
        defmt::error!(
            "FAIL: {=u32} instructions per PMSM period exceeds the regression budget of {=u32}",
            period,
            PERIOD_BUDGET
        );
        false
    } else {
        defmt::info!("PASS: the PMSM drive within budget");
        true
    }
}
