//! The measuring window: SysTick readings around a body at a dithered phase, the
//! calibration on known code, and the conversion of summed counts into instructions.

use core::sync::atomic::{AtomicU32, Ordering};

use cortex_m::peripheral::SYST;
use firmware::boards::active as board;

use crate::stack;

/// Instructions per SysTick count: 1 instruction = 1 ns (icount shift=0), 25 MHz clock.
pub(crate) const INSTRUCTIONS_PER_COUNT: u32 = 1_000_000_000 / board::CORE_CLOCK_HZ;

/// Spin `n` short iterations: shifts the window's phase against the SysTick edges.
#[inline(never)]
pub(crate) fn dither(n: u32) {
    for i in 0..n {
        core::hint::black_box(i);
    }
}

/// SysTick counts elapsed between two readings of the 24-bit down-counter.
pub(crate) fn elapsed(start: u32, end: u32) -> u32 {
    start.wrapping_sub(end) & 0x00FF_FFFF
}

/// Check the method on known code: 1,000 NOPs, timed like a tick (dithered windows net
/// of the empty-window overhead), 500 times. Returns instructions per block.
pub(crate) fn calibrate() -> u32 {
    let (mut counts, mut overhead) = (0_u32, 0_u32);
    for k in 0..500_u32 {
        dither(k % 23);
        let t0 = SYST::get_current();
        let t1 = SYST::get_current();
        overhead += elapsed(t0, t1);
        dither(k % 17);
        let t0 = SYST::get_current();
        thousand_nops();
        let t1 = SYST::get_current();
        counts += elapsed(t0, t1);
    }
    (counts.saturating_sub(overhead) * INSTRUCTIONS_PER_COUNT + 250) / 500
}

/// Exactly 1,000 NOP instructions, plus the call and return.
#[inline(never)]
fn thousand_nops() {
    // SAFETY: NOPs have no effect.
    #[allow(unsafe_code)]
    unsafe {
        core::arch::asm!(
            ".rept 1000",
            "nop",
            ".endr",
            options(nomem, nostack, preserves_flags)
        );
    }
}

/// Average net instructions per window.
pub(crate) fn per_call(counts: &AtomicU32, overhead: &AtomicU32, samples: &AtomicU32) -> u32 {
    let n = samples.load(Ordering::Relaxed).max(1);
    let net = counts
        .load(Ordering::Relaxed)
        .saturating_sub(overhead.load(Ordering::Relaxed));
    // Rounded: (net · 40 + n/2) / n.
    (net.saturating_mul(INSTRUCTIONS_PER_COUNT) + n / 2) / n
}

/// Longest window net of the mean measuring overhead [instructions].
pub(crate) fn longest(max: &AtomicU32, overhead: &AtomicU32, samples: &AtomicU32) -> u32 {
    let n = samples.load(Ordering::Relaxed).max(1);
    let max = max.load(Ordering::Relaxed) * INSTRUCTIONS_PER_COUNT;
    let mean_overhead = overhead.load(Ordering::Relaxed) * INSTRUCTIONS_PER_COUNT / n;
    max.saturating_sub(mean_overhead)
}

/// One measured window of a loop's interrupt body.
pub(crate) struct Window<T, B> {
    /// What the body returned.
    pub(crate) out: T,
    /// What `before` returned (read just before the window).
    pub(crate) before: B,
    /// The SysTick readings that bound the window.
    t0: u32,
    t1: u32,
    /// The handler's stack pointer, below which the stack was painted.
    pub(crate) sp: u32,
}

impl<T, B> Window<T, B> {
    /// The window [SysTick counts].
    #[inline(always)]
    pub(crate) fn counts(&self) -> u32 {
        elapsed(self.t0, self.t1)
    }
}

/// Time `body` (a loop's interrupt body) of tick `tick` as every window is: an empty window
/// at a dithered phase added to `overhead`, the stack painted below the handler's stack
/// pointer, the cycle tracer armed by `arm`, then `before` and the body's window at another
/// phase.
#[inline(always)]
pub(crate) fn timed<T, B>(
    tick: u32,
    overhead: &AtomicU32,
    arm: extern "C" fn(),
    before: impl FnOnce() -> B,
    body: impl FnOnce() -> T,
) -> Window<T, B> {
    dither(tick % 23);
    let t0 = SYST::get_current();
    let t1 = SYST::get_current();
    overhead.fetch_add(elapsed(t0, t1), Ordering::Relaxed);
    let sp = stack::sp();
    stack::paint(sp);
    arm();
    dither(tick % 17);
    let before = before();
    let t0 = SYST::get_current();
    let out = body();
    let t1 = SYST::get_current();
    Window {
        out,
        before,
        t0,
        t1,
        sp,
    }
}

/// Add an undisturbed window of `counts` to a loop's sums, longest window and samples.
#[inline(always)]
pub(crate) fn tally(counts: u32, sum: &AtomicU32, max: &AtomicU32, samples: &AtomicU32) {
    sum.fetch_add(counts, Ordering::Relaxed);
    max.fetch_max(counts, Ordering::Relaxed);
    samples.fetch_add(1, Ordering::Relaxed);
}

/// Run `f` (one block of a tick) in a measured window at a dithered `phase`, its result
/// kept, and add the window's SysTick counts to `total`.
#[inline(always)]
pub(crate) fn timed_block<R>(total: Option<&AtomicU32>, phase: u32, f: impl FnOnce() -> R) -> R {
    dither(phase);
    let t0 = SYST::get_current();
    let r = core::hint::black_box(f());
    let t1 = SYST::get_current();
    if let Some(total) = total {
        total.fetch_add(elapsed(t0, t1), Ordering::Relaxed);
    }
    r
}

/// What the last window mark armed (1: current tick, 2: velocity tick, 0: preempted).
static ARMED: AtomicU32 = AtomicU32::new(0);

/// A store the optimizer keeps (so the mark functions, and their calls, stay in the image),
/// of a different value in each (so they are not merged into one address).
#[inline(always)]
fn mark(value: u32) {
    // SAFETY: a volatile write of the atomic's own storage from its only writer context
    // (the mark functions run in the interrupt handlers, which never preempt each other's
    // marks: the current loop's mark runs at the higher priority and completes).
    #[allow(unsafe_code)]
    unsafe {
        core::ptr::write_volatile(ARMED.as_ptr(), value);
    }
}

/// Marks for the cycle tracer of `fw-runner --cycles` (QEMU plugin): executing this
/// function arms it, and the next two SysTick reads (the `t0`, `t1` of the window) bound
/// one current tick's body. Called before the window's dither, outside the window.
#[allow(unsafe_code)]
#[no_mangle]
#[inline(never)]
pub extern "C" fn cycle_window_arm_current() {
    mark(1);
}

/// As [`cycle_window_arm_current`], for a velocity tick's body.
#[allow(unsafe_code)]
#[no_mangle]
#[inline(never)]
pub extern "C" fn cycle_window_arm_velocity() {
    mark(2);
}

/// First call of the current-loop handler: the tracer drops a window this interrupt
/// preempts (as the SysTick figures drop a disturbed velocity window).
#[allow(unsafe_code)]
#[no_mangle]
#[inline(never)]
pub extern "C" fn cycle_window_preempt() {
    mark(0);
}

/// Called once between the bench's two drives: the cycle tracer starts a new group of
/// windows here (the runner reports and gates each group on its own budget).
#[allow(unsafe_code)]
#[no_mangle]
#[inline(never)]
pub extern "C" fn cycle_window_next_group() {
    mark(3);
}
