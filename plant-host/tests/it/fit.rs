//! The two-inertia fit on the Table 1 plant: its closed form is the state-space plant, and
//! it recovers the plant from exact data with coherence-weighted noise.
#![allow(clippy::indexing_slicing, clippy::unwrap_used, missing_docs)]

use crate::common;

use nalgebra::Complex;
use plant_host::analysis::{EngagedPlant, MeasuredResponse, TwoInertiaFit, fit_two_inertia};
use std::f64::consts::PI;

/// The closed form of the fit is the engaged plant's state-space response.
#[test]
fn model_matches_the_state_space_plant() {
    let mut m = common::table1().mechanics;
    m.backlash_deg = 0.0;
    m.motor_viscous_pu = 0.01;
    m.load_viscous_pu = 0.01;
    let wb = m.derived().base_speed_rad_s;
    let fit = TwoInertiaFit {
        motor_inertia_s: m.motor_inertia_s,
        load_inertia_s: m.load_inertia_s,
        anti_resonance_hz: m.anti_resonance_hz,
        shaft_damping_ratio: m.shaft_damping_ratio,
        viscous_pu: m.motor_viscous_pu + m.load_viscous_pu,
        delay_s: 0.0,
    };
    let plant = EngagedPlant::new(&m);
    let (f_ar, f_r) = (
        m.anti_resonance_hz,
        m.derived().resonance_rad_s / (2.0 * PI),
    );
    for f in [0.5, 5.0, 0.95 * f_ar, f_ar, 0.95 * f_r, f_r, 300.0] {
        let w = 2.0 * PI * f;
        let Some(r) = plant.response(w) else {
            unreachable!("pole at {f} Hz")
        };
        let want = r.motor_speed_per_motor_torque * wb / Complex::new(0.0, w);
        let got = fit.response(f, wb);
        assert!((got / want - 1.0).norm() < 1e-9, "{f}: {got} vs {want}");
    }
}

/// Exact model data with coherence-weighted noise: the fit recovers every parameter.
#[test]
fn fit_recovers_a_known_plant() {
    let m = common::table1().mechanics;
    let wb = m.derived().base_speed_rad_s;
    let truth = TwoInertiaFit {
        motor_inertia_s: m.motor_inertia_s,
        load_inertia_s: m.load_inertia_s,
        anti_resonance_hz: m.anti_resonance_hz,
        shaft_damping_ratio: 0.04,
        viscous_pu: 0.02,
        delay_s: 3.7e-4,
    };
    let mut seed = 7u64;
    let mut noise = || {
        seed = seed
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let freq_hz: Vec<f64> = (1..=400).map(|k| f64::from(k) * 0.5).collect();
    let h = freq_hz
        .iter()
        .map(|&f| {
            let e = Complex::new(0.02 * noise(), 0.02 * noise());
            truth.response(f, wb) * e.exp()
        })
        .collect();
    let measured = MeasuredResponse {
        coherence: vec![0.99; freq_hz.len()],
        freq_hz,
        h,
        segments: 50,
    };
    let r = fit_two_inertia(&measured, wb, 0.8, 1000.0).unwrap();
    let rel = |a: f64, b: f64| (a / b - 1.0).abs();
    let f = &r.fit;
    assert!(
        rel(f.motor_inertia_s, truth.motor_inertia_s) < 0.005,
        "{r:?}"
    );
    assert!(rel(f.load_inertia_s, truth.load_inertia_s) < 0.005, "{r:?}");
    assert!(
        rel(f.anti_resonance_hz, truth.anti_resonance_hz) < 0.002,
        "{r:?}"
    );
    assert!(
        rel(f.shaft_damping_ratio, truth.shaft_damping_ratio) < 0.05,
        "{r:?}"
    );
    assert!((f.delay_s - truth.delay_s).abs() < 2e-5, "{r:?}");
    assert!(rel(f.resonance_hz(), truth.resonance_hz()) < 0.002, "{r:?}");
    // The stated errors are consistent with the actual ones.
    let e = &r.std_error;
    assert!((f.motor_inertia_s - truth.motor_inertia_s).abs() < 5.0 * e.motor_inertia_s);
    assert!((f.load_inertia_s - truth.load_inertia_s).abs() < 5.0 * e.load_inertia_s);
}
