//! Decoding QEMU's disassembly of an instruction into the class that prices it.

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
    /// Its size \[bytes\]: 2 or 4.
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

/// Whether `m` is one of `bases` (with a condition, and a flag-setting `s` if `s_form`).
fn is_any(m: &str, bases: &[&str], s_form: bool) -> bool {
    bases.iter().any(|b| strip(m, b, s_form).is_some())
}

/// The class of mnemonic `m` (width and data type stripped) with `operands`: tried class
/// by class in this order, since some mnemonics are prefixes of others (`bls` is b + ls).
fn classify(m: &str, operands: &str) -> Kind {
    let writes_pc = operands.split(',').next().map(str::trim) == Some("pc");
    control_flow(m)
        .or_else(|| memory(m, operands, writes_pc))
        .or_else(|| system(m))
        .or_else(|| fpu(m, operands))
        .or_else(|| data_processing(m, writes_pc))
        .unwrap_or(Kind::Unknown)
}

/// Branches, table branches and `IT`.
fn control_flow(m: &str) -> Option<Kind> {
    // Branches first: their mnemonics overlap others' prefixes (`bls` is b + ls).
    if is_any(m, &["b", "bl", "bx", "blx", "cbz", "cbnz"], false) {
        return Some(Kind::Branch);
    }
    if is_any(m, &["tbb", "tbh"], false) {
        return Some(Kind::Table);
    }
    if m.starts_with("it") && m.chars().skip(2).all(|c| c == 't' || c == 'e') {
        return Some(Kind::It);
    }
    None
}

/// Loads and stores of the core registers: multiple, exclusive, double, single (and the
/// FPU's multiple forms).
fn memory(m: &str, operands: &str, writes_pc: bool) -> Option<Kind> {
    if is_any(
        m,
        &[
            "pop", "push", "ldm", "ldmia", "ldmdb", "stm", "stmia", "stmdb", "stmea",
        ],
        false,
    ) || is_any(
        m,
        &[
            "vpush", "vpop", "vldmia", "vldmdb", "vstmia", "vstmdb", "vldm", "vstm",
        ],
        false,
    ) {
        let (n, pc) = list_len(operands);
        return Some(Kind::Multiple { n, pc });
    }
    if is_any(
        m,
        &["ldrex", "ldrexb", "ldrexh", "strex", "strexb", "strexh"],
        false,
    ) {
        return Some(Kind::Exclusive);
    }
    if is_any(m, &["ldrd", "strd"], false) {
        return Some(Kind::Double);
    }
    if is_any(
        m,
        &[
            "ldr", "ldrb", "ldrh", "ldrsb", "ldrsh", "ldrt", "ldrbt", "ldrht",
        ],
        false,
    ) {
        return Some(single_load(operands, writes_pc));
    }
    if is_any(m, &["str", "strb", "strh", "strt", "strbt", "strht"], false) {
        let inside = operands
            .split_once('[')
            .and_then(|(_, r)| r.split_once(']'))
            .map_or("", |(i, _)| i);
        let reg_offset = inside.split(',').skip(1).any(|t| register(t).is_some());
        return Some(Kind::Store { reg_offset });
    }
    None
}

/// A single load: its destination and address registers, or a PC write.
fn single_load(operands: &str, writes_pc: bool) -> Kind {
    if writes_pc {
        return Kind::WritesPc { load: true };
    }
    let dest = operands
        .split(',')
        .next()
        .and_then(register)
        .unwrap_or(u8::MAX);
    Kind::Load {
        dest,
        addr: address_registers(operands),
    }
}

/// Divides, `ISB`, barriers, interrupt masks and hints.
fn system(m: &str) -> Option<Kind> {
    if is_any(m, &["sdiv", "udiv"], false) {
        return Some(Kind::Divide);
    }
    if is_any(m, &["isb"], false) {
        return Some(Kind::Isb);
    }
    if is_any(
        m,
        &[
            "dmb", "dsb", "cpsid", "cpsie", "wfi", "wfe", "sev", "bkpt", "svc", "clrex",
        ],
        false,
    ) {
        return Some(Kind::Simple);
    }
    None
}

/// The FPU's instructions other than its multiple loads and stores.
fn fpu(m: &str, operands: &str) -> Option<Kind> {
    if is_any(m, &["vdiv", "vsqrt"], false) {
        return Some(Kind::FpuDivide);
    }
    if is_any(
        m,
        &[
            "vmla", "vmls", "vnmla", "vnmls", "vfma", "vfms", "vfnma", "vfnms",
        ],
        false,
    ) {
        return Some(Kind::FpuMac);
    }
    if is_any(m, &["vldr", "vstr"], false) {
        return Some(Kind::FpuTwo);
    }
    if strip(m, "vmov", false).is_some() {
        // `vmov r0, r1, d0` / `vmov d0, r0, r1` / `vmov s0, s1, r0, r1`: two core registers.
        let cores = operands
            .split(',')
            .filter(|o| register(o).is_some())
            .count();
        return Some(if cores >= 2 { Kind::FpuTwo } else { Kind::Fpu });
    }
    if is_any(
        m,
        &[
            "vadd", "vsub", "vmul", "vnmul", "vabs", "vneg", "vcvt", "vcvtr", "vcvtb", "vcvtt",
            "vcmp", "vcmpe", "vmrs", "vmsr", "vsel", "vmaxnm", "vminnm", "vrint",
        ],
        false,
    ) {
        return Some(Kind::Fpu);
    }
    None
}

/// Data processing, moves, compares, multiplies ([`SIMPLE`], with their `s` forms).
fn data_processing(m: &str, writes_pc: bool) -> Option<Kind> {
    if !is_any(m, &SIMPLE, true) {
        return None;
    }
    Some(if writes_pc {
        Kind::WritesPc { load: false }
    } else {
        Kind::Simple
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
}
