//! What acceleration feedback does for the product, measured in the closed loop at the
//! same regulator gains with and without it (the PI sized for J_total, the default AFB
//! Ka = 0.5·J_total). Each test states the figure it requires and fails below it.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use hil_harness::{resolve, run_scenario};

fn shaft_ripple(scenario: &str) -> f64 {
    let cfg = resolve(scenario, None, &[]).expect("scenario resolves");
    let out = run_scenario(&cfg).expect("scenario runs");
    assert!(out.metrics.stable, "{scenario}: {:?}", out.metrics);
    out.metrics.shaft_torque_ripple_rms_pu
}

/// Fig. 2's shape: AFB adds stiffness above the velocity bandwidth (at least 1.4x at 20,
/// 40 and 100 rad/s, bandwidth 11 rad/s) and leaves it alone below a third of it
/// (0.9-1.1x at 0.3, 1 and 2 rad/s).
#[test]
fn afb_stiffens_above_the_velocity_bandwidth_and_not_below() {
    let low = [0.3, 1.0, 2.0];
    let high = [20.0, 40.0, 100.0];
    let freqs: Vec<f64> = low.iter().chain(high.iter()).copied().collect();
    let pts = hil_harness::stiffness::measure_all(&freqs).unwrap();
    let ratio = |w: f64| {
        let get = |source: &str| {
            pts.iter()
                .find(|p| p.source == source && p.freq_rad_s == w)
                .unwrap()
        };
        let (on, off) = (get("observer"), get("none"));
        assert!(on.stable && off.stable, "{on:?} {off:?}");
        on.measured / off.measured
    };
    for w in high {
        let r = ratio(w);
        assert!(r >= 1.4, "{w} rad/s: stiffness ratio {r}");
    }
    for w in low {
        let r = ratio(w);
        assert!((0.9..=1.1).contains(&r), "{w} rad/s: stiffness ratio {r}");
    }
}

/// A 50 % shock at rated speed (100 rad/s, the torque inside its limit): AFB cuts the
/// shaft-torque ripple by at least 30 %.
#[test]
fn afb_cuts_the_shaft_ripple_after_a_50_percent_shock_by_30_percent() {
    let (on, off) = (shaft_ripple("shock-50"), shaft_ripple("shock-50-no-afb"));
    assert!(on <= 0.7 * off, "with AFB {on} pu, without {off} pu");
}

/// Table 1 with a 65,536-count interpolated encoder: AFB cuts the shaft-torque ripple
/// after the 50 % load step by at least 40 %.
#[test]
fn with_an_interpolated_encoder_afb_cuts_the_fig6_ripple_by_40_percent() {
    let (on, off) = (shaft_ripple("fig6-65k"), shaft_ripple("fig6-65k-no-afb"));
    assert!(on <= 0.6 * off, "with AFB {on} pu, without {off} pu");
}
