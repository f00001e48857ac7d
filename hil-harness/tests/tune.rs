//! `tune` on a machine no shipped config describes: the design must be stable in the loop
//! and give less shaft-torque ripple after a load step than the no-AFB design tuned by the
//! same constraints.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use hil_harness::experiments::tune::{candidates, search, without_afb, Candidate, Constraints};

/// Table 1's file with another machine: heavier, softer, more lost motion, a finer encoder.
fn other_machine(dir: &std::path::Path) -> String {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../configs/table1.toml");
    let text = std::fs::read_to_string(root).unwrap();
    let mut doc: toml::Table = text.parse().unwrap();
    let plant = doc.get_mut("plant").and_then(|v| v.as_table_mut()).unwrap();
    for (k, v) in [
        ("motor_inertia_s", toml::Value::Float(0.21)),
        ("load_inertia_s", toml::Value::Float(1.37)),
        ("anti_resonance_hz", toml::Value::Float(14.0)),
        ("shaft_damping_ratio", toml::Value::Float(0.03)),
        ("backlash_deg", toml::Value::Float(0.35)),
        ("encoder_cpr", toml::Value::Integer(16384)),
    ] {
        plant.insert(k.into(), v);
    }
    let path = dir.join("other.toml");
    std::fs::write(&path, toml::to_string(&doc).unwrap()).unwrap();
    path.display().to_string()
}

#[test]
fn tune_on_a_machine_it_was_not_written_for() {
    let dir = tempfile::tempdir().unwrap();
    let config = other_machine(dir.path());
    let grid = candidates(&[60.0]);
    let k = Constraints::default();
    let with = search(&config, &grid, &k).unwrap();
    let without = search(&config, &without_afb(&grid), &k).unwrap();
    assert!(
        with.design.candidate.afb.mode != controller_core::AfbMode::Off,
        "{:?}",
        with.design
    );
    let ripple = |c: &Candidate| {
        let mut cfg = hil_harness::resolve("fig6", Some(&config), &[]).unwrap();
        c.apply(&mut cfg.drive);
        hil_harness::run_scenario(&cfg).unwrap().metrics
    };
    let (a, b) = (
        ripple(&with.design.candidate),
        ripple(&without.design.candidate),
    );
    eprintln!(
        "AFB design {:?}: ripple {:.4} pu; no-AFB design {:?}: ripple {:.4} pu",
        with.design.candidate,
        a.shaft_torque_ripple_rms_pu,
        without.design.candidate,
        b.shaft_torque_ripple_rms_pu
    );
    assert!(a.stable && !a.faulted);
    assert!(a.shaft_torque_ripple_rms_pu < b.shaft_torque_ripple_rms_pu);
}
