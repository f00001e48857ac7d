//! What acceleration feedback does for the product, measured in the closed loop at the
//! same regulator gains with and without it (the PI sized for J_total, the default AFB
//! Ka = 0.5·J_total). Each test states the figure it requires and fails below it.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use sim_engine::{resolve, run_scenario};

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
    let pts = machine_workflows::stiffness::measure_all(&freqs).unwrap();
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

/// The saturated dyno runs (Figs. 9–12), at the same gains with and without AFB: with the
/// velocity regulator's headroom and the AFB filter held at the limit (both set in
/// `configs/machines/dyno.toml`) the AFB run's shaft ripple is at most that without AFB in
/// the acceleration against 150 % load (the torque at its limit as long as without AFB) and
/// in the 150 % shock, whose peak shaft torque is at most that without AFB too. The
/// acceleration's peak shaft torque, reached while both runs sit at the limit, is within
/// 0.1 % of the run without AFB (REPORT.md gives the ratio; it is above 1 by 0.05 %). With
/// the plain clamp (`<name>-no-headroom`) the acceleration's ripple is higher than without
/// AFB and its torque leaves the limit, which is what the headroom is for.
#[test]
fn with_the_headroom_afb_does_not_add_ripple_at_the_torque_limit() {
    let run = |s: &str| {
        let cfg = resolve(s, None, &[]).expect("scenario resolves");
        let out = run_scenario(&cfg).expect("scenario runs");
        assert!(out.metrics.stable, "{s}: {:?}", out.metrics);
        out.metrics
    };
    let (on, off, plain) = (
        run("dyno-accel"),
        run("dyno-accel-no-afb"),
        run("dyno-accel-no-headroom"),
    );
    assert!(
        on.shaft_torque_ripple_rms_pu <= off.shaft_torque_ripple_rms_pu,
        "dyno-accel ripple {} against {} without AFB",
        on.shaft_torque_ripple_rms_pu,
        off.shaft_torque_ripple_rms_pu
    );
    let (p_on, p_off) = (
        on.peak_shaft_torque_pu.unwrap(),
        off.peak_shaft_torque_pu.unwrap(),
    );
    assert!(p_on <= p_off * (1.0 + 1e-3), "peak {p_on} against {p_off}");
    assert!(
        on.torque_saturated_s >= 0.99 * off.torque_saturated_s,
        "at the limit {} s with AFB, {} s without",
        on.torque_saturated_s,
        off.torque_saturated_s
    );
    assert!(
        plain.shaft_torque_ripple_rms_pu > 1.5 * off.shaft_torque_ripple_rms_pu
            && plain.torque_saturated_s < 0.8 * off.torque_saturated_s,
        "plain clamp: {plain:?}"
    );
    let (on, off) = (run("shock"), run("shock-no-afb"));
    assert!(
        on.peak_shaft_torque_pu <= off.peak_shaft_torque_pu
            && on.shaft_torque_ripple_rms_pu <= off.shaft_torque_ripple_rms_pu,
        "{on:?} {off:?}"
    );
}
