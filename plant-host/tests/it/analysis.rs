//! The linear analysis: frequencies of Table 1 and the printing press, Eq. 1 stiffness, and
//! the closed velocity loop (frequency-domain margins vs exact sampled-data eigenvalues).
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic,
    missing_docs
)]

use crate::common;

use common::config;
use plant_host::analysis::{EngagedPlant, PiStiffness, VelocityLoop};
use plant_host::{BacklashModel, PlantConfig, TwoInertiaPlant};
use std::f64::consts::PI;

/// Rockwell-style gains: Kp = ω_bw·J, Ki = Kp·ω_bw/4; single rate.
fn table1_loop(bw_rad_s: f64, ka: f64, filter_hz: f64, period_s: f64) -> VelocityLoop {
    table1_loop2(bw_rad_s, ka, filter_hz, period_s, period_s)
}

/// As `table1_loop` with the acceleration path at its own (faster) rate.
fn table1_loop2(
    bw_rad_s: f64,
    ka: f64,
    filter_hz: f64,
    period_s: f64,
    accel_period_s: f64,
) -> VelocityLoop {
    let cfg = config("table1.toml");
    let j = cfg.mechanics.motor_inertia_s + cfg.mechanics.load_inertia_s;
    let kp = bw_rad_s * j;
    VelocityLoop {
        plant: EngagedPlant::new(&cfg.mechanics),
        kp,
        ki: kp * bw_rad_s / 4.0,
        ka,
        accel_filter_hz: filter_hz,
        velocity_period_s: period_s,
        accel_period_s,
        delay_s: cfg.electrics.computational_delay_s,
        current_bandwidth_hz: Some(318.0),
    }
}

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
fn closed_loop_stiffness_tends_to_eq1_for_an_ideal_rigid_drive() {
    // A very stiff shaft, a fast sample rate and no delay: the loop's motor stiffness must be
    // Eq. 1 with Jp = Jm + Jl (θ in pu·s).
    let mut cfg = config("table1.toml");
    cfg.mechanics.anti_resonance_hz = 3000.0;
    let jp = cfg.mechanics.motor_inertia_s + cfg.mechanics.load_inertia_s;
    let eq1 = PiStiffness::from_zeros(jp, 1.0, 10.0);
    let lp = VelocityLoop {
        plant: EngagedPlant::new(&cfg.mechanics),
        kp: eq1.kp,
        ki: eq1.ki,
        ka: 0.0,
        accel_filter_hz: 1000.0,
        velocity_period_s: 1e-6,
        accel_period_s: 1e-6,
        delay_s: 0.0,
        current_bandwidth_hz: None,
    };
    for w in [0.3, 1.0, 3.0, 10.0, 30.0] {
        let got = lp.point(w).unwrap().motor_stiffness;
        let want = eq1.at(w);
        assert!(
            (got - want).norm() / want.norm() < 1e-3,
            "ω={w}: {got} vs {want}"
        );
    }
}

/// Runs the same sampled controller in the time domain against the crate's nonlinear plant
/// with the lost motion removed (a different code path from the eigenvalue model) and reports
/// whether a small speed disturbance grows (true) or dies out (false).
fn grows_in_time_domain(lp: &VelocityLoop, cfg: &PlantConfig) -> bool {
    let mut engaged = *cfg;
    engaged.mechanics.backlash_deg = 0.0;
    engaged.lost_motion.model = BacklashModel::DeadZone;
    let mech = engaged.mechanics;
    let mut plant = TwoInertiaPlant::torque_driven(&engaged);
    plant.set_state(0.0, 0.0, 0.01, 0.0, 0.0);
    let tv = lp.velocity_period_s;
    let n = (tv / lp.accel_period_s).round().max(1.0) as usize;
    let (ta, td) = (tv / n as f64, lp.delay_s);
    let wb = mech.derived().base_speed_rad_s;
    let alpha = (-2.0 * PI * lp.accel_filter_hz * ta).exp();
    let (mut th_v, mut th_a, mut wa_prev, mut af, mut integ, mut pi_out, mut u_prev) =
        (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    let steps = (4.0 / ta) as usize;
    let mut early = 0.0_f64;
    let mut late = 0.0_f64;
    for k in 0..steps {
        let th = plant.motor_pos_rad();
        if k % n == 0 {
            let w_v = (th - th_v) / (wb * tv);
            integ -= lp.ki * tv * w_v;
            pi_out = -lp.kp * w_v + integ;
            th_v = th;
        }
        let w_a = (th - th_a) / (wb * ta);
        af = alpha * af + (1.0 - alpha) * (w_a - wa_prev) / ta;
        (th_a, wa_prev) = (th, w_a);
        let u = pi_out - lp.ka * af;
        plant.advance(td, u_prev, 0.0);
        plant.advance(ta - td, u, 0.0);
        u_prev = u;
        let amp = plant.motor_vel_pu().abs() + plant.load_vel_pu().abs();
        if k * 10 < steps {
            early = early.max(amp);
        } else if k * 10 >= steps * 9 {
            late = late.max(amp);
        }
        if amp > 1e3 {
            return true;
        }
    }
    late > early
}

#[test]
fn sampled_eigenvalues_predict_time_domain_stability() {
    let cfg = config("table1.toml");
    let (mut stable, mut unstable) = (0, 0);
    for bw in [20.0, 60.0, 94.0, 150.0, 250.0, 400.0] {
        for (ka, fc) in [(0.0, 100.0), (0.98, 20.0), (0.98, 100.0), (0.3, 50.0)] {
            for (period, accel_period) in [(250e-6, 250e-6), (500e-6, 500e-6), (500e-6, 250e-6)] {
                let mut lp = table1_loop2(bw, ka, fc, period, accel_period);
                lp.current_bandwidth_hz = None;
                let rho = lp.sampled_spectral_radius();
                let m = lp.margins();
                println!(
                    "bw {bw:5} rad/s ka {ka} fc {fc:5} Hz Tv {:.2} ms Ta {:.2} ms: rho {rho:.5}; PM {:7.1} deg at {:7.1} rad/s, GM {:6.1} dB at {:7.1} rad/s",
                    period * 1e3, accel_period * 1e3, m.phase_margin_deg, m.gain_crossover_rad_s, m.gain_margin_db, m.phase_crossover_rad_s
                );
                // Decay/growth over 4 s must be visible: skip loops within 0.3 % of the boundary.
                if (rho - 1.0).abs() < 3e-3 {
                    continue;
                }
                assert_eq!(
                    grows_in_time_domain(&lp, &cfg),
                    rho > 1.0,
                    "bw {bw} ka {ka} fc {fc} T {period}: rho {rho}"
                );
                if rho < 1.0 {
                    stable += 1;
                } else {
                    unstable += 1;
                }
            }
        }
    }
    assert!(
        stable >= 5 && unstable >= 5,
        "{stable} stable, {unstable} unstable cases checked"
    );
}

#[test]
fn table1_15hz_without_acceleration_feedback_is_linearly_stable() {
    let lp = table1_loop(2.0 * PI * 15.0, 0.0, 100.0, 500e-6);
    let m = lp.margins();
    assert!(lp.is_stable());
    assert!(m.phase_margin_deg > 20.0, "{m:?}");
}

#[test]
fn acceleration_feedback_raises_high_frequency_stiffness_of_a_stable_design() {
    // 15 Hz bandwidth at 4 kHz; Ka = J_total with a 20 Hz filter is linearly stable there.
    let without = table1_loop(2.0 * PI * 15.0, 0.0, 20.0, 250e-6);
    let with = table1_loop(2.0 * PI * 15.0, 0.98, 20.0, 250e-6);
    assert!(without.is_stable() && with.is_stable());
    let stiff = |lp: &VelocityLoop, w: f64| lp.point(w).unwrap().motor_stiffness.norm();
    // Low frequency: the integral gain sets the stiffness either way (Eq. 1: → Ki).
    let (a, b) = (stiff(&without, 0.1), stiff(&with, 0.1));
    assert!((a / b - 1.0).abs() < 0.01, "{a} vs {b}");
    assert!((a / without.ki - 1.0).abs() < 0.01);
    // Above the bandwidth the motor behaves like Jm + Jl + Ka below the filter corner.
    for w in [60.0, 100.0] {
        let (a, b) = (stiff(&without, w), stiff(&with, w));
        println!(
            "ω = {w} rad/s: motor stiffness {a:.3e} without, {b:.3e} with acceleration feedback"
        );
        assert!(b > 1.2 * a, "ω = {w}: {b} vs {a}");
    }
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
    // Gains sized for J_total on Jm alone: the loop crosses over ~(Jm + Jl)/Jm = 8.4× higher.
    let mut lp = table1_loop(2.0 * PI * 15.0, 0.0, 100.0, 500e-6);
    let engaged_gc = lp.margins().gain_crossover_rad_s;
    lp.plant = p;
    let apart_gc = lp.margins().gain_crossover_rad_s;
    println!("gain crossover engaged {engaged_gc:.1} rad/s, gears apart {apart_gc:.1} rad/s");
    assert!(apart_gc > 6.0 * engaged_gc);
}
