//! `commission` on a machine no shipped config and no other test describes: identify it,
//! tune on the identified model, and verify on the machine itself (a plant the other
//! tests have not seen: identify -> tune gives a design whose nonlinear run is stable and
//! better than the no-AFB design).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use crate::common;

use hil_harness::experiments::commission::commission;
use hil_harness::experiments::tune::Constraints;

/// Table 1's file with another machine: a heavier motor, a lighter load, a stiffer shaft
/// with less lost motion, an 8192-count encoder.
const MACHINE: [(&str, f64); 5] = [
    ("motor_inertia_s", 0.35),
    ("load_inertia_s", 0.6),
    ("anti_resonance_hz", 18.0),
    ("shaft_damping_ratio", 0.04),
    ("backlash_deg", 0.2),
];

fn unseen_machine(dir: &std::path::Path) -> String {
    let mut keys = common::plant(&MACHINE);
    keys.push(("plant", "encoder_cpr", toml::Value::Integer(8192)));
    common::machine_file(dir, "unseen.toml", &keys)
}

#[test]
fn commissioning_an_unseen_machine_gives_a_stable_design_better_than_no_afb() {
    let tmp = tempfile::tempdir().unwrap();
    let config = unseen_machine(tmp.path());
    let out = tmp.path().join("commission");
    let line = commission(&config, &[], Some(60.0), &Constraints::default(), &out).unwrap();
    eprintln!("{line}");
    for f in [
        "commission.md",
        "commission.json",
        "identified.toml",
        "identify/plant.toml",
        "tune/drive.toml",
        "tune/tune.md",
    ] {
        assert!(out.join(f).is_file(), "{f} not written");
    }
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("commission.json")).unwrap())
            .unwrap();
    let runs = &json["runs"];
    let ripple = |i: usize| runs[i]["shaft_torque_ripple_rms_pu"].as_f64().unwrap();
    assert_eq!(json["passed"], true, "{json}");
    // The loop damps this machine's resonance: no notch, the designs as without the feature.
    assert!(json["notch"]["notch"].is_null(), "{json}");
    assert!(json["without_notch"].is_null(), "{json}");
    assert_eq!(runs[0]["stable"], true);
    assert_eq!(runs[0]["faulted"], false);
    assert!(ripple(0) < ripple(1), "{json}");
    assert_ne!(
        runs[0]["afb"].as_str().unwrap(),
        runs[1]["afb"].as_str().unwrap()
    );

    // The drive was tuned on the measurement, not on the file: identified.toml's plant is
    // the identified one, within the identification's tolerance of the machine's.
    let identified: toml::Table = std::fs::read_to_string(out.join("identified.toml"))
        .unwrap()
        .parse()
        .unwrap();
    for (k, truth) in &MACHINE[..3] {
        let v = identified["plant"][*k].as_float().unwrap();
        assert!(v != *truth, "{k}: the file's value, not a measurement");
        assert!((v / truth - 1.0).abs() < 0.05, "{k}: {v} against {truth}");
    }
    // The tuned machine file runs with `run --config` as it is.
    let tuned = out.join("tune/drive.toml").display().to_string();
    let cfg = hil_harness::resolve("fig6", Some(&tuned), &[]).unwrap();
    assert!(hil_harness::run_scenario(&cfg).unwrap().metrics.stable);
}
