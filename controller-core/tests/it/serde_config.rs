//! The `[drive]` TOML contract of `DriveConfig` (feature `serde`): required keys, design
//! defaults, enum words, the tagged filter table, whole numbers, unknown keys.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use crate::common;

use controller_core::config::defaults;
use controller_core::{
    AfbMode, AfbRate, DriveConfig, Estimator, FilterConfig, ObserverInertia, ObserverTorque,
    PiInertia, RANGES,
};

/// The required keys only (values of no particular drive).
const REQUIRED: &str = "
base_speed_rpm = 1500.0
encoder_cpr = 2048
motor_inertia_s = 0.2
load_inertia_s = 0.6
winding_resistance_pu = 0.04
winding_inductance_pu_s = 8e-4
current_rate_hz = 8000
velocity_rate_hz = 2000
position_bandwidth_rad_s = 12.0
velocity_bandwidth_rad_s = 60.0
current_bandwidth_rad_s = 1500.0
";

fn parse(extra: &str) -> Result<DriveConfig, String> {
    toml::from_str(&format!("{REQUIRED}\n{extra}")).map_err(|e| e.to_string())
}

#[test]
fn omitted_keys_take_the_design_defaults() {
    let c = parse("").unwrap();
    assert_eq!(c.counter_bits, 16);
    assert_eq!(c.velocity_damping, 1.0);
    assert_eq!(c.velocity_pi_inertia, PiInertia::Total);
    assert_eq!((c.torque_limit_pu, c.voltage_limit_pu), (2.0, 1.2));
    assert_eq!((c.velocity_ff_gain, c.accel_ff_gain), (1.0, 1.0));
    assert_eq!(c.velocity_filter, FilterConfig::None);
    assert_eq!(c.velocity_estimator, Estimator::Observer);
    assert_eq!(c.accel_feedback, defaults::ACCEL_FEEDBACK);
    assert_eq!(c.accel_feedback.mode, AfbMode::Error);
    assert_eq!(c.accel_feedback.gain_fraction, 0.5);
    assert_eq!(
        c.accel_feedback.filter,
        FilterConfig::FirstOrder { corner_hz: 100.0 }
    );
    assert_eq!(c.accel_feedback.rate, AfbRate::Current);
    assert_eq!(c.accel_feedback.source, Estimator::Observer);
    assert_eq!(c.observer.bandwidth_hz, 75.0);
    assert_eq!(c.observer.model_inertia, ObserverInertia::Motor);
    assert_eq!(c.observer.torque_input, ObserverTorque::Command);
    assert_eq!(
        (
            c.faults.overspeed_pu,
            c.faults.following_error_rev,
            c.faults.encoder_jump_margin
        ),
        (1.5, 0.25, 2.0)
    );
    assert!(c.validate().is_ok());
}

#[test]
fn every_required_key_is_required() {
    for line in REQUIRED.lines().filter(|l| !l.trim().is_empty()) {
        let key = line.split('=').next().unwrap().trim();
        let text: String = REQUIRED
            .lines()
            .filter(|l| *l != line)
            .map(|l| format!("{l}\n"))
            .collect();
        let e = toml::from_str::<DriveConfig>(&text)
            .unwrap_err()
            .to_string();
        assert!(e.contains(key), "{key}: {e}");
    }
}

#[test]
fn a_nested_table_may_name_one_key() {
    let c = parse("[observer]\nbandwidth_hz = 60").unwrap();
    assert_eq!(c.observer.bandwidth_hz, 60.0);
    assert_eq!(c.observer.model_inertia, ObserverInertia::Motor);
    let c = parse("[accel_feedback]\nmode = \"plain\"").unwrap();
    assert_eq!(c.accel_feedback.mode, AfbMode::Plain);
    assert_eq!(c.accel_feedback.gain_fraction, 0.5);
    let c = parse("[faults]\noverspeed_pu = 2").unwrap();
    assert_eq!(c.faults.overspeed_pu, 2.0);
    assert_eq!(c.faults.encoder_jump_margin, 2.0);
}

#[test]
fn enum_words() {
    let c = parse(
        "velocity_estimator = \"differentiation\"\nvelocity_pi_inertia = \"total_plus_afb\"\n\
         [accel_feedback]\nmode = \"off\"\nrate = \"velocity\"\nsource = \"differentiation\"\n\
         [observer]\nmodel_inertia = \"total\"\ntorque_input = \"measured_current\"",
    )
    .unwrap();
    assert_eq!(c.velocity_estimator, Estimator::Differentiation);
    assert_eq!(c.velocity_pi_inertia, PiInertia::TotalPlusAfb);
    assert_eq!(c.accel_feedback.mode, AfbMode::Off);
    assert_eq!(c.accel_feedback.rate, AfbRate::Velocity);
    assert_eq!(c.observer.model_inertia, ObserverInertia::Total);
    assert_eq!(c.observer.torque_input, ObserverTorque::MeasuredCurrent);
    assert!(parse("velocity_estimator = \"Observer\"").is_err());
}

#[test]
fn filters_are_tagged_by_kind() {
    let c = parse("velocity_filter = { kind = \"none\" }").unwrap();
    assert_eq!(c.velocity_filter, FilterConfig::None);
    let c = parse("velocity_filter = { kind = \"first_order\", corner_hz = 100.0 }").unwrap();
    assert_eq!(
        c.velocity_filter,
        FilterConfig::FirstOrder { corner_hz: 100.0 }
    );
    let c = parse("[accel_feedback.filter]\nkind = \"second_order\"\ncorner_hz = 40.0\nq = 0.5")
        .unwrap();
    assert_eq!(
        c.accel_feedback.filter,
        FilterConfig::SecondOrder {
            corner_hz: 40.0,
            q: 0.5
        }
    );
    let c = parse("velocity_filter = { corner_hz = 40, kind = \"second_order\" }").unwrap();
    assert_eq!(
        c.velocity_filter,
        FilterConfig::SecondOrder {
            corner_hz: 40.0,
            q: std::f32::consts::FRAC_1_SQRT_2
        }
    );
    let e = parse("velocity_filter = { kind = \"first_order\", corner_hz = 100.0, q = 0.7 }")
        .unwrap_err();
    assert!(e.contains("unknown field") && e.contains('q'), "{e}");
    let e = parse("velocity_filter = { kind = \"none\", corner_hz = 1.0 }").unwrap_err();
    assert!(e.contains("unknown field"), "{e}");
    let e = parse("velocity_filter = { kind = \"first_order\" }").unwrap_err();
    assert!(e.contains("corner_hz"), "{e}");
    assert!(parse("velocity_filter = { kind = \"third_order\", corner_hz = 1.0 }").is_err());
}

#[test]
fn whole_numbers_accept_integral_floats_only() {
    let c = toml::from_str::<DriveConfig>(&REQUIRED.replace("2048", "2048.0")).unwrap();
    assert_eq!(c.encoder_cpr, 2048);
    let c = parse("counter_bits = 24.0").unwrap();
    assert_eq!(c.counter_bits, 24);
    for (from, to) in [
        ("2048", "2048.5"),
        ("8000", "8000.25"),
        ("= 2000", "= 2000.5"),
    ] {
        let e = toml::from_str::<DriveConfig>(&REQUIRED.replacen(from, to, 1))
            .unwrap_err()
            .to_string();
        assert!(e.contains("must be a whole number"), "{to}: {e}");
    }
    let e = parse("counter_bits = 24.5").unwrap_err();
    assert!(e.contains("must be a whole number"), "{e}");
    assert!(parse("counter_bits = 300").is_err());
}

#[test]
fn unknown_keys_are_errors_at_every_level() {
    for extra in [
        "velocity_gain = 1.0",
        "[observer]\nbandwidth = 60",
        "[accel_feedback]\ngain = 0.5",
        "[faults]\noverspeed = 1.0",
    ] {
        let e = parse(extra).unwrap_err();
        assert!(e.contains("unknown field"), "{extra}: {e}");
    }
}

#[test]
fn the_table1_file_gives_a_valid_drive_with_its_own_winding() {
    let c = common::table1();
    assert!(controller_core::design(&c).is_ok());
    let l = common::table1_number("electrics", "winding_inductance_pu_s");
    assert_eq!(c.winding_inductance_pu_s, l as f32);
}

#[test]
fn the_range_table_names_each_setting_once_and_validate_uses_it() {
    for (i, r) in RANGES.iter().enumerate() {
        assert!(
            RANGES.iter().skip(i + 1).all(|o| o.key != r.key),
            "{} twice",
            r.key
        );
        assert!(r.min <= r.max, "{}", r.key);
    }
    // One entry per key: a value just outside the range is an error naming the key.
    let mut c = common::table1();
    c.accel_feedback.gain_fraction = 20.5;
    let e = c.validate().unwrap_err();
    assert_eq!(e.param(), "accel_feedback.gain_fraction");
    assert!(e.to_string().contains("[0, 20]"), "{e}");
}

#[test]
fn serialize_then_deserialize_is_the_same_drive() {
    let mut c = common::table1();
    c.velocity_filter = FilterConfig::SecondOrder {
        corner_hz: 40.0,
        q: 0.9,
    };
    let text = toml::to_string(&c).unwrap();
    assert_eq!(toml::from_str::<DriveConfig>(&text).unwrap(), c);
}

/// With `schema`: the JSON Schema names the required keys and the filter's tag.
#[cfg(feature = "schema")]
#[test]
#[allow(clippy::indexing_slicing)]
fn the_json_schema_names_required_keys_and_filter_kinds() {
    let schema = schemars::schema_for!(DriveConfig);
    let text = serde_json::to_string(&schema).unwrap();
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    let required: Vec<&str> = v["required"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|x| x.as_str())
        .collect();
    for key in [
        "base_speed_rpm",
        "current_rate_hz",
        "winding_inductance_pu_s",
    ] {
        assert!(required.contains(&key), "{required:?}");
    }
    assert!(!required.contains(&"counter_bits"));
    for word in [
        "first_order",
        "second_order",
        "total_plus_afb",
        "measured_current",
    ] {
        assert!(text.contains(word), "{word}");
    }
}
