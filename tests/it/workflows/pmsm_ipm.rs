//! `identify` on an interior-magnet machine no shipped config describes
//! (`tests/fixtures/ipm-noisy.toml`: λ 0.8 pu, Ld 2e-4 and Lq 5e-4 pu·s, so maximum torque
//! per ampere drives i_d < 0 and the reluctance adds torque; a light motor, Jm 0.02 s, on a
//! 0.5 s load with 1° of lost motion; 0.005 pu of current noise). Two things go wrong on it
//! when the method is not right, and each test checks one:
//! - the mechanics measured against the q current as if it were the torque (k_t = 1):
//!   the inertias came out 57 % low and the lost motion at 0.006°;
//! - the inductances by least squares on the noisy currents: Lq 33 % high with a standard
//!   error of 4.5 %.
//!
//! The 0.1 s square wave leaves Lq a scatter of a few per cent at this noise, which its
//! standard error states: the inductances are judged against their own standard errors.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use super::pmsm_identify::angle_error;
use machine_workflows::calibrate::{Estimate, MotorEstimates};
use machine_workflows::identify::{self, motor};
use std::path::Path;

fn fixture() -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures/ipm-noisy.toml")
        .display()
        .to_string()
}

/// The fixture's truth: (R, Ld, Lq, offset deg, pole pairs).
const TRUTH: (f64, f64, f64, f64, u32) = (0.03, 2e-4, 5e-4, 301.0, 5);

/// How many of its standard errors `e` lies from `truth`.
fn sigmas(e: &Estimate, truth: f64) -> f64 {
    (e.value - truth).abs() / e.std_error
}

/// The calibration's misses: R within 3 %, the offset within 2°, the pole pairs and the
/// direction exact, Ld and Lq within two standard errors of the truth.
fn misses(est: &MotorEstimates) -> Vec<String> {
    let (r, ld, lq, offset, pp) = TRUTH;
    let mut out = Vec::new();
    let r_err = est.winding_resistance_pu.value / r - 1.0;
    if r_err.abs() > 0.03 {
        out.push(format!("R off by {:+.2} %", 100.0 * r_err));
    }
    for (what, e, truth) in [
        ("Ld", &est.d_inductance_pu_s, ld),
        ("Lq", &est.q_inductance_pu_s, lq),
    ] {
        eprintln!(
            "{what} {:.4e} ± {:.1e} ({:+.2} %, {:.2} standard errors)",
            e.value,
            e.std_error,
            100.0 * (e.value / truth - 1.0),
            sigmas(e, truth)
        );
        let s = sigmas(e, truth);
        if s.is_nan() || s > 2.0 {
            out.push(format!("{what} {:.4e} ± {:.1e}", e.value, e.std_error));
        }
    }
    let off = angle_error(est.encoder_offset_elec_deg.value, offset);
    if off.abs() > 2.0 {
        out.push(format!("offset off by {off:+.3}°"));
    }
    if (est.pole_pairs, est.encoder_reversed) != (pp, false) {
        out.push(format!(
            "{} pole pairs, reversed {}",
            est.pole_pairs, est.encoder_reversed
        ));
    }
    out
}

/// Over four noise seeds the calibration's inductances scatter about the truth: each within
/// two standard errors, and their mean within 3 %.
#[test]
fn the_inductances_are_not_biased_by_current_noise() {
    let mut lq = Vec::new();
    for seed in 1..=4 {
        let sets = [format!("sensors.noise_seed={seed}")];
        let (base, _) = identify::load(&fixture(), &sets).unwrap();
        let est = motor::calibrate(&base).unwrap().expect("a PMSM");
        let m = misses(&est);
        assert!(m.is_empty(), "seed {seed}: {m:?}");
        lq.push(est.q_inductance_pu_s.value);
    }
    let mean = lq.iter().sum::<f64>() / lq.len() as f64;
    eprintln!("Lq over the seeds: {lq:?}, mean {mean:.4e}");
    assert!((mean / TRUTH.2 - 1.0).abs() <= 0.03, "{lq:?}");
}

/// `identify` as the fixture is: the calibration as above, and the mechanics measured with
/// the calibrated drive, the simulated twin's check run: Jm and Jl within 5 %, the lost
/// motion within 30 % of 1°.
#[test]
fn identify_measures_the_mechanics_against_the_motors_torque() {
    let (base, spec) = identify::load(&fixture(), &[]).unwrap();
    let ident = identify::identify_machine(&base, &spec).unwrap();
    let est = ident.motor.as_ref().expect("a PMSM is calibrated");
    let m = misses(est);
    assert!(m.is_empty(), "{m:?}");
    let (fit, lost) = (&ident.fit.fit, &ident.lost_motion);
    eprintln!(
        "Jm {:.4} s, Jl {:.4} s, lost motion {:.3}° (raw: Jm {:.4} s, Jl {:.4} s)",
        fit.motor_inertia_s,
        fit.load_inertia_s,
        lost.backlash_deg,
        ident.raw.0.fit.motor_inertia_s,
        ident.raw.0.fit.load_inertia_s
    );
    assert!(ident.twin.is_some(), "the twin gave no fit");
    assert!((fit.motor_inertia_s / 0.02 - 1.0).abs() <= 0.05, "{fit:?}");
    assert!((fit.load_inertia_s / 0.5 - 1.0).abs() <= 0.05, "{fit:?}");
    assert!((lost.backlash_deg - 1.0).abs() <= 0.3, "{lost:?}");
}
