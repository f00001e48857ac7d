//! Cycle estimate of the firmware's measured windows: the instruction stream QEMU executed,
//! priced by the Cortex-M4 Technical Reference Manual's instruction timings (ARM DDI 0439,
//! "Table of processor instructions" and the FPU's table; cycle counts for zero wait states).
//!
//! QEMU has no pipeline model. The TCG plugin of this crate ([`crate::plugin`]) hands every
//! executed instruction (its address and QEMU's own disassembly) to a [`Tracker`], and each
//! load's address. A window is what the firmware times with SysTick: the tracker is armed
//! when the firmware executes a mark function (`cycle_window_arm_current` or
//! `cycle_window_arm_velocity`), opens at the next load from SysTick's current-value
//! register and closes at the one after; every instruction between the two loads is priced.
//! A window into which the current-loop interrupt came (its handler first calls
//! `cycle_window_preempt`) is dropped, as `fw-bench` drops a disturbed SysTick window.
//!
//! The price of one instruction ([`cycles`]):
//! - data processing, moves, compares, shifts, extends, saturation, `MUL`, `MLA`, `MLS`
//!   and the long multiplies `UMULL`, `SMULL`, `UMLAL`, `SMLAL`: 1 (the M4 has a
//!   single-cycle multiplier and MAC);
//! - `SDIV`, `UDIV`: 2 to 12 by the operands' sizes (early termination); the plugin API of
//!   QEMU 7.2 cannot read registers, so every divide is priced at the worst case,
//!   [`DIVIDE_CYCLES`];
//! - single loads (`LDR`, `LDRB`, `LDRH`, `LDRSB`, `LDRSH`): 2, or 1 when the previous
//!   instruction was a single load and this one's address does not use its result
//!   (neighbouring loads pipeline their address and data phases); a load after a store is 2;
//! - single stores: 1 with an immediate offset (the write buffer), 2 with a register offset
//!   unless they follow a load; `LDRD`, `STRD`: 3; `LDREX`, `STREX`: 2;
//! - `LDM`, `STM`, `PUSH`, `POP`, `VLDM`, `VSTM`, `VPUSH`, `VPOP`: 1 + N registers;
//! - taken branches (`B`, `BL`, `BX`, `BLX`, `CBZ`, `CBNZ`, and a load, `POP` or move that
//!   writes the PC): their cost plus the pipeline refill P = [`PIPELINE_REFILL`] (the manual
//!   gives 1 to 3 by the target's alignment and width); a branch is taken when the next
//!   executed instruction is not the following one; not taken: 1; `TBB`, `TBH`: 2 + P;
//! - `IT`: 0 when it folds onto a preceding 16-bit instruction, else 1; `ISB`: 1 + P;
//!   `DMB`, `DSB`: 1;
//! - FPU: `VADD`, `VSUB`, `VMUL`, `VNMUL`, `VABS`, `VNEG`, `VCVT`, `VCMP`, `VMOV`, `VMRS`,
//!   `VMSR`: 1; `VMLA`, `VMLS`, `VNMLA`, `VNMLS`, `VFMA`, `VFMS`, `VFNMA`, `VFNMS`: 3;
//!   `VDIV`, `VSQRT`: 14; `VLDR`, `VSTR`: 2; `VMOV` of two core registers: 2.
//!
//! An interrupt adds [`EXCEPTION_ENTRY`] + [`EXCEPTION_EXIT`] (lazy FP stacking: the FP
//! registers are not stacked on entry). Instructions of an IT block whose condition fails
//! are priced as if executed (QEMU reports them executed). Flash wait states are assumed
//! zero: the STM32F4's ART accelerator hitting (at 168 MHz the flash has 5 wait states; a
//! miss on a branch target costs up to 5 more cycles, reported as a bound per taken branch).

use std::fmt::Write as _;

/// Pipeline refill of a taken branch [cycles] (the manual's P, 1 to 3).
pub const PIPELINE_REFILL: u32 = 2;
/// A divide's worst case [cycles] (the manual: 2 to 12 by the operands' sizes).
pub const DIVIDE_CYCLES: u32 = 12;
/// `VDIV`, `VSQRT` [cycles].
pub const FP_DIVIDE_CYCLES: u32 = 14;
/// Exception entry, from the interrupt to the handler's first instruction [cycles].
pub const EXCEPTION_ENTRY: u32 = 12;
/// Exception return [cycles].
pub const EXCEPTION_EXIT: u32 = 10;
/// Flash wait states at 168 MHz without an ART hit: the bound added per taken branch.
pub const FLASH_WAIT_STATES: u32 = 5;
/// SysTick's current-value register: the loads that bound a window.
pub const SYST_CVR: u64 = 0xE000_E018;

/// How an instruction is priced.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// Data processing, moves, compares, multiplies, hints, system moves: 1.
    Simple,
    /// `SDIV`, `UDIV`.
    Divide,
    /// A single load.
    Load {
        /// Its destination register.
        dest: u8,
        /// The registers its address reads (bit n: rn).
        addr: u16,
    },
    /// A single store.
    Store {
        /// Its offset is a register.
        reg_offset: bool,
    },
    /// `LDRD`, `STRD`.
    Double,
    /// `LDREX`, `STREX` and their byte and halfword forms.
    Exclusive,
    /// `LDM`, `STM`, `PUSH`, `POP` (and the FPU's).
    Multiple {
        /// Registers moved (words).
        n: u8,
        /// It loads the PC.
        pc: bool,
    },
    /// A branch: 1, + P when taken.
    Branch,
    /// `TBB`, `TBH`.
    Table,
    /// `IT`.
    It,
    /// `ISB`.
    Isb,
    /// An instruction that writes the PC (move, add, load): its cost + P.
    WritesPc {
        /// A load (2 + P), else 1 + P.
        load: bool,
    },
    /// FPU add, multiply, convert, compare, move: 1.
    Fpu,
    /// FPU multiply-accumulate: 3.
    FpuMac,
    /// `VDIV`, `VSQRT`.
    FpuDivide,
    /// `VLDR`, `VSTR`, `VMOV` of two core registers: 2.
    FpuTwo,
    /// Not recognised: priced 1 and counted.
    Unknown,
}

/// A decoded instruction.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Insn {
    /// Its size [bytes]: 2 or 4.
    pub size: u8,
    /// How it is priced.
    pub kind: Kind,
}

impl Insn {
    /// Whether it reads memory with one load (the loads whose address the tracker watches).
    #[must_use]
    pub fn is_single_load(&self) -> bool {
        matches!(self.kind, Kind::Load { .. } | Kind::WritesPc { load: true })
    }
}

const CONDITIONS: [&str; 16] = [
    "eq", "ne", "cs", "hs", "cc", "lo", "mi", "pl", "vs", "vc", "hi", "ls", "ge", "lt", "gt", "le",
];

/// Register number of an operand name (`r0`–`r12`, `sb`, `sl`, `fp`, `ip`, `sp`, `lr`, `pc`).
fn register(name: &str) -> Option<u8> {
    let name = name.trim().trim_end_matches('!');
    match name {
        "sb" => Some(9),
        "sl" => Some(10),
        "fp" => Some(11),
        "ip" => Some(12),
        "sp" => Some(13),
        "lr" => Some(14),
        "pc" => Some(15),
        _ => name
            .strip_prefix('r')
            .and_then(|n| n.parse::<u8>().ok())
            .filter(|&n| n <= 15),
    }
}

/// Registers named in a register list `{r4, r5, lr}` (or `{d8, d9}`, `{s0-s3}`): how many.
fn list_len(operands: &str) -> (u8, bool) {
    let inner = operands
        .split_once('{')
        .and_then(|(_, rest)| rest.split_once('}'))
        .map_or("", |(list, _)| list);
    let mut n = 0_u8;
    let mut pc = false;
    for item in inner.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        if let Some((a, b)) = item.split_once('-') {
            let num = |s: &str| s.trim().get(1..).and_then(|d| d.parse::<u8>().ok());
            if let (Some(a), Some(b)) = (num(a), num(b)) {
                n = n.saturating_add(b.saturating_sub(a).saturating_add(1));
                continue;
            }
        }
        // A double register moves two words.
        n = n.saturating_add(if item.starts_with('d') { 2 } else { 1 });
        pc |= item == "pc";
    }
    (n, pc)
}

/// The bit set of the registers inside the brackets of a memory operand.
fn address_registers(operands: &str) -> u16 {
    operands
        .split_once('[')
        .and_then(|(_, rest)| rest.split_once(']'))
        .map_or(0, |(inside, _)| {
            inside
                .split(|c: char| c == ',' || c.is_whitespace())
                .filter_map(register)
                .fold(0, |set, r| set | (1 << r))
        })
}

/// The base mnemonic with the flag-setting `s` and the condition stripped, if `m` is
/// `base`, `base` + condition, `base` + `s`, or `base` + `s` + condition.
fn strip<'a>(m: &'a str, base: &str, s_form: bool) -> Option<&'a str> {
    let rest = m.strip_prefix(base)?;
    let rest = if s_form {
        rest.strip_prefix('s').unwrap_or(rest)
    } else {
        rest
    };
    (rest.is_empty() || CONDITIONS.contains(&rest)).then_some(m.get(..base.len()).unwrap_or(m))
}

/// Mnemonics priced as one simple instruction (data processing and the like).
const SIMPLE: [&str; 67] = [
    "mov", "mvn", "movw", "movt", "add", "addw", "adc", "adr", "sub", "subw", "sbc", "rsb", "mul",
    "mla", "mls", "smull", "umull", "smlal", "umlal", "smul", "smla", "smmul", "smmla", "smmls",
    "smuad", "smusd", "smlad", "smlsd", "umaal", "and", "orr", "orn", "eor", "bic", "lsl", "lsr",
    "asr", "ror", "rrx", "cmp", "cmn", "tst", "teq", "ssat", "usat", "qadd", "qsub", "sxth",
    "sxtb", "uxth", "uxtb", "sxtah", "sxtab", "uxtah", "uxtab", "ubfx", "sbfx", "bfi", "bfc",
    "clz", "rbit", "rev", "rev16", "revsh", "nop", "mrs", "msr",
];

/// Decodes one instruction from QEMU's disassembly of it (capstone's syntax, as
/// `-d in_asm` prints it: `ldr.w r0, [r1, #4]`, `bne #0x1234`, `vadd.f32 s0, s1, s2`).
#[must_use]
pub fn decode(disas: &str, size: u32) -> Insn {
    let size = if size >= 4 { 4 } else { 2 };
    let text = disas.trim().to_ascii_lowercase();
    let (mnemonic, operands) = text
        .split_once(char::is_whitespace)
        .map_or((text.as_str(), ""), |(m, o)| (m, o.trim()));
    // Width qualifiers and data types (`.w`, `.f32`) do not change the price.
    let m = mnemonic.split('.').next().unwrap_or(mnemonic);
    let kind = classify(m, operands);
    Insn { size, kind }
}

fn classify(m: &str, operands: &str) -> Kind {
    let writes_pc = operands.split(',').next().map(str::trim) == Some("pc");
    let any = |bases: &[&str], s_form: bool| bases.iter().any(|b| strip(m, b, s_form).is_some());
    // Branches first: their mnemonics overlap others' prefixes (`bls` is b + ls).
    if any(&["b", "bl", "bx", "blx", "cbz", "cbnz"], false) {
        return Kind::Branch;
    }
    if any(&["tbb", "tbh"], false) {
        return Kind::Table;
    }
    if m.starts_with("it") && m.chars().skip(2).all(|c| c == 't' || c == 'e') {
        return Kind::It;
    }
    if any(
        &[
            "pop", "push", "ldm", "ldmia", "ldmdb", "stm", "stmia", "stmdb", "stmea",
        ],
        false,
    ) || any(
        &[
            "vpush", "vpop", "vldmia", "vldmdb", "vstmia", "vstmdb", "vldm", "vstm",
        ],
        false,
    ) {
        let (n, pc) = list_len(operands);
        return Kind::Multiple { n, pc };
    }
    if any(
        &["ldrex", "ldrexb", "ldrexh", "strex", "strexb", "strexh"],
        false,
    ) {
        return Kind::Exclusive;
    }
    if any(&["ldrd", "strd"], false) {
        return Kind::Double;
    }
    if any(
        &[
            "ldr", "ldrb", "ldrh", "ldrsb", "ldrsh", "ldrt", "ldrbt", "ldrht",
        ],
        false,
    ) {
        if writes_pc {
            return Kind::WritesPc { load: true };
        }
        let dest = operands
            .split(',')
            .next()
            .and_then(register)
            .unwrap_or(u8::MAX);
        return Kind::Load {
            dest,
            addr: address_registers(operands),
        };
    }
    if any(&["str", "strb", "strh", "strt", "strbt", "strht"], false) {
        let inside = operands
            .split_once('[')
            .and_then(|(_, r)| r.split_once(']'))
            .map_or("", |(i, _)| i);
        let reg_offset = inside.split(',').skip(1).any(|t| register(t).is_some());
        return Kind::Store { reg_offset };
    }
    if any(&["sdiv", "udiv"], false) {
        return Kind::Divide;
    }
    if any(&["isb"], false) {
        return Kind::Isb;
    }
    if any(
        &[
            "dmb", "dsb", "cpsid", "cpsie", "wfi", "wfe", "sev", "bkpt", "svc", "clrex",
        ],
        false,
    ) {
        return Kind::Simple;
    }
    if any(&["vdiv", "vsqrt"], false) {
        return Kind::FpuDivide;
    }
    if any(
        &[
            "vmla", "vmls", "vnmla", "vnmls", "vfma", "vfms", "vfnma", "vfnms",
        ],
        false,
    ) {
        return Kind::FpuMac;
    }
    if any(&["vldr", "vstr"], false) {
        return Kind::FpuTwo;
    }
    if strip(m, "vmov", false).is_some() {
        // `vmov r0, r1, d0` / `vmov d0, r0, r1` / `vmov s0, s1, r0, r1`: two core registers.
        let cores = operands
            .split(',')
            .filter(|o| register(o).is_some())
            .count();
        return if cores >= 2 { Kind::FpuTwo } else { Kind::Fpu };
    }
    if any(
        &[
            "vadd", "vsub", "vmul", "vnmul", "vabs", "vneg", "vcvt", "vcvtr", "vcvtb", "vcvtt",
            "vcmp", "vcmpe", "vmrs", "vmsr", "vsel", "vmaxnm", "vminnm", "vrint",
        ],
        false,
    ) {
        return Kind::Fpu;
    }
    if SIMPLE.iter().any(|b| strip(m, b, true).is_some()) {
        return if writes_pc {
            Kind::WritesPc { load: false }
        } else {
            Kind::Simple
        };
    }
    Kind::Unknown
}

/// Cycles of `insn` after `prev` (the instruction executed just before it in the same
/// window, if any); `taken` when the next executed instruction is not the following one.
#[must_use]
pub fn cycles(insn: &Insn, prev: Option<&Insn>, taken: bool) -> u32 {
    let refill = if taken { PIPELINE_REFILL } else { 0 };
    match insn.kind {
        Kind::Simple | Kind::Fpu | Kind::Unknown => 1,
        Kind::Divide => DIVIDE_CYCLES,
        Kind::Load { addr, .. } => match prev.map(|p| p.kind) {
            Some(Kind::Load { dest, .. }) if u32::from(addr) & (1_u32 << dest.min(31)) == 0 => 1,
            _ => 2,
        },
        Kind::Store { reg_offset } => {
            let after_load = matches!(prev.map(|p| p.kind), Some(Kind::Load { .. }));
            if reg_offset && !after_load {
                2
            } else {
                1
            }
        }
        Kind::Double => 3,
        Kind::Exclusive | Kind::FpuTwo => 2,
        Kind::Multiple { n, pc } => 1 + u32::from(n) + if pc { PIPELINE_REFILL } else { 0 },
        Kind::Branch => 1 + refill,
        Kind::Table => 2 + PIPELINE_REFILL,
        Kind::It => match prev {
            Some(p) if p.size == 2 => 0,
            _ => 1,
        },
        Kind::Isb => 1 + PIPELINE_REFILL,
        Kind::WritesPc { load } => (if load { 2 } else { 1 }) + PIPELINE_REFILL,
        Kind::FpuMac => 3,
        Kind::FpuDivide => FP_DIVIDE_CYCLES,
    }
}

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

/// One window as a line of the plugin's output file.
#[must_use]
pub fn window_line(which: Which, w: &Window) -> String {
    let tag = match which {
        Which::Current => "current",
        Which::Velocity => "velocity",
    };
    format!(
        "{tag} {} {} {} {} {} {}",
        w.instructions, w.cycles, w.taken, w.divides, w.fpu, w.unknown
    )
}

/// What the plugin's output file holds.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Trace {
    /// The windows, in order.
    pub windows: Vec<(Which, Window)>,
    /// Windows dropped because an interrupt came into them.
    pub dropped: u32,
}

impl Trace {
    /// Parses the plugin's output file.
    pub fn parse(text: &str) -> Result<Self, String> {
        let mut t = Self::default();
        for line in text.lines().filter(|l| !l.trim().is_empty()) {
            let mut f = line.split_whitespace();
            let tag = f.next().unwrap_or_default();
            let nums: Vec<u32> = f
                .map(str::parse)
                .collect::<Result<_, _>>()
                .map_err(|e| format!("cycle trace: bad line {line:?}: {e}"))?;
            let which = match tag {
                "current" => Which::Current,
                "velocity" => Which::Velocity,
                "dropped" => {
                    t.dropped += nums.first().copied().unwrap_or(0);
                    continue;
                }
                _ => return Err(format!("cycle trace: unknown line {line:?}")),
            };
            let [instructions, cycles, taken, divides, fpu, unknown] = nums[..] else {
                return Err(format!("cycle trace: line {line:?} needs 6 numbers"));
            };
            t.windows.push((
                which,
                Window {
                    instructions,
                    cycles,
                    taken,
                    divides,
                    fpu,
                    unknown,
                },
            ));
        }
        Ok(t)
    }

    /// The windows of one kind.
    pub fn of(&self, which: Which) -> impl Iterator<Item = &Window> {
        self.windows
            .iter()
            .filter(move |(w, _)| *w == which)
            .map(|(_, w)| w)
    }
}

/// Mean and worst case of one figure over the windows.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Stat {
    /// Windows.
    pub n: usize,
    /// Mean.
    pub mean: f64,
    /// Worst case.
    pub max: u32,
}

impl Stat {
    /// Over `values`.
    pub fn of(values: impl Iterator<Item = u32>) -> Self {
        let (mut n, mut sum, mut max) = (0_usize, 0_u64, 0_u32);
        for v in values {
            n += 1;
            sum += u64::from(v);
            max = max.max(v);
        }
        let mean = if n == 0 { 0.0 } else { sum as f64 / n as f64 };
        Self { n, mean, max }
    }
}

/// The figures of one tick kind.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TickFigures {
    /// Instructions of the body.
    pub instructions: Stat,
    /// Cycles of the body.
    pub cycles: Stat,
    /// Taken branches (for the flash bound).
    pub taken: Stat,
}

impl TickFigures {
    /// Over the windows of `which`.
    #[must_use]
    pub fn of(trace: &Trace, which: Which) -> Self {
        Self {
            instructions: Stat::of(trace.of(which).map(|w| w.instructions)),
            cycles: Stat::of(trace.of(which).map(|w| w.cycles)),
            taken: Stat::of(trace.of(which).map(|w| w.taken)),
        }
    }
}

/// The cycle figures of a `fw-bench` run: per tick and per 4 kHz period.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BenchFigures {
    /// The current tick.
    pub current: TickFigures,
    /// The velocity tick.
    pub velocity: TickFigures,
    /// Mean period: current + velocity / 2, with each interrupt's entry and exit [cycles].
    pub period_mean: f64,
    /// Worst period: worst current + worst velocity / 2 (rounded up), with each
    /// interrupt's entry and exit [cycles].
    pub period_worst: u32,
    /// Mean and worst period [instructions], as the cycles.
    pub period_instructions_mean: f64,
    /// Worst period [instructions].
    pub period_instructions_worst: u32,
    /// Windows dropped (an interrupt came into them).
    pub dropped: u32,
    /// Instructions of no known class over the run (priced 1).
    pub unknown: u32,
}

/// Exception entry and exit of one interrupt [cycles].
pub const EXCEPTION_CYCLES: u32 = EXCEPTION_ENTRY + EXCEPTION_EXIT;

impl BenchFigures {
    /// From a trace of `fw-bench`.
    #[must_use]
    pub fn of(trace: &Trace) -> Self {
        let current = TickFigures::of(trace, Which::Current);
        let velocity = TickFigures::of(trace, Which::Velocity);
        let exc = f64::from(EXCEPTION_CYCLES);
        let period_mean = current.cycles.mean + exc + (velocity.cycles.mean + exc) / 2.0;
        let period_worst = current.cycles.max
            + EXCEPTION_CYCLES
            + (velocity.cycles.max + EXCEPTION_CYCLES).div_ceil(2);
        Self {
            current,
            velocity,
            period_mean,
            period_worst,
            period_instructions_mean: current.instructions.mean + velocity.instructions.mean / 2.0,
            period_instructions_worst: current.instructions.max
                + velocity.instructions.max.div_ceil(2),
            dropped: trace.dropped,
            unknown: trace.windows.iter().map(|(_, w)| w.unknown).sum(),
        }
    }

    /// The report's lines.
    #[must_use]
    pub fn lines(&self) -> Vec<String> {
        let mut out = vec![format!(
            "cycle estimate: every instruction QEMU executed in each measured window (TCG plugin), \
             priced by the Cortex-M4 TRM's timings: pipeline refill P = {PIPELINE_REFILL} per taken branch, \
             divides at their worst case ({DIVIDE_CYCLES}), flash at 0 wait states (ART accelerator hits), \
             exception entry {EXCEPTION_ENTRY} + exit {EXCEPTION_EXIT} per interrupt (lazy FP stacking); \
             windows as the SysTick figures (net of the measuring code)"
        )];
        for (name, t) in [("current", &self.current), ("velocity", &self.velocity)] {
            out.push(format!(
                "{name}_tick_cycles: mean {:.0} worst {} (body; {} with exception entry/exit: mean {:.0} worst {}); \
                 instructions mean {:.1} worst {}; over {} ticks",
                t.cycles.mean,
                t.cycles.max,
                name,
                t.cycles.mean + f64::from(EXCEPTION_CYCLES),
                t.cycles.max + EXCEPTION_CYCLES,
                t.instructions.mean,
                t.instructions.max,
                t.cycles.n
            ));
        }
        out.push(format!(
            "period_cycles: mean {:.0} worst {} (one 4 kHz period: current + velocity/2, each with exception entry/exit; \
             worst = worst current + worst velocity/2)",
            self.period_mean, self.period_worst
        ));
        out.push(format!(
            "period_instructions (traced): mean {:.1} worst {}",
            self.period_instructions_mean, self.period_instructions_worst
        ));
        let flash = f64::from(FLASH_WAIT_STATES)
            * (self.current.taken.mean + self.velocity.taken.mean / 2.0);
        let mut note = format!(
            "cycle bounds: P = 1 or 3 instead of {PIPELINE_REFILL} moves the mean period by ∓/± {:.0}; \
             a flash miss ({FLASH_WAIT_STATES} wait states at 168 MHz) on every taken branch would add up to {flash:.0}",
            self.current.taken.mean + self.velocity.taken.mean / 2.0
        );
        if self.dropped > 0 || self.unknown > 0 {
            let _ = write!(
                note,
                "; {} windows dropped (interrupted), {} instructions of no known class priced 1",
                self.dropped, self.unknown
            );
        }
        out.push(note);
        out
    }
}

/// The value of a `name: N` line of the firmware's log, if there is one.
#[must_use]
pub fn log_value(lines: &[String], name: &str) -> Option<u32> {
    lines.iter().find_map(|l| {
        l.strip_prefix(name)
            .and_then(|r| r.strip_prefix(':'))
            .and_then(|r| r.split_whitespace().next())
            .and_then(|v| v.parse().ok())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn k(s: &str) -> Kind {
        decode(s, 2).kind
    }

    #[test]
    fn mnemonics_decode_into_their_classes() {
        assert_eq!(k("adds r0, r0, #1"), Kind::Simple);
        assert_eq!(k("movlt r1, r2"), Kind::Simple);
        assert_eq!(k("mls r0, r0, r1, r10"), Kind::Simple);
        assert_eq!(k("smlal r0, r1, r2, r3"), Kind::Simple);
        assert_eq!(k("udiv r0, r1, r2"), Kind::Divide);
        assert_eq!(k("sdiv.w r0, r1, r2"), Kind::Divide);
        assert_eq!(k("bls #0x100"), Kind::Branch);
        assert_eq!(k("bxeq lr"), Kind::Branch);
        assert_eq!(k("bl #0x15a3c"), Kind::Branch);
        assert_eq!(k("cbz r0, #0x20"), Kind::Branch);
        assert_eq!(k("itt ne"), Kind::It);
        assert_eq!(k("ittte ne"), Kind::It);
        assert_eq!(k("pop {r7, pc}"), Kind::Multiple { n: 2, pc: true });
        assert_eq!(
            k("poplo {r4, r5, r6, r7, pc}"),
            Kind::Multiple { n: 5, pc: true }
        );
        assert_eq!(
            k("push.w {r8, r9, sl, fp}"),
            Kind::Multiple { n: 4, pc: false }
        );
        assert_eq!(k("vpush {d8, d9}"), Kind::Multiple { n: 4, pc: false });
        assert_eq!(k("stm r0!, {r2}"), Kind::Multiple { n: 1, pc: false });
        assert_eq!(
            k("ldr.w r0, [fp]"),
            Kind::Load {
                dest: 0,
                addr: 1 << 11
            }
        );
        assert_eq!(
            k("ldrls r1, [r2, r3, lsl #2]"),
            Kind::Load {
                dest: 1,
                addr: (1 << 2) | (1 << 3)
            }
        );
        assert_eq!(k("ldr pc, [sp], #4"), Kind::WritesPc { load: true });
        assert_eq!(k("mov pc, lr"), Kind::WritesPc { load: false });
        assert_eq!(k("str r1, [r0]"), Kind::Store { reg_offset: false });
        assert_eq!(
            k("strb.w r0, [sp, #0x64]"),
            Kind::Store { reg_offset: false }
        );
        assert_eq!(k("str r1, [r0, r2]"), Kind::Store { reg_offset: true });
        assert_eq!(k("ldrd r0, r1, [r2]"), Kind::Double);
        assert_eq!(k("ldrex sl, [r8, #0x14]"), Kind::Exclusive);
        assert_eq!(k("strexb r3, r2, [r0]"), Kind::Exclusive);
        assert_eq!(k("vadd.f32 s0, s1, s2"), Kind::Fpu);
        assert_eq!(k("vmov s8, r0"), Kind::Fpu);
        assert_eq!(k("vmov r0, r1, d0"), Kind::FpuTwo);
        assert_eq!(k("vcvt.f32.u32 s18, s8"), Kind::Fpu);
        assert_eq!(k("vfma.f32 s0, s1, s2"), Kind::FpuMac);
        assert_eq!(k("vdiv.f32 s0, s1, s2"), Kind::FpuDivide);
        assert_eq!(k("vsqrt.f32 s0, s1"), Kind::FpuDivide);
        assert_eq!(k("vldr s26, [r8, #0x28]"), Kind::FpuTwo);
        assert_eq!(k("isb sy"), Kind::Isb);
        assert_eq!(k("cpsid i"), Kind::Simple);
        assert_eq!(k("frobnicate r0"), Kind::Unknown);
    }

    #[test]
    fn loads_pipeline_unless_the_address_needs_the_previous_result() {
        let l1 = decode("ldr r0, [r1]", 2);
        let independent = decode("ldr r2, [r1, #4]", 2);
        let dependent = decode("ldr r3, [r0]", 2);
        let store = decode("str r2, [r1]", 2);
        assert_eq!(cycles(&l1, None, false), 2);
        assert_eq!(cycles(&independent, Some(&l1), false), 1);
        assert_eq!(cycles(&dependent, Some(&l1), false), 2);
        assert_eq!(
            cycles(&l1, Some(&store), false),
            2,
            "nothing pipelines after a store"
        );
        assert_eq!(cycles(&store, None, false), 1);
    }

    #[test]
    fn branches_cost_the_refill_only_when_taken() {
        let b = decode("bne #0x10", 2);
        assert_eq!(cycles(&b, None, false), 1);
        assert_eq!(cycles(&b, None, true), 1 + PIPELINE_REFILL);
        let it = decode("it ne", 2);
        let wide = decode("cmp.w r0, #0x7d0", 4);
        assert_eq!(
            cycles(&it, Some(&decode("cmp r0, r1", 2)), false),
            0,
            "folded"
        );
        assert_eq!(cycles(&it, Some(&wide), false), 1);
    }

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
    }

    #[test]
    fn the_trace_file_round_trips_and_the_period_adds_half_a_velocity_tick() {
        let w = |i, c| Window {
            instructions: i,
            cycles: c,
            ..Window::default()
        };
        let mut text = String::new();
        for (which, win) in [
            (Which::Current, w(400, 500)),
            (Which::Current, w(420, 540)),
            (Which::Velocity, w(470, 600)),
        ] {
            text.push_str(&window_line(which, &win));
            text.push('\n');
        }
        text.push_str("dropped 2\n");
        let trace = Trace::parse(&text).unwrap_or_default();
        assert_eq!(trace.windows.len(), 3);
        assert_eq!(trace.dropped, 2);
        let f = BenchFigures::of(&trace);
        assert_eq!(f.current.cycles.max, 540);
        assert!((f.current.cycles.mean - 520.0).abs() < 1e-9);
        assert_eq!(f.period_worst, 540 + 22 + (600 + 22) / 2);
        assert_eq!(f.period_instructions_worst, 420 + 235);
        assert!(Trace::parse("current 1 2\n").is_err());
        let lines = vec!["period_cycle_budget: 900".to_string()];
        assert_eq!(log_value(&lines, "period_cycle_budget"), Some(900));
        assert_eq!(log_value(&lines, "period_cycles"), None);
    }
}
