//! The damping of a design measured in the nonlinear loop, against the linear model's.
//!
//! The run: the design on its machine's `fig6` move (to 1 pu in the ramp), a load held from
//! just before the ramp ends ([`PRELOAD_PU`]), so that the gears stay engaged, and then
//! [`STEPS`] steps of [`STEP_PU`] on and off it, [`RECORD_S`] apart. After each step
//! nothing else changes, so the load speed error is the loop's free response: a sum of its
//! modes, Σ hᵢ·zᵢᵏ. The records (sign turned after a step off) are averaged, which averages
//! the quantization noise down, and the modes are fitted to the mean with the matrix-pencil
//! method ([`fit_modes`]); the oscillatory mode with the most energy in the response is
//! the one the steps excite. Its damping is compared with the damping of the linear
//! model's pole nearest to it, and the smallest damping of the model is reported beside
//! it. The load speed is fitted rather than the motor speed, because the shaft filters the
//! quantization chatter out of it; the poles are the same.

use crate::linear::LoopModel;
use nalgebra::{Complex, DMatrix, DVector};
use serde::Serialize;
use sim_engine::config::RunConfig;
use sim_engine::engine::runner::run_scenario;
use sim_engine::error::{HarnessError, Result};

/// Load torque held under the steps \[pu\]: keeps the gears pressed together, also in the
/// shaft torque's undershoot after a step down.
pub const PRELOAD_PU: f64 = 0.4;
/// The step on and off the preload \[pu\]: large against the quantization chatter, small
/// enough that the torque stays below its limit ([`StepFit::max_torque_pu`]).
pub const STEP_PU: f64 = 0.6;
/// Steps, alternately on and off; their responses (those of the steps off with the sign
/// turned) are averaged before the fit, which averages the quantization noise down.
pub const STEPS: usize = 8;
/// The preload starts this long before the ramp ends \[s\] (the ramp already engages the
/// gears in the same direction), the first step this long after it \[s\].
pub const PRELOAD_LEAD_S: f64 = 0.1;
/// See [`PRELOAD_LEAD_S`].
pub const STEP_DELAY_S: f64 = 0.6;
/// Time from one step to the next, the length of each fitted record \[s\].
pub const RECORD_S: f64 = 0.5;
/// Velocity ticks averaged into one fitted sample (an anti-alias filter: block means of a
/// sum of exponentials are a sum of the same exponentials).
pub const DECIMATION: usize = 4;
/// Singular values of the fit's Hankel matrix below this fraction of the largest are noise.
pub const SINGULAR_FLOOR: f64 = 0.02;

/// A mode fitted to a response.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Mode {
    /// The pole in the s-plane \[1/s\]: re, im.
    pub s: [f64; 2],
    /// Σₖ |hᵢ·zᵢᵏ|² over the window: the mode's share of the response.
    pub energy: f64,
}

impl Mode {
    /// Damping ratio −Re s / |s|.
    #[must_use]
    pub fn damping(&self) -> f64 {
        let [re, im] = self.s;
        -re / re.hypot(im)
    }

    /// Damped frequency \[Hz\].
    #[must_use]
    pub fn hz(&self) -> f64 {
        self.s[1] / (2.0 * std::f64::consts::PI)
    }
}

/// What the step run measured and the model predicted.
#[derive(Debug, Clone, Serialize)]
pub struct StepFit {
    /// Load torque off and on \[pu\].
    pub load_pu: [f64; 2],
    /// Steps applied (and records averaged).
    pub steps: usize,
    /// The steps' window \[s\].
    pub window_s: [f64; 2],
    /// Smallest shaft torque in the window \[pu\]: above 0, the gears stayed engaged.
    pub min_shaft_torque_pu: f64,
    /// Largest |torque reference| in the window \[pu\]: below the limit, the loop stayed
    /// linear apart from the quantization.
    pub max_torque_pu: f64,
    /// Every mode fitted to the load speed error.
    pub modes: Vec<Mode>,
    /// The dominant oscillatory mode among them ([`dominant`]).
    pub fitted: Mode,
    /// Its damping.
    pub fitted_damping: f64,
    /// Its damped frequency \[Hz\].
    pub fitted_hz: f64,
    /// The same fit applied to the linear model's own response to the step: how far the
    /// method itself lands from the model's pole.
    pub fitted_to_model_damping: f64,
    /// The model's pole nearest to it (gears engaged): damping.
    pub nearest_pole_damping: f64,
    /// That pole's damped frequency \[Hz\].
    pub nearest_pole_hz: f64,
    /// The model's smallest damping (gears engaged).
    pub smallest_damping: f64,
    /// Whether the nearest pole is the least damped one: then the step measures the
    /// smallest damping itself.
    pub nearest_is_smallest: bool,
}

/// `fig6` (with the design applied) turned into the step run.
#[must_use]
pub fn step_config(fig6: &RunConfig) -> RunConfig {
    let mut cfg = fig6.clone();
    let ramp_end = cfg.scenario.profile.ramp_end_s();
    let step_t = ramp_end + STEP_DELAY_S;
    let mut load = vec![sim_engine::config::scenario::LoadStep {
        t_s: ramp_end - PRELOAD_LEAD_S,
        torque_pu: PRELOAD_PU,
    }];
    load.extend((0..STEPS).map(|k| sim_engine::config::scenario::LoadStep {
        t_s: step_t + k as f64 * RECORD_S,
        torque_pu: PRELOAD_PU + if k % 2 == 0 { STEP_PU } else { 0.0 },
    }));
    cfg.scenario.load = load;
    cfg.scenario.sine_load = None;
    cfg.scenario.duration_s = step_t + STEPS as f64 * RECORD_S;
    cfg.scenario.metrics = Default::default();
    cfg
}

/// Block means of `n` samples.
fn decimate(y: &[f64], n: usize) -> Vec<f64> {
    y.chunks_exact(n.max(1))
        .map(|c| c.iter().sum::<f64>() / c.len() as f64)
        .collect()
}

/// The modes of `y[k] = Σ hᵢ·zᵢᵏ` (sampled every `dt_s`) by the matrix-pencil method: the
/// Hankel matrix of `y`, its dominant right singular vectors V (those above
/// [`SINGULAR_FLOOR`]), the eigenvalues of V₁⁺·V₂ (V without its last, and without its
/// first row) as the zᵢ, then the hᵢ by least squares. Too short a signal gives none.
#[must_use]
pub fn fit_modes(y: &[f64], dt_s: f64) -> Vec<Mode> {
    let n = y.len();
    let l = n / 3;
    if l < 4 {
        return Vec::new();
    }
    let hankel = DMatrix::from_fn(n - l, l + 1, |i, j| y.get(i + j).copied().unwrap_or(0.0));
    let svd = hankel.svd(false, true);
    let Some(v_t) = svd.v_t else {
        return Vec::new();
    };
    // (σ, row of Vᵀ), largest first.
    let mut sv: Vec<(f64, usize)> = svd.singular_values.iter().copied().zip(0..).collect();
    sv.sort_by(|a, b| b.0.total_cmp(&a.0));
    let top = sv.first().map_or(0.0, |p| p.0);
    let order: Vec<usize> = sv.iter().map(|p| p.1).collect();
    let m = sv
        .iter()
        .filter(|p| p.0 > SINGULAR_FLOOR * top)
        .count()
        .clamp(2, 12)
        .min(l);
    let v = DMatrix::from_fn(l + 1, m, |i, j| {
        order
            .get(j)
            .map_or(0.0, |r| v_t.get((*r, i)).copied().unwrap_or(0.0))
    });
    let (v1, v2) = (v.rows(0, l).into_owned(), v.rows(1, l).into_owned());
    let Ok(pinv) = v1.pseudo_inverse(1e-12) else {
        return Vec::new();
    };
    let z: Vec<Complex<f64>> = (pinv * v2).complex_eigenvalues().iter().copied().collect();
    let vander = DMatrix::from_fn(n, z.len(), |k, i| {
        z.get(i).map_or(Complex::default(), |zi| zi.powu(k as u32))
    });
    let yc = DVector::from_iterator(n, y.iter().map(|v| Complex::new(*v, 0.0)));
    let Ok(h) = vander.clone().svd(true, true).solve(&yc, 1e-12) else {
        return Vec::new();
    };
    z.iter()
        .zip(h.iter())
        .filter(|(zi, _)| zi.norm() > 1e-9)
        .map(|(zi, hi)| {
            let s = zi.ln() / dt_s;
            let energy = (0..n).map(|k| (hi * zi.powu(k as u32)).norm_sqr()).sum();
            Mode {
                s: [s.re, s.im],
                energy,
            }
        })
        .collect()
}

/// The oscillatory mode with the most energy: decaying, and of at least one period in
/// a record of `record_s` (a slower pair is the fit's split of real poles, not a swing
/// the record shows).
#[must_use]
pub fn dominant(modes: &[Mode], record_s: f64) -> Option<Mode> {
    modes
        .iter()
        .filter(|m| m.hz() * record_s >= 1.0 && m.s[0] < 0.0)
        .copied()
        .max_by(|a, b| a.energy.total_cmp(&b.energy))
}

/// Runs the step on `fig6` (the design applied) and compares with `model` (that drive,
/// gears engaged).
pub fn measure(fig6: &RunConfig, model: &LoopModel) -> Result<StepFit> {
    measure_if_oscillatory(fig6, model)?.ok_or_else(|| {
        HarnessError::Backend("the step response has no decaying oscillatory mode".into())
    })
}

/// [`measure`], with `None` when the loop's step response has no decaying oscillatory
/// mode that the fit finds: a result to report, not an error.
pub fn measure_if_oscillatory(fig6: &RunConfig, model: &LoopModel) -> Result<Option<StepFit>> {
    let cfg = step_config(fig6);
    let first = cfg.scenario.load.get(1).map_or(0.0, |s| s.t_s);
    let window_s = [first, cfg.scenario.duration_s];
    let out = run_scenario(&cfg)?;
    let rows: Vec<_> = out
        .trace
        .rows
        .iter()
        .filter(|r| r.t_s >= window_s[0] && r.t_s < window_s[1])
        .collect();
    let min_shaft_torque_pu = rows
        .iter()
        .map(|r| r.shaft_torque_pu)
        .fold(f64::INFINITY, f64::min);
    let max_torque_pu = rows
        .iter()
        .map(|r| r.torque_cmd_pu.abs())
        .fold(0.0, f64::max);
    // The mean of the records, each the load speed error after one step (sign turned
    // after a step off).
    let per_record = (RECORD_S * f64::from(cfg.drive.velocity_rate_hz)).round() as usize;
    let mut error = vec![0.0; per_record];
    for (k, record) in rows.chunks_exact(per_record.max(1)).enumerate() {
        let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
        for (e, r) in error.iter_mut().zip(record) {
            *e += sign * (r.load_vel_pu - r.vel_cmd_pu) / STEPS as f64;
        }
    }
    let dt = DECIMATION as f64 / f64::from(cfg.drive.velocity_rate_hz);
    let modes = fit_modes(&decimate(&error, DECIMATION), dt);
    // The same fit on the linear model's own response to the step: the method's error.
    let linear = model.load_step_response(STEP_PU, per_record);
    let fitted_to_model = dominant(&fit_modes(&decimate(&linear, DECIMATION), dt), RECORD_S)
        .map_or(f64::NAN, |m| m.damping());
    let Some(fitted) = dominant(&modes, RECORD_S) else {
        return Ok(None);
    };
    let period = 1.0 / f64::from(cfg.drive.velocity_rate_hz);
    let poles: Vec<Complex<f64>> = model
        .poles()
        .iter()
        .filter(|l| l.norm() > 1e-12)
        .map(|l| l.ln() / period)
        .filter(|s| s.im >= 0.0)
        .collect();
    let target = Complex::new(fitted.s[0], fitted.s[1]);
    let nearest = poles
        .iter()
        .min_by(|a, b| (*a - target).norm().total_cmp(&(*b - target).norm()))
        .copied()
        .unwrap_or_default();
    let zeta = |s: Complex<f64>| -s.re / s.norm();
    let smallest_damping = model.smallest_damping();
    let nearest_pole_damping = zeta(nearest);
    Ok(Some(StepFit {
        load_pu: [PRELOAD_PU, PRELOAD_PU + STEP_PU],
        steps: STEPS,
        window_s,
        min_shaft_torque_pu,
        max_torque_pu,
        modes,
        fitted,
        fitted_damping: fitted.damping(),
        fitted_hz: fitted.hz(),
        fitted_to_model_damping: fitted_to_model,
        nearest_pole_damping,
        nearest_pole_hz: nearest.im / (2.0 * std::f64::consts::PI),
        smallest_damping,
        nearest_is_smallest: (nearest_pole_damping - smallest_damping).abs() < 1e-9,
    }))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn the_fit_finds_the_mode_of_a_known_response() {
        // Two modes and a slow real one: 8 Hz at ζ = 0.3 (the largest) and 60 Hz at 0.1.
        let dt = 2e-3;
        let mode = |zeta: f64, hz: f64, a: f64, k: usize| {
            let wn = 2.0 * std::f64::consts::PI * hz / (1.0 - zeta * zeta).sqrt();
            let t = k as f64 * dt;
            a * (-zeta * wn * t).exp() * (wn * (1.0 - zeta * zeta).sqrt() * t).cos()
        };
        let y: Vec<f64> = (0..400)
            .map(|k| {
                mode(0.3, 8.0, 1.0, k) + mode(0.1, 60.0, 0.2, k)
                    - 0.3 * (-(k as f64) * dt * 20.0).exp()
            })
            .collect();
        let d = dominant(&fit_modes(&y, dt), 0.8).unwrap();
        assert!((d.damping() - 0.3).abs() < 1e-6, "{d:?}");
        assert!((d.hz() - 8.0).abs() < 1e-6, "{d:?}");
    }
}
