//! `tune` on a machine no shipped config describes: the design must be stable in the loop
//! and give less shaft-torque ripple after a load step than the no-AFB design tuned by the
//! same constraints.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use super::common;

use machine_workflows::tune::{candidates, search, without_afb, Candidate, Constraints};

/// Table 1's file with another machine: heavier, softer, more lost motion, a finer encoder.
fn other_machine(dir: &std::path::Path) -> String {
    let mut keys = common::plant(&[
        ("motor_inertia_s", 0.21),
        ("load_inertia_s", 1.37),
        ("anti_resonance_hz", 14.0),
        ("shaft_damping_ratio", 0.03),
        ("backlash_deg", 0.35),
    ]);
    keys.push(("plant", "encoder_cpr", toml::Value::Integer(16384)));
    common::machine_file(dir, "other.toml", &keys)
}

#[test]
fn tune_on_a_machine_it_was_not_written_for() {
    let dir = tempfile::tempdir().unwrap();
    let config = other_machine(dir.path());
    let grid = candidates(&sim_engine::config::tune_grid().unwrap(), &[60.0]);
    let k = Constraints::default();
    let with = search(&config, &grid, &k).unwrap();
    let without = search(&config, &without_afb(&grid), &k).unwrap();
    assert!(
        with.design.candidate.afb.mode != controller_core::AfbMode::Off,
        "{:?}",
        with.design
    );
    let ripple = |c: &Candidate| {
        let mut cfg = sim_engine::resolve("fig6", Some(&config), &[]).unwrap();
        c.apply(&mut cfg.drive);
        sim_engine::run_scenario(&cfg).unwrap().metrics
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

/// A loop whose load-step response shows no decaying oscillatory mode is a result: `tune`
/// on the printing press at its own 30 rad/s writes the design and says that no damping
/// could be fitted, instead of failing with nothing written.
#[test]
fn a_step_response_without_an_oscillatory_mode_is_reported_not_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("press");
    let line =
        machine_workflows::tune::tune("printing-press", Some(30.0), &Constraints::default(), &out)
            .unwrap();
    eprintln!("{line}");
    assert!(line.contains("no decaying oscillatory mode"), "{line}");
    let md = std::fs::read_to_string(out.join("tune.md")).unwrap();
    assert!(md.contains("has no decaying oscillatory mode"), "{md}");
    assert!(!md.contains("matrix-pencil"), "{md}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("tune.json")).unwrap()).unwrap();
    assert_eq!(json["no_oscillatory_mode"], true, "{json}");
    assert!(json["step"].is_null());
    assert!(out.join("drive.toml").is_file() && !out.join("config.toml").exists());
}
