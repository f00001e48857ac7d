//! The accumulators of [`super::compute`]'s one pass: per-row sums and extremes, and the
//! windowed RMS of the high-passed signals, each summed in trace order.

use super::{in_window, MetricWindows};
use crate::engine::trace::TraceRow;

/// The signals that are high-passed: the speed error, the motor torque (measured current)
/// and the shaft torque.
pub(super) const HP_SIGNALS: usize = 3;

fn speed_err(r: &TraceRow) -> f64 {
    r.vel_cmd_pu - r.motor_vel_pu
}

pub(super) fn hp_inputs(r: &TraceRow) -> [f64; HP_SIGNALS] {
    [speed_err(r), r.current_pu, r.shaft_torque_pu]
}

/// Whether every value is finite: v − v is +0 for a finite v and NaN otherwise, so the
/// sums (two lanes, to go two at a time) are 0 exactly when all are finite.
#[allow(clippy::eq_op)] // v − v on purpose: NaN exactly for a value that is not finite.
fn all_finite(values: &[f64; 18]) -> bool {
    let mut lanes = [0.0; 2];
    for pair in values.chunks_exact(2) {
        for (lane, v) in lanes.iter_mut().zip(pair) {
            *lane += v - v;
        }
    }
    let [a, b] = lanes;
    a + b == 0.0
}

/// Adds a row's values to the running probe: a sum is finite only if every value in it is
/// (an infinity or NaN stays one; finite values may overflow it too, which only sends the
/// pass to the exact row-by-row test).
#[inline]
fn add_to_probe(probe: &mut [f64; 2], values: &[f64; 18]) {
    for pair in values.chunks_exact(2) {
        for (lane, v) in probe.iter_mut().zip(pair) {
            *lane += v;
        }
    }
}

/// RMS of a high-passed signal inside a window, accumulated in order.
#[derive(Clone, Copy, Debug)]
pub(super) struct Ripple {
    sum_sq: f64,
    n: usize,
}

impl Ripple {
    const EMPTY: Self = Self {
        // As `Iterator::sum` starts.
        sum_sq: -0.0,
        n: 0,
    };

    fn add(&mut self, v: f64) {
        self.sum_sq += v * v;
        self.n += 1;
    }

    pub(super) fn rms(&self) -> f64 {
        if self.n == 0 {
            0.0
        } else {
            (self.sum_sq / self.n as f64).sqrt()
        }
    }
}

/// A running mean, summed in order from −0.0 as `Iterator::sum` does.
#[derive(Clone, Copy, Debug)]
pub(super) struct Mean {
    sum: f64,
    n: usize,
}

impl Mean {
    const EMPTY: Self = Self { sum: -0.0, n: 0 };

    fn add(&mut self, v: f64) {
        self.sum += v;
        self.n += 1;
    }

    pub(super) fn get(&self) -> f64 {
        if self.n == 0 {
            0.0
        } else {
            self.sum / self.n as f64
        }
    }
}

/// Everything [`super::compute`] gathers in its one pass over the trace.
pub(super) struct Pass<'a> {
    pub(super) w: &'a MetricWindows,
    pub(super) sat_threshold: f64,
    /// Set by [`Self::find_first_bad`].
    pub(super) first_bad_t_s: Option<f64>,
    /// Running sums of every value of every row, two lanes ([`add_to_probe`]).
    finite_probe: [f64; 2],
    pub(super) faulted: bool,
    pub(super) stable_rows: usize,
    pub(super) bounded: bool,
    pub(super) saturated_in_window: usize,
    pub(super) saturated_rows: usize,
    pub(super) before_step_err: Option<f64>,
    pub(super) worst_after_step: f64,
    pub(super) overshoot: f64,
    pub(super) ripple_torque: Mean,
    pub(super) ripple_speed_err: Mean,
    pub(super) max_following: f64,
    pub(super) max_twist: f64,
    /// High-passed speed error and torque in the stability window.
    pub(super) stable_hp: [Ripple; 2],
    /// High-passed torque and shaft torque in the ripple window.
    pub(super) ripple_hp: [Ripple; 2],
}

impl<'a> Pass<'a> {
    pub(super) fn new(w: &'a MetricWindows) -> Self {
        Self {
            w,
            sat_threshold: w.torque_limit_pu * 0.999,
            first_bad_t_s: None,
            finite_probe: [0.0; 2],
            faulted: false,
            stable_rows: 0,
            bounded: true,
            saturated_in_window: 0,
            saturated_rows: 0,
            before_step_err: None,
            worst_after_step: f64::NEG_INFINITY,
            overshoot: 0.0,
            ripple_torque: Mean::EMPTY,
            ripple_speed_err: Mean::EMPTY,
            max_following: 0.0,
            max_twist: 0.0,
            stable_hp: [Ripple::EMPTY; 2],
            ripple_hp: [Ripple::EMPTY; 2],
        }
    }

    /// The metrics of one row that need no neighbours.
    pub(super) fn row(&mut self, r: &TraceRow) {
        let w = self.w;
        let err = speed_err(r);
        add_to_probe(&mut self.finite_probe, &r.values());
        self.faulted |= r.fault != 0.0;
        let saturated = r.torque_cmd_pu.abs() >= self.sat_threshold;
        self.saturated_rows += usize::from(saturated);
        if in_window(r, w.stable_window_s) {
            self.stable_rows += 1;
            self.bounded &= err.abs() < 0.5;
            self.saturated_in_window += usize::from(saturated);
        }
        if let Some(ts) = w.step_time_s {
            if r.t_s < ts {
                self.before_step_err = Some(err);
            } else {
                self.worst_after_step = self.worst_after_step.max(err);
            }
        }
        if let Some(win) = w.overshoot_window_s {
            if in_window(r, win) {
                self.overshoot = self.overshoot.max(r.load_vel_pu - r.vel_cmd_pu);
            }
        }
        if in_window(r, w.ripple_window_s) {
            self.ripple_torque.add(r.current_pu);
            self.ripple_speed_err.add(err);
        }
        self.max_following = self.max_following.max(r.cmd_minus_motor_counts().abs());
        self.max_twist = self.max_twist.max(r.motor_minus_load_counts().abs());
    }

    /// Sets `first_bad_t_s`, the time of the first row that holds a value that is not
    /// finite, once every row has been through [`Self::row`]: none when the probe's sums
    /// are finite, else the rows tested one by one.
    pub(super) fn find_first_bad(&mut self, rows: &[TraceRow]) {
        let [a, b] = self.finite_probe;
        if (a + b).is_finite() {
            return;
        }
        self.first_bad_t_s = rows
            .iter()
            .find(|r| !all_finite(&r.values()))
            .map(|r| r.t_s);
    }

    /// The high-passed signals of one row ([`HP_SIGNALS`] order), into the windows' ripple.
    pub(super) fn high_passed(&mut self, r: &TraceRow, [err, torque, shaft]: [f64; HP_SIGNALS]) {
        if in_window(r, self.w.stable_window_s) {
            let [e, t] = &mut self.stable_hp;
            e.add(err);
            t.add(torque);
        }
        if in_window(r, self.w.ripple_window_s) {
            let [t, s] = &mut self.ripple_hp;
            t.add(torque);
            s.add(shaft);
        }
    }
}
