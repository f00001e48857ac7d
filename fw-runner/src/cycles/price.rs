//! The price of one instruction on the Cortex-M4 (the module's list in [`super`]) and the
//! timing constants it uses.

use super::decode::{Insn, Kind};

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
/// Exception entry and exit of one interrupt [cycles].
pub const EXCEPTION_CYCLES: u32 = EXCEPTION_ENTRY + EXCEPTION_EXIT;

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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cycles::decode;

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
}
