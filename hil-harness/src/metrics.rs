//! Metrics computed from a trace. Each definition here is repeated in the README; the
//! windows come from the scenario's `[scenario.metrics]` table.

use crate::trace::{Trace, TraceRow};
use serde::Serialize;

/// Time windows and thresholds of the metrics (all times in s of simulated time).
#[derive(Clone, Debug, PartialEq)]
pub struct MetricWindows {
    /// Time of the load step the droop and settling refer to, if any.
    pub step_time_s: Option<f64>,
    /// Time the velocity ramp ends (overshoot is measured from here), if any.
    pub ramp_end_s: Option<f64>,
    /// Window over which torque ripple is measured.
    pub ripple_window_s: (f64, f64),
    /// Window over which overshoot is measured.
    pub overshoot_window_s: Option<(f64, f64)>,
    /// Window over which stability is judged (normally the last 0.5 s).
    pub stable_window_s: (f64, f64),
    /// Length of the centred moving average removed before taking the ripple (s).
    pub ripple_average_s: f64,
    /// Settling band on the motor speed error (pu).
    pub settle_band_pu: f64,
    /// Stability threshold on the standard deviation of the speed error (pu).
    pub stable_oscillation_pu: f64,
    /// Largest fraction of the stability window the torque may spend saturated.
    pub stable_saturation_fraction: f64,
    /// Torque limit of the drive (pu), to count saturation.
    pub torque_limit_pu: f64,
}

/// The metrics written to `summary.json`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Metrics {
    /// Stable by the criterion of [`MetricWindows`]: no fault, all signals finite, speed
    /// error bounded by 0.5 pu, its oscillation (`oscillation_pu`) below the threshold and
    /// the torque not stuck at its limit in the stability window.
    pub stable: bool,
    /// The controller reported a fault at some point of the run.
    pub faulted: bool,
    /// RMS of the motor speed error minus its centred moving average (the ripple
    /// high-pass), in the stability window (pu): the limit-cycle amplitude.
    pub oscillation_pu: f64,
    /// RMS of the motor torque (measured current) minus its centred moving average in the
    /// stability window (pu): torque chatter / limit cycle that the speed may not show.
    pub limit_cycle_torque_pu: f64,
    /// RMS of the motor torque (the measured current, k_t = 1) minus its centred moving
    /// average, in the ripple window (pu).
    pub torque_ripple_rms_pu: f64,
    /// The same for the shaft (transducer) torque (pu).
    pub shaft_torque_ripple_rms_pu: f64,
    /// Dominant ripple frequency of the shaft torque, from zero crossings (Hz).
    pub shaft_ripple_freq_hz: f64,
    /// Largest drop of motor speed below command after the load step, less the error
    /// just before it (pu). `None` without a step.
    pub load_step_droop_pu: Option<f64>,
    /// Largest excess of load speed over the command in the overshoot window (pu).
    pub overshoot_pu: Option<f64>,
    /// Time from the step (or ramp end) until the motor speed error stays inside the band
    /// for the rest of the run (s); `None` if it never settles.
    pub settling_s: Option<f64>,
    /// Time the torque command spends at its limit (s).
    pub torque_saturated_s: f64,
    /// Mean motor torque (measured current) in the ripple window (pu).
    pub mean_torque_pu: f64,
    /// Mean motor speed error (command − motor) in the ripple window (pu).
    pub mean_speed_error_pu: f64,
    /// Largest |command − motor position| (counts).
    pub max_following_error_counts: f64,
    /// Largest |motor − load position| (counts).
    pub max_twist_counts: f64,
    /// Why the value metrics above are not finite (`null` in JSON), when they are not: the
    /// trace holds non-finite values from the time named. `None` for a valid run.
    pub invalid_reason: Option<String>,
}

fn in_window(r: &TraceRow, w: (f64, f64)) -> bool {
    r.t_s >= w.0 && r.t_s <= w.1
}

fn mean(values: &[f64]) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    values.iter().sum::<f64>() / values.len() as f64
}

fn rms(values: &[f64]) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    (values.iter().map(|v| v * v).sum::<f64>() / values.len() as f64).sqrt()
}

/// `x − centred moving average of x` over `half` samples each side (clipped at the ends):
/// keeps the ripple above about 1/(2·average length) and removes slow trends.
pub fn high_pass(x: &[f64], half: usize) -> Vec<f64> {
    let mut prefix = Vec::with_capacity(x.len() + 1);
    prefix.push(0.0);
    let mut acc = 0.0;
    for v in x {
        acc += v;
        prefix.push(acc);
    }
    x.iter()
        .enumerate()
        .map(|(i, v)| {
            let lo = i.saturating_sub(half);
            let hi = (i + half + 1).min(x.len());
            let sum =
                prefix.get(hi).copied().unwrap_or(0.0) - prefix.get(lo).copied().unwrap_or(0.0);
            let n = (hi - lo).max(1) as f64;
            v - sum / n
        })
        .collect()
}

/// Ripple (RMS of the high-passed signal) of `f` in `window`, and its dominant
/// frequency from zero crossings.
fn ripple(
    trace: &Trace,
    f: impl Fn(&TraceRow) -> f64,
    window: (f64, f64),
    avg_s: f64,
) -> (f64, f64) {
    let rows = &trace.rows;
    let dt = match (rows.first(), rows.get(1)) {
        (Some(a), Some(b)) if b.t_s > a.t_s => b.t_s - a.t_s,
        _ => return (0.0, 0.0),
    };
    let half = ((avg_s / dt) / 2.0).round().max(1.0) as usize;
    let x: Vec<f64> = rows.iter().map(&f).collect();
    let hp = high_pass(&x, half);
    let sel: Vec<f64> = rows
        .iter()
        .zip(hp.iter())
        .filter(|(r, _)| in_window(r, window))
        .map(|(_, v)| *v)
        .collect();
    let crossings = sel
        .windows(2)
        .filter(|w| matches!(w, [a, b] if (*a < 0.0) != (*b < 0.0)))
        .count();
    let span = window.1 - window.0;
    let freq = if span > 0.0 {
        crossings as f64 / (2.0 * span)
    } else {
        0.0
    };
    (rms(&sel), freq)
}

/// Computes every metric of a trace.
pub fn compute(trace: &Trace, w: &MetricWindows) -> Metrics {
    let rows = &trace.rows;
    let speed_err = |r: &TraceRow| r.vel_cmd_pu - r.motor_vel_pu;
    let finite = rows
        .iter()
        .all(|r| r.values().iter().all(|v| v.is_finite()));

    let stable_rows: Vec<&TraceRow> = rows
        .iter()
        .filter(|r| in_window(r, w.stable_window_s))
        .collect();
    let stable_err: Vec<f64> = stable_rows.iter().map(|r| speed_err(r)).collect();
    // Oscillation: the speed error with its slow part (centred moving average over
    // `ripple_average_s`) removed, so a slow recovery from a step is not counted as a
    // limit cycle; growth beyond bounds is caught by `bounded`.
    let (oscillation_pu, _) = ripple(trace, speed_err, w.stable_window_s, w.ripple_average_s);
    let (limit_cycle_torque_pu, _) = ripple(
        trace,
        |r| r.current_pu,
        w.stable_window_s,
        w.ripple_average_s,
    );
    let bounded = stable_err.iter().all(|e| e.abs() < 0.5);
    let sat_threshold = w.torque_limit_pu * 0.999;
    let saturated_in_window = stable_rows
        .iter()
        .filter(|r| r.torque_cmd_pu.abs() >= sat_threshold)
        .count();
    let sat_fraction = if stable_rows.is_empty() {
        1.0
    } else {
        saturated_in_window as f64 / stable_rows.len() as f64
    };
    let faulted = rows.iter().any(|r| r.fault != 0.0);
    let stable = finite
        && !faulted
        && !stable_rows.is_empty()
        && bounded
        && oscillation_pu.is_finite()
        && oscillation_pu < w.stable_oscillation_pu
        && sat_fraction <= w.stable_saturation_fraction;

    let (torque_ripple_rms_pu, _) = ripple(
        trace,
        |r| r.current_pu,
        w.ripple_window_s,
        w.ripple_average_s,
    );
    let (shaft_torque_ripple_rms_pu, shaft_ripple_freq_hz) = ripple(
        trace,
        |r| r.shaft_torque_pu,
        w.ripple_window_s,
        w.ripple_average_s,
    );

    let load_step_droop_pu = w.step_time_s.map(|ts| {
        let before = rows
            .iter()
            .rev()
            .find(|r| r.t_s < ts)
            .map(speed_err)
            .unwrap_or(0.0);
        let worst = rows
            .iter()
            .filter(|r| r.t_s >= ts)
            .map(speed_err)
            .fold(f64::NEG_INFINITY, f64::max);
        (worst - before).max(0.0)
    });

    let overshoot_pu = w.overshoot_window_s.map(|win| {
        rows.iter()
            .filter(|r| in_window(r, win))
            .map(|r| r.load_vel_pu - r.vel_cmd_pu)
            .fold(0.0, f64::max)
    });

    let settle_from = w.step_time_s.or(w.ramp_end_s);
    let settling_s = settle_from.and_then(|t0| {
        let last_out = rows
            .iter()
            .rev()
            .find(|r| r.t_s >= t0 && speed_err(r).abs() > w.settle_band_pu)
            .map(|r| r.t_s);
        match last_out {
            None => Some(0.0),
            Some(t) => {
                // Never settled if it is still outside the band at the end of the run.
                let end = rows.last().map(|r| r.t_s).unwrap_or(t);
                if t >= end {
                    None
                } else {
                    Some(t - t0)
                }
            }
        }
    });

    let dt = match (rows.first(), rows.get(1)) {
        (Some(a), Some(b)) => b.t_s - a.t_s,
        _ => 0.0,
    };
    let torque_saturated_s = rows
        .iter()
        .filter(|r| r.torque_cmd_pu.abs() >= sat_threshold)
        .count() as f64
        * dt;

    let ripple_rows: Vec<&TraceRow> = rows
        .iter()
        .filter(|r| in_window(r, w.ripple_window_s))
        .collect();
    let mean_torque_pu = mean(&ripple_rows.iter().map(|r| r.current_pu).collect::<Vec<_>>());
    let mean_speed_error_pu = mean(&ripple_rows.iter().map(|r| speed_err(r)).collect::<Vec<_>>());

    let max_following_error_counts = rows
        .iter()
        .map(|r| r.cmd_minus_motor_counts().abs())
        .fold(0.0, f64::max);
    let max_twist_counts = rows
        .iter()
        .map(|r| r.motor_minus_load_counts().abs())
        .fold(0.0, f64::max);

    if let Some(bad) = rows
        .iter()
        .find(|r| !r.values().iter().all(|v| v.is_finite()))
    {
        // Max/min folds skip NaN, so these figures would read as plain numbers (0.0000):
        // none of them means anything for this run.
        let nan = f64::NAN;
        let some_nan = |o: Option<f64>| o.map(|_| nan);
        return Metrics {
            stable: false,
            faulted,
            oscillation_pu: nan,
            limit_cycle_torque_pu: nan,
            torque_ripple_rms_pu: nan,
            shaft_torque_ripple_rms_pu: nan,
            shaft_ripple_freq_hz: nan,
            load_step_droop_pu: some_nan(load_step_droop_pu),
            overshoot_pu: some_nan(overshoot_pu),
            settling_s: None,
            torque_saturated_s: nan,
            mean_torque_pu: nan,
            mean_speed_error_pu: nan,
            max_following_error_counts: nan,
            max_twist_counts: nan,
            invalid_reason: Some(format!(
                "the trace holds non-finite values from t = {} s; no metric of this run is a number",
                bad.t_s
            )),
        };
    }
    Metrics {
        stable,
        faulted,
        oscillation_pu,
        limit_cycle_torque_pu,
        torque_ripple_rms_pu,
        shaft_torque_ripple_rms_pu,
        shaft_ripple_freq_hz,
        load_step_droop_pu,
        overshoot_pu,
        settling_s,
        torque_saturated_s,
        mean_torque_pu,
        mean_speed_error_pu,
        max_following_error_counts,
        max_twist_counts,
        invalid_reason: None,
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;

    fn windows() -> MetricWindows {
        MetricWindows {
            step_time_s: Some(1.0),
            ramp_end_s: None,
            ripple_window_s: (1.2, 2.0),
            overshoot_window_s: None,
            stable_window_s: (1.5, 2.0),
            ripple_average_s: 0.1,
            settle_band_pu: 0.02,
            stable_oscillation_pu: 0.02,
            stable_saturation_fraction: 0.2,
            torque_limit_pu: 2.0,
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
        assert!(m.stable);
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

    #[test]
    fn high_pass_removes_a_constant() {
        let hp = high_pass(&[3.0; 50], 5);
        assert!(hp.iter().all(|v| v.abs() < 1e-12));
    }
}
