//! `stiffdrive identify --board --qemu --out D` as a user first runs it: no `--config` (the
//! image's baked `configs/machines/table1.toml`), no `--set`, so identify's default
//! measurement: 32 PRBS periods of 8191 ticks at ±0.3 pu (65.5 s at 4 kHz, four times the
//! board's 65,536-sample ring, which the board streams while it records), then the 1.5 s
//! lost-motion test. The `board` image's virtual machine is the file's `[plant]` (two
//! inertias, a 5 %-damped shaft, 0.5° of lost motion), and the fit must find that machine
//! with the targets of host identify's own tests (`tests/it/workflows/identify.rs`): Jm and
//! Jl within 5 %, anti-resonance and resonance within 3 %, lost motion within one count or
//! 10 %.
//!
//! QEMU runs the loops in real time, so the command lasts at least its 67 s of ticks; about
//! 110 s here beside the other board cases on 2 cores.
//! The board runs both loops from one tick source (`firmware/src/rig.rs`), so the records,
//! and the estimates, are the same on every run however loaded the host is.

use plant_host::MechanicsConfig;
use std::process::Command;

/// The image's baked machine file, `identify --board`'s default `--config`.
const CONFIG: &str = "configs/machines/table1.toml";

/// The file's `[plant]`: the virtual machine the image carries.
fn truth() -> (MechanicsConfig, u32) {
    let m = machine_file::load(std::path::Path::new(CONFIG)).unwrap();
    (m.plant.mechanics, m.plant.counts_per_rev())
}

/// The estimate `name` of `identify.json`.
pub(crate) fn estimate(json: &serde_json::Value, name: &str) -> f64 {
    json["estimates"]
        .as_array()
        .unwrap()
        .iter()
        .find(|e| e["name"] == name)
        .and_then(|e| e["value"].as_f64())
        .unwrap_or_else(|| panic!("no estimate {name} in identify.json"))
}

pub fn identify_on_the_board_with_its_defaults_recovers_the_qemu_machine() {
    fw_runner::provision::ensure_qemu().unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("id");
    let run = Command::new(env!("CARGO_BIN_EXE_stiffdrive"))
        .args(["identify", "--board", "--qemu", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&run.stdout);
    eprintln!("{stdout}{}", String::from_utf8_lossy(&run.stderr));
    assert!(run.status.success());
    assert!(stdout.contains("measured on the board"), "{stdout}");
    for f in [
        "plant.toml",
        "identify.json",
        "identify.md",
        "bode.png",
        "bode.svg",
    ] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("identify.json")).unwrap()).unwrap();
    assert!(json["measured_on"].as_str().unwrap().contains("QEMU"));
    // The whole default record after its 0.5 s settling: 262,112 - 2,000 ticks at 4 kHz.
    let record_s = json["record_s"].as_f64().unwrap();
    assert!((record_s - 65.028).abs() < 1e-9, "record of {record_s} s");

    let (m, cpr) = truth();
    let resonance_hz = m.derived().resonance_rad_s / std::f64::consts::TAU;
    let rows = [
        ("motor_inertia_s", m.motor_inertia_s, 0.05),
        ("load_inertia_s", m.load_inertia_s, 0.05),
        ("anti_resonance_hz", m.anti_resonance_hz, 0.03),
        ("resonance_hz", resonance_hz, 0.03),
    ];
    let mut failures = Vec::new();
    for (name, true_value, limit) in rows {
        let fitted = estimate(&json, name);
        let err = fitted / true_value - 1.0;
        eprintln!(
            "board identify: {name} {fitted:.5}, true {true_value:.5}: {:+.2} % (limit {} %)",
            100.0 * err,
            100.0 * limit
        );
        if err.is_nan() || err.abs() > limit {
            failures.push(format!("{name} off by {:+.2} %", 100.0 * err));
        }
    }
    let counts = |deg: f64| deg * f64::from(cpr) / 360.0;
    let lm_err = counts(estimate(&json, "backlash_deg")) - counts(m.backlash_deg);
    let lm_limit = (0.1 * counts(m.backlash_deg)).max(1.0);
    eprintln!(
        "board identify: lost motion {:.3} counts, true {:.3}: {lm_err:+.3} (limit {lm_limit:.3})",
        counts(estimate(&json, "backlash_deg")),
        counts(m.backlash_deg)
    );
    if lm_err.is_nan() || lm_err.abs() > lm_limit {
        failures.push(format!("lost motion off by {lm_err:+.3} counts"));
    }
    assert!(failures.is_empty(), "{failures:#?}");
}
