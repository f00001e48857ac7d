//! The per-block measurements: the bare controller's blocks, each timed on its own with
//! its own state, fed the bare controller's signals: where the core's instructions go.

use core::sync::atomic::AtomicU32;

use controller_core::controller::Blocks;
use controller_core::filter::LowPassState;
use controller_core::notch::{Notch, NotchState};
use controller_core::observer::ObserverState;
use controller_core::per_unit::count_diff;
use controller_core::pi::PiState;
use controller_core::Pu;
use firmware::isr::TaskLocal;

use crate::target::{CURRENT_OVERHEAD, CURRENT_SAMPLES, VELOCITY_OVERHEAD, VELOCITY_SAMPLES};
use crate::window::{per_call, timed_block};

/// The bare controller's blocks with one state each.
struct BlockBench {
    blocks: Blocks,
    observer: ObserverState,
    afb_filter: LowPassState,
    filter_alone: LowPassState,
    current_pi: PiState,
    velocity_pi: PiState,
    /// Unwrapped encoder position [counts] and the last raw reading.
    position: i64,
    last_raw: u32,
    /// Torque reference of the last current tick (the observer's input) [pu].
    torque: Pu,
    /// The notched controller's notch (the bare controller has none), with its own state.
    notch: Option<Notch>,
    notch_state: NotchState,
}
static BLOCKS: TaskLocal<BlockBench> = TaskLocal::new();

/// The timed blocks, in table order.
#[derive(Clone, Copy)]
pub(crate) enum Block {
    ObserverUpdate,
    ObserverReads,
    AfbClosed,
    FirstOrderFilter,
    CurrentPi,
    VelocityPi,
    Notch,
}
const BLOCK_COUNT: usize = 7;
static BLOCK_COUNTS: [AtomicU32; BLOCK_COUNT] = [const { AtomicU32::new(0) }; BLOCK_COUNT];

/// Install the block bench on the bare controller's blocks and the notched controller's
/// notch (fresh states).
pub(crate) fn install(blocks: Blocks, notch: Option<Notch>) {
    let _ = BLOCKS.install(BlockBench {
        blocks,
        observer: ObserverState::default(),
        afb_filter: LowPassState::default(),
        filter_alone: LowPassState::default(),
        current_pi: PiState::default(),
        velocity_pi: PiState::default(),
        position: 0,
        last_raw: 0,
        torque: Pu::ZERO,
        notch,
        notch_state: NotchState::default(),
    });
}

/// Run `f` in a measured window (dithered, like the ticks) and add its SysTick counts
/// to `block`'s total.
#[inline(always)]
fn timed<R>(block: Block, phase: u32, f: impl FnOnce() -> R) -> R {
    timed_block(BLOCK_COUNTS.get(block as usize), phase, f)
}

/// The current-rate blocks (observer, closed-form AFB with its filter, the filter step
/// alone, the notch step, current PI) on this tick's encoder reading and the bare tick's
/// current reference.
pub(crate) fn current_blocks(tick: u32, raw: u32, current: Pu, a_cmd: Pu, i_vel: Pu) {
    let _ = BLOCKS.with(|b| {
        let d = count_diff(raw, b.last_raw, 16);
        b.last_raw = raw;
        b.position = b.position.wrapping_add(i64::from(d));
        let (position, torque) = core::hint::black_box((b.position, b.torque));
        let obs = b.blocks.observer;
        timed(Block::ObserverUpdate, tick % 11, || {
            obs.update(&mut b.observer, position, torque)
        });
        let afb = b.blocks.accel_feedback;
        let os = b.observer;
        let (p, c) = core::hint::black_box((i_vel, a_cmd));
        let term = timed(Block::AfbClosed, tick % 7, || {
            afb.update_closed_from(&mut b.afb_filter, p, c, |t| {
                obs.predicted_acceleration_pu_s(&os, t)
            })
        });
        let x = core::hint::black_box(c);
        let _ = timed(Block::FirstOrderFilter, tick % 5, || {
            afb.filter.process(&mut b.filter_alone, x)
        });
        let limit = afb.limit;
        let i_ref = i_vel.saturating_add(term).max(-limit).min(limit);
        if let Some(n) = b.notch {
            let x = core::hint::black_box(i_ref);
            let _ = timed(Block::Notch, tick % 3, || n.process(&mut b.notch_state, x));
        }
        b.torque = i_ref;
        let e = core::hint::black_box(i_ref.saturating_sub(current));
        let pi = b.blocks.current_regulator;
        let _ = timed(Block::CurrentPi, tick % 13, || {
            pi.update(&mut b.current_pi, e, Pu::ZERO)
        });
    });
}

/// The velocity-rate blocks (observer outputs, velocity PI) on the bare tick's signals.
pub(crate) fn velocity_blocks(tick: u32, e: Pu, ff: Pu, afb: Pu) {
    let _ = BLOCKS.with(|b| {
        let obs = b.blocks.observer;
        let os = core::hint::black_box(b.observer);
        let _ = timed(Block::ObserverReads, tick % 11, || {
            (
                obs.velocity_pu(&os),
                obs.acceleration_pu_s(&os),
                obs.load_torque_pu(&os),
            )
        });
        let (e, ff, afb) = core::hint::black_box((e, ff, afb));
        let pi = b.blocks.velocity_regulator;
        let _ = timed(Block::VelocityPi, tick % 13, || {
            pi.update_with_offset(&mut b.velocity_pi, e, ff, afb)
        });
    });
}

/// Average net instructions of `b`, with the overhead and sample count of its rate.
pub(crate) fn per_block(b: Block, velocity_rate: bool) -> u32 {
    let (overhead, samples) = if velocity_rate {
        (&VELOCITY_OVERHEAD, &VELOCITY_SAMPLES)
    } else {
        (&CURRENT_OVERHEAD, &CURRENT_SAMPLES)
    };
    BLOCK_COUNTS
        .get(b as usize)
        .map_or(0, |total| per_call(total, overhead, samples))
}
