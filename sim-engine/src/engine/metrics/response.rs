//! The load-step response a drive engineer reads, from the rows between the load step
//! (or the ramp's end) and the next load change (or the end of the run):
//!
//! - the **deviation** d(t) = e(t) − e(t₀⁻), e = command − motor speed (pu), e(t₀⁻) the
//!   error just before the step t₀: the mean over the last 2·n rows before it, n =
//!   round(1/(2·f_bw·dt)) (one velocity-bandwidth period, so a chatter sample does not
//!   offset every deviation); the last row's error when the machine is unknown;
//! - `peak_droop_pu` = max |d| over the rows from t₀ on, `peak_droop_time_s` = the time of
//!   that row less t₀;
//! - `recovery_s` = the time of the last row with |d̄| ≥ [`RECOVERY_FRACTION`] of the peak,
//!   less t₀ (from then on the deviation stays under it); `None` if that row is the last.
//!   d̄ is d through a centred moving average one velocity-bandwidth period (1/f_bw) long,
//!   so that quantization chatter far above the loop's bandwidth does not hold the
//!   recovery open (d̄ = d when the machine is unknown);
//! - `settling_s` = the same with the band [`SETTLE_FRACTION`] of the peak (or the
//!   scenario's `settle_band_pu`, if larger);
//! - `peak_shaft_torque_pu` = max |shaft torque| over the rows from t₀ on.
//! - the shaft's **ring** after the step: the shaft torque band-passed to the machine's
//!   resonance band (high-passed by the ripple average when the machine is unknown), its
//!   successive
//!   maxima above [`RING_FLOOR`] of the first; `ring_freq_hz` = (their number − 1) over
//!   the time from the first to the last, `ring_damping` = δ/√(4π² + δ²) with δ the mean
//!   log decrement between them (ζ of a second-order ring).

use super::MetricWindows;
use crate::engine::trace::TraceRow;
use std::f64::consts::PI;

/// Share of the peak deviation under which the speed has recovered.
pub const RECOVERY_FRACTION: f64 = 0.1;
/// Share of the peak deviation that is the settling band.
pub const SETTLE_FRACTION: f64 = 0.05;
/// Smallest maximum of a ring still counted, as a share of its first maximum.
pub const RING_FLOOR: f64 = 0.1;

/// The step-response figures (module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct StepResponse {
    pub peak_droop_pu: f64,
    pub peak_droop_time_s: f64,
    pub recovery_s: Option<f64>,
    pub settling_s: Option<f64>,
    pub peak_shaft_torque_pu: f64,
}

/// The rows from `t0` to the next load change after it (or the end), and the error just
/// before `t0`.
pub(super) fn after(rows: &[TraceRow], t0: f64, until: Option<f64>) -> (&[TraceRow], f64) {
    after_averaged(rows, t0, until, 0)
}

/// [`after`], the error before `t0` averaged over the last `2·n` rows (at least one).
fn after_averaged(rows: &[TraceRow], t0: f64, until: Option<f64>, n: usize) -> (&[TraceRow], f64) {
    let start = rows.partition_point(|r| r.t_s < t0);
    let end = until.map_or(rows.len(), |u| rows.partition_point(|r| r.t_s < u));
    let pre = rows
        .get(start.saturating_sub((2 * n).max(1))..start)
        .unwrap_or_default();
    let before = pre
        .iter()
        .map(|r| r.vel_cmd_pu - r.motor_vel_pu)
        .sum::<f64>()
        / pre.len().max(1) as f64;
    (rows.get(start..end.max(start)).unwrap_or_default(), before)
}

/// n = round(1/(2·f_bw·dt)), half the rows of one velocity-bandwidth period (0 when the
/// machine or the sample period is unknown).
pub fn smoothing_rows(w: &MetricWindows, dt: f64) -> usize {
    w.machine.map_or(0, |m| {
        if dt > 0.0 && m.velocity_bandwidth_hz > 0.0 {
            (0.5 / (m.velocity_bandwidth_hz * dt)).round() as usize
        } else {
            0
        }
    })
}

/// The time from `t0` of the last row whose |deviation| is at least `band`; `None` when it
/// is the last row (never stays inside).
fn last_outside(rows: &[TraceRow], dev: &[f64], t0: f64, band: f64) -> Option<f64> {
    match dev.iter().rposition(|d| d.abs() >= band) {
        None => Some(0.0),
        Some(i) if i + 1 == dev.len() => None,
        Some(i) => rows.get(i).map(|r| r.t_s - t0),
    }
}

/// The step response from `t0` (module docs).
pub(super) fn step_response(rows: &[TraceRow], t0: f64, w: &MetricWindows) -> StepResponse {
    let dt = match rows {
        [a, b, ..] => b.t_s - a.t_s,
        _ => 0.0,
    };
    let smooth_n = smoothing_rows(w, dt);
    let (post, before) = after_averaged(rows, t0, w.step_end_s, smooth_n);
    let dev: Vec<f64> = post
        .iter()
        .map(|r| r.vel_cmd_pu - r.motor_vel_pu - before)
        .collect();
    let smooth: Vec<f64> = if smooth_n == 0 {
        dev.clone()
    } else {
        dev.iter()
            .zip(super::high_pass(&dev, smooth_n))
            .map(|(d, hp)| d - hp)
            .collect()
    };
    let (i_peak, peak) = dev
        .iter()
        .enumerate()
        .fold((0, 0.0_f64), |(bi, b), (i, d)| {
            if d.abs() > b {
                (i, d.abs())
            } else {
                (bi, b)
            }
        });
    StepResponse {
        peak_droop_pu: peak,
        peak_droop_time_s: post.get(i_peak).map_or(0.0, |r| r.t_s - t0),
        recovery_s: last_outside(post, &smooth, t0, RECOVERY_FRACTION * peak),
        settling_s: last_outside(
            post,
            &smooth,
            t0,
            (SETTLE_FRACTION * peak).max(w.settle_band_pu),
        ),
        peak_shaft_torque_pu: post.iter().fold(0.0, |m, r| m.max(r.shaft_torque_pu.abs())),
    }
}

/// Frequency (Hz) and damping ratio of a decaying ring sampled every `dt_s` (module docs);
/// `None` with fewer than three maxima.
pub(super) fn ring(x: &[f64], dt_s: f64) -> Option<(f64, f64)> {
    let maxima: Vec<(usize, f64)> = x
        .windows(3)
        .enumerate()
        .filter_map(|(i, w)| match *w {
            [a, b, c] if b > a && b >= c && b > 0.0 => Some((i + 1, b)),
            _ => None,
        })
        .collect();
    let first = maxima.iter().map(|m| m.1).fold(0.0, f64::max);
    let start = maxima.iter().position(|m| m.1 == first)?;
    let kept: Vec<(usize, f64)> = maxima
        .iter()
        .skip(start)
        .take_while(|m| m.1 >= RING_FLOOR * first)
        .copied()
        .collect();
    let (&(i0, p0), &(i1, p1)) = (kept.first()?, kept.last()?);
    let cycles = kept.len().checked_sub(1).filter(|n| *n >= 2)? as f64;
    // A maximum's time refined by a parabola through it and its neighbours.
    let at = |i: usize| {
        let (a, b, c) = (x.get(i - 1), x.get(i), x.get(i + 1));
        let shift = match (a, b, c) {
            (Some(a), Some(b), Some(c)) if a - 2.0 * b + c < 0.0 => {
                0.5 * (a - c) / (a - 2.0 * b + c)
            }
            _ => 0.0,
        };
        (i as f64 + shift) * dt_s
    };
    let freq_hz = cycles / (at(i1) - at(i0));
    let delta = (p0 / p1).ln() / cycles;
    Some((freq_hz, delta / (4.0 * PI * PI + delta * delta).sqrt()))
}
