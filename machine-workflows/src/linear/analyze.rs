//! `hil-harness linear`: the linear model of one run's loop, written as `DIR/linear.json`
//! and `DIR/linear.md`. It covers the poles and smallest damping with the gears engaged
//! and apart, the margins of the velocity loop and of the acceleration loop, the dynamic
//! stiffness over frequency, and the torque noise from encoder quantization.

use super::{for_run, Break, Margins};
use controller_core::AfbMode;
use plant_host::analysis::Gears;
use serde::Serialize;
use sim_engine::config::{resolve, RunConfig};
use sim_engine::error::{HarnessError, Result};
use sim_engine::output::Staging;
use std::fmt::Write as _;
use std::path::Path;

/// Margins as written (`null` for an infinite margin: no crossing).
#[derive(Debug, Clone, Copy, Serialize)]
pub struct MarginsOut {
    /// Gain margin \[dB\].
    pub gain_margin_db: Option<f64>,
    /// Phase margin \[deg\].
    pub phase_margin_deg: Option<f64>,
    /// Gain crossover \[Hz\].
    pub crossover_hz: Option<f64>,
}

impl From<Margins> for MarginsOut {
    fn from(m: Margins) -> Self {
        let finite = |v: f64| v.is_finite().then_some(v);
        Self {
            gain_margin_db: finite(m.gain_margin_db),
            phase_margin_deg: finite(m.phase_margin_deg),
            crossover_hz: finite(m.crossover_hz),
        }
    }
}

/// The loop with the gears in one state.
#[derive(Debug, Clone, Serialize)]
pub struct GearsAnalysis {
    /// Largest |λ| of the one-period map (stable below 1).
    pub spectral_radius: f64,
    /// Smallest damping ratio over the poles.
    pub smallest_damping: f64,
    /// The velocity loop opened at the velocity regulator's output.
    pub velocity_loop: MarginsOut,
    /// The acceleration loop opened at the AFB term (`None` without AFB).
    pub acceleration_loop: Option<MarginsOut>,
    /// The poles in the s-plane, s = ln(λ)/T_v: \[re, im\] in 1/s.
    pub poles_s: Vec<[f64; 2]>,
}

/// Everything `linear` writes.
#[derive(Debug, Clone, Serialize)]
pub struct Analysis {
    /// Scenario.
    pub scenario: String,
    /// Config file.
    pub config: String,
    /// Velocity bandwidth \[rad/s\].
    pub velocity_bandwidth_rad_s: f64,
    /// Whether acceleration feedback is on.
    pub accel_feedback: bool,
    /// Gears engaged.
    pub engaged: GearsAnalysis,
    /// Gears apart (`None` on a plant without lost motion).
    pub apart: Option<GearsAnalysis>,
    /// Dynamic stiffness |τ_L/θl| \[pu torque per pu·s\] at `stiffness_rad_s`, engaged.
    pub stiffness: Vec<[f64; 2]>,
    /// RMS torque-reference noise from encoder quantization \[pu\], engaged.
    pub quantization_torque_rms_pu: f64,
}

/// Frequencies of the stiffness curve \[rad/s\].
pub const STIFFNESS_RAD_S: [f64; 9] = [1.0, 3.0, 10.0, 30.0, 100.0, 300.0, 1000.0, 3000.0, 6000.0];

fn gears(cfg: &RunConfig, g: Gears) -> Result<GearsAnalysis> {
    let model = for_run(cfg, g)?;
    let afb = cfg.drive.accel_feedback.mode != AfbMode::Off;
    let period = 1.0 / f64::from(cfg.drive.velocity_rate_hz);
    Ok(GearsAnalysis {
        spectral_radius: model.spectral_radius(),
        smallest_damping: model.smallest_damping(),
        velocity_loop: model.margins(Break::VelocityRegulator).into(),
        acceleration_loop: afb.then(|| model.margins(Break::AccelerationFeedback).into()),
        poles_s: model
            .poles()
            .iter()
            .filter(|l| l.norm() > 1e-12)
            .map(|l| {
                let s = l.ln() / period;
                [s.re, s.im]
            })
            .collect(),
    })
}

/// The analysis of `cfg`.
pub fn analyze(cfg: &RunConfig) -> Result<Analysis> {
    let engaged_model = for_run(cfg, Gears::Engaged)?;
    let hz: Vec<f64> = STIFFNESS_RAD_S
        .iter()
        .map(|w| w / (2.0 * std::f64::consts::PI))
        .collect();
    let stiffness = STIFFNESS_RAD_S
        .iter()
        .zip(engaged_model.stiffness(&hz))
        .map(|(w, k)| [*w, k])
        .collect();
    Ok(Analysis {
        scenario: cfg.name.clone(),
        config: cfg.config_path.display().to_string(),
        velocity_bandwidth_rad_s: f64::from(cfg.drive.velocity_bandwidth_rad_s),
        accel_feedback: cfg.drive.accel_feedback.mode != AfbMode::Off,
        engaged: gears(cfg, Gears::Engaged)?,
        apart: if cfg.plant.mechanics.backlash_deg > 0.0 {
            Some(gears(cfg, Gears::Apart)?)
        } else {
            None
        },
        stiffness,
        quantization_torque_rms_pu: engaged_model.quantization_torque_rms(),
    })
}

fn fmt(v: Option<f64>, unit: &str) -> String {
    v.map_or_else(|| "none (no crossing)".into(), |x| format!("{x:.2} {unit}"))
}

/// `linear.md`: every number from [`Analysis`].
#[must_use]
pub fn markdown(a: &Analysis) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# Linear model of `{}` ({})\n\nVelocity bandwidth {:.2} rad/s, acceleration feedback {}. \
         The model is the controller's ticks with their quantized coefficients around the \
         exactly sampled plant, without clamps or rounding (`machine-workflows/src/linear`).\n",
        a.scenario,
        a.config,
        a.velocity_bandwidth_rad_s,
        if a.accel_feedback { "on" } else { "off" }
    );
    let _ = writeln!(s, "| gears | spectral radius | smallest damping | velocity loop GM / PM / crossover | acceleration loop GM / PM / crossover |");
    let _ = writeln!(s, "|---|---|---|---|---|");
    let row = |name: &str, g: &GearsAnalysis| {
        let m = |m: &MarginsOut| {
            format!(
                "{} / {} / {}",
                fmt(m.gain_margin_db, "dB"),
                fmt(m.phase_margin_deg, "deg"),
                fmt(m.crossover_hz, "Hz")
            )
        };
        format!(
            "| {name} | {:.5} | {:.3} | {} | {} |",
            g.spectral_radius,
            g.smallest_damping,
            m(&g.velocity_loop),
            g.acceleration_loop
                .as_ref()
                .map_or_else(|| "(no AFB)".into(), m)
        )
    };
    let _ = writeln!(s, "{}", row("engaged", &a.engaged));
    if let Some(apart) = &a.apart {
        let _ = writeln!(s, "{}", row("apart", apart));
    }
    let _ = writeln!(
        s,
        "\nTorque-reference noise from encoder quantization (white, 1/12 count² per reading): \
         {:.4} pu RMS.\n\n| ω (rad/s) | stiffness (pu torque per pu·s) |\n|---|---|",
        a.quantization_torque_rms_pu
    );
    for [w, k] in &a.stiffness {
        let _ = writeln!(s, "| {w} | {k:.4e} |");
    }
    s
}

/// `hil-harness linear`.
pub fn linear(scenario: &str, config: Option<&str>, sets: &[String], out: &Path) -> Result<String> {
    let cfg = resolve(scenario, config, sets)?;
    let staging = Staging::new(out)?;
    let a = analyze(&cfg)?;
    let dir = staging.dir();
    let json = serde_json::to_string_pretty(&a)
        .map_err(|e| HarnessError::io(dir.join("linear.json"), e))?;
    for (name, text) in [("linear.json", json + "\n"), ("linear.md", markdown(&a))] {
        let path = dir.join(name);
        std::fs::write(&path, text).map_err(|e| HarnessError::io(&path, e))?;
    }
    staging.commit()?;
    Ok(format!(
        "{scenario}: engaged radius {:.5}, smallest damping {:.3}{}; quantization torque noise {:.4} pu -> {}",
        a.engaged.spectral_radius,
        a.engaged.smallest_damping,
        a.apart.as_ref().map_or_else(String::new, |g| format!(
            "; apart radius {:.5}, damping {:.3}",
            g.spectral_radius, g.smallest_damping
        )),
        a.quantization_torque_rms_pu,
        out.display()
    ))
}
