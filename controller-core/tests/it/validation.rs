//! Every validation error: each bad setting gives a typed error naming its parameter.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

use crate::common;
use controller_core::{
    ConfigError, Controller, DriveConfig, FilterConfig, Profile, ProfileConfig, ProfileKind, design,
};

fn expect_err(mutate: impl Fn(&mut DriveConfig), param: &str) -> ConfigError {
    let mut cfg = common::table1();
    mutate(&mut cfg);
    let err = Controller::new(&cfg).expect_err(param);
    assert!(
        err.param().starts_with(param),
        "expected {param}, got {err:?}"
    );
    let text = err.to_string();
    assert!(text.contains(param), "Display must name {param}: {text}");
    err
}

#[test]
fn table1_is_valid() {
    assert!(design(&common::table1()).is_ok());
    assert!(Controller::new(&common::table1()).is_ok());
}

#[test]
fn every_drive_setting_is_validated() {
    use ConfigError::*;
    let nan = f32::NAN;
    let inf = f32::INFINITY;
    assert!(matches!(
        expect_err(|c| c.base_speed_rpm = 0.0, "base_speed_rpm"),
        OutOfRange { .. }
    ));
    // NaN gets its range like any other bad number; a frequency's range ends below its
    // loop's Nyquist limit.
    let e = expect_err(|c| c.base_speed_rpm = nan, "base_speed_rpm");
    assert!(matches!(e, OutOfRange { .. }), "{e:?}");
    assert!(e.to_string().contains("(0, 100000]"), "{e}");
    let e = expect_err(
        |c| c.velocity_bandwidth_rad_s = nan,
        "velocity_bandwidth_rad_s",
    );
    assert!(
        matches!(e, OutOfRange { max, .. } if max < 6283.19 && max > 6283.18),
        "{e:?}"
    );
    assert!(e.to_string().contains("(0, 6283.18"), "{e}");
    expect_err(|c| c.encoder_cpr = 2, "encoder_cpr");
    expect_err(|c| c.counter_bits = 8, "counter_bits");
    expect_err(|c| c.counter_bits = 33, "counter_bits");
    expect_err(|c| c.current_rate_hz = 50, "current_rate_hz");
    expect_err(|c| c.velocity_rate_hz = 5, "velocity_rate_hz");
    assert!(matches!(
        expect_err(|c| c.velocity_rate_hz = 3000, "velocity_rate_hz"),
        RateRatio { .. }
    ));
    assert!(matches!(
        expect_err(|c| c.velocity_rate_hz = 100, "velocity_rate_hz"),
        RateRatio { .. }
    ));
    for bad in [0.0, -1.0, nan, inf] {
        expect_err(|c| c.motor_inertia_s = bad, "motor_inertia_s");
    }
    expect_err(|c| c.load_inertia_s = -0.1, "load_inertia_s");
    expect_err(|c| c.load_inertia_s = inf, "load_inertia_s");
    expect_err(
        |c| c.position_bandwidth_rad_s = -1.0,
        "position_bandwidth_rad_s",
    );
    assert!(matches!(
        expect_err(
            |c| c.position_bandwidth_rad_s = 7000.0,
            "position_bandwidth_rad_s"
        ),
        AboveNyquist { .. }
    ));
    expect_err(
        |c| c.velocity_bandwidth_rad_s = 0.0,
        "velocity_bandwidth_rad_s",
    );
    assert!(matches!(
        expect_err(
            |c| c.velocity_bandwidth_rad_s = 6300.0,
            "velocity_bandwidth_rad_s"
        ),
        AboveNyquist { .. }
    ));
    expect_err(|c| c.velocity_damping = 0.05, "velocity_damping");
    expect_err(
        |c| c.current_bandwidth_rad_s = nan,
        "current_bandwidth_rad_s",
    );
    assert!(matches!(
        expect_err(
            |c| c.current_bandwidth_rad_s = 13_000.0,
            "current_bandwidth_rad_s"
        ),
        AboveNyquist { .. }
    ));
    expect_err(|c| c.winding_resistance_pu = 0.0, "winding_resistance_pu");
    expect_err(
        |c| c.winding_inductance_pu_s = -1.0,
        "winding_inductance_pu_s",
    );
    expect_err(|c| c.torque_limit_pu = 0.0, "torque_limit_pu");
    expect_err(|c| c.voltage_limit_pu = nan, "voltage_limit_pu");
    expect_err(|c| c.velocity_ff_gain = 1.5, "velocity_ff_gain");
    expect_err(|c| c.accel_ff_gain = -0.1, "accel_ff_gain");
    expect_err(
        |c| c.accel_feedback.gain_fraction = 25.0,
        "accel_feedback.gain_fraction",
    );
    assert!(matches!(
        expect_err(
            |c| c.accel_feedback.filter = FilterConfig::FirstOrder { corner_hz: 2500.0 },
            "accel_feedback.filter.corner_hz"
        ),
        AboveNyquist { .. }
    ));
    expect_err(
        |c| {
            c.accel_feedback.filter = FilterConfig::SecondOrder {
                corner_hz: 50.0,
                q: 0.0,
            }
        },
        "accel_feedback.filter.q",
    );
    expect_err(
        |c| c.velocity_filter = FilterConfig::FirstOrder { corner_hz: 0.0 },
        "velocity_filter.corner_hz",
    );
    // At the velocity rate the same corner can be above Nyquist.
    expect_err(
        |c| {
            c.accel_feedback.rate = controller_core::AfbRate::Velocity;
            c.accel_feedback.filter = FilterConfig::FirstOrder { corner_hz: 1500.0 };
        },
        "accel_feedback.filter.corner_hz",
    );
    assert!(matches!(
        expect_err(
            |c| c.observer.bandwidth_hz = 2000.0,
            "observer.bandwidth_hz"
        ),
        AboveNyquist { .. }
    ));
    expect_err(|c| c.observer.bandwidth_hz = -5.0, "observer.bandwidth_hz");
    expect_err(|c| c.faults.overspeed_pu = 0.0, "faults.overspeed_pu");
    expect_err(
        |c| c.faults.following_error_rev = 2000.0,
        "faults.following_error_rev",
    );
    // The limit in counts must fit Q24.8 (below 2^23): 8 revolutions of a 2^20 encoder.
    let e = expect_err(
        |c| {
            c.encoder_cpr = 1 << 20;
            c.faults.following_error_rev = 8.0;
        },
        "faults.following_error_rev",
    );
    assert!(
        matches!(e, OutOfRangeGiven { max, .. } if max < 8.0 && max > 7.999),
        "{e:?}"
    );
    assert!(e.to_string().contains("encoder_cpr"), "{e}");
    expect_err(
        |c| c.faults.encoder_jump_margin = 0.5,
        "faults.encoder_jump_margin",
    );
}

/// The range of an `OutOfRangeGiven` error, which must hold `ok` and not the value given.
fn given_range(e: &ConfigError) -> (f32, f32, f32) {
    match *e {
        ConfigError::OutOfRangeGiven {
            value, min, max, ..
        } => (value, min, max),
        _ => panic!("expected a range given the other settings: {e:?}"),
    }
}

#[test]
fn derived_coefficients_that_do_not_fit_name_the_users_key_and_its_range() {
    // Kp = ω·J = 6000 rad/s × 900 s overflows Q16.16: the velocity bandwidth, with the range
    // that fits given the inertia, the damping and the rate.
    let e = expect_err(
        |c| {
            c.motor_inertia_s = 400.0;
            c.load_inertia_s = 500.0;
            c.velocity_bandwidth_rad_s = 6000.0;
            c.current_bandwidth_rad_s = 12_000.0;
        },
        "velocity_bandwidth_rad_s",
    );
    let (v, _, max) = given_range(&e);
    assert!(v > max && max > 0.0, "{e}");
    assert!(!e.to_string().contains("kp_vel"), "{e}");
    // At the range's top the same drive is accepted.
    let mut cfg = common::table1();
    cfg.motor_inertia_s = 400.0;
    cfg.load_inertia_s = 500.0;
    cfg.current_bandwidth_rad_s = 12_000.0;
    cfg.velocity_bandwidth_rad_s = max * 0.999;
    assert!(Controller::new(&cfg).is_ok(), "{max}");
    // Table 1 at 3000 rad/s: Ki·Ts = 1102 does not fit Q8.24; the bandwidth is named.
    let e = expect_err(
        |c| {
            c.velocity_bandwidth_rad_s = 3000.0;
            c.current_bandwidth_rad_s = 12_000.0;
        },
        "velocity_bandwidth_rad_s",
    );
    let (_, _, max) = given_range(&e);
    assert!(e.to_string().contains("velocity_damping"), "{e}");
    let mut cfg = common::table1();
    cfg.current_bandwidth_rad_s = 12_000.0;
    cfg.velocity_bandwidth_rad_s = max * 0.999;
    assert!(Controller::new(&cfg).is_ok(), "{max}");
    let e = expect_err(
        |c| {
            c.winding_inductance_pu_s = 90.0;
            c.current_bandwidth_rad_s = 10_000.0;
        },
        "current_bandwidth_rad_s",
    );
    let (v, _, max) = given_range(&e);
    assert!(v > max, "{e}");
    assert!(e.to_string().contains("winding_inductance_pu_s"), "{e}");
    // A position gain of 1.8e-9 pu per count is too fine for Q1.31 (resolution 4.7e-10):
    // the position bandwidth, with its smallest value at this encoder.
    let e = expect_err(
        |c| {
            c.encoder_cpr = 1_000_000;
            c.position_bandwidth_rad_s = 0.03;
        },
        "position_bandwidth_rad_s",
    );
    let (v, min, max) = given_range(&e);
    assert!(v < min && max < 6283.19, "{e}");
    let mut cfg = common::table1();
    cfg.encoder_cpr = 1_000_000;
    cfg.position_bandwidth_rad_s = min;
    assert!(Controller::new(&cfg).is_ok(), "{min}");
    // 2^30 counts per rev (the static maximum) does not fit the observer's scales nor a
    // 16-bit counter at Table 1's speed and rates: the encoder is named, with its range.
    for bits in [16, 32] {
        let e = expect_err(
            |c| {
                c.encoder_cpr = 1 << 30;
                c.counter_bits = bits;
            },
            "encoder_cpr",
        );
        let (_, min, max) = given_range(&e);
        assert!(min <= 4096.0 && max < (1u32 << 30) as f32, "{e}");
        assert!(e.to_string().contains("counter_bits"), "{e}");
        let mut cfg = common::table1();
        cfg.counter_bits = bits;
        cfg.encoder_cpr = max as u32;
        assert!(Controller::new(&cfg).is_ok(), "{bits} bits, {max}");
        cfg.encoder_cpr = max as u32 + 1;
        assert_eq!(
            Controller::new(&cfg).map(|_| ()).unwrap_err().param(),
            "encoder_cpr"
        );
    }
    // A 1e6 CPR drive (the printing-press stand) is fine.
    let mut cfg = common::table1();
    cfg.encoder_cpr = 1_000_000;
    cfg.counter_bits = 32;
    assert!(
        Controller::new(&cfg).is_ok(),
        "{:?}",
        Controller::new(&cfg).err()
    );
}

/// The current loop must be at least 1.5 times as fast as the velocity loop; the error
/// names both bandwidths. Table 1 (94.25 in 1998 rad/s) and the sweep's fastest point
/// (1000 in 1998) pass.
#[test]
fn the_velocity_bandwidth_stays_below_the_current_bandwidth() {
    let e = expect_err(
        |c| {
            c.velocity_bandwidth_rad_s = 40.0;
            c.current_bandwidth_rad_s = 30.0;
        },
        "velocity_bandwidth_rad_s",
    );
    assert!(e.to_string().contains("current_bandwidth_rad_s"), "{e}");
    assert!(
        matches!(e, ConfigError::OutOfRangeGiven { max, .. } if max == 20.0),
        "{e:?}"
    );
    let mut cfg = common::table1();
    cfg.velocity_bandwidth_rad_s = 1000.0;
    assert!(Controller::new(&cfg).is_ok());
    cfg.current_bandwidth_rad_s = 600.0;
    cfg.velocity_bandwidth_rad_s = 399.0;
    assert!(cfg.validate().is_ok());
    cfg.velocity_bandwidth_rad_s = 401.0;
    let e = cfg.validate().unwrap_err();
    assert_eq!(e.param(), "velocity_bandwidth_rad_s");
    assert!(
        e.to_string()
            .contains(", 400] given current_bandwidth_rad_s"),
        "{e}"
    );
}

#[test]
fn every_profile_setting_is_validated() {
    let drive = common::table1();
    let check = |mutate: &dyn Fn(&mut ProfileConfig), param: &str| {
        let mut p = ProfileConfig::fig6();
        p.hold_time_s = 1.0;
        mutate(&mut p);
        let e = Profile::new(&p, &drive).expect_err(param);
        assert_eq!(e.param(), param, "{e:?}");
        assert!(e.to_string().contains(param));
    };
    check(&|p| p.peak_velocity_pu = 20.0, "profile.peak_velocity_pu");
    check(
        &|p| p.peak_velocity_pu = f32::NAN,
        "profile.peak_velocity_pu",
    );
    check(&|p| p.accel_time_s = 0.0, "profile.accel_time_s");
    check(&|p| p.decel_time_s = -1.0, "profile.decel_time_s");
    check(&|p| p.hold_time_s = f32::NAN, "profile.hold_time_s");
    check(&|p| p.hold_time_s = -1.0, "profile.hold_time_s");
    check(
        &|p| p.start_delay_s = f32::INFINITY,
        "profile.start_delay_s",
    );
    check(
        &|p| p.kind = ProfileKind::SCurve { jerk_time_s: 0.6 },
        "profile.kind.jerk_time_s",
    );
    check(
        &|p| p.kind = ProfileKind::SCurve { jerk_time_s: 0.0 },
        "profile.kind.jerk_time_s",
    );
    // A bad drive is reported through the profile too.
    let mut bad = drive;
    bad.motor_inertia_s = -1.0;
    assert_eq!(
        Profile::new(&ProfileConfig::fig6(), &bad)
            .unwrap_err()
            .param(),
        "motor_inertia_s"
    );
}
