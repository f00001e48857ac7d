//! `summary.json`: a run's metrics, the protections' record, and the drive that ran.

use super::metrics::Metrics;
use super::protection::{FaultRecord, ProtectionSummary};
use super::runner::{regulator_gains, RunOutput};
use crate::config::RunConfig;
use controller_core::{AfbMode, Gains};
use serde::Serialize;

/// The drive a run actually ran (after the file, the scenario's `set` and `--set`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DriveRun {
    /// Position-loop bandwidth (rad/s); 0 = velocity mode.
    pub position_bandwidth_rad_s: f64,
    /// Velocity-loop bandwidth (rad/s).
    pub velocity_bandwidth_rad_s: f64,
    /// Acceleration feedback mode (`off`, `plain`, `error`).
    pub accel_feedback_mode: String,
    /// Where the AFB path's acceleration comes from (`observer`, `differentiation`).
    pub accel_feedback_source: String,
    /// Ka (s); 0 without acceleration feedback.
    pub ka_s: f64,
}

impl DriveRun {
    /// The drive of `cfg`, whose designed Ka is `ka_s`.
    pub fn of(cfg: &RunConfig, ka_s: f64) -> Self {
        let d = &cfg.drive;
        let word = |v: String| v.to_lowercase();
        Self {
            position_bandwidth_rad_s: f64::from(d.position_bandwidth_rad_s),
            velocity_bandwidth_rad_s: f64::from(d.velocity_bandwidth_rad_s),
            accel_feedback_mode: word(format!("{:?}", d.accel_feedback.mode)),
            accel_feedback_source: word(format!("{:?}", d.accel_feedback.source)),
            ka_s: if d.accel_feedback.mode == AfbMode::Off {
                0.0
            } else {
                ka_s
            },
        }
    }

    /// "NAME on FILE: position loop P rad/s, velocity loop V rad/s, AFB MODE (Ka K s)".
    pub fn title(&self, cfg: &RunConfig) -> String {
        let file = cfg
            .config_path
            .file_stem()
            .map_or_else(String::new, |s| s.to_string_lossy().to_string());
        let position = if self.position_bandwidth_rad_s > 0.0 {
            format!("position loop {:.4} rad/s", self.position_bandwidth_rad_s)
        } else {
            "velocity mode".to_string()
        };
        let afb = if self.accel_feedback_mode == "off" {
            "AFB off".to_string()
        } else {
            format!(
                "AFB {} from {} (Ka {:.4} s)",
                self.accel_feedback_mode, self.accel_feedback_source, self.ka_s
            )
        };
        format!(
            "{} on {file}: {position}, velocity loop {:.4} rad/s, {afb}",
            cfg.name, self.velocity_bandwidth_rad_s
        )
    }
}

/// `summary.json`.
#[derive(Clone, Debug, Serialize)]
pub struct Summary {
    /// Scenario name.
    pub scenario: String,
    /// What it shows.
    pub description: String,
    /// Paper reference.
    pub paper: String,
    /// Config file used.
    pub config: String,
    /// The metrics.
    #[serde(flatten)]
    pub metrics: Metrics,
    /// Simulated time (s).
    pub sim_time_s: f64,
    /// Wall-clock time of the loop (s).
    pub wall_time_s: f64,
    /// Current ticks executed.
    pub ticks: u64,
    /// Simulated seconds per wall-clock second.
    pub realtime_factor: f64,
    /// The drive that ran: its loops' bandwidths, AFB mode, source and Ka.
    pub drive: DriveRun,
    /// What the run's plot titles say: the scenario on the drive that ran.
    pub title: String,
    /// Velocity bandwidth used (rad/s).
    pub velocity_bandwidth_rad_s: f64,
    /// Acceleration feedback mode used.
    pub accel_feedback: String,
    /// Whose designed regulator gains this run uses (`null` = its own design).
    pub gains_of: Option<String>,
    /// Velocity Kp used (pu torque per pu speed).
    pub kp_vel: f64,
    /// Velocity Ki used (pu torque per pu speed per s).
    pub ki_vel: f64,
    /// Ka used (s); 0 without acceleration feedback.
    pub ka_s: f64,
    /// The fault the drive latched first: its kind, code and time; `null` without one.
    pub fault: Option<FaultRecord>,
    /// The protections' figures: overcurrent level and first sample over it, the I²t
    /// model's prediction of its trip.
    pub protection: ProtectionSummary,
}

impl RunOutput {
    /// The summary of this run under `cfg`.
    pub fn summary(&self, cfg: &RunConfig) -> Summary {
        let gains = regulator_gains(cfg).ok();
        let g = |f: fn(&Gains) -> f32| gains.as_ref().map_or(f64::NAN, |x| f64::from(f(x)));
        Summary {
            scenario: cfg.name.clone(),
            description: cfg.scenario.description.clone(),
            paper: cfg.scenario.paper.clone(),
            config: cfg.config_path.display().to_string(),
            metrics: self.metrics.clone(),
            sim_time_s: self.sim_time_s,
            wall_time_s: self.wall_time_s,
            ticks: self.ticks,
            realtime_factor: if self.wall_time_s > 0.0 {
                self.sim_time_s / self.wall_time_s
            } else {
                f64::INFINITY
            },
            drive: DriveRun::of(cfg, g(|x| x.ka)),
            title: DriveRun::of(cfg, g(|x| x.ka)).title(cfg),
            velocity_bandwidth_rad_s: f64::from(cfg.drive.velocity_bandwidth_rad_s),
            accel_feedback: format!("{:?}", cfg.drive.accel_feedback.mode),
            gains_of: cfg.gains_of.as_ref().map(|o| o.source.clone()),
            kp_vel: g(|x| x.kp_vel),
            ki_vel: g(|x| x.ki_vel),
            ka_s: g(|x| x.ka),
            fault: self.fault.clone(),
            protection: self.protection.clone(),
        }
    }
}
