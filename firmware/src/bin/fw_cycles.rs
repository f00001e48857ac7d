//! Microbenchmarks of the cycle estimate (QEMU; run by fw-runner's test `cycles`): short
//! instruction sequences whose Cortex-M4 cycle counts the Technical Reference Manual fixes
//! (dependent ADDs, multiplies, dependent and independent loads, stores, PUSH/POP, a
//! taken-branch loop, divides with small and large operands, FPU operations), each timed
//! exactly as `fw-bench` times a tick: the window mark `cycle_window_arm_current`, then a
//! SysTick read, the sequence, a SysTick read. The runner's plugin prices each window; the
//! test compares the figures with the manual's. The order of the windows is the order of
//! `BENCHES` in `fw-runner/tests/cycles.rs`.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod target {
    // SAFETY (whole module): inline assembly on registers the compiler assigns, on the
    // module's own statics, and SysTick reads.
    #![allow(unsafe_code)]

    use core::arch::asm;
    use core::sync::atomic::{AtomicU32, Ordering};

    use cortex_m_rt::entry;
    use firmware as _;

    /// SysTick's current-value register.
    const SYST_CVR: u32 = 0xE000_E018;

    static ARMED: AtomicU32 = AtomicU32::new(0);

    /// The window mark (see `fw_bench/window.rs`).
    #[no_mangle]
    #[inline(never)]
    pub extern "C" fn cycle_window_arm_current() {
        // SAFETY: a volatile write of the atomic's own storage, single context.
        unsafe { core::ptr::write_volatile(ARMED.as_ptr(), 1) };
    }

    /// A word that holds its own address (a pointer chase) and words to load and store.
    static mut CHAIN: u32 = 0;
    static mut WORDS: [u32; 8] = [1, 2, 3, 4, 5, 6, 7, 8];
    static mut FLOATS: [f32; 2] = [2.0, 3.0];

    /// One window: arm, SysTick read, `$body`, SysTick read.
    macro_rules! window {
        ($($body:tt)*) => {{
            cycle_window_arm_current();
            asm!(
                "ldr {t}, [{syst}]",
                $($body)*
                syst = in(reg) SYST_CVR,
                t = out(reg) _,
            );
        }};
    }

    #[entry]
    fn main() -> ! {
        let chain = &raw mut CHAIN;
        let words = (&raw mut WORDS).cast::<u32>();
        let floats = (&raw mut FLOATS).cast::<f32>();
        unsafe {
            core::ptr::write_volatile(chain, chain as u32);
            // 1. 16 dependent ADDs: 1 cycle each.
            window!(
                ".rept 16", "adds {a}, {a}, #1", ".endr",
                "ldr {t}, [{syst}]",
                a = inout(reg) 0_u32 => _,
            );
            // 2. MUL, MLA, UMULL, SMLAL, 4 of each: 1 cycle each on the M4.
            window!(
                ".rept 4", "mul {a}, {a}, {b}", ".endr",
                ".rept 4", "mla {a}, {a}, {b}, {a}", ".endr",
                ".rept 4", "umull {c}, {d}, {a}, {b}", ".endr",
                ".rept 4", "smlal {c}, {d}, {a}, {b}", ".endr",
                "ldr {t}, [{syst}]",
                a = inout(reg) 3_u32 => _,
                b = in(reg) 5_u32,
                c = out(reg) _,
                d = out(reg) _,
            );
            // 3. 8 dependent loads (each address is the previous load's result): 2 each.
            window!(
                ".rept 8", "ldr {p}, [{p}]", ".endr",
                "ldr {t}, [{syst}]",
                p = inout(reg) chain => _,
            );
            // 4. 8 independent loads: 2 for the first, 1 for each pipelined one after.
            window!(
                "ldr {a}, [{p}]", "ldr {b}, [{p}, #4]", "ldr {a}, [{p}, #8]", "ldr {b}, [{p}, #12]",
                "ldr {a}, [{p}, #16]", "ldr {b}, [{p}, #20]", "ldr {a}, [{p}, #24]", "ldr {b}, [{p}, #28]",
                "ldr {t}, [{syst}]",
                p = in(reg) words,
                a = out(reg) _,
                b = out(reg) _,
            );
            // 5. 4 stores with an immediate offset: 1 each.
            window!(
                "str {v}, [{p}]", "str {v}, [{p}, #4]", "str {v}, [{p}, #8]", "str {v}, [{p}, #12]",
                "ldr {t}, [{syst}]",
                p = in(reg) words,
                v = in(reg) 9_u32,
            );
            // 6. PUSH and POP of 4 registers: 1 + N each.
            window!(
                "push {{r4, r5, r8, r9}}",
                "pop {{r4, r5, r8, r9}}",
                "ldr {t}, [{syst}]",
            );
            // 7. A loop of 8 iterations: the branch taken 7 times (1 + P), not taken once (1).
            window!(
                "movs {n}, #8",
                "2:",
                "subs {n}, {n}, #1",
                "bne 2b",
                "ldr {t}, [{syst}]",
                n = out(reg) _,
            );
            // 8. 4 UDIVs of small operands (100 / 7): 2 to 12 each by the manual.
            window!(
                ".rept 4", "udiv {q}, {a}, {b}", ".endr",
                "ldr {t}, [{syst}]",
                a = in(reg) 100_u32,
                b = in(reg) 7_u32,
                q = out(reg) _,
            );
            // 9. 4 UDIVs of large operands (0xFFFF_FFFF / 3): 2 to 12 each by the manual.
            window!(
                ".rept 4", "udiv {q}, {a}, {b}", ".endr",
                "ldr {t}, [{syst}]",
                a = in(reg) 0xFFFF_FFFF_u32,
                b = in(reg) 3_u32,
                q = out(reg) _,
            );
            // 10. FPU: 2 VLDR (2 each), 4 VADD and 4 VMUL (1 each), VDIV and VSQRT (14 each),
            //     VSTR (2).
            window!(
                "vldr s0, [{p}]", "vldr s1, [{p}, #4]",
                ".rept 4", "vadd.f32 s2, s0, s1", ".endr",
                ".rept 4", "vmul.f32 s2, s2, s1", ".endr",
                "vdiv.f32 s3, s2, s1",
                "vsqrt.f32 s3, s3",
                "vstr s3, [{p}]",
                "ldr {t}, [{syst}]",
                p = in(reg) floats,
                out("s0") _, out("s1") _, out("s2") _, out("s3") _,
            );
        }
        let _ = ARMED.load(Ordering::Relaxed);
        defmt::info!("fw-cycles: 10 microbenchmarks ran");
        firmware::rt::exit(true)
    }
}

#[cfg(not(target_os = "none"))]
fn main() {
    println!("fw-cycles: runs in QEMU under fw-runner's cycle tracer (cargo test -p fw-runner --test cycles)");
}
