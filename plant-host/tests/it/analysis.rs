//! The plant's linear analysis: the frequencies of Table 1 and the printing press, the
//! engaged plant's response, and the disengaged plant.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic,
    missing_docs
)]

use crate::common;

use common::config;
use plant_host::analysis::EngagedPlant;
use std::f64::consts::PI;

#[test]
fn table1_resonance_and_anti_resonance() {
    let m = EngagedPlant::new(&config("table1.toml").mechanics).modes();
    println!("table1 modes: {m:?}");
    assert!((m.resonance_hz - 65.1).abs() < 0.05, "{}", m.resonance_hz);
    assert!(
        (m.anti_resonance_hz - 22.5).abs() < 1e-9,
        "{}",
        m.anti_resonance_hz
    );
    assert!((m.anti_resonance_damping - 0.05).abs() < 1e-9);
    // Cross-check against the closed form ω_r = ω_ar·√(1 + Jl/Jm).
    let d = config("table1.toml").mechanics.derived();
    assert!((m.resonance_hz - d.resonance_rad_s / (2.0 * PI)).abs() < 1e-9);
}

#[test]
fn printing_press_resonance_is_about_90_hz() {
    let m = EngagedPlant::new(&config("printing-press.toml").mechanics).modes();
    assert!((m.resonance_hz - 90.0).abs() < 0.5, "{}", m.resonance_hz);
    assert!((m.anti_resonance_hz - 30.0).abs() < 1e-9);
}

#[test]
fn plant_response_has_peak_and_notch() {
    let p = EngagedPlant::new(&config("table1.toml").mechanics);
    let g = |f: f64| {
        p.response(2.0 * PI * f)
            .unwrap()
            .motor_speed_per_motor_torque
            .norm()
    };
    let rigid = |f: f64| 1.0 / (0.98 * 2.0 * PI * f);
    assert!(g(65.1) > 5.0 * rigid(65.1), "resonance peak");
    assert!(g(22.5) < 0.2 * rigid(22.5), "anti-resonance notch");
    assert!(
        (g(0.5) / rigid(0.5) - 1.0).abs() < 0.01,
        "rigid at low frequency"
    );
}

#[test]
fn disengaged_plant_is_the_motor_alone() {
    let cfg = config("table1.toml");
    let p = EngagedPlant::disengaged(&cfg.mechanics);
    for w in [1.0, 100.0, 1000.0] {
        let g = p.response(w).unwrap();
        // ωm/Tm = 1/(Jm·jω); the load does not feel the motor.
        let want = 1.0 / (cfg.mechanics.motor_inertia_s * w);
        assert!((g.motor_speed_per_motor_torque.norm() / want - 1.0).abs() < 1e-12);
        assert!(g.load_speed_per_motor_torque.norm() < 1e-15);
    }
}
