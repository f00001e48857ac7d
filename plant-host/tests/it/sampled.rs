//! The sampled-data model of the drive plant against the simulated plant.
#![allow(clippy::indexing_slicing, clippy::unwrap_used, missing_docs)]

use crate::common;

use nalgebra::DVector;
use plant_host::TwoInertiaPlant;
use plant_host::analysis::{Gears, SampledPlant, continuous, state};

/// With no lost motion the sampled map is the simulated drive, tick for tick.
#[test]
fn the_sampled_map_reproduces_the_drive_plant() {
    let mut cfg = common::table1();
    cfg.mechanics.backlash_deg = 0.0;
    cfg.mechanics.motor_viscous_pu = 0.01;
    cfg.mechanics.load_viscous_pu = 0.02;
    let (t, d) = (250e-6, cfg.electrics.computational_delay_s);
    let sp = SampledPlant::new(&cfg.mechanics, &cfg.electrics, Gears::Engaged, t, d);
    let mut drive = TwoInertiaPlant::voltage_driven(&cfg);
    let mut x = DVector::zeros(state::COUNT);
    let mut v_old = 0.0;
    let mut seed = 5u64;
    for k in 0..400 {
        seed = seed
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        let v = ((seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 0.2;
        let tl = if k > 200 { 0.3 } else { 0.0 };
        x = sp.step(&x, v, v_old, tl);
        drive.advance(d, v_old, tl);
        drive.advance(t - d, v, tl);
        v_old = v;
        let want = [
            drive.current_pu(),
            drive.motor_pos_rad(),
            drive.load_pos_rad(),
            drive.motor_vel_pu(),
            drive.load_vel_pu(),
        ];
        for (i, w) in want.iter().enumerate() {
            let got = x[i];
            assert!(
                (got - w).abs() <= 1e-9 * (1.0 + w.abs()),
                "tick {k}, state {i}: {got} vs {w}"
            );
        }
    }
}

/// Apart, the motor sees only its own inertia: a held current accelerates it by i/Jm.
#[test]
fn apart_the_motor_is_alone() {
    let cfg = common::table1();
    let sp = SampledPlant::new(&cfg.mechanics, &cfg.electrics, Gears::Apart, 250e-6, 0.0);
    let mut x = DVector::zeros(state::COUNT);
    x[state::CURRENT] = 1.0;
    let (a, _) = continuous(&cfg.mechanics, &cfg.electrics, Gears::Apart);
    let accel = (&a * &x)[state::MOTOR_SPEED];
    assert!((accel - 1.0 / cfg.mechanics.motor_inertia_s).abs() < 1e-12);
    let y = sp.step(&x, 0.0, 0.0, 0.0);
    assert_eq!(y[state::LOAD_SPEED], 0.0);
}
