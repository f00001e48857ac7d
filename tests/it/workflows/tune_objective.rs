//! `tune` chooses by the objective (machine-workflows/src/tune/objective.rs): on Table 1
//! (from `tune_table1`) and on a heavy motor with a soft coupling, the chosen drive's
//! `fig6` peak droop and peak shaft torque are no worse than the shipped default drive's,
//! its torque noise is within the budget, and `drive.toml` and `runner-up.toml` load as
//! they are, each with the figures `tune.json` reports.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use super::common;

use controller_core::AfbMode;
use machine_workflows::tune::objective::{NOISE_FACTOR, NOISE_FLAG, NOISE_FLOOR_PU};
use machine_workflows::tune::{tune, Constraints};
use sim_engine::engine::metrics::Metrics;
use std::path::Path;
use std::time::Instant;

fn fig6(config: &str) -> (sim_engine::config::RunConfig, Metrics) {
    let cfg = sim_engine::resolve("fig6", Some(config), &[]).unwrap();
    let m = sim_engine::run_scenario(&cfg).unwrap().metrics;
    (cfg, m)
}

fn j(m: &Metrics, d: &Metrics) -> f64 {
    m.peak_droop_pu.unwrap() / d.peak_droop_pu.unwrap()
        + m.peak_shaft_torque_pu.unwrap() / d.peak_shaft_torque_pu.unwrap()
        + m.recovery_s.unwrap() / d.recovery_s.unwrap()
}

/// The checks on a `tune` output `out` of `config` (the default budget).
pub fn check_choice(config: &str, out: &Path) {
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("tune.json")).unwrap()).unwrap();
    let o = &json["objective"];
    let (_, default) = fig6(config);
    let drive = out.join("drive.toml").display().to_string();
    let runner = out.join("runner-up.toml").display().to_string();
    let (cfg, chosen) = fig6(&drive);
    let (cfg_r, other) = fig6(&runner);
    // Both files load as they are, as the firmware build composes them.
    assert_eq!(
        machine_file::load(&out.join("drive.toml")).unwrap().drive,
        cfg.drive
    );
    assert_eq!(
        machine_file::load(&out.join("runner-up.toml"))
            .unwrap()
            .drive,
        cfg_r.drive
    );
    let budget = o["reference"]["max_torque_noise_pu"].as_f64().unwrap();
    let row = |name: &str, m: &Metrics| {
        eprintln!(
            "{config} {name}: peak droop {:.4} pu, peak shaft torque {:.4} pu, recovery {:.4} s, \
             torque noise {:.4} pu (budget {budget:.4}), J {:.3}",
            m.peak_droop_pu.unwrap(),
            m.peak_shaft_torque_pu.unwrap(),
            m.recovery_s.unwrap(),
            m.torque_noise_rms_pu,
            j(m, &default)
        );
    };
    let kind = json["chosen_kind"].as_str().unwrap();
    row("default drive", &default);
    row(&format!("chosen ({kind})"), &chosen);
    row("runner-up", &other);

    assert!(chosen.stable && !chosen.faulted, "{chosen:?}");
    assert!(chosen.peak_droop_pu.unwrap() <= default.peak_droop_pu.unwrap());
    assert!(chosen.peak_shaft_torque_pu.unwrap() <= default.peak_shaft_torque_pu.unwrap());
    assert!(chosen.torque_noise_rms_pu <= budget);
    assert_eq!(
        budget,
        (NOISE_FACTOR * default.torque_noise_rms_pu).max(NOISE_FLOOR_PU)
    );
    // The files are the designs tune.json reports, and the chosen one has the lower J.
    let (jc, jo) = (j(&chosen, &default), j(&other, &default));
    let (with, without) = if kind == "with AFB" {
        (jc, jo)
    } else {
        (jo, jc)
    };
    let reported = |k: &str| o[k]["score"]["objective"].as_f64().unwrap();
    assert!((reported("with_afb") - with).abs() < 1e-9, "{o}");
    assert!((reported("without_afb") - without).abs() < 1e-9, "{o}");
    assert!(jc <= jo, "chosen J {jc} > runner-up J {jo}");
    let afb = |c: &sim_engine::config::RunConfig| c.drive.accel_feedback.mode != AfbMode::Off;
    assert_eq!(afb(&cfg), kind == "with AFB");
    assert_eq!(afb(&cfg_r), kind != "with AFB");
    let md = std::fs::read_to_string(out.join("tune.md")).unwrap();
    assert!(md.contains(&format!("**Chosen: {kind}**")), "{md}");
}

/// A heavy motor (0.4 s against Table 1's 0.117 s) on a lighter load through a soft,
/// 12 Hz coupling.
#[test]
fn tune_on_a_heavy_motor_with_a_soft_coupling_chooses_no_worse_than_the_default_drive() {
    let dir = tempfile::tempdir().unwrap();
    let config = common::machine_file(
        dir.path(),
        "heavy.toml",
        &common::plant(&[
            ("motor_inertia_s", 0.4),
            ("load_inertia_s", 0.3),
            ("anti_resonance_hz", 12.0),
            ("shaft_damping_ratio", 0.04),
            ("backlash_deg", 0.3),
        ]),
    );
    let out = dir.path().join("tune");
    let t0 = Instant::now();
    // At 94.25 rad/s, where `--max-bandwidth` chooses on this machine (docs/tuning.md);
    // `tune_table1` runs the search over every bandwidth.
    let line = tune(&config, Some(94.25), &Constraints::default(), &out).unwrap();
    eprintln!("{line} ({:.1} s)", t0.elapsed().as_secs_f64());
    check_choice(&config, &out);
}

/// The budget given with `--max-torque-noise-pu` binds: below the designs' noise, `tune`
/// chooses a quieter one or none. A budget that is not a finite positive number is refused,
/// naming the flag, before anything runs or is written.
#[test]
fn the_noise_budget_binds_and_a_bad_one_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    for bad in [0.0, -0.1, f64::NAN, f64::INFINITY] {
        let k = Constraints {
            max_torque_noise_pu: Some(bad),
            ..Constraints::default()
        };
        let out = dir.path().join("bad");
        let e = tune("table1", Some(60.0), &k, &out)
            .unwrap_err()
            .to_string();
        assert!(e.contains(NOISE_FLAG) && e.contains("> 0"), "{e}");
        assert!(!out.exists());
    }
    let free = dir.path().join("free");
    tune("table1", Some(60.0), &Constraints::default(), &free).unwrap();
    let noise = |out: &Path| {
        let (_, m) = fig6(&out.join("drive.toml").display().to_string());
        m.torque_noise_rms_pu
    };
    let unbound = noise(&free);
    let budget = 0.9 * unbound;
    let k = Constraints {
        max_torque_noise_pu: Some(budget),
        ..Constraints::default()
    };
    let tight = dir.path().join("tight");
    match tune("table1", Some(60.0), &k, &tight) {
        Ok(line) => {
            let n = noise(&tight);
            eprintln!("{line}: noise {n:.4} pu within {budget:.4} (unbound {unbound:.4})");
            assert!(n <= budget);
            let md = std::fs::read_to_string(tight.join("tune.md")).unwrap();
            assert!(md.contains(NOISE_FLAG), "{md}");
        }
        Err(e) => {
            eprintln!("{e}");
            assert_eq!(e.exit_code(), sim_engine::error::NO_DESIGN_EXIT_CODE, "{e}");
        }
    }
}
