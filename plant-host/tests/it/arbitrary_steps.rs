//! `advance` is accurate for arbitrary step lengths: random step sequences (from 0 to 2 ms,
//! with random torques) agree with the independent reference, and splitting steps anywhere
//! does not change the result.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic,
    missing_docs
)]

use crate::common;

use common::{RefParams, Reference};
use plant_host::{BacklashModel, TwoInertiaPlant};
use proptest::prelude::*;

fn steps() -> impl Strategy<Value = Vec<(f64, f64, f64, f64)>> {
    // (dt_s, split fraction, motor torque, load torque)
    prop::collection::vec(
        (
            prop_oneof![Just(0.0), 1e-9..1e-6_f64, 1e-6..2e-3_f64],
            0.0..1.0_f64,
            -2.0..2.0_f64,
            -0.5..0.5_f64,
        ),
        20..120,
    )
}

fn run(clamped: bool, seq: &[(f64, f64, f64, f64)]) {
    let mut cfg = common::table1();
    if clamped {
        cfg.lost_motion.model = BacklashModel::Clamped;
    }
    let m = &cfg.mechanics;
    let mut whole = TwoInertiaPlant::torque_driven(&cfg);
    let mut split = TwoInertiaPlant::torque_driven(&cfg);
    let mut r = Reference::new(
        RefParams::from_raw(
            m.base_speed_rpm,
            m.motor_inertia_s,
            m.load_inertia_s,
            m.anti_resonance_hz,
            m.shaft_damping_ratio,
            m.backlash_deg,
            clamped,
            None,
        ),
        1e-6,
    );
    for &(dt, frac, tm, tl) in seq {
        whole.advance(dt, tm, tl);
        split.advance(dt * frac, tm, tl);
        split.advance(dt - dt * frac, tm, tl);
        r.advance(dt, tm, tl);
        let e_split = (whole.motor_pos_rad() - split.motor_pos_rad()).abs()
            + (whole.load_pos_rad() - split.load_pos_rad()).abs()
            + (whole.motor_vel_pu() - split.motor_vel_pu()).abs()
            + (whole.load_vel_pu() - split.load_vel_pu()).abs();
        assert!(e_split < 1e-9, "split changes the result by {e_split}");
        let e_ref = (whole.motor_pos_rad() - r.x[0]).abs()
            + (whole.load_pos_rad() - r.x[1]).abs()
            + (whole.motor_vel_pu() - r.x[2]).abs()
            + (whole.load_vel_pu() - r.x[3]).abs();
        assert!(e_ref < 1e-8, "reference differs by {e_ref}");
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    #[test]
    fn dead_zone_arbitrary_steps(seq in steps()) {
        run(false, &seq);
    }

    #[test]
    fn clamped_arbitrary_steps(seq in steps()) {
        run(true, &seq);
    }
}

#[test]
fn invalid_steps_are_rejected_and_leave_the_plant_unchanged() {
    let cfg = common::table1();
    let mut p = TwoInertiaPlant::torque_driven(&cfg);
    p.advance(1e-3, 1.0, 0.0);
    let before = (p.motor_pos_rad(), p.motor_vel_pu(), p.time_s());
    assert!(p.try_advance(-1e-3, 1.0, 0.0).is_err());
    assert!(p.try_advance(f64::NAN, 1.0, 0.0).is_err());
    assert!(p.try_advance(1e-3, f64::INFINITY, 0.0).is_err());
    assert!(p.try_advance(1e-3, 0.0, f64::NAN).is_err());
    p.advance(f64::NAN, 1.0, 0.0);
    assert_eq!(before, (p.motor_pos_rad(), p.motor_vel_pu(), p.time_s()));
}

#[test]
fn advance_with_load_ends_steps_at_load_changes() {
    use plant_host::LoadTorque;
    let cfg = common::table1();
    let load = LoadTorque::Sum(vec![
        LoadTorque::Step {
            at_s: 0.010_1,
            torque_pu: 0.5,
        },
        LoadTorque::Shock {
            start_s: 0.020_05,
            duration_s: 0.001,
            torque_pu: 1.5,
        },
    ]);
    let mut a = TwoInertiaPlant::torque_driven(&cfg);
    let mut b = TwoInertiaPlant::torque_driven(&cfg);
    for _ in 0..120 {
        a.advance_with_load(250e-6, 1.0, &load).unwrap();
    }
    // By hand: the same held torques over the exact segments.
    for (dt, tl) in [
        (0.010_1, 0.0),
        (0.020_05 - 0.010_1, 0.5),
        (0.001, 2.0),
        (0.03 - 0.021_05, 0.5),
    ] {
        b.advance(dt, 1.0, tl);
    }
    assert!((a.time_s() - 0.03).abs() < 1e-12);
    assert!((a.motor_pos_rad() - b.motor_pos_rad()).abs() < 1e-10);
    assert!((a.load_vel_pu() - b.load_vel_pu()).abs() < 1e-10);
    assert!(a.advance_with_load(f64::NAN, 1.0, &load).is_err());
}
