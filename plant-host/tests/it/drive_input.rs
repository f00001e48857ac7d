//! How the input drives the plant: a voltage-driven plant has its winding and a
//! torque-driven one none, and each reports the configured computational delay and an
//! internal sub-step of at most 250 µs; one sampling period with the computational delay
//! (`TwoInertiaPlant::advance_period`) is the input applied so far for the delay, then the
//! new one for the rest of the period, bit for bit two `try_advance` steps; a bad period or
//! input is refused and changes nothing.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use crate::common;
use plant_host::{PlantError, TwoInertiaPlant};

fn state(p: &TwoInertiaPlant) -> [u64; 5] {
    [
        p.motor_pos_rad().to_bits(),
        p.load_pos_rad().to_bits(),
        p.motor_vel_pu().to_bits(),
        p.current_pu().to_bits(),
        p.time_s().to_bits(),
    ]
}

#[test]
fn a_period_is_the_old_input_for_the_delay_then_the_new_one() {
    let cfg = common::table1();
    let delay = cfg.electrics.computational_delay_s;
    assert!(delay > 0.0 && delay < 250e-6, "table1's delay {delay}");
    let mut a = TwoInertiaPlant::voltage_driven(&cfg);
    let mut b = TwoInertiaPlant::voltage_driven(&cfg);
    let mut applied = 0.0;
    for k in 0..400 {
        let v = 0.4 * (f64::from(k) / 25.0).sin();
        let load = if k > 200 { 0.2 } else { 0.0 };
        a.advance_period(250e-6, v, load).unwrap();
        b.try_advance(delay, applied, load).unwrap();
        b.try_advance(250e-6 - delay, v, load).unwrap();
        applied = v;
        assert_eq!(a.applied_input_pu().to_bits(), v.to_bits(), "period {k}");
        assert_eq!(state(&a), state(&b), "period {k}");
    }
    assert!(a.motor_vel_pu().abs() > 1e-3, "the plant moved");
}

#[test]
fn a_bad_period_or_input_is_refused_and_changes_nothing() {
    let cfg = common::table1();
    let mut p = TwoInertiaPlant::voltage_driven(&cfg);
    p.advance_period(250e-6, 0.3, 0.0).unwrap();
    let before = state(&p);
    for (period, input, load) in [
        (-1e-4, 0.3, 0.0),
        (f64::NAN, 0.3, 0.0),
        (250e-6, f64::INFINITY, 0.0),
        (250e-6, 0.3, f64::NAN),
    ] {
        let e = p.advance_period(period, input, load).unwrap_err();
        assert!(
            matches!(e, PlantError::BadStep { .. } | PlantError::BadInput { .. }),
            "{e:?}"
        );
        assert_eq!(state(&p), before);
        assert_eq!(p.applied_input_pu(), 0.3);
    }
}

#[test]
fn the_plant_reports_its_winding_delay_and_sub_step() {
    let cfg = common::table1();
    assert!(TwoInertiaPlant::voltage_driven(&cfg).winding().is_some());
    assert!(TwoInertiaPlant::torque_driven(&cfg).winding().is_none());
    for p in [
        TwoInertiaPlant::voltage_driven(&cfg),
        TwoInertiaPlant::torque_driven(&cfg),
    ] {
        let delay = p.computational_delay_s();
        assert_eq!(
            delay.to_bits(),
            cfg.electrics.computational_delay_s.to_bits()
        );
        let h = p.max_substep_s();
        assert!(h > 0.0 && h <= 250e-6, "sub-step {h}");
    }
}

/// A locked load (`with_locked_load`, the locked-rotor test) stays where it is whatever the
/// motor does: under a torque the motor takes up the lost motion and twists the shaft, and
/// stops there, with the shaft torque carrying the motor torque (K·twist, less the gap);
/// the plant it returns starts at rest even from a plant that had moved.
#[test]
fn a_locked_load_holds_still_and_the_shaft_takes_the_motor_torque() {
    let cfg = common::table1();
    let mut moved = TwoInertiaPlant::torque_driven(&cfg);
    for _ in 0..400 {
        moved.advance_period(250e-6, 0.5, 0.0).unwrap();
    }
    assert!(moved.time_s() > 0.0 && moved.motor_vel_pu() > 0.0);
    assert!(moved.encoder_count() > 0 && moved.applied_input_pu() == 0.5);
    let mut p = moved.with_locked_load();
    assert_eq!(
        (p.time_s(), p.motor_pos_rad(), p.motor_vel_pu()),
        (0.0, 0.0, 0.0)
    );
    assert_eq!(p.applied_input_pu(), 0.0);
    assert_eq!(p.encoder_count(), 0);
    for _ in 0..4000 {
        p.try_advance(250e-6, 1.0, 0.3).unwrap();
        assert_eq!((p.load_vel_pu(), p.load_pos_rad()), (0.0, 0.0));
    }
    // Damped by the shaft, the motor has come to rest against the locked load.
    assert!(p.motor_vel_pu().abs() < 1e-6, "{}", p.motor_vel_pu());
    assert!(
        (p.shaft_torque_pu() - 1.0).abs() < 1e-6,
        "{}",
        p.shaft_torque_pu()
    );
    assert!(p.motor_pos_rad() > 0.0 && p.encoder_count() > 0);
    // A free plant under the same input accelerates the load.
    let mut free = TwoInertiaPlant::torque_driven(&cfg);
    free.try_advance(1.0, 1.0, 0.3).unwrap();
    assert!(free.load_vel_pu() > 0.1);
}

/// The locked plant's sensors start afresh too: with encoder and current noise, a plant
/// locked after it had moved reads, sample for sample, what a plant locked at rest reads.
#[test]
fn a_locked_load_starts_its_sensors_afresh() {
    let mut cfg = common::table1();
    cfg.sensors.encoder_noise_counts = 2.0;
    cfg.sensors.current_noise_pu = 0.01;
    let mut moved = TwoInertiaPlant::voltage_driven(&cfg);
    for _ in 0..400 {
        moved.advance_period(250e-6, 0.2, 0.0).unwrap();
        let _ = (moved.encoder_count(), moved.current_sample());
    }
    let mut a = moved.with_locked_load();
    let mut b = TwoInertiaPlant::voltage_driven(&cfg).with_locked_load();
    for k in 0..400 {
        a.advance_period(250e-6, 0.3, 0.0).unwrap();
        b.advance_period(250e-6, 0.3, 0.0).unwrap();
        assert_eq!(a.encoder_count(), b.encoder_count(), "tick {k}");
        assert_eq!(
            a.current_sample().to_bits(),
            b.current_sample().to_bits(),
            "tick {k}"
        );
    }
}
