//! The PMSM drive's per-block measurements: the FOC loop's steps, each timed on its own on
//! the bare controller's signals of the tick (its coefficients, a copy of its FOC state):
//! where `Controller::pmsm_tick`'s instructions go.

use core::sync::atomic::AtomicU32;

use controller_core::foc::transforms::{inverse_park, CosSin};
use controller_core::foc::{FocCoefficients, FocState};
use controller_core::per_unit::count_diff;
use controller_core::{PmsmInputs, PmsmOutputs, Pu};
use firmware::isr::TaskLocal;

use crate::window::{per_call, timed_block};

/// The timed blocks, in table order.
#[derive(Clone, Copy)]
pub(crate) enum Block {
    /// `FocCoefficients::measure`: the angle's update, cos/sin, Clarke and Park.
    Measure,
    /// `CosSin::of` alone (idsp's `cossin`).
    CosSin,
    /// `FocCoefficients::regulate`: references, the two PIs in the voltage circle, the
    /// advanced angle's cos/sin, inverse Park, the modulator, the commutation check.
    Regulate,
    /// `Mtpa::references` alone.
    Mtpa,
    /// `VoltageCircle::q_bound` alone (a 64-bit integer square root, `per_unit::isqrt_u64`).
    QBound,
    /// `Svpwm::duties` alone (with its inverse Park).
    Svpwm,
    /// `CommutationCheck::update` alone.
    Commutation,
    /// The current vector's squared magnitude for the protections (no root).
    Magnitude,
}

/// The blocks and their names, in table order.
pub(crate) const BLOCKS: [(Block, &str); 8] = [
    (Block::Measure, "foc measure (angle, cos/sin, Clarke, Park)"),
    (Block::CosSin, "  of which cos/sin (idsp cossin) alone"),
    (Block::Regulate, "foc regulate (references, d/q PIs, voltage circle, advanced cos/sin, inverse Park, SVPWM, commutation check)"),
    (Block::Mtpa, "  of which current references (Mtpa::references) alone"),
    (Block::QBound, "  of which the voltage circle's q bound (u64 isqrt) alone"),
    (Block::Svpwm, "  of which inverse Park + SVPWM duties alone"),
    (Block::Commutation, "  of which the commutation check alone"),
    (Block::Magnitude, "|i|² for the protections (i_d² + i_q², no root) alone"),
];
const BLOCK_COUNT: usize = 8;
static BLOCK_COUNTS: [AtomicU32; BLOCK_COUNT] = [const { AtomicU32::new(0) }; BLOCK_COUNT];

/// The FOC coefficients of the bare controller with a state of their own (its angle
/// follows the encoder), and the last raw count.
static BENCH: TaskLocal<(FocCoefficients, FocState, u32)> = TaskLocal::new();

/// Install the block bench on the bare controller's FOC coefficients, the angle at `raw`.
pub(crate) fn install(foc: FocCoefficients, raw: u32) {
    let st = foc.state_at(i64::from(raw));
    let _ = BENCH.install((foc, st, raw));
}

/// Run `f` in a measured window (dithered, like the ticks) and add its SysTick counts
/// to `block`'s total.
#[inline(always)]
fn timed<R>(block: Block, phase: u32, f: impl FnOnce() -> R) -> R {
    timed_block(BLOCK_COUNTS.get(block as usize), phase, f)
}

/// The current-rate blocks on the tick's inputs and the bare tick's outputs (`speed`: the
/// motion's).
pub(crate) fn current_blocks(tick: u32, inputs: PmsmInputs, out: &PmsmOutputs, speed: Pu) {
    let _ = BENCH.with(|(foc, st, last)| {
        let delta = count_diff(inputs.encoder_count, *last, 16);
        *last = inputs.encoder_count;
        blocks(tick, foc, st, inputs.phase_current_pu, delta, out, speed);
    });
}

fn blocks(
    tick: u32,
    foc: &FocCoefficients,
    st: &mut FocState,
    currents: [Pu; 2],
    delta: i32,
    out: &PmsmOutputs,
    speed: Pu,
) {
    let (currents, delta) = core::hint::black_box((currents, delta));
    let (phase, current) = timed(Block::Measure, tick % 11, || {
        foc.measure(st, currents, delta)
    });
    let p = core::hint::black_box(phase);
    let _ = timed(Block::CosSin, tick % 7, || CosSin::of(p));
    let (w, torque) = core::hint::black_box((speed, out.torque_ref_pu));
    let mut st2 = core::hint::black_box(*st);
    let _ = timed(Block::Regulate, tick % 5, || {
        foc.regulate(&mut st2, phase, current, w, torque)
    });
    let _ = timed(Block::Mtpa, tick % 3, || foc.mtpa.references(torque));
    let vd = core::hint::black_box(out.voltage.d);
    let _ = timed(Block::QBound, tick % 13, || foc.circle.q_bound(vd));
    let (v, cs) = core::hint::black_box((out.voltage, CosSin::of(phase)));
    let _ = timed(Block::Svpwm, tick % 11, || {
        foc.svpwm.duties(inverse_park(v, cs))
    });
    let mut cst = core::hint::black_box(st.commutation);
    let _ = timed(Block::Commutation, tick % 7, || {
        foc.commutation.update(&mut cst, current, w, v)
    });
    let i = core::hint::black_box(out.current);
    let _ = timed(Block::Magnitude, tick % 5, || {
        let d = i64::from(i.d.to_bits());
        let q = i64::from(i.q.to_bits());
        ((d * d) as u64 + (q * q) as u64).min(1 << 62)
    });
}

/// Average net instructions of `b` over the current ticks.
pub(crate) fn per_block(b: Block, overhead: &AtomicU32, samples: &AtomicU32) -> u32 {
    BLOCK_COUNTS
        .get(b as usize)
        .map_or(0, |total| per_call(total, overhead, samples))
}
