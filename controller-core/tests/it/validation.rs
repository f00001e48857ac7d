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
    assert!(matches!(
        expect_err(|c| c.base_speed_rpm = nan, "base_speed_rpm"),
        NotFinite { .. }
    ));
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
        |c| c.faults.following_error_counts = 1e7,
        "faults.following_error_counts",
    );
    expect_err(
        |c| c.faults.encoder_jump_margin = 0.5,
        "faults.encoder_jump_margin",
    );
}

#[test]
fn derived_coefficients_that_do_not_fit_are_errors() {
    // Kp = ω·J = 6000 rad/s × 900 s overflows Q16.16.
    let e = expect_err(
        |c| {
            c.motor_inertia_s = 400.0;
            c.load_inertia_s = 500.0;
            c.velocity_bandwidth_rad_s = 6000.0;
        },
        "kp_vel",
    );
    assert!(
        matches!(e, ConfigError::CoefficientOverflow { .. }),
        "{e:?}"
    );
    let e = expect_err(
        |c| {
            c.winding_inductance_pu_s = 90.0;
            c.current_bandwidth_rad_s = 10_000.0;
        },
        "kp_cur",
    );
    assert!(
        matches!(e, ConfigError::CoefficientOverflow { .. }),
        "{e:?}"
    );
    // A position gain of 1.8e-9 pu per count is too fine for Q1.31 (resolution 4.7e-10).
    let e = expect_err(
        |c| {
            c.encoder_cpr = 1_000_000;
            c.position_bandwidth_rad_s = 0.03;
        },
        "k_pos",
    );
    assert!(
        matches!(e, ConfigError::CoefficientUnderflow { .. }),
        "{e:?}"
    );
    // The observer's torque-to-counts factor overflows Q8.24 at 2^30 counts per rev.
    let e = expect_err(
        |c| {
            c.encoder_cpr = 1 << 30;
            c.counter_bits = 32;
        },
        "observer k_u",
    );
    assert!(
        matches!(e, ConfigError::CoefficientOverflow { .. }),
        "{e:?}"
    );
    // A 1e6 CPR drive (the printing-press stand) is fine.
    let mut cfg = common::table1();
    cfg.encoder_cpr = 1_000_000;
    cfg.counter_bits = 32;
    assert!(
        Controller::new(&cfg).is_ok(),
        "{:?}",
        Controller::new(&cfg).err()
    );
    let e = expect_err(
        |c| {
            c.encoder_cpr = 1_000_000;
            c.position_bandwidth_rad_s = 0.03;
        },
        "k_pos",
    );
    assert!(
        matches!(e, ConfigError::CoefficientUnderflow { .. }),
        "{e:?}"
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
