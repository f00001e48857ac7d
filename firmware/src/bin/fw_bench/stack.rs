//! Stack high-water marks of each interrupt, by a painted stack.
//!
//! Inside a measured tick, before the tick's body runs, the handler paints the
//! [`SPAN_BYTES`] of free stack below its own stack pointer (all but [`GUARD_BYTES`] just
//! under it, where the painter's own frame lies); after the body it scans the span up from
//! its bottom to the first word that no longer holds the paint. The body's depth is the
//! handler's stack pointer less that word's address. The interrupt's whole mark adds what
//! lies above the handler's stack pointer: the exception frame the core stacked, the vector
//! and the handler's own frame (the bench's handler, whose frame also holds the bench's
//! own locals), measured as the distance from the stack pointer of the interrupted main
//! loop. The maxima over every measured tick are kept; a velocity tick preempted by the
//! current loop is not counted (the current tick wrote into its span).

use core::sync::atomic::{AtomicU32, Ordering};

/// The paint (as the whole-image mark of `firmware::rt` uses).
const PAINT: u32 = 0xA5A5_A5A5;
/// Free stack painted below the handler's stack pointer [bytes].
pub(crate) const SPAN_BYTES: u32 = 4096;
/// Left unpainted just below the stack pointer: the painter's own frame [bytes].
const GUARD_BYTES: u32 = 64;

extern "C" {
    /// End of static RAM (cortex-m-rt): the stack may not grow below it.
    static __sheap: u32;
}

/// The main loop's stack pointer while it waits for interrupts (0 until set).
static MAIN_SP: AtomicU32 = AtomicU32::new(0);

/// One interrupt's marks [bytes].
pub(crate) struct StackMark {
    /// Deepest use of the tick's body below the handler's stack pointer.
    body: AtomicU32,
    /// Main loop's stack pointer less the handler's (exception frame, vector, handler).
    above: AtomicU32,
    /// Whole interrupt: the largest `above + body` of one tick.
    whole: AtomicU32,
}

impl StackMark {
    pub(crate) const fn new() -> Self {
        Self {
            body: AtomicU32::new(0),
            above: AtomicU32::new(0),
            whole: AtomicU32::new(0),
        }
    }

    /// (body, above, whole) [bytes].
    pub(crate) fn get(&self) -> (u32, u32, u32) {
        (
            self.body.load(Ordering::Relaxed),
            self.above.load(Ordering::Relaxed),
            self.whole.load(Ordering::Relaxed),
        )
    }

    /// Record one tick: the handler's stack pointer `sp` (from [`paint`]) and the depth
    /// [`depth`] found below it. `nested` when the interrupt came into another handler
    /// (whose frames then lie above this one's): its body counts, its whole does not.
    pub(crate) fn record(&self, sp: u32, depth: u32, nested: bool) {
        self.body.fetch_max(depth, Ordering::Relaxed);
        if nested {
            return;
        }
        let main = MAIN_SP.load(Ordering::Relaxed);
        let above = main.saturating_sub(sp);
        self.above.fetch_max(above, Ordering::Relaxed);
        self.whole.fetch_max(above + depth, Ordering::Relaxed);
    }
}

/// Note the main loop's stack pointer (call where it waits for interrupts).
#[inline(always)]
pub(crate) fn note_main_sp() {
    MAIN_SP.store(cortex_m::register::msp::read(), Ordering::Relaxed);
}

/// The current stack pointer (of the calling function's frame).
#[inline(always)]
pub(crate) fn sp() -> u32 {
    cortex_m::register::msp::read()
}

/// The lowest address the span below `sp` may reach.
fn span_bottom(sp: u32) -> u32 {
    let heap = &raw const __sheap as usize as u32;
    sp.saturating_sub(SPAN_BYTES).max(heap)
}

/// Paint the free stack below `sp` (the caller's stack pointer, from [`sp`]).
#[inline(never)]
pub(crate) fn paint(sp: u32) {
    let top = sp.saturating_sub(GUARD_BYTES);
    let mut addr = span_bottom(sp);
    while addr + 4 <= top {
        // SAFETY: [span bottom, sp − guard) is free stack below the live frames of this
        // interrupt (nothing of higher priority runs in a measured window, and the guard
        // covers this function's own frame), above the end of static RAM, word aligned.
        #[allow(unsafe_code)]
        unsafe {
            core::ptr::write_volatile(addr as *mut u32, PAINT);
        }
        addr += 4;
    }
}

/// Depth below `sp` of the deepest word written since [`paint`] [bytes]; [`SPAN_BYTES`]
/// when the span's last word was written (the depth may be larger).
#[inline(never)]
pub(crate) fn depth(sp: u32) -> u32 {
    let mut addr = span_bottom(sp);
    while addr + 4 <= sp {
        // SAFETY: reads of the painted span, word aligned (see `paint`).
        #[allow(unsafe_code)]
        let word = unsafe { core::ptr::read_volatile(addr as *const u32) };
        if word != PAINT {
            break;
        }
        addr += 4;
    }
    sp - addr
}
