//! Validation of the cycle estimate (`fw-runner --cycles`, the pricing of `cargo fw-bench`)
//! against the Cortex-M4 Technical Reference Manual: the firmware's `fw-cycles` image runs
//! microbenchmarks whose cycle counts the manual fixes, through the same pipeline as
//! `fw-bench` (QEMU, this crate's TCG plugin, the price table), and each window's
//! instructions and estimated cycles must equal the manual's figures.
//!
//! Builds the image into `<target>/firmware` (as the PIL tests do; installs the ARM target
//! and QEMU on first use).

use fw_runner::cycles::{Trace, Which, DIVIDE_CYCLES, PIPELINE_REFILL};
use fw_runner::provision;
use std::fs::File;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

/// One microbenchmark: what it runs, its instructions, and its cycles by the manual
/// (M4 TRM, "Table of processor instructions" and the FPU's instruction table).
struct Bench {
    name: &'static str,
    instructions: u32,
    cycles: u32,
    /// The manual's range when it gives one (divides: 2 to 12 each by operand size).
    manual_range: Option<(u32, u32)>,
}

const P: u32 = PIPELINE_REFILL;

/// In the order `firmware/src/bin/fw_cycles.rs` runs them.
const BENCHES: [Bench; 10] = [
    Bench {
        name: "16 dependent ADDs (1 each)",
        instructions: 16,
        cycles: 16,
        manual_range: None,
    },
    Bench {
        name: "4 each of MUL, MLA, UMULL, SMLAL (1 each on the M4)",
        instructions: 16,
        cycles: 16,
        manual_range: None,
    },
    Bench {
        name: "8 dependent LDRs, a pointer chase (2 each: no pipelining)",
        instructions: 8,
        cycles: 16,
        manual_range: None,
    },
    Bench {
        name: "8 independent LDRs (2, then 1 each pipelined)",
        instructions: 8,
        cycles: 9,
        manual_range: None,
    },
    Bench {
        name: "4 STRs, immediate offset (1 each)",
        instructions: 4,
        cycles: 4,
        manual_range: None,
    },
    Bench {
        name: "PUSH and POP of 4 registers (1 + N each)",
        instructions: 2,
        cycles: 10,
        manual_range: None,
    },
    Bench {
        name: "loop of 8: MOVS, 8 SUBS, BNE taken 7 times (1 + P), not taken once (1)",
        instructions: 17,
        cycles: 1 + 8 + 7 * (1 + P) + 1,
        manual_range: None,
    },
    Bench {
        name: "4 UDIVs, small operands 100 / 7",
        instructions: 4,
        cycles: 4 * DIVIDE_CYCLES,
        manual_range: Some((4 * 2, 4 * 12)),
    },
    Bench {
        name: "4 UDIVs, large operands 0xFFFFFFFF / 3",
        instructions: 4,
        cycles: 4 * DIVIDE_CYCLES,
        manual_range: Some((4 * 2, 4 * 12)),
    },
    Bench {
        name: "FPU: 2 VLDR (2), 4 VADD, 4 VMUL (1), VDIV, VSQRT (14), VSTR (2)",
        instructions: 13,
        cycles: 2 * 2 + 4 + 4 + 14 + 14 + 2,
        manual_range: None,
    },
];

fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map_or_else(|| PathBuf::from("."), Path::to_path_buf)
}

/// Builds `fw-cycles` into `<target>/firmware` (under the image builds' lock file) and
/// returns a copy of it in `dir`.
fn build_image(dir: &Path) -> PathBuf {
    let root = workspace_root();
    provision::ensure_arm_target(&root).unwrap_or_else(|e| unreachable!("{e}"));
    let target_dir = std::env::var_os("CARGO_TARGET_DIR")
        .map_or_else(|| root.join("target"), PathBuf::from)
        .join("firmware");
    std::fs::create_dir_all(&target_dir).unwrap_or_else(|e| unreachable!("{e}"));
    let lock = File::create(target_dir.join("stiffdrive-images.lock"))
        .unwrap_or_else(|e| unreachable!("{e}"));
    lock.lock().unwrap_or_else(|e| unreachable!("{e}"));
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let status = Command::new(cargo)
        .current_dir(&root)
        .args([
            "build",
            "-p",
            "firmware",
            "--release",
            "--target",
            provision::ARM_TARGET,
        ])
        .args(["--bin", "fw-cycles"])
        .env("CARGO_TARGET_DIR", &target_dir)
        .env_remove("STIFFDRIVE_DRIVE")
        .stdout(Stdio::null())
        .status()
        .unwrap_or_else(|e| unreachable!("cannot run cargo: {e}"));
    assert!(status.success(), "building fw-cycles failed: {status}");
    let image = dir.join("fw-cycles");
    std::fs::copy(
        target_dir
            .join(provision::ARM_TARGET)
            .join("release/fw-cycles"),
        &image,
    )
    .unwrap_or_else(|e| unreachable!("{e}"));
    image
}

#[test]
fn microbenchmarks_price_as_the_cortex_m4_manual_says() {
    let dir = tempfile::tempdir().unwrap_or_else(|e| unreachable!("{e}"));
    let image = build_image(dir.path());
    let trace_file = dir.path().join("trace.txt");
    let out = Command::new(env!("CARGO_BIN_EXE_fw-runner"))
        .arg(&image)
        .args(["--plain-log", "--cycles"])
        .env("CYCLE_TRACE", &trace_file)
        .env_remove("QEMU_EXTRA")
        .stdin(Stdio::null())
        .output()
        .unwrap_or_else(|e| unreachable!("cannot run fw-runner: {e}"));
    let log = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success() && log.contains("fw-cycles: 10 microbenchmarks ran"),
        "fw-runner failed ({}): {log}\n{}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(&trace_file).unwrap_or_else(|e| unreachable!("{e}"));
    let trace = Trace::parse(&text).unwrap_or_else(|e| unreachable!("{e}"));
    let windows: Vec<_> = trace.of(Which::Current).collect();
    assert_eq!(
        windows.len(),
        BENCHES.len(),
        "one window per microbenchmark: {text}"
    );
    let mut failures = Vec::new();
    for (b, w) in BENCHES.iter().zip(windows) {
        let line = format!(
            "{}: {} instructions, estimate {} cycles, manual {}",
            b.name,
            w.instructions,
            w.cycles,
            b.manual_range
                .map_or_else(|| b.cycles.to_string(), |(lo, hi)| format!("{lo} to {hi}"))
        );
        println!("{line}");
        if let Some((lo, hi)) = b.manual_range {
            assert!(
                (lo..=hi).contains(&w.cycles),
                "{line}: outside the manual's range"
            );
        }
        if w.instructions != b.instructions || w.cycles != b.cycles || w.unknown != 0 {
            failures.push(line);
        }
    }
    assert!(
        failures.is_empty(),
        "estimates off the manual:\n{}",
        failures.join("\n")
    );
}

#[test]
fn an_image_without_window_marks_is_refused_by_name() {
    let dir = tempfile::tempdir().unwrap_or_else(|e| unreachable!("{e}"));
    let not_elf = dir.path().join("fw.elf");
    std::fs::write(&not_elf, b"not an elf").unwrap_or_else(|e| unreachable!("{e}"));
    let err = fw_runner::runner::elf_marks(&not_elf)
        .err()
        .unwrap_or_default();
    assert!(err.contains("not an ELF image"), "{err}");
}
