//! Interrupt glue: where the tick functions, the board I/O and the profile live between
//! interrupts, and the bodies the current-loop and velocity-loop handlers run.
//!
//! Sharing rules (single core, the current loop at a higher NVIC priority):
//! * the [`App`] (controller + trend buffer) is shared by both ticks and the thread-mode
//!   dump; it sits in a [`Shared`] cell, reached only under a critical section and refused
//!   (never a panic) to a second, re-entrant borrower. The current tick is the most urgent
//!   interrupt, so holding the section there delays nothing. The velocity interrupt takes
//!   it only around the core's `velocity_tick` (one call: the core keeps both loops' state
//!   in one `Controller`), so the current loop is held off for at most that call
//!   (`cargo fw-bench` prints it as "controller-core alone: Controller::velocity_tick":
//!   ≈ 300 instructions, ≈ 2 µs at 168 MHz, against a 250 µs period; with the two timers
//!   aligned the current tick has always run first, so in practice it never waits);
//! * the velocity loop's own I/O and profile live in a [`TaskLocal`], touched by the
//!   velocity interrupt only, so reading them and computing the next setpoint run with the
//!   current loop free to preempt.

use core::cell::{Cell, UnsafeCell};
use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use controller_core::{CurrentOutputs, PmsmOutputs, VelocityOutputs};
use critical_section::{CriticalSection, Mutex};

use crate::app::{velocity_inputs, App, SetpointSource};
use crate::board::three_phase::PmsmLoopIo;
use crate::board::{CurrentLoopIo, VelocityLoopIo};
use crate::trace::{TraceSample, TraceState};

/// A value owned by one interrupt: a non-blocking exclusive cell. `with` fails (returns
/// `None`) instead of waiting if the value is already borrowed, so it can never deadlock,
/// and it never masks interrupts.
pub struct TaskLocal<T> {
    taken: AtomicBool,
    value: UnsafeCell<Option<T>>,
}

// SAFETY: the only access to `value` is inside `with`, after winning the `taken` flag with an
// atomic swap and before releasing it, so at most one context holds `&mut T` at any time;
// `T: Send` because the value moves between thread mode (install) and an interrupt.
#[allow(unsafe_code)]
unsafe impl<T: Send> Sync for TaskLocal<T> {}

impl<T> TaskLocal<T> {
    /// An empty cell.
    pub const fn new() -> Self {
        Self {
            taken: AtomicBool::new(false),
            value: UnsafeCell::new(None),
        }
    }

    /// Run `f` on the value; `None` if the cell is empty or already borrowed.
    pub fn with<R>(&self, f: impl FnOnce(&mut T) -> R) -> Option<R> {
        if self.taken.swap(true, Ordering::Acquire) {
            return None;
        }
        // SAFETY: we won the flag (see the `Sync` impl): no other reference to `value` exists
        // until we store `false` below.
        #[allow(unsafe_code)]
        let slot = unsafe { &mut *self.value.get() };
        let result = slot.as_mut().map(f);
        self.taken.store(false, Ordering::Release);
        result
    }

    /// Put a value in (before the interrupt that uses it is started). Returns false if the
    /// cell was borrowed at that moment.
    pub fn install(&self, value: T) -> bool {
        if self.taken.swap(true, Ordering::Acquire) {
            return false;
        }
        // SAFETY: as in `with`.
        #[allow(unsafe_code)]
        let slot = unsafe { &mut *self.value.get() };
        *slot = Some(value);
        self.taken.store(false, Ordering::Release);
        true
    }
}

impl<T> Default for TaskLocal<T> {
    fn default() -> Self {
        Self::new()
    }
}

/// A value shared by interrupts of different priorities and thread mode, reached only under
/// a critical section. Unlike a `RefCell` a second borrow (a re-entrant call from inside
/// `with`) is refused with `None` rather than a panic, so the handlers carry no
/// `panic_already_borrowed` path; under the critical section the flag is a plain load and
/// store (no exclusive-access loop).
pub struct Shared<T> {
    busy: Mutex<Cell<bool>>,
    value: UnsafeCell<Option<T>>,
}

// SAFETY: `value` is only touched inside `with`, which needs a `CriticalSection` token (on
// this single-core target: interrupts masked, so no other context runs meanwhile) and holds
// the `busy` flag for the whole borrow, so a re-entrant call from inside `f` gets `None`:
// at most one `&mut T` exists at any time. `T: Send` because the value moves between thread
// mode (install) and the interrupts.
#[allow(unsafe_code)]
unsafe impl<T: Send> Sync for Shared<T> {}

impl<T> Shared<T> {
    /// An empty cell.
    pub const fn new() -> Self {
        Self {
            busy: Mutex::new(Cell::new(false)),
            value: UnsafeCell::new(None),
        }
    }

    /// Run `f` on the value slot (`None` inside means empty); `None` if the slot is already
    /// borrowed further up this critical section.
    #[inline]
    pub fn with_slot<R>(
        &self,
        cs: CriticalSection<'_>,
        f: impl FnOnce(&mut Option<T>) -> R,
    ) -> Option<R> {
        self.with_slot_or(cs, None, |slot| Some(f(slot)))
    }

    /// Run `f` on the value slot and return what it returns, or `busy` if the slot is
    /// already borrowed further up this critical section. The one place the slot is
    /// reached; [`Shared::with`] and [`Shared::with_slot`] pick their own `busy` value, so
    /// neither wraps an `Option` in another (which would copy the result once more).
    #[inline]
    fn with_slot_or<R>(
        &self,
        cs: CriticalSection<'_>,
        busy_result: R,
        f: impl FnOnce(&mut Option<T>) -> R,
    ) -> R {
        let busy = self.busy.borrow(cs);
        if busy.replace(true) {
            return busy_result;
        }
        // SAFETY: see the `Sync` impl: the critical section excludes every other context and
        // the flag, won just above, excludes re-entry until it is cleared below.
        #[allow(unsafe_code)]
        let slot = unsafe { &mut *self.value.get() };
        let result = f(slot);
        busy.set(false);
        result
    }

    /// Run `f` on the value; `None` if the cell is empty or already borrowed.
    #[inline]
    pub fn with<R>(&self, cs: CriticalSection<'_>, f: impl FnOnce(&mut T) -> R) -> Option<R> {
        self.with_slot_or(cs, None, |slot| slot.as_mut().map(f))
    }
}

impl<T> Default for Shared<T> {
    fn default() -> Self {
        Self::new()
    }
}

/// The velocity interrupt's own state: its board I/O and the setpoint source.
pub struct VelocityTask<V, S> {
    /// Encoder and fault input.
    pub io: V,
    /// Motion profile.
    pub profile: S,
}

/// Everything the two loop interrupts share, for one board I/O type `C`/`V` and setpoint
/// source `S`. A binary declares one as a `static` and calls [`Loops::current_isr`] (a DC
/// drive, `C: CurrentLoopIo`) or [`Loops::pmsm_isr`] (a PMSM drive, `C: PmsmLoopIo`) and
/// [`Loops::velocity_isr`] from its handlers.
pub struct Loops<C, V, S> {
    /// The app and the current loop's I/O (one cell: one borrow per current tick).
    app: Shared<(App, C)>,
    velocity: TaskLocal<VelocityTask<V, S>>,
    /// Velocity ticks skipped because the task state was unavailable (should stay 0).
    overruns: AtomicU32,
}

impl<C, V, S> Loops<C, V, S>
where
    C: Send,
    V: VelocityLoopIo + Send,
    S: SetpointSource + Send,
{
    /// Empty: the handlers do nothing until [`Loops::install`].
    pub const fn new() -> Self {
        Self {
            app: Shared::new(),
            velocity: TaskLocal::new(),
            overruns: AtomicU32::new(0),
        }
    }

    /// Hand the app, the I/O halves and the profile to the interrupts (before starting the
    /// timers).
    pub fn install(&self, app: App, current_io: C, velocity_io: V, profile: S) {
        let placed = critical_section::with(|cs| {
            self.app
                .with_slot(cs, |slot| *slot = Some((app, current_io)))
        });
        if placed.is_none() {
            self.overruns.fetch_add(1, Ordering::Relaxed);
        }
        if !self.velocity.install(VelocityTask {
            io: velocity_io,
            profile,
        }) {
            self.overruns.fetch_add(1, Ordering::Relaxed);
        }
    }

    /// Body of the velocity-loop interrupt (2 kHz).
    #[inline]
    pub fn velocity_isr(&self) -> Option<VelocityOutputs> {
        // Preemptible part: board reads and the profile.
        let Some(inputs) = self
            .velocity
            .with(|task| velocity_inputs(&mut task.io, &mut task.profile))
        else {
            self.overruns.fetch_add(1, Ordering::Relaxed);
            return None;
        };
        // The controller, with the current loop held off for this one call.
        critical_section::with(|cs| self.app.with(cs, |(app, _)| app.on_velocity_tick(inputs)))
    }

    /// Run `f` on the app (thread mode: status, enable, dump requests), under a critical
    /// section: keep it short.
    pub fn with_app<R>(&self, f: impl FnOnce(&mut App) -> R) -> Option<R> {
        critical_section::with(|cs| self.app.with(cs, |(app, _)| f(app)))
    }

    /// Run `f` on the current loop's I/O (thread mode, e.g. a stand-in board's inputs),
    /// under a critical section.
    pub fn with_current_io<R>(&self, f: impl FnOnce(&mut C) -> R) -> Option<R> {
        critical_section::with(|cs| self.app.with(cs, |(_, io)| f(io)))
    }

    /// Run `f` on the velocity loop's I/O; `None` if the velocity interrupt holds it.
    pub fn with_velocity_io<R>(&self, f: impl FnOnce(&mut V) -> R) -> Option<R> {
        self.velocity.with(|task| f(&mut task.io))
    }

    /// Velocity ticks skipped so far.
    pub fn overruns(&self) -> u32 {
        self.overruns.load(Ordering::Relaxed)
    }

    /// If the trend buffer is frozen, hand its samples one by one (oldest first, each copied
    /// out under a short critical section) to `sink`, then re-arm it. Returns the state it
    /// was dumped in, or `None` if it was not frozen.
    pub fn dump_trace(&self, mut sink: impl FnMut(usize, &TraceSample)) -> Option<TraceState> {
        let state = self.with_app(|app| app.trace().state())?;
        if !matches!(state, TraceState::Frozen { .. }) {
            return None;
        }
        let mut index = 0;
        while let Some(Some(sample)) = self.with_app(|app| app.trace().sample(index)) {
            sink(index, &sample);
            index += 1;
        }
        self.with_app(|app| app.trace_mut().rearm());
        Some(state)
    }
}

impl<C, V, S> Loops<C, V, S>
where
    C: CurrentLoopIo + Send,
    V: VelocityLoopIo + Send,
    S: SetpointSource + Send,
{
    /// Body of a DC drive's current-loop interrupt (4 kHz).
    #[inline]
    pub fn current_isr(&self) -> Option<CurrentOutputs> {
        critical_section::with(|cs| self.app.with(cs, |(app, io)| app.on_current_tick(io)))
    }
}

impl<C, V, S> Loops<C, V, S>
where
    C: PmsmLoopIo + Send,
    V: VelocityLoopIo + Send,
    S: SetpointSource + Send,
{
    /// Body of a PMSM drive's current-loop interrupt ([`App::on_pmsm_tick`]).
    #[inline]
    pub fn pmsm_isr(&self) -> Option<PmsmOutputs> {
        critical_section::with(|cs| self.app.with(cs, |(app, io)| app.on_pmsm_tick(io)))
    }
}

impl<C, V, S> Default for Loops<C, V, S>
where
    C: Send,
    V: VelocityLoopIo + Send,
    S: SetpointSource + Send,
{
    fn default() -> Self {
        Self::new()
    }
}
