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
//! Executing `cycle_window_next_group` starts another group of windows (`fw-bench`'s
//! next drive), reported and gated on its own.
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

mod decode;
mod figures;
mod price;
mod trace;
mod tracker;

pub use decode::{decode, Insn, Kind};
pub use figures::{log_value, log_values, BenchFigures, Stat, TickFigures};
pub use price::{
    cycles, DIVIDE_CYCLES, EXCEPTION_CYCLES, EXCEPTION_ENTRY, EXCEPTION_EXIT, FLASH_WAIT_STATES,
    FP_DIVIDE_CYCLES, PIPELINE_REFILL,
};
pub use trace::{window_line, Trace};
pub use tracker::{Marks, Tracker, Which, Window, SYST_CVR};
