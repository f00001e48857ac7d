//! Scenario files (`configs/scenarios/NAME.toml`): the velocity profile, the load torque,
//! the run length, the metric windows, which drive/plant config is used by default and
//! the overrides that make this scenario what it is.

use crate::engine::metrics::MetricWindows;
use crate::error::{HarnessError, Result};
use serde::Deserialize;
use std::collections::BTreeMap;

/// A scenario file: one `[scenario]` table.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScenarioFile {
    /// The scenario.
    pub scenario: ScenarioSpec,
}

/// What to run.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScenarioSpec {
    /// One line saying what the run shows.
    pub description: String,
    /// The paper's figure or claim this run reproduces.
    #[serde(default)]
    pub paper: String,
    /// Default configuration (name under `configs/` or a path).
    pub config: String,
    /// Simulated time (s).
    pub duration_s: f64,
    /// Velocity command.
    pub profile: ProfileSpec,
    /// Load torque steps on the load inertia, applied in time order.
    #[serde(default)]
    pub load: Vec<LoadStep>,
    /// Optional sinusoidal load torque (stiffness measurement).
    #[serde(default)]
    pub sine_load: Option<SineLoad>,
    /// The load held still from the start (a locked-rotor test): its speed stays zero and
    /// the motor turns only through the lost motion and the shaft's twist.
    #[serde(default)]
    pub load_locked: bool,
    /// Metric windows.
    #[serde(default)]
    pub metrics: MetricSpec,
    /// A comparison run: whose regulator gains it uses instead of designing its own.
    #[serde(default)]
    pub comparison: Option<ComparisonSpec>,
    /// Configuration overrides (`"drive.velocity_bandwidth_rad_s" = 50.0`), applied on top
    /// of the config file and below the command line's `--set`.
    #[serde(default)]
    pub set: BTreeMap<String, toml::Value>,
}

/// `[scenario.comparison]`: what makes a run "the same drive without acceleration
/// feedback". Without this table a scenario designs its own gains.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ComparisonSpec {
    /// The scenario (with acceleration feedback on) whose designed regulator gains this run
    /// uses bit for bit, with Ka = 0. This run must have acceleration feedback off, and its
    /// drive may differ from that scenario's only in `[drive.accel_feedback]`.
    pub gains_of: String,
}

/// A trapezoidal velocity command: 0 → `speed_pu` in `accel_s` from `start_s`, hold,
/// then optionally back to 0 in `decel_s`.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ProfileSpec {
    /// Plateau speed (pu).
    pub speed_pu: f64,
    /// Ramp-up time (s); 0 means a step.
    pub accel_s: f64,
    /// Ramp start (s).
    #[serde(default)]
    pub start_s: f64,
    /// Plateau length (s); absent means hold to the end.
    #[serde(default)]
    pub hold_s: Option<f64>,
    /// Ramp-down time (s), used when `hold_s` is given.
    #[serde(default)]
    pub decel_s: Option<f64>,
}

/// The command at one instant, in per-unit.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Command {
    /// Position as the integral of pu speed (pu·s).
    pub position_pu_s: f64,
    /// Speed (pu).
    pub velocity_pu: f64,
    /// Acceleration (pu/s).
    pub acceleration_pu_s: f64,
}

impl ProfileSpec {
    /// Time the ramp up ends (s).
    pub fn ramp_end_s(&self) -> f64 {
        self.start_s + self.accel_s
    }

    /// The exact command at `t_s` (closed form, so no drift over a long run).
    pub fn command(&self, t_s: f64) -> Command {
        let v = self.speed_pu;
        let t0 = self.start_s;
        let ta = self.accel_s.max(0.0);
        let t1 = t0 + ta;
        if t_s <= t0 {
            return Command::default();
        }
        let acc = if ta > 0.0 { v / ta } else { 0.0 };
        if t_s < t1 {
            let tau = t_s - t0;
            return Command {
                position_pu_s: 0.5 * acc * tau * tau,
                velocity_pu: acc * tau,
                acceleration_pu_s: acc,
            };
        }
        let ramp_pos = 0.5 * v * ta;
        let Some(hold) = self.hold_s else {
            return Command {
                position_pu_s: ramp_pos + v * (t_s - t1),
                velocity_pu: v,
                acceleration_pu_s: 0.0,
            };
        };
        let t2 = t1 + hold.max(0.0);
        if t_s < t2 {
            return Command {
                position_pu_s: ramp_pos + v * (t_s - t1),
                velocity_pu: v,
                acceleration_pu_s: 0.0,
            };
        }
        let td = self.decel_s.unwrap_or(ta).max(0.0);
        let dec = if td > 0.0 { v / td } else { 0.0 };
        let pos2 = ramp_pos + v * (t2 - t1);
        let tau = (t_s - t2).min(td);
        let pos = pos2 + v * tau - 0.5 * dec * tau * tau;
        if t_s - t2 < td {
            Command {
                position_pu_s: pos,
                velocity_pu: v - dec * tau,
                acceleration_pu_s: -dec,
            }
        } else {
            Command {
                position_pu_s: pos,
                velocity_pu: 0.0,
                acceleration_pu_s: 0.0,
            }
        }
    }
}

/// A load torque step.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct LoadStep {
    /// When (s).
    pub t_s: f64,
    /// New load torque from then on (pu, positive opposes forward motion).
    pub torque_pu: f64,
}

/// Sinusoidal load torque `bias + amplitude·sin(ω·(t − start))` from `start_s`.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SineLoad {
    /// Constant part that keeps the gears engaged (pu).
    pub bias_pu: f64,
    /// Amplitude (pu).
    pub amplitude_pu: f64,
    /// Frequency (rad/s).
    pub freq_rad_s: f64,
    /// Start (s).
    #[serde(default)]
    pub start_s: f64,
}

/// Metric windows and thresholds; absent values take the defaults documented in
/// `sim-engine/README.md`.
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct MetricSpec {
    /// Ripple window (s); default: from one averaging length (`ripple_average_s`) after
    /// the first load step (or the ramp end) to the end.
    pub ripple_window_s: Option<[f64; 2]>,
    /// Overshoot window (s); default: ramp end to the first load step (or the end).
    pub overshoot_window_s: Option<[f64; 2]>,
    /// Stability window (s); default: the last 0.5 s.
    pub stable_window_s: Option<[f64; 2]>,
    /// Length of the moving average removed before the ripple RMS (s); default 0.1.
    pub ripple_average_s: Option<f64>,
    /// Smallest settling band on the speed deviation (pu); default 0: the band is 5 % of
    /// the peak deviation.
    pub settle_band_pu: Option<f64>,
    /// Stability threshold on the speed-error standard deviation (pu); default 0.02.
    pub stable_oscillation_pu: Option<f64>,
    /// Largest saturated fraction of the stability window; default 0.2.
    pub stable_saturation_fraction: Option<f64>,
}

impl ScenarioSpec {
    /// Load torque at `t_s` (pu): the last step at or before `t_s` plus the sine.
    pub fn load_torque_pu(&self, t_s: f64) -> f64 {
        self.load_step_pu(t_s) + self.load_sine_pu(t_s)
    }

    /// The steps' part of [`Self::load_torque_pu`]: the torque of the last step in the list
    /// at or before `t_s` (0 before the first).
    pub fn load_step_pu(&self, t_s: f64) -> f64 {
        self.load
            .iter()
            .rev()
            .find(|s| s.t_s <= t_s)
            .map(|s| s.torque_pu)
            .unwrap_or(0.0)
    }

    /// The sine's part of [`Self::load_torque_pu`] (0 without one, or before it starts).
    #[inline]
    pub fn load_sine_pu(&self, t_s: f64) -> f64 {
        self.sine_load.map_or(0.0, |s| {
            if t_s >= s.start_s {
                s.bias_pu + s.amplitude_pu * (s.freq_rad_s * (t_s - s.start_s)).sin()
            } else {
                0.0
            }
        })
    }

    /// Checks every key against its range (times within the run); errors name the key and
    /// the range. A key the scenario's other settings make meaningless is an error too.
    pub fn validate(&self) -> Result<()> {
        in_range(
            "duration_s",
            self.duration_s,
            (0.0, false),
            MAX_DURATION_S,
            "s",
        )?;
        self.validate_profile()?;
        self.validate_loads()?;
        self.validate_metrics()
    }

    fn validate_profile(&self) -> Result<()> {
        let p = &self.profile;
        in_range("profile.speed_pu", p.speed_pu, (-3.0, true), 3.0, "pu")?;
        in_range("profile.accel_s", p.accel_s, (0.0, true), 100.0, "s")?;
        in_range(
            "profile.start_s",
            p.start_s,
            (0.0, true),
            MAX_DURATION_S,
            "s",
        )?;
        if let Some(h) = p.hold_s {
            in_range("profile.hold_s", h, (0.0, true), 1000.0, "s")?;
        }
        if let Some(d) = p.decel_s {
            in_range("profile.decel_s", d, (0.0, true), 100.0, "s")?;
            if p.hold_s.is_none() {
                return Err(HarnessError::config(
                    "scenario.profile.decel_s",
                    "is used only with profile.hold_s (without it the plateau lasts to the end)",
                ));
            }
        }
        Ok(())
    }

    fn validate_loads(&self) -> Result<()> {
        for (i, l) in self.load.iter().enumerate() {
            // A step after the end of a shortened run never acts: allowed, but bounded.
            in_range(
                &format!("load[{i}].t_s"),
                l.t_s,
                (0.0, true),
                MAX_DURATION_S,
                "s",
            )?;
            in_range(
                &format!("load[{i}].torque_pu"),
                l.torque_pu,
                (-10.0, true),
                10.0,
                "pu",
            )?;
        }
        if let Some(sl) = self.sine_load {
            in_range("sine_load.bias_pu", sl.bias_pu, (-10.0, true), 10.0, "pu")?;
            in_range(
                "sine_load.amplitude_pu",
                sl.amplitude_pu,
                (0.0, true),
                10.0,
                "pu",
            )?;
            in_range(
                "sine_load.freq_rad_s",
                sl.freq_rad_s,
                (0.0, false),
                20_000.0,
                "rad/s",
            )?;
            in_range(
                "sine_load.start_s",
                sl.start_s,
                (0.0, true),
                MAX_DURATION_S,
                "s",
            )?;
        }
        Ok(())
    }

    fn validate_metrics(&self) -> Result<()> {
        let end = self.duration_s;
        let m = &self.metrics;
        for (key, w) in [
            ("metrics.ripple_window_s", m.ripple_window_s),
            ("metrics.overshoot_window_s", m.overshoot_window_s),
            ("metrics.stable_window_s", m.stable_window_s),
        ] {
            if let Some([a, b]) = w {
                let ok = a.is_finite() && b.is_finite() && 0.0 <= a && a < b && b <= end;
                if !ok {
                    return Err(HarnessError::config(
                        format!("scenario.{key}"),
                        format!("[{a}, {b}] must be [start, end] with 0 <= start < end <= duration_s = {end} s"),
                    ));
                }
            }
        }
        for (key, v, lo, hi, unit) in [
            (
                "metrics.ripple_average_s",
                m.ripple_average_s,
                (0.0, false),
                end,
                "s",
            ),
            (
                "metrics.settle_band_pu",
                m.settle_band_pu,
                (0.0, false),
                10.0,
                "pu",
            ),
            (
                "metrics.stable_oscillation_pu",
                m.stable_oscillation_pu,
                (0.0, false),
                10.0,
                "pu",
            ),
            (
                "metrics.stable_saturation_fraction",
                m.stable_saturation_fraction,
                (0.0, true),
                1.0,
                "",
            ),
        ] {
            if let Some(v) = v {
                in_range(key, v, lo, hi, unit)?;
            }
        }
        Ok(())
    }

    /// The metric windows resolved against this scenario.
    pub fn metric_windows(&self, torque_limit_pu: f64) -> MetricWindows {
        let end = self.duration_s;
        let step = self.load.iter().find(|l| l.torque_pu != 0.0).map(|l| l.t_s);
        let step_end = step.and_then(|t| self.load.iter().map(|l| l.t_s).find(|u| *u > t));
        let ramp_end = (self.profile.accel_s > 0.0 || self.profile.speed_pu != 0.0)
            .then(|| self.profile.ramp_end_s());
        let pair = |p: Option<[f64; 2]>| p.map(|[a, b]| (a, b));
        let m = &self.metrics;
        let average_s = m.ripple_average_s.unwrap_or(0.1);
        // One averaging length after the step: the step itself no longer leaks through
        // the high-pass, the ringing it excites does count.
        let ripple_from = step.or(ramp_end).unwrap_or(0.0) + average_s;
        MetricWindows {
            step_time_s: step,
            step_end_s: step_end,
            ramp_end_s: ramp_end,
            ripple_window_s: pair(m.ripple_window_s).unwrap_or((ripple_from.min(end), end)),
            overshoot_window_s: pair(m.overshoot_window_s)
                .or_else(|| ramp_end.map(|r| (r, step.unwrap_or(end)))),
            stable_window_s: pair(m.stable_window_s).unwrap_or(((end - 0.5).max(0.0), end)),
            ripple_average_s: average_s,
            settle_band_pu: m.settle_band_pu.unwrap_or(0.0),
            stable_oscillation_pu: m.stable_oscillation_pu.unwrap_or(0.02),
            stable_saturation_fraction: m.stable_saturation_fraction.unwrap_or(0.2),
            torque_limit_pu,
            machine: None,
            excitation_hz: self
                .sine_load
                .map(|sl| sl.freq_rad_s / (2.0 * std::f64::consts::PI)),
        }
    }
}

/// The longest run a scenario may ask for (s); every scenario time is bounded by it.
pub const MAX_DURATION_S: f64 = 1000.0;

/// `scenario.KEY` must be finite and within (lo, hi] or [lo, hi] (`lo.1` = inclusive).
fn in_range(key: &str, v: f64, lo: (f64, bool), hi: f64, unit: &str) -> Result<()> {
    let (lo, lo_inclusive) = lo;
    let above_lo = if lo_inclusive { v >= lo } else { v > lo };
    if v.is_finite() && above_lo && v <= hi {
        return Ok(());
    }
    let open = if lo_inclusive { '[' } else { '(' };
    Err(HarnessError::config(
        format!("scenario.{key}"),
        format!("{v} is outside {open}{lo}, {hi}] {unit}")
            .trim_end()
            .to_string(),
    ))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn trapezoid_position_is_the_integral_of_velocity() {
        let p = ProfileSpec {
            speed_pu: 1.0,
            accel_s: 0.5,
            start_s: 0.1,
            hold_s: Some(0.3),
            decel_s: Some(0.4),
        };
        let dt = 1e-5;
        let mut pos = 0.0;
        let mut t = 0.0;
        while t < 1.6 {
            pos += p.command(t + dt / 2.0).velocity_pu * dt;
            t += dt;
        }
        let c = p.command(t);
        assert!(
            (c.position_pu_s - pos).abs() < 1e-6,
            "{} vs {pos}",
            c.position_pu_s
        );
        // 0.25 ramp up + 0.3 hold + 0.2 ramp down.
        assert!((c.position_pu_s - 0.75).abs() < 1e-9);
        assert_eq!(c.velocity_pu, 0.0);
    }

    #[test]
    fn unknown_scenario_lists_the_known_ones() {
        use crate::config::load_scenario;
        let e = load_scenario("no-such-scenario").unwrap_err();
        assert!(matches!(e, HarnessError::UnknownScenario { .. }));
        let e = load_scenario("../etc/passwd").unwrap_err();
        assert!(matches!(e, HarnessError::UnknownScenario { .. }));
    }
}
