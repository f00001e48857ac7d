//! Must-show: a replay of a 1 s, 4 kHz torque profile that crosses the lost-motion gap many
//! times agrees with an independent high-accuracy integration (`common`) within 1e-4 rad
//! and 1e-4 pu at every row. Run with `-- --nocapture` to see the measured errors.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic,
    missing_docs
)]

use crate::common;

use common::config_path;
use common::{RefParams, Reference};
use plant_host::{BacklashModel, PlantConfig, TwoInertiaPlant, replay};
use std::f64::consts::PI;
use std::fmt::Write as _;

/// Motor torque reversing at 4 Hz with a 31 Hz ripple, load torque with a slow sine and a step:
/// the gears cross the gap at every reversal and rattle in between.
fn profile(t: f64) -> (f64, f64) {
    let tm = 1.2 * (2.0 * PI * 4.0 * t).sin() + 0.4 * (2.0 * PI * 31.0 * t + 1.0).sin();
    let tl = 0.2 * (2.0 * PI * 1.3 * t).sin() + if t >= 0.5 { 0.3 } else { 0.0 };
    (tm, tl)
}

fn ref_params(cfg: &PlantConfig, winding: bool) -> RefParams {
    let m = &cfg.mechanics;
    let mut p = RefParams::from_raw(
        m.base_speed_rpm,
        m.motor_inertia_s,
        m.load_inertia_s,
        m.anti_resonance_hz,
        m.shaft_damping_ratio,
        m.backlash_deg,
        cfg.lost_motion.model == BacklashModel::Clamped,
        winding.then_some((
            cfg.electrics.winding_resistance_pu,
            cfg.electrics.winding_inductance_pu_s,
        )),
    );
    p.bm = m.motor_viscous_pu;
    p.bl = m.load_viscous_pu;
    p
}

#[derive(Default, Debug)]
struct MaxErr {
    pos_rad: f64,
    vel_pu: f64,
    torque_pu: f64,
    count_mismatch: usize,
}

/// Writes the profile to IN.csv, replays it through the public `replay`, and compares every
/// OUT.csv row with the reference integrated over the same held inputs.
fn replay_vs_reference(cfg_file: &str, model: Option<&str>) -> (MaxErr, u64, u64) {
    let dir = tempfile::tempdir().unwrap();
    let mut cfg_text = std::fs::read_to_string(config_path(cfg_file)).unwrap();
    if let Some(m) = model {
        cfg_text = cfg_text.replace("model = \"dead_zone\"", &format!("model = \"{m}\""));
    }
    let cfg_path = dir.path().join("plant.toml");
    std::fs::write(&cfg_path, &cfg_text).unwrap();
    let cfg = PlantConfig::from_machine_toml(&cfg_text).unwrap();

    let rows = 4001;
    let dt = 250e-6;
    let mut input = String::from("t_s,motor_torque_pu,load_torque_pu\n");
    let mut torques = Vec::new();
    for k in 0..rows {
        let t = k as f64 * dt;
        let (tm, tl) = profile(t);
        torques.push((t, tm, tl));
        writeln!(input, "{t},{tm},{tl}").unwrap();
    }
    let in_path = dir.path().join("in.csv");
    let out_path = dir.path().join("out.csv");
    std::fs::write(&in_path, input).unwrap();
    let summary = replay(&cfg_path, &in_path, &out_path).unwrap();
    assert_eq!(summary.rows, rows);

    let out = std::fs::read_to_string(&out_path).unwrap();
    let mut lines = out.lines();
    assert_eq!(
        lines.next().unwrap(),
        "t_s,motor_pos_rad,load_pos_rad,motor_vel_pu,load_vel_pu,shaft_torque_pu,encoder_count"
    );
    // 1 µs RK4 steps: truncation error ~ (ω_r·h)^4 ≈ 1e-13 per unit time.
    let mut r = Reference::new(ref_params(&cfg, false), 1e-6);
    let cpr = f64::from(cfg.counts_per_rev());
    let mut err = MaxErr::default();
    let mut prev: Option<(f64, f64, f64)> = None;
    for ((t, tm, tl), line) in torques.iter().zip(lines) {
        if let Some((t0, tm0, tl0)) = prev {
            r.advance(t - t0, tm0, tl0);
        }
        prev = Some((*t, *tm, *tl));
        let f: Vec<f64> = line.split(',').map(|s| s.parse().unwrap()).collect();
        assert_eq!(f.len(), 7);
        assert_eq!(f[0], *t);
        err.pos_rad = err
            .pos_rad
            .max((f[1] - r.x[0]).abs())
            .max((f[2] - r.x[1]).abs());
        err.vel_pu = err
            .vel_pu
            .max((f[3] - r.x[2]).abs())
            .max((f[4] - r.x[3]).abs());
        err.torque_pu = err.torque_pu.max((f[5] - r.shaft_torque()).abs());
        let ref_count = (r.x[0] * cpr / (2.0 * PI)).floor();
        if ref_count != f[6] {
            err.count_mismatch += 1;
        }
    }
    (err, summary.edge_crossings, r.switches)
}

fn check(name: &str, (err, crossings, ref_switches): (MaxErr, u64, u64)) {
    println!(
        "{name}: max |error| position {:.2e} rad, speed {:.2e} pu, shaft torque {:.2e} pu; \
         {crossings} edge crossings (reference {ref_switches}); encoder rows differing {}",
        err.pos_rad, err.vel_pu, err.torque_pu, err.count_mismatch
    );
    assert!(
        crossings >= 20,
        "profile must cross the gap many times: {crossings}"
    );
    assert_eq!(
        crossings, ref_switches,
        "both integrators see the same contact changes"
    );
    assert!(err.pos_rad < 1e-4, "{name}: position error {}", err.pos_rad);
    assert!(err.vel_pu < 1e-4, "{name}: speed error {}", err.vel_pu);
    assert!(
        err.torque_pu < 1e-4,
        "{name}: shaft torque error {}",
        err.torque_pu
    );
    // An encoder edge can only differ when the angle is within the error of a count boundary.
    assert!(
        err.count_mismatch <= 2,
        "{name}: {} encoder rows differ",
        err.count_mismatch
    );
}

#[test]
fn table1_dead_zone_replay_matches_reference() {
    check("table1 dead zone", replay_vs_reference("table1.toml", None));
}

#[test]
fn table1_clamped_replay_matches_reference() {
    check(
        "table1 clamped",
        replay_vs_reference("table1.toml", Some("clamped")),
    );
}

#[test]
fn printing_press_replay_matches_reference() {
    check(
        "printing press",
        replay_vs_reference("printing-press.toml", None),
    );
}

/// The drive (winding + mechanics) under the harness's event pattern: a new voltage 0.18 ms
/// after each 0.25 ms tick, so `advance` sees alternating 180 µs and 70 µs steps.
#[test]
fn drive_with_winding_matches_reference_for_irregular_steps() {
    let cfg = common::table1();
    let mut drive = TwoInertiaPlant::voltage_driven(&cfg);
    let delay = cfg.electrics.computational_delay_s;
    let mut r = Reference::new(ref_params(&cfg, true), 1e-6);
    let (mut max_pos, mut max_vel, mut max_cur) = (0.0_f64, 0.0_f64, 0.0_f64);
    let mut v_applied = 0.0;
    let mut t = 0.0;
    for tick in 0..4000 {
        let (tm_wish, tl) = profile(t);
        // A crude voltage: what would push the wished torque through R plus the back-EMF.
        let v_new = 0.05 * tm_wish + drive.motor_vel_pu() + 0.02 * ((tick % 7) as f64 - 3.0);
        for (dt, v) in [(delay, v_applied), (250e-6 - delay, v_new)] {
            drive.advance(dt, v, tl);
            r.advance(dt, v, tl);
            t += dt;
        }
        v_applied = v_new;
        max_pos = max_pos
            .max((drive.motor_pos_rad() - r.x[0]).abs())
            .max((drive.load_pos_rad() - r.x[1]).abs());
        max_vel = max_vel
            .max((drive.motor_vel_pu() - r.x[2]).abs())
            .max((drive.load_vel_pu() - r.x[3]).abs());
        max_cur = max_cur.max((drive.current_pu() - r.x[4]).abs());
    }
    println!(
        "drive: max |error| position {max_pos:.2e} rad, speed {max_vel:.2e} pu, current {max_cur:.2e} pu, \
         {} crossings (reference {})",
        drive.mode_changes(),
        r.switches
    );
    assert!(drive.mode_changes() >= 20);
    assert!(max_pos < 1e-6 && max_vel < 1e-6 && max_cur < 1e-6);
}

/// Why the edges are located: RK4 at 62.5 µs stepping straight over them (the contact law
/// frozen per step) misses the fine reference by far more than the 1e-4 bound.
#[test]
fn stepping_over_the_edges_would_fail_the_bound() {
    let cfg = common::table1();
    let p = ref_params(&cfg, false);
    let mut fine = Reference::new(p, 1e-6);
    let mut naive = Reference::new(p, 62.5e-6);
    naive.locate = false;
    let (mut pos, mut torque) = (0.0_f64, 0.0_f64);
    for k in 0..4000 {
        let (tm, tl) = profile(k as f64 * 250e-6);
        fine.advance(250e-6, tm, tl);
        naive.advance(250e-6, tm, tl);
        pos = pos
            .max((fine.x[0] - naive.x[0]).abs())
            .max((fine.x[1] - naive.x[1]).abs());
        torque = torque.max((fine.shaft_torque() - naive.shaft_torque()).abs());
    }
    println!(
        "RK4 62.5 µs without edge location: max position error {pos:.2e} rad, shaft torque {torque:.2e} pu"
    );
    assert!(torque > 1e-4, "{torque}");
}
