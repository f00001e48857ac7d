//! The window accounting: which instructions a SysTick-timed window holds, priced as they
//! execute (the module's text in [`super`]).

use super::decode::{Insn, Kind};
use super::price::cycles;

/// SysTick's current-value register: the loads that bound a window.
pub const SYST_CVR: u64 = 0xE000_E018;

/// Which tick a window times.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Which {
    /// The current loop's tick.
    Current,
    /// The velocity loop's tick.
    Velocity,
}

/// One priced window.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Window {
    /// Instructions executed.
    pub instructions: u32,
    /// Estimated cycles (the body only: no exception entry or exit).
    pub cycles: u32,
    /// Taken branches (and other PC writes).
    pub taken: u32,
    /// Divides (each priced at its worst case).
    pub divides: u32,
    /// FPU instructions.
    pub fpu: u32,
    /// Instructions of no known class (priced 1).
    pub unknown: u32,
}

/// Where the tracker's marks are in the image.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Marks {
    /// `cycle_window_arm_current`.
    pub arm_current: Option<u64>,
    /// `cycle_window_arm_velocity`.
    pub arm_velocity: Option<u64>,
    /// `cycle_window_preempt`.
    pub preempt: Option<u64>,
    /// `cycle_window_next_group`: the windows after it are another group (the bench's
    /// next drive).
    pub next_group: Option<u64>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum State {
    Idle,
    Armed(Which),
    Open(Which),
}

/// Turns the executed instruction stream into priced windows (see the module's text).
#[derive(Debug)]
pub struct Tracker {
    marks: Marks,
    state: State,
    /// The instruction executed last, not yet priced (its price needs the next address).
    pending: Option<(u64, Insn)>,
    /// The instruction priced last in the open window.
    last: Option<Insn>,
    acc: Window,
    /// Finished windows, in order.
    pub windows: Vec<(Which, Window)>,
    /// Windows dropped because an interrupt came into them.
    pub dropped: u32,
    /// Group marks passed so far (each starts a new group of windows).
    pub groups: u32,
}

impl Tracker {
    /// A tracker for an image with these marks.
    #[must_use]
    pub fn new(marks: Marks) -> Self {
        Self {
            marks,
            state: State::Idle,
            pending: None,
            last: None,
            acc: Window::default(),
            windows: Vec::new(),
            dropped: 0,
            groups: 0,
        }
    }

    /// The instruction at `pc` is about to execute.
    pub fn exec(&mut self, pc: u64, insn: Insn) {
        if let Some((ppc, _)) = self.pending {
            if ppc == pc {
                // QEMU re-executes an instruction whose device access ended its block
                // early (icount): the same instruction again, not a loop.
                return;
            }
        }
        if let Some((ppc, p)) = self.pending.take() {
            if matches!(self.state, State::Open(_)) {
                let taken = pc != ppc + u64::from(p.size);
                self.price(&p, taken);
            }
        }
        let m = self.marks;
        if Some(pc) == m.preempt && self.state != State::Idle {
            self.dropped += 1;
            self.state = State::Idle;
        }
        if Some(pc) == m.next_group {
            self.groups += 1;
            self.state = State::Idle;
        }
        if Some(pc) == m.arm_current {
            self.arm(Which::Current);
        } else if Some(pc) == m.arm_velocity {
            self.arm(Which::Velocity);
        }
        self.pending = Some((pc, insn));
    }

    fn arm(&mut self, which: Which) {
        if self.state != State::Idle {
            self.dropped += 1;
        }
        self.state = State::Armed(which);
    }

    /// The instruction executed last loaded from `addr`.
    pub fn load(&mut self, addr: u64) {
        if addr != SYST_CVR {
            return;
        }
        match self.state {
            State::Armed(which) => {
                // The window's first SysTick read: what follows it is timed.
                self.pending = None;
                self.last = None;
                self.acc = Window::default();
                self.state = State::Open(which);
            }
            State::Open(which) => {
                // The closing read itself is not part of the window.
                self.pending = None;
                self.windows.push((which, self.acc));
                self.state = State::Idle;
            }
            State::Idle => {}
        }
    }

    fn price(&mut self, insn: &Insn, taken: bool) {
        let c = cycles(insn, self.last.as_ref(), taken);
        let a = &mut self.acc;
        a.instructions += 1;
        a.cycles += c;
        let pc_write = matches!(
            insn.kind,
            Kind::WritesPc { .. } | Kind::Table | Kind::Multiple { pc: true, .. }
        );
        if (taken && insn.kind == Kind::Branch) || pc_write {
            a.taken += 1;
        }
        match insn.kind {
            Kind::Divide => a.divides += 1,
            Kind::Fpu | Kind::FpuMac | Kind::FpuDivide | Kind::FpuTwo => a.fpu += 1,
            Kind::Unknown => a.unknown += 1,
            _ => {}
        }
        self.last = Some(*insn);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cycles::{decode, PIPELINE_REFILL};

    /// Feeds `prog` (address, disassembly, size, whether it loads from SysTick) to `t`.
    fn run(t: &mut Tracker, prog: &[(u64, &str, u32, bool)]) {
        for &(pc, text, size, syst) in prog {
            t.exec(pc, decode(text, size));
            if syst {
                t.load(SYST_CVR);
            }
        }
    }

    #[test]
    fn a_window_is_what_runs_between_the_armed_systick_reads() {
        let marks = Marks {
            arm_current: Some(0x100),
            arm_velocity: Some(0x200),
            preempt: Some(0x300),
            next_group: Some(0x400),
        };
        let mut t = Tracker::new(marks);
        // An unarmed SysTick read is ignored; the armed pair bounds a loop of 3 iterations.
        let prog = [
            (0x10, "ldr r0, [r1]", 2, true),
            (0x100, "bx lr", 2, false),
            // QEMU runs a device access again as the last instruction of a new block: the
            // same instruction twice in a row, counted once.
            (0x12, "ldr r4, [fp]", 4, false),
            (0x12, "ldr r4, [fp]", 4, true),
            (0x16, "movs r0, #3", 2, false),
            (0x18, "subs r0, #1", 2, false),
            (0x1a, "bne #0x18", 2, false),
            (0x18, "subs r0, #1", 2, false),
            (0x1a, "bne #0x18", 2, false),
            (0x18, "subs r0, #1", 2, false),
            (0x1a, "bne #0x18", 2, false),
            (0x1c, "ldr r0, [fp]", 4, true),
            (0x20, "nop", 2, false),
        ];
        run(&mut t, &prog);
        assert_eq!(t.windows.len(), 1);
        let (which, w) = t
            .windows
            .first()
            .copied()
            .unwrap_or((Which::Velocity, Window::default()));
        assert_eq!(which, Which::Current);
        assert_eq!(w.instructions, 7);
        // movs 1, 3 × subs 1, 2 taken bne 1 + P, 1 not taken.
        assert_eq!(w.cycles, 1 + 3 + 2 * (1 + PIPELINE_REFILL) + 1);
        assert_eq!(w.taken, 2);
        // A window the current loop's handler preempts is dropped.
        let prog = [
            (0x200, "bx lr", 2, false),
            (0x40, "ldr r4, [fp]", 4, true),
            (0x44, "adds r0, #1", 2, false),
            (0x300, "bx lr", 2, false),
            (0x46, "ldr r0, [fp]", 4, true),
        ];
        run(&mut t, &prog);
        assert_eq!((t.windows.len(), t.dropped), (1, 1));
        // The group mark counts a new group.
        run(&mut t, &[(0x400, "bx lr", 2, false)]);
        assert_eq!(t.groups, 1);
    }
}
