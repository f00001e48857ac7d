//! The lost motion from the reversal test, fitted by simulation: the test is run again on
//! the identified two-inertia model (the fitted Jm, Jl, f_ar, ζ and friction, no noise)
//! with the same drive and the same rig torque, for candidate widths of the lost motion,
//! and the width whose torque reference matches the measured one best (least squares) is
//! the estimate.
//!
//! What the torque shows: at each reversal of the rig's load torque the shaft unloads, the
//! load flies across the lost motion (the drive sees only the motor inertia) and strikes
//! the other flank; the time of flight and the impact set the torque reference's response,
//! and the flight lasts as long as the lost motion is wide. The search is a grid over
//! [0, `max_lost_motion_deg`] (zero and 40 logarithmic steps) refined by golden sections
//! around the best grid point. The standard error comes from the curvature of the sum of
//! squares there: σ² = 2·s²/S'' with s² = S/(N − 1).
//!
//! The model plant takes from the machine file only what the drive itself knows: the
//! encoder, the base speed, the winding and the computational delay. Every mechanical
//! value is the identified one.

use super::measure::{record, reversal_load, rig_run, Record};
use super::spec::IdentifySpec;
use plant_host::analysis::TwoInertiaFit;
use plant_host::{LostMotionConfig, MechanicsConfig};
use sim_engine::config::RunConfig;
use sim_engine::engine::runner::controller;
use sim_engine::error::Result;

/// The fitted lost motion.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LostMotionFit {
    /// Total lost motion \[deg at the motor\].
    pub backlash_deg: f64,
    /// Its standard error \[deg\] (NaN where the curvature gives none).
    pub std_error_deg: f64,
    /// Root mean square torque-reference mismatch at the optimum \[pu\].
    pub rms_mismatch_pu: f64,
    /// Simulations run.
    pub evaluations: usize,
}

/// The identified mechanics with lost motion `backlash_deg`, on the drive's base speed
/// and encoder.
pub fn identified_mechanics(
    base: &RunConfig,
    fit: &TwoInertiaFit,
    backlash_deg: f64,
) -> MechanicsConfig {
    let drive = &base.drive;
    // The drive's counts per revolution are the encoder's times its interpolation.
    let interpolation = base.plant.sensors.encoder_interpolation.max(1);
    let viscous = fit.viscous_pu.max(0.0);
    MechanicsConfig {
        base_speed_rpm: f64::from(drive.base_speed_rpm),
        motor_inertia_s: fit.motor_inertia_s,
        load_inertia_s: fit.load_inertia_s,
        anti_resonance_hz: fit.anti_resonance_hz,
        shaft_damping_ratio: fit.shaft_damping_ratio,
        backlash_deg,
        // Only the sum shows in motor-side data; it is split evenly, as the fit's model does.
        motor_viscous_pu: 0.5 * viscous,
        load_viscous_pu: 0.5 * viscous,
        encoder_cpr: drive.encoder_cpr / interpolation,
    }
}

/// The rig run on the identified model with lost motion `backlash_deg`: noise-free sensors,
/// the paper's dead zone.
fn model_run(
    base: &RunConfig,
    spec: &IdentifySpec,
    fit: &TwoInertiaFit,
    backlash_deg: f64,
) -> Result<Record> {
    let (load, duration_s) = reversal_load(spec);
    let mut cfg = rig_run(base, duration_s, load);
    cfg.plant.mechanics = identified_mechanics(base, fit, backlash_deg);
    cfg.plant.sensors.encoder_noise_counts = 0.0;
    cfg.plant.sensors.current_noise_pu = 0.0;
    cfg.plant.lost_motion = LostMotionConfig::default();
    let mut ctl = controller(&cfg)?;
    record(&cfg, &mut ctl, "lost-motion simulation")
}

/// Sum of squared torque-reference differences between the measured test and the model's.
fn mismatch(measured: &Record, model: &Record) -> f64 {
    measured
        .torque_ref
        .iter()
        .zip(&model.torque_ref)
        .map(|(a, b)| (a - b).powi(2))
        .sum()
}

/// σ = √(2·s²/S'') from S at `lower`, `deg`, `upper` (`s` = (S(lower), S(deg), S(upper))),
/// s² = S(deg)/(n − 1); NaN where the curvature is not positive.
fn std_error(deg: f64, (lower, upper): (f64, f64), s: (f64, f64, f64), n: f64) -> f64 {
    let (hl, hu) = ((deg - lower).max(1e-12), (upper - deg).max(1e-12));
    let curvature = 2.0 * ((s.2 - s.1) / hu - (s.1 - s.0) / hl) / (hl + hu);
    let s2 = s.1 / (n - 1.0);
    if curvature > 0.0 {
        (2.0 * s2 / curvature).sqrt()
    } else {
        f64::NAN
    }
}

/// Fits the lost motion to the measured reversal test `measured` (module docs).
pub fn fit_lost_motion(
    base: &RunConfig,
    spec: &IdentifySpec,
    fit: &TwoInertiaFit,
    measured: &Record,
) -> Result<LostMotionFit> {
    let mut evaluations = 0;
    let mut cost = |deg: f64| -> Result<f64> {
        evaluations += 1;
        Ok(mismatch(
            measured,
            &model_run(base, spec, fit, deg.max(0.0))?,
        ))
    };
    let max = spec.max_lost_motion_deg;
    let mut grid = vec![0.0];
    grid.extend((0..=40).map(|k| max * (1e-3f64).powf(1.0 - f64::from(k) / 40.0)));
    let costs = grid
        .iter()
        .map(|&g| cost(g))
        .collect::<Result<Vec<f64>>>()?;
    let best = costs
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.total_cmp(b.1))
        .map_or(0, |(i, _)| i);
    let at = |i: usize| grid.get(i).copied().unwrap_or(0.0);
    let (mut lo, mut hi) = (
        at(best.saturating_sub(1)),
        at((best + 1).min(grid.len() - 1)),
    );
    // Golden-section refinement inside the bracket of the best grid point.
    let r = 0.5 * (5f64.sqrt() - 1.0);
    let (mut a, mut b) = (hi - r * (hi - lo), lo + r * (hi - lo));
    let (mut fa, mut fb) = (cost(a)?, cost(b)?);
    for _ in 0..24 {
        if fa < fb {
            hi = b;
            (b, fb) = (a, fa);
            a = hi - r * (hi - lo);
            fa = cost(a)?;
        } else {
            lo = a;
            (a, fa) = (b, fb);
            b = lo + r * (hi - lo);
            fb = cost(b)?;
        }
    }
    let grid_best = costs.get(best).copied().unwrap_or(f64::INFINITY);
    let (deg, s_min) = if fa.min(fb) < grid_best {
        if fa < fb {
            (a, fa)
        } else {
            (b, fb)
        }
    } else {
        (at(best), grid_best)
    };
    // Curvature of S at the optimum, a quarter count (or 1 % of the width) either side.
    let count_deg = 360.0 / f64::from(base.drive.encoder_cpr.max(1));
    let h = (0.25 * count_deg).max(0.01 * deg);
    let lower = (deg - h).max(0.0);
    let sides = (cost(lower)?, cost(deg + h)?);
    let n = measured.torque_ref.len().max(2) as f64;
    let std_error_deg = std_error(deg, (lower, deg + h), (sides.0, s_min, sides.1), n);
    Ok(LostMotionFit {
        backlash_deg: deg,
        std_error_deg,
        rms_mismatch_pu: (s_min / n).sqrt(),
        evaluations,
    })
}
