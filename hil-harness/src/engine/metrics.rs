//! Metrics computed from a trace. Each definition here is repeated in the README; the
//! windows come from the scenario's `[scenario.metrics]` table.

mod pass;

use crate::engine::trace::{Trace, TraceRow};
use pass::{hp_inputs, Pass, HP_SIGNALS};
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

/// `x − centred moving average of x` over `half` samples each side (clipped at the ends):
/// keeps the ripple above about 1/(2·average length) and removes slow trends. [`compute`]
/// forms the same values as it goes; this is the definition, whole-signal form.
pub fn high_pass(x: &[f64], half: usize) -> Vec<f64> {
    let mut prefix = Vec::with_capacity(x.len() + 1);
    prefix.push(0.0);
    let mut acc = 0.0;
    for v in x {
        acc += v;
        prefix.push(acc);
    }
    (0..x.len())
        .map(|i| {
            let at = |k: usize| prefix.get(k).copied().unwrap_or(0.0);
            centred(at, i, half, x.len(), x.get(i).copied().unwrap_or(0.0))
        })
        .collect()
}

/// v − (mean of the samples i−half ..= i+half, clipped to 0..len), from prefix sums
/// (`at(k)` = the sum of the first k samples).
fn centred(at: impl Fn(usize) -> f64, i: usize, half: usize, len: usize, v: f64) -> f64 {
    let (lo, hi, n) = window(i, half, len);
    v - (at(hi) - at(lo)) / n
}

/// The moving average's window at sample i: lo..hi, and its length as a divisor (≥ 1).
fn window(i: usize, half: usize, len: usize) -> (usize, usize, f64) {
    let lo = i.saturating_sub(half);
    let hi = (i + half + 1).min(len);
    (lo, hi, (hi - lo).max(1) as f64)
}

/// Computes every metric of a trace in one pass. The high pass of row j needs the samples up
/// to j + half, so the ripple sums run `half` rows behind the rest, on one vector of prefix
/// sums; every sum is taken in trace order, so the figures are those of the whole-signal
/// definitions ([`high_pass`], then the RMS over the window) bit for bit.
pub fn compute(trace: &Trace, w: &MetricWindows) -> Metrics {
    let rows = &trace.rows;
    let len = rows.len();
    let dt = match (rows.first(), rows.get(1)) {
        (Some(a), Some(b)) => b.t_s - a.t_s,
        _ => 0.0,
    };
    let mut pass = Pass::new(w);
    // Without a positive sample period there is no moving average: every ripple is 0.
    let Some(half) =
        (dt > 0.0).then(|| ((w.ripple_average_s / dt) / 2.0).round().max(1.0) as usize)
    else {
        rows.iter().for_each(|r| pass.row(r));
        pass.find_first_bad(rows);
        return finish(&pass, rows);
    };
    let mut prefix: Vec<[f64; HP_SIGNALS]> = Vec::with_capacity(len + 1);
    let mut acc = [0.0; HP_SIGNALS];
    prefix.push(acc);
    for (i, r) in rows.iter().enumerate() {
        pass.row(r);
        for (a, v) in acc.iter_mut().zip(hp_inputs(r)) {
            *a += v;
        }
        prefix.push(acc);
        // Row j = i − half has its window now: rows (j − half)⁺ ..= i, the last just summed.
        let Some(j) = i.checked_sub(half) else {
            continue;
        };
        if let Some(rj) = rows.get(j) {
            let lo = j.saturating_sub(half);
            let below = prefix.get(lo).copied().unwrap_or_default();
            pass.high_passed(rj, centred_row(rj, below, acc, (i + 1 - lo) as f64));
        }
    }
    // The last `half` rows: their windows end at the end of the trace.
    for (j, rj) in rows.iter().enumerate().skip(len.saturating_sub(half)) {
        let (lo, _, n) = window(j, half, len);
        let below = prefix.get(lo).copied().unwrap_or_default();
        pass.high_passed(rj, centred_row(rj, below, acc, n));
    }
    pass.find_first_bad(rows);
    finish(&pass, rows)
}

/// [`centred`] for the high-passed signals of row `r`, from the prefix sums below and at
/// the top of its window, `n` samples long.
#[inline]
fn centred_row(
    r: &TraceRow,
    below: [f64; HP_SIGNALS],
    upto: [f64; HP_SIGNALS],
    n: f64,
) -> [f64; HP_SIGNALS] {
    let x = hp_inputs(r);
    core::array::from_fn(|s| {
        let at = |p: &[f64; HP_SIGNALS]| p.get(s).copied().unwrap_or(0.0);
        at(&x) - (at(&upto) - at(&below)) / n
    })
}

/// The metrics of a trace that holds non-finite values from `bad_t_s`. Max/min folds skip
/// NaN, so these figures would read as plain numbers (0.0000): none of them means anything
/// for this run.
fn invalid(
    faulted: bool,
    bad_t_s: f64,
    load_step_droop_pu: Option<f64>,
    overshoot_pu: Option<f64>,
) -> Metrics {
    let nan = f64::NAN;
    let some_nan = |o: Option<f64>| o.map(|_| nan);
    Metrics {
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
            "the trace holds non-finite values from t = {bad_t_s} s; no metric of this run is a number"
        )),
    }
}

/// The metrics from the pass's sums.
fn finish(p: &Pass, rows: &[TraceRow]) -> Metrics {
    let w = p.w;
    let dt = match (rows.first(), rows.get(1)) {
        (Some(a), Some(b)) => b.t_s - a.t_s,
        _ => 0.0,
    };
    // Oscillation: the speed error with its slow part (centred moving average over
    // `ripple_average_s`) removed, so a slow recovery from a step is not counted as a
    // limit cycle; growth beyond bounds is caught by `bounded`.
    let [osc, cycle] = p.stable_hp;
    let oscillation_pu = osc.rms();
    let sat_fraction = if p.stable_rows == 0 {
        1.0
    } else {
        p.saturated_in_window as f64 / p.stable_rows as f64
    };
    let stable = p.first_bad_t_s.is_none()
        && !p.faulted
        && p.stable_rows > 0
        && p.bounded
        && oscillation_pu.is_finite()
        && oscillation_pu < w.stable_oscillation_pu
        && sat_fraction <= w.stable_saturation_fraction;
    let [torque, shaft] = p.ripple_hp;
    let load_step_droop_pu = w
        .step_time_s
        .map(|_| (p.worst_after_step - p.before_step_err.unwrap_or(0.0)).max(0.0));
    let overshoot_pu = w.overshoot_window_s.map(|_| p.overshoot);
    let settling_s = w.step_time_s.or(w.ramp_end_s).and_then(|t0| {
        match p.last_out_of_band_t_s {
            None => Some(0.0),
            Some(t) => {
                // Never settled if it is still outside the band at the end of the run.
                let end = rows.last().map_or(t, |r| r.t_s);
                (t < end).then_some(t - t0)
            }
        }
    });
    if let Some(bad_t_s) = p.first_bad_t_s {
        return invalid(p.faulted, bad_t_s, load_step_droop_pu, overshoot_pu);
    }
    Metrics {
        stable,
        faulted: p.faulted,
        oscillation_pu,
        limit_cycle_torque_pu: cycle.rms(),
        torque_ripple_rms_pu: torque.rms(),
        shaft_torque_ripple_rms_pu: shaft.rms(),
        shaft_ripple_freq_hz: shaft.freq_hz(w.ripple_window_s.1 - w.ripple_window_s.0),
        load_step_droop_pu,
        overshoot_pu,
        settling_s,
        torque_saturated_s: p.saturated_rows as f64 * dt,
        mean_torque_pu: p.ripple_torque.get(),
        mean_speed_error_pu: p.ripple_speed_err.get(),
        max_following_error_counts: p.max_following,
        max_twist_counts: p.max_twist,
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
            let hp = |f: fn(&TraceRow) -> f64| {
                high_pass(&t.rows.iter().map(f).collect::<Vec<_>>(), half)
            };
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
}
