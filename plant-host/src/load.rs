//! Load torque inputs (pu, acting on the load inertia): steps, shocks, sinusoids, arbitrary
//! time series, and sums of them.

use crate::error::PlantError;

/// A load torque as a function of time, pu.
///
/// ```
/// use plant_host::LoadTorque;
/// // The paper's Fig. 6: a 50 % step at 1.5 s, plus a small 30 Hz ripple.
/// let tl = LoadTorque::Sum(vec![
///     LoadTorque::Step { at_s: 1.5, torque_pu: 0.5 },
///     LoadTorque::Sine { amplitude_pu: 0.01, freq_hz: 30.0, phase_rad: 0.0 },
/// ]);
/// assert_eq!(LoadTorque::Step { at_s: 1.5, torque_pu: 0.5 }.at(1.49), 0.0);
/// assert!((tl.at(1.5) - 0.5).abs() < 1e-12);
/// assert_eq!(tl.next_change_after(0.0), Some(1.5));
/// ```
#[derive(Debug, Clone, PartialEq)]
pub enum LoadTorque {
    /// No load.
    None,
    /// Constant torque.
    Constant(f64),
    /// 0 before `at_s`, `torque_pu` from `at_s` on.
    Step {
        /// Switch-on time, s.
        at_s: f64,
        /// Torque after the step, pu.
        torque_pu: f64,
    },
    /// A rectangular shock: `torque_pu` on [start_s, start_s + duration_s), 0 elsewhere.
    Shock {
        /// Start, s.
        start_s: f64,
        /// Length, s.
        duration_s: f64,
        /// Torque during the shock, pu.
        torque_pu: f64,
    },
    /// amplitude·sin(2π·f·t + phase).
    Sine {
        /// Amplitude, pu.
        amplitude_pu: f64,
        /// Frequency, Hz.
        freq_hz: f64,
        /// Phase at t = 0, rad.
        phase_rad: f64,
    },
    /// Piecewise constant: each value holds from its time until the next; 0 before the first.
    Series(TimeSeries),
    /// The sum of several loads.
    Sum(Vec<LoadTorque>),
}

/// Piecewise-constant samples with strictly increasing times.
#[derive(Debug, Clone, PartialEq)]
pub struct TimeSeries {
    times_s: Vec<f64>,
    values_pu: Vec<f64>,
}

impl TimeSeries {
    /// Validates (finite, strictly increasing times; finite values).
    pub fn new(points: &[(f64, f64)]) -> Result<Self, PlantError> {
        let mut prev = f64::NEG_INFINITY;
        for (i, (t, v)) in points.iter().enumerate() {
            if !t.is_finite() || !v.is_finite() || *t <= prev {
                return Err(PlantError::BadSeries {
                    index: i,
                    message: "times must be finite and strictly increasing, values finite".into(),
                });
            }
            prev = *t;
        }
        Ok(Self {
            times_s: points.iter().map(|p| p.0).collect(),
            values_pu: points.iter().map(|p| p.1).collect(),
        })
    }

    fn at(&self, t: f64) -> f64 {
        // Index of the last time ≤ t.
        let n = self.times_s.partition_point(|&ti| ti <= t);
        n.checked_sub(1)
            .and_then(|i| self.values_pu.get(i))
            .copied()
            .unwrap_or(0.0)
    }

    fn next_after(&self, t: f64) -> Option<f64> {
        let n = self.times_s.partition_point(|&ti| ti <= t);
        self.times_s.get(n).copied()
    }
}

impl LoadTorque {
    /// The torque at time `t_s`, pu.
    pub fn at(&self, t_s: f64) -> f64 {
        match self {
            Self::None => 0.0,
            Self::Constant(v) => *v,
            Self::Step { at_s, torque_pu } => {
                if t_s >= *at_s {
                    *torque_pu
                } else {
                    0.0
                }
            }
            Self::Shock {
                start_s,
                duration_s,
                torque_pu,
            } => {
                if t_s >= *start_s && t_s < start_s + duration_s {
                    *torque_pu
                } else {
                    0.0
                }
            }
            Self::Sine {
                amplitude_pu,
                freq_hz,
                phase_rad,
            } => amplitude_pu * (2.0 * std::f64::consts::PI * freq_hz * t_s + phase_rad).sin(),
            Self::Series(s) => s.at(t_s),
            Self::Sum(parts) => parts.iter().map(|p| p.at(t_s)).sum(),
        }
    }

    /// The first discontinuity strictly after `t_s`, if any: a simulation should end a step
    /// there so the jump is not smeared over a step.
    pub fn next_change_after(&self, t_s: f64) -> Option<f64> {
        let later = |x: f64| (x > t_s).then_some(x);
        match self {
            Self::None | Self::Constant(_) | Self::Sine { .. } => None,
            Self::Step { at_s, .. } => later(*at_s),
            Self::Shock {
                start_s,
                duration_s,
                ..
            } => later(*start_s).or_else(|| later(start_s + duration_s)),
            Self::Series(s) => s.next_after(t_s),
            Self::Sum(parts) => parts
                .iter()
                .filter_map(|p| p.next_change_after(t_s))
                .reduce(f64::min),
        }
    }

    /// Whether the torque varies smoothly somewhere (a sinusoid), so a held value needs short
    /// steps: sample it at the middle of each step.
    pub fn is_smooth_varying(&self) -> bool {
        match self {
            Self::Sine { .. } => true,
            Self::Sum(parts) => parts.iter().any(Self::is_smooth_varying),
            _ => false,
        }
    }
}

/// Longest sub-step over which a smoothly varying load is held at its midpoint value, s.
/// (A 100 Hz sine held at midpoints of 50 µs: relative error (ωh)²/24 ≈ 4e-5.)
pub const SMOOTH_LOAD_STEP_S: f64 = 50e-6;

/// Splits [t0, t0 + dt] into pieces over which `load` is held: pieces end at every
/// discontinuity of the load, and a smoothly varying load is sampled at the midpoint of pieces
/// of at most [`SMOOTH_LOAD_STEP_S`]. Calls `step(piece_s, load_pu)` in order.
pub fn for_each_load_piece(t0: f64, dt: f64, load: &LoadTorque, mut step: impl FnMut(f64, f64)) {
    let end = t0 + dt;
    let smooth = load.is_smooth_varying();
    let mut t = t0;
    // Bounded: each pass ends at a discontinuity or advances by ≥ min(dt, SMOOTH_LOAD_STEP_S).
    while t < end {
        let stop = load
            .next_change_after(t)
            .filter(|c| *c < end)
            .unwrap_or(end);
        let span = stop - t;
        let n = if smooth {
            (span / SMOOTH_LOAD_STEP_S).ceil().max(1.0)
        } else {
            1.0
        };
        let h = span / n;
        for k in 0..n as u64 {
            let mid = t + (k as f64 + 0.5) * h;
            step(h, load.at(mid));
        }
        t = stop;
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn shock_and_series() {
        let s = LoadTorque::Shock {
            start_s: 1.0,
            duration_s: 0.1,
            torque_pu: 1.5,
        };
        assert_eq!(s.at(0.99), 0.0);
        assert_eq!(s.at(1.05), 1.5);
        assert_eq!(s.at(1.1), 0.0);
        assert_eq!(s.next_change_after(1.0), Some(1.1));
        let ts = TimeSeries::new(&[(0.0, 1.0), (0.5, -1.0)]);
        assert!(ts.is_ok());
        if let Ok(ts) = ts {
            let l = LoadTorque::Series(ts);
            assert_eq!(l.at(-0.1), 0.0);
            assert_eq!(l.at(0.2), 1.0);
            assert_eq!(l.at(0.5), -1.0);
            assert_eq!(l.next_change_after(0.2), Some(0.5));
        }
        assert!(TimeSeries::new(&[(0.0, 1.0), (0.0, 2.0)]).is_err());
        // Pieces end at the shock's edges and the torque is the one acting on each piece.
        let mut pieces = Vec::new();
        for_each_load_piece(0.95, 0.2, &s, |h, tl| pieces.push((h, tl)));
        assert_eq!(pieces.len(), 3);
        assert!((pieces[0].0 - 0.05).abs() < 1e-12 && pieces[0].1 == 0.0);
        assert!((pieces[1].0 - 0.1).abs() < 1e-12 && pieces[1].1 == 1.5);
        assert!((pieces[2].0 - 0.05).abs() < 1e-12 && pieces[2].1 == 0.0);
        assert!(TimeSeries::new(&[(0.0, f64::NAN)]).is_err());
    }
}
