//! `commission` on a stiff spindle (`tests/fixtures/stiff-spindle.toml`), whose own drive
//! has AFB on (the design default) while commission ranks a design without AFB: the file
//! it writes for that design runs with AFB off, as `commission.json` says, through `run
//! --config` as a user runs it, and that run's summary has the figures commission verified.
//! `commission.md` lists every file with its settings CRC, judges the file's own drive,
//! states the noise rule, and names no file it did not write.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use machine_workflows::commission::commission;
use machine_workflows::tune::Constraints;
use std::path::Path;
use std::process::Command;

fn fixture() -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures/stiff-spindle.toml")
        .display()
        .to_string()
}

/// A figure of `summary.json` (top level or under `metrics`).
fn figure(summary: &serde_json::Value, key: &str) -> serde_json::Value {
    match &summary[key] {
        serde_json::Value::Null => summary["metrics"][key].clone(),
        v => v.clone(),
    }
}

#[test]
fn the_no_afb_file_commission_writes_runs_with_afb_off_and_the_figures_it_verified() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("commission");
    let config = fixture();
    let result = commission(&config, &[], None, &Constraints::default(), &out);
    eprintln!("{result:?}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("commission.json")).unwrap())
            .unwrap();
    let md = std::fs::read_to_string(out.join("commission.md")).unwrap();
    assert_eq!(json["no_design"], false, "{md}");
    // The file's own drive has AFB on; the design ranked without AFB is written as
    // drive.toml when chosen, else as runner-up.toml.
    let own = machine_file::load(Path::new(&config)).unwrap().drive;
    assert_ne!(own.accel_feedback.mode, controller_core::AfbMode::Off);
    let no_afb = &json["runs"][1];
    assert!(
        no_afb["afb"].as_str().unwrap().starts_with("no AFB"),
        "{no_afb}"
    );
    let name = if json["chosen"] == "without AFB" {
        "drive.toml"
    } else {
        "runner-up.toml"
    };
    let file = out.join(name);
    let text = std::fs::read_to_string(&file).unwrap();
    assert!(text.starts_with("# Verified on the machine"), "{text}");
    let drive = machine_file::load(&file).unwrap().drive;
    assert_eq!(drive.accel_feedback.mode, controller_core::AfbMode::Off);
    assert_eq!(
        f64::from(drive.velocity_bandwidth_rad_s),
        no_afb["bandwidth_rad_s"].as_f64().unwrap()
    );
    // commission.md lists it with the CRC of the drive it composes to.
    let crc = format!("{:08x}", pil_link::board::session::settings_crc(&drive));
    assert!(
        md.contains(&format!("| `{name}` | `{crc}` | yes |")),
        "{md}"
    );
    assert!(text.contains(&format!("# settings crc {crc}")), "{text}");

    // `run --scenario fig6 --config D/<file>`, as a user runs it.
    let run_out = tmp.path().join("run");
    let o = Command::new(env!("CARGO_BIN_EXE_stiffdrive"))
        .args([
            "run",
            "--scenario",
            "fig6",
            "--config",
            file.to_str().unwrap(),
            "--out",
            run_out.to_str().unwrap(),
        ])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    eprintln!("{stdout}");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run_out.join("summary.json")).unwrap())
            .unwrap();
    // The run's figures are the ones commission verified on the machine, to the bit.
    let verified = &no_afb["figures"];
    for key in [
        "peak_droop_pu",
        "peak_shaft_torque_pu",
        "recovery_s",
        "torque_noise_rms_pu",
    ] {
        assert_eq!(figure(&summary, key), verified[key], "{key}: {summary}");
    }
    assert_eq!(
        figure(&summary, "shaft_torque_ripple_rms_pu"),
        no_afb["shaft_torque_ripple_rms_pu"]
    );
    assert_eq!(figure(&summary, "stable"), no_afb["stable"]);

    // The report: the file's own drive judged by the designs' constraints, the noise rule
    // with its measured spread, the credit and the price, and every file with its CRC.
    assert!(
        md.contains("### The machine file's own drive, judged as the designs are"),
        "{md}"
    );
    assert!(md.contains("| the file's own `[drive]` |"), "{md}");
    assert!(md.contains("worse beyond the noise"), "{md}");
    let spread = json["spread"]["range"].as_array().unwrap();
    assert_eq!(json["reference"]["spread"][0], spread[0]);
    assert!(
        md.contains("**Credit.**") && md.contains("**Price.**"),
        "{md}"
    );
    // What AFB itself adds: the AFB design at its gains without AFB, run on the machine.
    let same = &json["same_gains_without_afb"];
    assert!(
        same["afb"]
            .as_str()
            .unwrap()
            .starts_with("off, at the gains"),
        "{same}"
    );
    assert_eq!(same["bandwidth_rad_s"], json["runs"][0]["bandwidth_rad_s"]);
    eprintln!(
        "AFB design on the machine: J {}, {}; at the same gains without AFB: {}",
        json["objective"][0], json["runs"][0]["figures"], same["figures"]
    );
    for f in json["files"].as_array().unwrap() {
        let name = f["name"].as_str().unwrap();
        assert!(out.join(name).is_file(), "{name} listed, not written");
        let first = std::fs::read_to_string(out.join(name)).unwrap();
        let first = first.lines().next().unwrap();
        let verified = f["verified_on_machine"].as_bool().unwrap();
        assert_eq!(
            first.starts_with("# Verified on the machine"),
            verified,
            "{first}"
        );
        assert_eq!(
            first.starts_with("# NOT verified on the machine"),
            !verified,
            "{first}"
        );
        // Each composes to the drive with the CRC listed.
        let d = machine_file::load(&out.join(name)).unwrap().drive;
        assert_eq!(
            format!("{:08x}", pil_link::board::session::settings_crc(&d)),
            f["settings_crc"].as_str().unwrap(),
            "{name}"
        );
    }
    assert!(!out.join("tune/drive.toml").exists());
    eprintln!(
        "chosen {}; J on the machine {} with AFB, {} without; spread {:?}; files {}",
        json["chosen"], json["objective"][0], json["objective"][1], spread, json["files"]
    );
}
