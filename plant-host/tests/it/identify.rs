//! Identification end to end on the exact plant: a random binary torque excitation inside a
//! velocity loop closed on a quantized encoder, the closed-loop frequency response from the
//! recorded signals only, and the two-inertia fit against the plant's own parameters.
#![allow(clippy::indexing_slicing, clippy::unwrap_used, clippy::expect_used)]

use crate::common;
use plant_host::analysis::{closed_loop_response, fit_two_inertia};

use plant_host::{PlantConfig, TwoInertiaPlant};
use std::f64::consts::PI;

const RATE_HZ: f64 = 4000.0;

struct Record {
    excitation: Vec<f64>,
    torque: Vec<f64>,
    position_rad: Vec<f64>,
}

/// 60 s at 4 kHz: the torque is r − kp·ω̂ with ω̂ from the count difference, r a ±0.1 pu
/// random binary sequence, held for one tick (ZOH), and the position read in whole counts.
fn run(cfg: &PlantConfig, cpr: f64, kp: f64, amplitude: f64) -> Record {
    let mut plant = TwoInertiaPlant::torque_driven(cfg);
    let wb = cfg.mechanics.derived().base_speed_rad_s;
    let counts_per_rad = cpr / (2.0 * PI);
    let n = (60.0 * RATE_HZ) as usize;
    let mut seed = 11u64;
    let mut rec = Record {
        excitation: Vec::with_capacity(n),
        torque: Vec::with_capacity(n),
        position_rad: Vec::with_capacity(n),
    };
    let mut last_count = 0.0;
    for _ in 0..n {
        let count = (plant.motor_pos_rad() * counts_per_rad).floor();
        let speed_pu = (count - last_count) / counts_per_rad * RATE_HZ / wb;
        last_count = count;
        seed = seed
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        let r = if seed >> 63 == 1 {
            amplitude
        } else {
            -amplitude
        };
        let u = r - kp * speed_pu;
        rec.excitation.push(r);
        rec.torque.push(u);
        rec.position_rad.push(count / counts_per_rad);
        plant.advance(1.0 / RATE_HZ, u, 0.0);
    }
    rec
}

fn identify_table1(cpr: f64) {
    // Table 1 without its lost motion.
    let mut cfg = common::table1();
    cfg.mechanics.backlash_deg = 0.0;
    let m = cfg.mechanics;
    let rec = run(&cfg, cpr, 0.5, 0.3);
    let frf = closed_loop_response(
        &rec.excitation,
        &rec.torque,
        &rec.position_rad,
        RATE_HZ,
        8192,
    )
    .unwrap();
    let wb = m.derived().base_speed_rad_s;
    let r = fit_two_inertia(&frf, wb, 0.6, 400.0).unwrap();
    let rel = |a: f64, b: f64| (a / b - 1.0).abs();
    let resonance = m.derived().resonance_rad_s / (2.0 * PI);
    eprintln!("{cpr} counts: {r:?}");
    assert!(
        rel(r.fit.motor_inertia_s, m.motor_inertia_s) < 0.05,
        "Jm {r:?}"
    );
    assert!(
        rel(r.fit.load_inertia_s, m.load_inertia_s) < 0.05,
        "Jl {r:?}"
    );
    assert!(
        rel(r.fit.anti_resonance_hz, m.anti_resonance_hz) < 0.03,
        "f_ar {r:?}"
    );
    assert!(rel(r.fit.resonance_hz(), resonance) < 0.03, "f_r {r:?}");
    // The ZOH puts the torque half a tick before the position sample on average.
    assert!(
        (r.fit.delay_s - 0.5 / RATE_HZ).abs() < 0.1 / RATE_HZ,
        "delay {r:?}"
    );
    // The model explains the data to within the estimate's own noise.
    assert!(r.weighted_rms > 0.5 && r.weighted_rms < 2.0, "rms {r:?}");
    // No friction in the plant: the fitted sum is zero within three standard errors.
    assert!(
        r.fit.viscous_pu.abs() < 3.0 * r.std_error.viscous_pu,
        "B {r:?}"
    );
}

#[test]
fn the_fit_recovers_table1_through_a_4096_count_encoder() {
    identify_table1(4096.0);
}

#[test]
fn the_fit_recovers_table1_through_a_65536_count_encoder() {
    identify_table1(65_536.0);
}
