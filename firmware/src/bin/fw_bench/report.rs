//! The bench's log: the figures, the per-block table, the image's memory use, and the
//! pass/fail verdict.

use core::sync::atomic::{AtomicU32, Ordering};

use controller_core::Fault;
use firmware::boards::active as board;
use firmware::rt::MemoryUse;

use crate::blocks::{per_block, Block};
use crate::stack::SPAN_BYTES;
use crate::target::{
    BARE_CURRENT_COUNTS, BARE_PROFILE_COUNTS, BARE_VELOCITY_COUNTS, BENCH_NOTCH, CURRENT_MAX,
    CURRENT_OVERHEAD, CURRENT_SAMPLES, CURRENT_STACK, DISTURBED, LOOPS, MEASURED_TICKS,
    PERIOD_BUDGET, PERIOD_CYCLE_BUDGET, PREEMPTIONS, VELOCITY_MAX, VELOCITY_OVERHEAD,
    VELOCITY_SAMPLES, VELOCITY_STACK,
};
use crate::window::{longest, per_call, INSTRUCTIONS_PER_COUNT};

/// What the run measured, gathered as soon as the loops stopped.
pub(crate) struct Results {
    /// Net instructions of the 1,000-NOP calibration block.
    pub(crate) calibration: u32,
    /// Mean current-loop interrupt body [instructions].
    pub(crate) current: u32,
    /// Mean velocity-loop interrupt body [instructions].
    pub(crate) velocity: u32,
    /// One 4 kHz period: current + velocity / 2 [instructions].
    pub(crate) period: u32,
    /// The notched controller's `current_tick` [instructions].
    pub(crate) notched_current: u32,
    /// The period with the notch configured: `period` plus the notched controller's current
    /// tick less the bare one's [instructions].
    pub(crate) period_with_notch: u32,
    /// The drive's latched fault, if any.
    pub(crate) fault: Option<Fault>,
    pub(crate) mem: MemoryUse,
    pub(crate) stack: u32,
}

/// One loop's window sums, as the handlers tally them (`window::tally`).
pub(crate) struct Sums<'a> {
    /// Undisturbed windows.
    pub(crate) samples: &'a AtomicU32,
    /// Their empty windows' counts.
    pub(crate) overhead: &'a AtomicU32,
    /// The longest window's counts.
    pub(crate) max: &'a AtomicU32,
}

/// Log the windows measured (`disturbed`: the velocity windows a current tick preempted),
/// each loop's mean interrupt body [instructions] and its longest window.
pub(crate) fn print_ticks(current: (u32, &Sums), velocity: (u32, &Sums), disturbed: &AtomicU32) {
    defmt::info!(
        "measured: {=u32} current ticks, {=u32} velocity ticks ({=u32} disturbed), averaged",
        current.1.samples.load(Ordering::Relaxed),
        velocity.1.samples.load(Ordering::Relaxed),
        disturbed.load(Ordering::Relaxed)
    );
    defmt::info!("current_tick_instructions: {=u32}", current.0);
    defmt::info!("velocity_tick_instructions: {=u32}", velocity.0);
    defmt::info!(
        "longest single tick: current {=u32}, velocity {=u32} instructions (one window, ±{=u32})",
        longest(current.1.max, current.1.overhead, current.1.samples),
        longest(velocity.1.max, velocity.1.overhead, velocity.1.samples),
        INSTRUCTIONS_PER_COUNT
    );
}

/// Log the figures: method, interrupt bodies, the core's share, the per-block table, and
/// the image's memory use.
pub(crate) fn print(r: &Results) {
    defmt::info!("fw-bench: instruction counts (QEMU -icount shift=0: 1 instruction = 1 ns, SysTick at {=u32} Hz = {=u32} instructions per count); these are instructions, not cycles: the runner's cycle estimate follows the firmware's lines", board::CORE_CLOCK_HZ, INSTRUCTIONS_PER_COUNT);
    defmt::info!(
        "calibration: a block of 1000 NOPs (+ call/return) measures {=u32} instructions",
        r.calibration
    );
    let current = Sums {
        samples: &CURRENT_SAMPLES,
        overhead: &CURRENT_OVERHEAD,
        max: &CURRENT_MAX,
    };
    let velocity = Sums {
        samples: &VELOCITY_SAMPLES,
        overhead: &VELOCITY_OVERHEAD,
        max: &VELOCITY_MAX,
    };
    print_ticks((r.current, &current), (r.velocity, &velocity), &DISTURBED);
    defmt::info!(
        "period_instructions: {=u32} (current + velocity/2; budget {=u32})",
        r.period,
        PERIOD_BUDGET
    );
    defmt::info!(
        "of which controller-core alone: Controller::current_tick {=u32}, Controller::velocity_tick {=u32}, Profile::next {=u32} (the rest is the firmware's board I/O, locking and trend buffer)",
        per_call(&BARE_CURRENT_COUNTS, &CURRENT_OVERHEAD, &CURRENT_SAMPLES),
        per_call(&BARE_VELOCITY_COUNTS, &VELOCITY_OVERHEAD, &VELOCITY_SAMPLES),
        per_call(&BARE_PROFILE_COUNTS, &VELOCITY_OVERHEAD, &VELOCITY_SAMPLES)
    );
    print_blocks(r.current, r.velocity);
    defmt::info!(
        "with a notch configured (centre {=f32} Hz, width {=f32} Hz, depth {=f32} dB; the bare controller plus the notch, fed the same inputs): Controller::current_tick {=u32}",
        BENCH_NOTCH.centre_hz,
        BENCH_NOTCH.width_hz,
        BENCH_NOTCH.depth_db,
        r.notched_current
    );
    defmt::info!(
        "period_with_notch_instructions: {=u32} (period + the notched current tick − the bare one; reported, not gated: the budget of {=u32} is the baked drive's, which has no notch)",
        r.period_with_notch,
        PERIOD_BUDGET
    );
    if r.period_with_notch > PERIOD_BUDGET {
        defmt::warn!(
            "a drive with a notch configured would exceed the {=u32}-instruction budget by {=u32}",
            PERIOD_BUDGET,
            r.period_with_notch - PERIOD_BUDGET
        );
    }
    defmt::info!("flash_bytes: {=u32}", r.mem.flash_bytes);
    defmt::info!("static_ram_bytes: {=u32}", r.mem.static_ram_bytes);
    defmt::info!(
        "stack_high_water_bytes: {=u32} (the whole run: start-up, main loop and interrupts)",
        r.stack
    );
    for (name, mark) in [("current", &CURRENT_STACK), ("velocity", &VELOCITY_STACK)] {
        let (body, above, whole) = mark.get();
        defmt::info!(
            "stack_{=str}_interrupt_bytes: {=u32} (worst tick; painted stack: {=u32} used by the tick's body below the handler's stack pointer, {=u32} above it for the exception frame, the vector and the bench's handler frame)",
            name,
            whole,
            body,
            above
        );
    }
    // Read by the runner (`fw-runner --cycles`), which gates the traced worst period of this
    // group of windows on it.
    defmt::info!("period_velocity_share: {=u32}", 2);
    defmt::info!("period_cycle_budget: {=u32}", PERIOD_CYCLE_BUDGET);
    // The DC drive's target is its budget.
    defmt::info!("period_cycle_target: {=u32}", PERIOD_CYCLE_BUDGET);
}

/// The per-block table: each block of the core timed alone, the rest of each tick, and the
/// firmware glue (the interrupt body minus the core).
fn print_blocks(current: u32, velocity: u32) {
    let bare_current = per_call(&BARE_CURRENT_COUNTS, &CURRENT_OVERHEAD, &CURRENT_SAMPLES);
    let bare_velocity = per_call(&BARE_VELOCITY_COUNTS, &VELOCITY_OVERHEAD, &VELOCITY_SAMPLES);
    let profile_next = per_call(&BARE_PROFILE_COUNTS, &VELOCITY_OVERHEAD, &VELOCITY_SAMPLES);
    let observer_update = per_block(Block::ObserverUpdate, false);
    let afb_closed = per_block(Block::AfbClosed, false);
    let current_pi = per_block(Block::CurrentPi, false);
    let observer_reads = per_block(Block::ObserverReads, true);
    let velocity_pi = per_block(Block::VelocityPi, true);
    defmt::info!("per-block instructions (each block timed alone on the bare controller's signals; a 4 kHz period runs the current-rate rows once and the velocity-rate rows half the time):");
    defmt::info!("block current  observer_update: {=u32}", observer_update);
    defmt::info!(
        "block current  afb_closed_form (incl. its first-order filter and two observer predictions): {=u32}",
        afb_closed
    );
    defmt::info!(
        "block current  first_order_filter (LowPass::process alone, for reference): {=u32}",
        per_block(Block::FirstOrderFilter, false)
    );
    defmt::info!("block current  current_pi: {=u32}", current_pi);
    defmt::info!(
        "block current  notch (Notch::process alone; runs only when a notch is configured): {=u32}",
        per_block(Block::Notch, false)
    );
    defmt::info!(
        "block current  rest_of_current_tick (encoder, observer input, clamps, outputs): {=u32}",
        bare_current.saturating_sub(observer_update + afb_closed + current_pi)
    );
    defmt::info!(
        "block current  glue (board I/O, locking, enable logic, trend buffer): {=u32}",
        current.saturating_sub(bare_current)
    );
    defmt::info!(
        "block velocity observer_outputs (velocity, acceleration, load torque): {=u32}",
        observer_reads
    );
    defmt::info!("block velocity velocity_pi: {=u32}", velocity_pi);
    defmt::info!(
        "block velocity rest_of_velocity_tick (encoder, position loop, faults, filter, outputs): {=u32}",
        bare_velocity.saturating_sub(observer_reads + velocity_pi)
    );
    defmt::info!("block velocity profile: {=u32}", profile_next);
    defmt::info!(
        "block velocity glue (board reads, locking): {=u32}",
        velocity.saturating_sub(bare_velocity + profile_next)
    );
}

/// False if the drive faulted, the measurement was incomplete or disturbed, the current
/// loop did not preempt the velocity loop, or the period is over budget.
pub(crate) fn verdict(r: &Results) -> bool {
    let ok_samples = CURRENT_SAMPLES.load(Ordering::Relaxed) == MEASURED_TICKS
        && VELOCITY_SAMPLES.load(Ordering::Relaxed) >= MEASURED_TICKS / 2 - 1;
    if r.fault.is_some() {
        defmt::error!(
            "FAIL: the drive faulted ({}): the figures would not be the full path",
            defmt::Debug2Format(&r.fault)
        );
        return false;
    }
    if !ok_samples || LOOPS.overruns() != 0 {
        defmt::error!("FAIL: measurement incomplete or disturbed");
        return false;
    }
    let stack_body = CURRENT_STACK.get().0.max(VELOCITY_STACK.get().0);
    if stack_body == 0 || stack_body >= SPAN_BYTES {
        defmt::error!(
            "FAIL: an interrupt's stack mark is {=u32} bytes: outside the painted span of {=u32}",
            stack_body,
            SPAN_BYTES
        );
        return false;
    }
    let preemptions = PREEMPTIONS.load(Ordering::Relaxed);
    defmt::info!(
        "preemption: {=u32} current ticks ran inside one 600 µs velocity interrupt",
        preemptions
    );
    if preemptions < 2 {
        defmt::error!("FAIL: the current loop did not preempt the velocity loop");
        return false;
    }
    if r.period > PERIOD_BUDGET {
        defmt::error!(
            "FAIL: {=u32} instructions per 4 kHz period exceeds the budget of {=u32}",
            r.period,
            PERIOD_BUDGET
        );
        return false;
    }
    defmt::info!("PASS: within budget");
    true
}
