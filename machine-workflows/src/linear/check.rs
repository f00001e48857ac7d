//! The linear model's stability prediction against the nonlinear loop, point by point on
//! the sweep's grid (`configs/scenarios/sweep.toml`: ramp, load step on and off, unloaded
//! at speed).
//!
//! Predicted stable: every pole of the loop inside the unit circle with the gears engaged,
//! and, on a plant with lost motion, also with the gears apart (the loop must live with the
//! motor alone while it crosses the gap). Measured stable: the run's `stable` metric, as
//! the sweep judges it.

use super::for_run;
use crate::sweep::{point_config, AfbDesign};
use plant_host::analysis::Gears;
use rayon::prelude::*;
use serde::Serialize;
use sim_engine::engine::metrics::Oscillation;
use sim_engine::engine::runner::run_scenario;
use sim_engine::error::Result;

/// One grid point, predicted and measured.
#[derive(Debug, Clone, Serialize)]
pub struct CheckPoint {
    /// Plant config name.
    pub plant: String,
    /// Design label.
    pub design: String,
    /// Velocity bandwidth \[rad/s\].
    pub bandwidth_rad_s: f64,
    /// Spectral radius with the gears engaged.
    pub radius_engaged: f64,
    /// Spectral radius with the gears apart (0 without lost motion).
    pub radius_apart: f64,
    /// Smallest damping, engaged.
    pub damping_engaged: f64,
    /// Predicted stable.
    pub predicted: bool,
    /// Measured stable (the run's `stable` metric).
    pub measured: bool,
    /// Motor-torque chatter in the stability window \[pu\] (the sweep's quiet test).
    pub limit_cycle_torque_pu: f64,
    /// The run's oscillation verdict, with its evidence.
    pub oscillation: Oscillation,
}

/// Predicts and runs one grid point.
pub fn check_point(plant: &str, design: &AfbDesign, bw: f64) -> Result<CheckPoint> {
    let cfg = point_config(plant, design, bw, &[])?;
    let engaged = for_run(&cfg, Gears::Engaged)?;
    let radius_engaged = engaged.spectral_radius();
    let damping_engaged = engaged.smallest_damping();
    let lost_motion = cfg.plant.mechanics.backlash_deg > 0.0;
    let radius_apart = if lost_motion {
        for_run(&cfg, Gears::Apart)?.spectral_radius()
    } else {
        0.0
    };
    let predicted = radius_engaged < 1.0 && radius_apart < 1.0;
    let metrics = run_scenario(&cfg)?.metrics;
    Ok(CheckPoint {
        plant: plant.into(),
        design: design.label(),
        bandwidth_rad_s: bw,
        radius_engaged,
        radius_apart,
        damping_engaged,
        predicted,
        measured: metrics.stable,
        limit_cycle_torque_pu: metrics.limit_cycle_torque_pu,
        oscillation: metrics.oscillation,
    })
}

/// Every point of `plants` × `bandwidths` × `designs`, in parallel. Points whose
/// configuration is refused (a gain that does not fit) are left out.
#[must_use]
pub fn check_grid(plants: &[&str], bandwidths: &[f64], designs: &[AfbDesign]) -> Vec<CheckPoint> {
    let jobs: Vec<(&str, &AfbDesign, f64)> = plants
        .iter()
        .flat_map(|p| {
            designs
                .iter()
                .flat_map(move |d| bandwidths.iter().map(move |bw| (*p, d, *bw)))
        })
        .collect();
    jobs.par_iter()
        .filter_map(|(p, d, bw)| check_point(p, d, *bw).ok())
        .collect()
}
