//! `identify` and `commission` end to end on the PMSM machine of
//! `tests/fixtures/pmsm-odd.toml`, whose drive lacks the encoder offset. Criteria fixed
//! before the runs:
//! - `identify` writes the motor calibration into `identify.json`'s `estimates` under the
//!   machine-file keys, each with a finite standard error, and into `identify.md`: R within
//!   3 %, Ld and Lq within 5 %, the offset within 2° electrical, the pole pairs and the
//!   direction exact;
//! - `commission` writes a `drive.toml` whose `[drive.pmsm]` and `winding_resistance_pu`
//!   are that calibration (to the f32 the drive holds), and `run --scenario fig6 --config
//!   D/drive.toml`, as a user runs it, exits 0, stable, without a fault, with the figures
//!   commission verified on the machine, to the bit.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use super::pmsm_identify::{angle_error, fixture, TRUTH};
use machine_workflows::commission::commission;
use machine_workflows::identify;
use machine_workflows::tune::Constraints;
use std::path::Path;
use std::process::Command;

/// The estimate `name` of an `identify.json`: its value, and its standard error checked
/// finite.
fn estimate(json: &serde_json::Value, name: &str) -> f64 {
    let est = json["estimates"].as_array().unwrap();
    let e = est
        .iter()
        .find(|e| e["name"] == name)
        .unwrap_or_else(|| panic!("{name} not in {est:?}"));
    let v = e["value"].as_f64().unwrap();
    let se = e["std_error"]
        .as_f64()
        .unwrap_or_else(|| panic!("{name}: no standard error"));
    assert!(se.is_finite() && se >= 0.0, "{name}: {se}");
    eprintln!("{name}: {v} ± {se:.2e}");
    v
}

fn read_json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// The calibration of an `identify.json` against the fixture's truth.
fn check_calibration(json: &serde_json::Value) {
    let (r, ld, lq, offset, pp) = TRUTH;
    let rel = |name: &str, t: f64| estimate(json, name) / t - 1.0;
    assert!(rel("winding_resistance_pu", r).abs() <= 0.03);
    assert!(rel("d_inductance_pu_s", ld).abs() <= 0.05);
    assert!(rel("q_inductance_pu_s", lq).abs() <= 0.05);
    assert!(angle_error(estimate(json, "encoder_offset_elec_deg"), offset).abs() <= 2.0);
    assert_eq!(estimate(json, "pole_pairs"), f64::from(pp));
    assert_eq!(estimate(json, "encoder_reversed"), 0.0);
}

#[test]
fn identify_writes_the_motor_calibration() {
    let dir = tempfile::TempDir::new().unwrap();
    let out = dir.path().join("id");
    let line = identify::identify(&fixture(), &[], &out).unwrap();
    eprintln!("{line}");
    let json = read_json(&out.join("identify.json"));
    check_calibration(&json);
    estimate(&json, "motor_inertia_s");
    let md = std::fs::read_to_string(out.join("identify.md")).unwrap();
    for key in [
        "| winding_resistance_pu |",
        "| d_inductance_pu_s |",
        "| q_inductance_pu_s |",
        "| encoder_offset_elec_deg |",
        "| encoder_reversed |",
        "| pole_pairs |",
        "[drive.pmsm]",
    ] {
        assert!(md.contains(key), "{key} not in identify.md:\n{md}");
    }
    assert!(line.contains("7 pole pairs"), "{line}");
}

/// A figure of `summary.json` (top level or under `metrics`).
fn figure(summary: &serde_json::Value, key: &str) -> serde_json::Value {
    match &summary[key] {
        serde_json::Value::Null => summary["metrics"][key].clone(),
        v => v.clone(),
    }
}

#[test]
fn commission_writes_the_calibration_into_a_drive_toml_that_runs_fig6_stable() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("commission");
    let result = commission(&fixture(), &[], None, &Constraints::default(), &out);
    eprintln!("{result:?}");
    let json = read_json(&out.join("commission.json"));
    let md = std::fs::read_to_string(out.join("commission.md")).unwrap();
    assert_eq!(json["no_design"], false, "{md}");
    let id = read_json(&out.join("identify/identify.json"));
    check_calibration(&id);
    // commission.md's identified section has the calibration beside the machine's truth.
    assert!(
        md.contains("| encoder_offset_elec_deg | ") && md.contains(" | 137.000000 | deg"),
        "{md}"
    );

    // drive.toml: the calibration, as the drive holds it.
    let file = out.join("drive.toml");
    let text = std::fs::read_to_string(&file).unwrap();
    assert!(text.starts_with("# Verified on the machine"), "{text}");
    let drive = machine_file::load(&file).unwrap().drive;
    let p = drive.pmsm.expect("drive.toml has [drive.pmsm]");
    let f = |name: &str| estimate(&id, name) as f32;
    assert_eq!(
        p.encoder_offset_elec_deg,
        Some(f("encoder_offset_elec_deg"))
    );
    assert_eq!(p.pole_pairs, TRUTH.4);
    assert!(!p.encoder_reversed);
    assert_eq!(p.d_inductance_pu_s, f("d_inductance_pu_s"));
    assert_eq!(p.q_inductance_pu_s, f("q_inductance_pu_s"));
    assert_eq!(drive.winding_resistance_pu, f("winding_resistance_pu"));
    // The file's [drive] table alone says so (the machine's [electrics] holds its truth).
    let table: toml::Table = text.parse().unwrap();
    let pmsm = table["drive"]["pmsm"].as_table().unwrap();
    assert!(pmsm.contains_key("encoder_offset_elec_deg"), "{text}");

    // `run --scenario fig6 --config D/drive.toml`, as a user runs it.
    let run_out = tmp.path().join("run");
    let o = Command::new(env!("CARGO_BIN_EXE_stiffdrive"))
        .args(["run", "--scenario", "fig6", "--config"])
        .arg(&file)
        .arg("--out")
        .arg(&run_out)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    eprintln!("{}", String::from_utf8_lossy(&o.stdout));
    let summary = read_json(&run_out.join("summary.json"));
    assert_eq!(figure(&summary, "stable"), true, "{summary}");
    assert!(summary["fault"].is_null(), "{}", summary["fault"]);
    // The figures commission verified on the machine for the chosen design, to the bit.
    let chosen = &json["runs"][if json["chosen"] == "with AFB" { 0 } else { 1 }];
    for key in [
        "peak_droop_pu",
        "peak_shaft_torque_pu",
        "recovery_s",
        "torque_noise_rms_pu",
    ] {
        assert_eq!(figure(&summary, key), chosen["figures"][key], "{key}");
    }
    assert_eq!(figure(&summary, "stable"), chosen["stable"]);
    eprintln!(
        "chosen {} ({} rad/s, {}), passed {}; J on the machine {} with AFB, {} without; \
         ripple {}",
        json["chosen"],
        chosen["bandwidth_rad_s"],
        chosen["afb"],
        json["passed"],
        json["objective"][0],
        json["objective"][1],
        figure(&summary, "shaft_torque_ripple_rms_pu")
    );
}
