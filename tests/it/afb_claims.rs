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
    let pts = hil_harness::experiments::stiffness::measure_all(&freqs).unwrap();
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

/// At the same gains, AFB lowers the shaft-torque ripple after a 50 % shock at rated speed
/// (the torque inside its limit) and after fig6's 50 % load step with a 65,536-count
/// interpolated encoder (the report's criterion for these comparisons). The stronger
/// targets (30 % and 40 % lower) are not met: see REPORT.md.
#[test]
fn afb_lowers_the_shaft_ripple_after_a_load_step_at_the_same_gains() {
    for (afb, off) in [
        ("shock-50", "shock-50-no-afb"),
        ("fig6-65k", "fig6-65k-no-afb"),
    ] {
        let (on, without) = (shaft_ripple(afb), shaft_ripple(off));
        assert!(
            on < without,
            "{afb}: with AFB {on} pu, without {without} pu"
        );
    }
}
