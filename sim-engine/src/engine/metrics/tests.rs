#![allow(clippy::unwrap_used, clippy::indexing_slicing)]
use super::*;

fn windows() -> MetricWindows {
    MetricWindows {
        step_time_s: Some(1.0),
        step_end_s: None,
        ramp_end_s: None,
        ripple_window_s: (1.2, 2.0),
        overshoot_window_s: None,
        stable_window_s: (1.5, 2.0),
        ripple_average_s: 0.1,
        settle_band_pu: 0.02,
        stable_oscillation_pu: 0.02,
        stable_saturation_fraction: 0.2,
        torque_limit_pu: 2.0,
        machine: None,
        excitation_hz: None,
    }
}

fn trace(f: impl Fn(f64) -> TraceRow) -> Trace {
    Trace {
        rows: (0..4000).map(|i| f(i as f64 * 0.0005)).collect(),
    }
}

#[test]
fn a_trace_with_non_finite_values_gives_null_metrics_with_a_reason() {
    let t = trace(|t| TraceRow {
        t_s: t,
        vel_cmd_pu: 1.0,
        motor_vel_pu: if t > 1.4 { f64::NAN } else { 1.0 },
        ..Default::default()
    });
    let m = compute(&t, &windows());
    assert!(!m.stable);
    assert!(m.torque_ripple_rms_pu.is_nan() && m.load_step_droop_pu.unwrap().is_nan());
    let reason = m.invalid_reason.clone().unwrap();
    assert!(
        reason.contains("non-finite") && reason.contains("1.4"),
        "{reason}"
    );
    let json = serde_json::to_value(&m).unwrap();
    assert!(json["torque_ripple_rms_pu"].is_null() && json["load_step_droop_pu"].is_null());
    // A finite run has no reason.
    let ok = compute(
        &trace(|t| TraceRow {
            t_s: t,
            ..Default::default()
        }),
        &windows(),
    );
    assert_eq!(ok.invalid_reason, None);
}

#[test]
fn sine_ripple_has_rms_amplitude_over_root_two_and_its_frequency() {
    let t = trace(|t| TraceRow {
        t_s: t,
        current_pu: 0.5 + 0.1 * (2.0 * std::f64::consts::PI * 25.0 * t).sin(),
        shaft_torque_pu: 0.1 * (2.0 * std::f64::consts::PI * 25.0 * t).sin(),
        ..Default::default()
    });
    let m = compute(&t, &windows());
    assert!(
        (m.torque_ripple_rms_pu - 0.1 / 2f64.sqrt()).abs() < 0.01,
        "{m:?}"
    );
    assert!((m.shaft_ripple_freq_hz - 25.0).abs() < 1.0, "{m:?}");
    assert!((m.mean_torque_pu - 0.5).abs() < 1e-3);
    // ±0.1 pu at 25 Hz, narrowband, on a machine with no count-rate tone: a limit cycle.
    assert_eq!(m.oscillation.kind, OscillationKind::LimitCycle, "{m:?}");
    assert!(
        (m.oscillation.freq_hz - 25.0).abs() < 0.5 && !m.stable,
        "{m:?}"
    );
}

#[test]
fn growing_speed_oscillation_is_unstable_and_droop_is_measured() {
    let t = trace(|t| TraceRow {
        t_s: t,
        vel_cmd_pu: 1.0,
        motor_vel_pu: 1.0
            - if t > 1.0 {
                0.2 * (t - 1.0) * (200.0 * t).sin()
            } else {
                0.0
            },
        ..Default::default()
    });
    let m = compute(&t, &windows());
    assert!(!m.stable);
    assert!(m.load_step_droop_pu.unwrap() > 0.02);
    assert!(m.settling_s.is_none());
}

/// The one-pass ripple figures are those of the definition (the whole-signal
/// [`high_pass`], then the RMS over the window, summed in order) bit for bit, for a
/// window near each end of the trace and one in the middle.
#[test]
fn the_one_pass_ripple_is_the_whole_signal_definition_bit_for_bit() {
    let t = trace(|t| TraceRow {
        t_s: t,
        vel_cmd_pu: 1.0,
        motor_vel_pu: 1.0 + 0.01 * (377.0 * t).sin() + 0.003 * (t * 1e4).cos(),
        current_pu: 0.5 + 0.1 * (2.0 * std::f64::consts::PI * 25.0 * t).sin() + t * t,
        shaft_torque_pu: 0.1 * (150.0 * t).sin() - 0.02 * t,
        ..Default::default()
    });
    for (ripple, stable) in [((0.0, 0.3), (1.8, 2.0)), ((0.7, 1.3), (0.0, 0.05))] {
        let w = MetricWindows {
            ripple_window_s: ripple,
            stable_window_s: stable,
            ..windows()
        };
        let m = compute(&t, &w);
        let half = ((w.ripple_average_s / 0.0005) / 2.0).round().max(1.0) as usize;
        let hp =
            |f: fn(&TraceRow) -> f64| high_pass(&t.rows.iter().map(f).collect::<Vec<_>>(), half);
        let rms = |x: &[f64], win: (f64, f64)| {
            let v: Vec<f64> = t
                .rows
                .iter()
                .zip(x)
                .filter(|(r, _)| in_window(r, win))
                .map(|(_, v)| *v)
                .collect();
            (v.iter().map(|v| v * v).sum::<f64>() / v.len() as f64).sqrt()
        };
        let err = hp(|r| r.vel_cmd_pu - r.motor_vel_pu);
        let (torque, shaft) = (hp(|r| r.current_pu), hp(|r| r.shaft_torque_pu));
        let got = [
            m.oscillation_pu,
            m.limit_cycle_torque_pu,
            m.torque_ripple_rms_pu,
            m.shaft_torque_ripple_rms_pu,
        ];
        let want = [
            rms(&err, stable),
            rms(&torque, stable),
            rms(&torque, ripple),
            rms(&shaft, ripple),
        ];
        assert_eq!(
            got.map(f64::to_bits),
            want.map(f64::to_bits),
            "{got:?} {want:?}"
        );
    }
}

/// Finite values whose sum overflows are still a valid run; an infinity is not.
#[test]
fn huge_finite_values_are_valid_and_an_infinity_is_not() {
    let huge = trace(|t| TraceRow {
        t_s: t,
        load_torque_pu: 1e308,
        ..Default::default()
    });
    assert_eq!(compute(&huge, &windows()).invalid_reason, None);
    let inf = trace(|t| TraceRow {
        t_s: t,
        accel_est_pu_s: if t >= 0.75 { f64::INFINITY } else { 1e308 },
        ..Default::default()
    });
    let reason = compute(&inf, &windows()).invalid_reason.unwrap();
    assert!(reason.contains("t = 0.75 s"), "{reason}");
}

#[test]
fn high_pass_removes_a_constant() {
    let hp = high_pass(&[3.0; 50], 5);
    assert!(hp.iter().all(|v| v.abs() < 1e-12));
}
