//! `identify` on a PMSM machine no shipped config describes (`tests/fixtures/pmsm-odd.toml`:
//! 7 pole pairs, Ld 3e-4 and Lq 4.5e-4 pu·s, the encoder at 137° electrical, a soft
//! coupling, sensor noise): the motor calibration `identify` runs first, and the drive
//! without its encoder offset refused until it has one. Targets fixed before the runs: R
//! within 3 %, Ld and Lq within 5 %, the offset within 2° electrical, the pole pairs and the
//! direction exact. `identify` and `commission` end to end on it: `pmsm_commission.rs`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use machine_workflows::identify::{self, motor};
use std::path::Path;
use std::process::Command;

/// The fixture's path.
pub fn fixture() -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures/pmsm-odd.toml")
        .display()
        .to_string()
}

/// The fixture's truth: (R, Ld, Lq, offset deg, pole pairs).
pub const TRUTH: (f64, f64, f64, f64, u32) = (0.06, 3e-4, 4.5e-4, 137.0, 7);

/// `a` − `b` in degrees, in (−180, 180].
pub fn angle_error(a: f64, b: f64) -> f64 {
    -((b - a + 180.0).rem_euclid(360.0) - 180.0)
}

/// The calibration's misses of the targets, printed.
pub fn misses(est: &machine_workflows::calibrate::MotorEstimates) -> Vec<String> {
    let (r, ld, lq, offset, pp) = TRUTH;
    let rel = |e: f64, t: f64| e / t - 1.0;
    let off = angle_error(est.encoder_offset_elec_deg.value, offset);
    let rows = [
        ("R", rel(est.winding_resistance_pu.value, r), 0.03),
        ("Ld", rel(est.d_inductance_pu_s.value, ld), 0.05),
        ("Lq", rel(est.q_inductance_pu_s.value, lq), 0.05),
    ];
    let mut out = Vec::new();
    for (what, err, limit) in rows {
        eprintln!("{what}: {:+.3} % (limit {} %)", 100.0 * err, 100.0 * limit);
        if err.abs() > limit {
            out.push(format!("{what} off by {:+.3} %", 100.0 * err));
        }
    }
    eprintln!(
        "offset {:.3}° ± {:.3} ({off:+.3}° off, limit 2°); pole pairs {} ({pp}); reversed {}; \
         lag {:.2}°",
        est.encoder_offset_elec_deg.value,
        est.encoder_offset_elec_deg.std_error,
        est.pole_pairs,
        est.encoder_reversed,
        est.sweep_lag_elec_deg
    );
    if off.abs() > 2.0 {
        out.push(format!("offset off by {off:+.3}°"));
    }
    if est.pole_pairs != pp {
        out.push(format!("{} pole pairs", est.pole_pairs));
    }
    if est.encoder_reversed {
        out.push("reversed".into());
    }
    out
}

#[test]
fn the_calibration_finds_the_motor_of_the_odd_machine() {
    let (base, _) = identify::load(&fixture(), &[]).unwrap();
    assert_eq!(
        base.drive.pmsm.unwrap().encoder_offset_elec_deg,
        None,
        "the fixture's drive must lack the offset"
    );
    let est = motor::calibrate(&base)
        .unwrap()
        .expect("a PMSM is calibrated");
    let m = misses(&est);
    assert!(m.is_empty(), "{m:?}");
    // The calibrated drive builds a controller, with the measurement in it.
    let d = motor::calibrated(&base.drive, &est).unwrap();
    let p = d.pmsm.unwrap();
    assert_eq!(p.pole_pairs, 7);
    assert_eq!(
        p.encoder_offset_elec_deg,
        Some(est.encoder_offset_elec_deg.value as f32)
    );
    assert_eq!(
        d.winding_resistance_pu,
        est.winding_resistance_pu.value as f32
    );
    controller_core::Controller::new(&d).unwrap();
    assert!(controller_core::Controller::new(&base.drive).is_err());
}

#[test]
fn a_dc_machine_has_no_calibration() {
    let (base, _) = identify::load("table1", &[]).unwrap();
    assert!(motor::calibrate(&base).unwrap().is_none());
}

/// `run` on the fixture as given: refused, naming the key and the command that measures
/// it, non-zero exit, nothing written.
#[test]
fn running_the_fixture_without_an_offset_is_refused_naming_the_key_and_the_command() {
    let dir = tempfile::TempDir::new().unwrap();
    let out = dir.path().join("out");
    let o = Command::new(env!("CARGO_BIN_EXE_stiffdrive"))
        .args(["run", "--scenario", "fig6", "--config", &fixture(), "--out"])
        .arg(&out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    eprintln!("{err}");
    assert!(!o.status.success());
    assert!(err.contains("pmsm.encoder_offset_elec_deg"), "{err}");
    assert!(err.contains("identify"), "{err}");
    assert!(!out.exists(), "{}", out.display());
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
}

/// The sweep of a heavy load on a light winding: Table 1's PMSM (R = 0.05 pu, λ = 1, the
/// whole Table 1 inertia behind 0.5° of lost motion). Its sweep is slowed to where the
/// back-EMF's drag is a quarter of the vector's pull (0.42 electrical turns/s, not the
/// 2 turns/s at which it slipped poles and the calibration failed), and the calibration
/// finds its 4 pole pairs and the offset within 2° of the file's 23°.
#[test]
fn the_calibration_follows_table1s_heavy_load() {
    let (base, _) = identify::load("table1-pmsm", &[]).unwrap();
    let n = motor::Nominal::of(&base.drive).unwrap();
    let hz = n.sweep_hz(0.5);
    assert!(
        (hz / (0.05 * 0.5 / 4.0 * 4.0 * 1000.0 / 60.0) - 1.0).abs() < 1e-6,
        "{hz}"
    );
    let est = motor::calibrate(&base).unwrap().unwrap();
    let off = angle_error(est.encoder_offset_elec_deg.value, 23.0);
    eprintln!(
        "table1-pmsm: {hz:.3} turns/s, pole pairs {}, offset {:.3}° ({off:+.3}°), lag {:.2}°",
        est.pole_pairs, est.encoder_offset_elec_deg.value, est.sweep_lag_elec_deg
    );
    assert_eq!((est.pole_pairs, est.encoder_reversed), (4, false));
    assert!(off.abs() <= 2.0, "{off}");
}

/// The odd machine with its encoder counting against the electrical angle
/// (`electrics.encoder_reversed`, two motor leads swapped): the calibration finds it
/// reversed, with the other targets as above, and `identify` then measures the mechanics
/// with the drive it calibrated (the inertias within 10 % of the file's 0.06 and 0.35 s).
#[test]
fn identify_finds_a_reversed_encoder_and_measures_the_mechanics_with_it() {
    let sets = ["electrics.encoder_reversed=true".to_string()];
    let (base, spec) = identify::load(&fixture(), &sets).unwrap();
    let ident = identify::identify_machine(&base, &spec).unwrap();
    let est = ident.motor.expect("a PMSM is calibrated");
    let m: Vec<String> = misses(&est)
        .into_iter()
        .filter(|m| m != "reversed")
        .collect();
    assert!(m.is_empty(), "{m:?}");
    assert!(est.encoder_reversed);
    let fit = ident.fit.fit;
    eprintln!(
        "Jm {:.4} s, Jl {:.4} s",
        fit.motor_inertia_s, fit.load_inertia_s
    );
    assert!((fit.motor_inertia_s / 0.06 - 1.0).abs() < 0.1, "{fit:?}");
    assert!((fit.load_inertia_s / 0.35 - 1.0).abs() < 0.1, "{fit:?}");
}
