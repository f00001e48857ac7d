//! `hil-harness tune`: design the acceleration feedback, the estimator and (with
//! `--max-bandwidth`) the velocity bandwidth of a machine from its config, on the linear
//! model of the whole loop ([`crate::linear`]), then prove the design in the nonlinear loop.
//!
//! 1. Every candidate of a fixed grid (form, Ka, filter, acceleration source, observer
//!    bandwidth, and the velocity bandwidth when asked for the maximum) is judged on the
//!    linear model, with the gears engaged and, on a machine with lost motion, apart:
//!    - smallest damping ≥ `min_damping` in both;
//!    - velocity-loop phase margin ≥ 40° and gain margin ≥ 6 dB;
//!    - torque noise from encoder quantization ≤ `max_noise_pu`.
//! 2. The candidates that pass are ranked by the stiffness above the velocity bandwidth:
//!    the weakest |τ_L/θl| over ω_v … 10·ω_v, where a load-torque disturbance moves the
//!    load most (with `--max-bandwidth`, the highest bandwidth first).
//! 3. In that order, each is run in the nonlinear loop with this config on `fig6` (a move
//!    with a load step), `shock` (a 150 % step at speed) and the sweep's probe. The first
//!    that is stable in all three without a fault, and quiet on the probe, is the design.
//!    A design that fails is refused and the next one is tried.

use crate::config::{resolve, RunConfig};
use crate::error::{HarnessError, Result};
use crate::linear::{for_run, Break};
use crate::output::Staging;
use crate::runner::run_scenario;
use crate::sweep::AfbDesign;
use plant_host::analysis::Gears;
use rayon::prelude::*;
use serde::Serialize;
use std::fmt::Write as _;
use std::path::Path;

/// The constraints of a design.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Constraints {
    /// Smallest damping ratio of the loop, gears engaged and apart.
    pub min_damping: f64,
    /// Smallest velocity-loop phase margin \[deg\].
    pub min_phase_margin_deg: f64,
    /// Smallest velocity-loop gain margin \[dB\].
    pub min_gain_margin_db: f64,
    /// Largest quantization torque noise \[pu RMS\].
    pub max_noise_pu: f64,
}

impl Default for Constraints {
    fn default() -> Self {
        Self {
            min_damping: 0.3,
            min_phase_margin_deg: 40.0,
            min_gain_margin_db: 6.0,
            max_noise_pu: 0.2,
        }
    }
}

/// Velocity bandwidths tried with `--max-bandwidth` \[rad/s\].
pub const BANDWIDTHS_RAD_S: [f64; 10] = [
    30.0, 45.0, 60.0, 94.25, 120.0, 150.0, 200.0, 250.0, 350.0, 500.0,
];
/// Ka / J_total tried (and no AFB at every bandwidth and observer).
pub const GAINS: [f64; 4] = [0.25, 0.5, 1.0, 2.0];
/// AFB filters tried: (kind, corner Hz).
pub const FILTERS: [(&str, f64); 6] = [
    ("first_order", 50.0),
    ("first_order", 100.0),
    ("first_order", 200.0),
    ("first_order", 400.0),
    ("second_order", 100.0),
    ("second_order", 200.0),
];
/// Observer bandwidths tried \[Hz\].
pub const OBSERVER_HZ: [f64; 4] = [75.0, 100.0, 150.0, 250.0];

/// One candidate: a velocity bandwidth and an acceleration-feedback design (the sweep's
/// [`AfbDesign`], observer bandwidth included), as `--set` overrides of the config.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Candidate {
    /// Velocity bandwidth \[rad/s\].
    pub bandwidth_rad_s: f64,
    /// The AFB design and the observer bandwidth.
    #[serde(flatten)]
    pub afb: AfbDesign,
}

impl Candidate {
    fn sets(&self) -> Vec<String> {
        let mut s = vec![
            format!("drive.velocity_bandwidth_rad_s={}", self.bandwidth_rad_s),
            "drive.velocity_pi_inertia=total".to_string(),
        ];
        s.extend(self.afb.sets());
        s
    }

    /// The `[drive]` keys of this candidate, as (key below `drive.`, TOML value).
    #[must_use]
    pub fn keys(&self) -> Vec<(String, String)> {
        self.sets()
            .into_iter()
            .filter_map(|kv| {
                let (k, v) = kv.strip_prefix("drive.")?.split_once('=')?;
                let value = if v.parse::<f64>().is_ok() {
                    v.to_string()
                } else {
                    format!("\"{v}\"")
                };
                Some((k.to_string(), value))
            })
            .collect()
    }
}

/// The grid for the bandwidths `bws`: without AFB, and the error and plain forms over
/// [`GAINS`] × [`FILTERS`] × (observer, differentiation), at every observer bandwidth.
#[must_use]
pub fn candidates(bws: &[f64]) -> Vec<Candidate> {
    let mut v = Vec::new();
    for &bandwidth_rad_s in bws {
        for observer_hz in OBSERVER_HZ {
            let mut push = |afb: AfbDesign| {
                v.push(Candidate {
                    bandwidth_rad_s,
                    afb,
                })
            };
            push(AfbDesign {
                observer_hz,
                ..AfbDesign::OFF
            });
            for gain_fraction in GAINS {
                for source in ["observer", "differentiation"] {
                    for mode in ["error", "plain"] {
                        for (filter, filter_corner_hz) in FILTERS {
                            push(AfbDesign {
                                mode,
                                gain_fraction,
                                filter,
                                filter_corner_hz,
                                source,
                                observer_hz,
                            });
                        }
                    }
                }
            }
        }
    }
    v
}

/// The candidates of `grid` without acceleration feedback: the "without AFB" design tuned
/// by the same constraints.
#[must_use]
pub fn without_afb(grid: &[Candidate]) -> Vec<Candidate> {
    grid.iter()
        .filter(|c| c.afb.mode == "off")
        .cloned()
        .collect()
}

/// The `--set` overrides of a candidate (for `resolve`).
#[must_use]
pub fn sets_of(c: &Candidate) -> Vec<String> {
    c.sets()
}

/// A candidate judged on the linear model.
#[derive(Debug, Clone, Serialize)]
pub struct Judged {
    /// The candidate.
    pub candidate: Candidate,
    /// Smallest damping, engaged and (with lost motion) apart.
    pub damping: [f64; 2],
    /// Velocity-loop phase margin \[deg\] and gain margin \[dB\], engaged.
    pub margins: [f64; 2],
    /// Quantization torque noise \[pu RMS\].
    pub noise_pu: f64,
    /// The weakest dynamic stiffness |τ_L/θl| over ω_v … 10·ω_v \[pu torque per pu·s\].
    pub stiffness: f64,
    /// Meets every constraint.
    pub feasible: bool,
}

fn judge(config: &str, c: &Candidate, k: &Constraints) -> Result<Judged> {
    let cfg = resolve("fig6", Some(config), &c.sets())?;
    let engaged = for_run(&cfg, Gears::Engaged)?;
    let apart = if cfg.plant.mechanics.backlash_deg > 0.0 {
        for_run(&cfg, Gears::Apart)?.smallest_damping()
    } else {
        f64::INFINITY
    };
    let damping = [engaged.smallest_damping(), apart];
    let m = engaged.margins(Break::VelocityRegulator);
    let noise_pu = engaged.quantization_torque_rms();
    let w = c.bandwidth_rad_s / (2.0 * std::f64::consts::PI);
    let band = plant_host::analysis::log_space(w, 10.0 * w, 16);
    let stiffness = engaged
        .stiffness(&band)
        .into_iter()
        .fold(f64::INFINITY, f64::min);
    let feasible = damping.iter().all(|d| *d >= k.min_damping)
        && m.phase_margin_deg >= k.min_phase_margin_deg
        && m.gain_margin_db >= k.min_gain_margin_db
        && noise_pu <= k.max_noise_pu;
    Ok(Judged {
        candidate: c.clone(),
        damping,
        margins: [m.phase_margin_deg, m.gain_margin_db],
        noise_pu,
        stiffness,
        feasible,
    })
}

/// A nonlinear verification run.
#[derive(Debug, Clone, Serialize)]
pub struct Verification {
    /// Scenario.
    pub scenario: &'static str,
    /// Its `stable` metric.
    pub stable: bool,
    /// Whether the controller faulted.
    pub faulted: bool,
    /// Shaft-torque ripple after the step \[pu\].
    pub shaft_torque_ripple_rms_pu: f64,
    /// Motor-torque chatter in the stability window \[pu\].
    pub limit_cycle_torque_pu: f64,
    /// Whether the run passes: stable, no fault, and on the sweep probe also quiet
    /// (chatter below [`crate::sweep::QUIET_TORQUE_PU`], the sweep's own test).
    pub passed: bool,
}

/// Scenarios a design must pass: a move with a load step, a 150 % shock, and the sweep's
/// probe (ramp, load on and off, unloaded at speed), on which it must also be quiet.
pub const VERIFY: [&str; 3] = ["fig6", "shock", "sweep"];

fn verify(config: &str, c: &Candidate) -> Result<Vec<Verification>> {
    VERIFY
        .iter()
        .map(|s| {
            let mut sets = c.sets();
            if *s == "sweep" {
                // The probe runs in speed mode, as the sweep runs it.
                sets.push("drive.position_bandwidth_rad_s=0".into());
            }
            let m = run_scenario(&resolve(s, Some(config), &sets)?)?.metrics;
            let quiet = *s != "sweep" || m.limit_cycle_torque_pu < crate::sweep::QUIET_TORQUE_PU;
            Ok(Verification {
                scenario: s,
                stable: m.stable,
                faulted: m.faulted,
                shaft_torque_ripple_rms_pu: m.shaft_torque_ripple_rms_pu,
                limit_cycle_torque_pu: m.limit_cycle_torque_pu,
                passed: m.stable && !m.faulted && quiet,
            })
        })
        .collect()
}

/// What `tune` found.
#[derive(Debug, Clone, Serialize)]
pub struct TuneResult {
    /// The config tuned.
    pub config: String,
    /// Candidates judged and feasible.
    pub judged: usize,
    /// Feasible on the linear model.
    pub feasible: usize,
    /// Designs refused in the nonlinear loop before the chosen one.
    pub refused: Vec<(Judged, Vec<Verification>)>,
    /// The design.
    pub design: Judged,
    /// Its verification runs.
    pub verification: Vec<Verification>,
}

/// Searches `grid`, ranks and verifies (module docs).
pub fn search(config: &str, grid: &[Candidate], k: &Constraints) -> Result<TuneResult> {
    let pb = crate::progress::bar(grid.len() as u64, "tune");
    let mut judged: Vec<Judged> = grid
        .par_iter()
        .filter_map(|c| {
            pb.inc(1);
            judge(config, c, k).ok()
        })
        .collect();
    pb.finish_and_clear();
    let total = judged.len();
    judged.retain(|j| j.feasible);
    let feasible = judged.len();
    judged.sort_by(|a, b| {
        b.candidate
            .bandwidth_rad_s
            .total_cmp(&a.candidate.bandwidth_rad_s)
            .then(b.stiffness.total_cmp(&a.stiffness))
    });
    let mut refused = Vec::new();
    for j in judged {
        let runs = verify(config, &j.candidate)?;
        if runs.iter().all(|r| r.passed) {
            return Ok(TuneResult {
                config: config.into(),
                judged: total,
                feasible,
                refused,
                design: j,
                verification: runs,
            });
        }
        refused.push((j, runs));
    }
    Err(HarnessError::config(
        "tune",
        format!(
            "no design of the {total} tried meets the constraints on the linear model and is \
             stable in the loop ({feasible} met the constraints)"
        ),
    ))
}

/// The `[drive]` table of a design, as TOML text.
#[must_use]
pub fn drive_toml(c: &Candidate) -> String {
    let mut top = String::from("[drive]\n");
    let mut afb = String::from("\n[drive.accel_feedback]\n");
    let mut obs = String::from("\n[drive.observer]\n");
    for (k, v) in c.keys() {
        if let Some(k) = k.strip_prefix("accel_feedback.") {
            let _ = writeln!(afb, "{k} = {v}");
        } else if let Some(k) = k.strip_prefix("observer.") {
            let _ = writeln!(obs, "{k} = {v}");
        } else {
            let _ = writeln!(top, "{k} = {v}");
        }
    }
    top + &afb + &obs
}

/// `config` with its `[drive]` table's keys set to the design's.
fn merged_config(config_path: &Path, c: &Candidate) -> Result<String> {
    let text =
        std::fs::read_to_string(config_path).map_err(|e| HarnessError::io(config_path, e))?;
    let mut doc: toml::Table = text
        .parse()
        .map_err(|e: toml::de::Error| HarnessError::config("config", e.message().to_string()))?;
    let design: toml::Table = drive_toml(c)
        .parse()
        .map_err(|e: toml::de::Error| HarnessError::config("tune", e.message().to_string()))?;
    let Some(toml::Value::Table(new_drive)) = design.get("drive").cloned() else {
        return Err(HarnessError::config(
            "tune",
            "no [drive] table in the design",
        ));
    };
    let drive = doc
        .entry("drive")
        .or_insert_with(|| toml::Value::Table(toml::Table::new()));
    if let toml::Value::Table(d) = drive {
        for (k, v) in new_drive {
            match (d.get_mut(&k), v) {
                (Some(toml::Value::Table(old)), toml::Value::Table(new)) => old.extend(new),
                (_, v) => {
                    d.insert(k, v);
                }
            }
        }
    }
    toml::to_string(&doc).map_err(|e| HarnessError::config("tune", e.to_string()))
}

fn markdown(r: &TuneResult) -> String {
    let d = &r.design;
    let c = &d.candidate;
    let mut s = format!(
        "# tune: `{}`\n\n{} candidates judged on the linear model, {} met the constraints; {} \
         refused in the nonlinear loop before this one.\n\n## Design\n\n```toml\n{}```\n\n",
        r.config,
        r.judged,
        r.feasible,
        r.refused.len(),
        drive_toml(c)
    );
    let _ = writeln!(
        s,
        "Predicted (linear model): smallest damping {:.3} engaged, {} apart; velocity-loop phase \
         margin {:.1}°, gain margin {:.1} dB; quantization torque noise {:.4} pu RMS; weakest \
         stiffness over ω_v … 10·ω_v {:.4e} pu per pu·s.\n",
        d.damping[0],
        if d.damping[1].is_finite() {
            format!("{:.3}", d.damping[1])
        } else {
            "(no lost motion)".into()
        },
        d.margins[0],
        d.margins[1],
        d.noise_pu,
        d.stiffness
    );
    let _ = writeln!(
        s,
        "| verification | stable | faulted | shaft-torque ripple (pu) |\n|---|---|---|---|"
    );
    for v in &r.verification {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {:.4} |",
            v.scenario, v.stable, v.faulted, v.shaft_torque_ripple_rms_pu
        );
    }
    s
}

/// `hil-harness tune`.
pub fn tune(
    config: &str,
    target_bandwidth: Option<f64>,
    constraints: &Constraints,
    out: &Path,
) -> Result<String> {
    let bws: Vec<f64> = match target_bandwidth {
        Some(w) if w.is_finite() && w > 0.0 => vec![w],
        Some(w) => {
            return Err(HarnessError::config(
                "--target-bandwidth",
                format!("{w}: must be a positive number of rad/s"),
            ))
        }
        None => BANDWIDTHS_RAD_S.to_vec(),
    };
    // Resolve once first, so a bad config is reported before the search.
    let base: RunConfig = resolve("fig6", Some(config), &[])?;
    let result = search(config, &candidates(&bws), constraints)?;
    let staging = Staging::new(out)?;
    let dir = staging.dir();
    let json = serde_json::to_string_pretty(&result)
        .map_err(|e| HarnessError::io(dir.join("tune.json"), e))?;
    let files = [
        ("drive.toml", drive_toml(&result.design.candidate)),
        (
            "config.toml",
            merged_config(&base.config_path, &result.design.candidate)?,
        ),
        ("tune.md", markdown(&result)),
        ("tune.json", json + "\n"),
    ];
    for (name, text) in files {
        let path = dir.join(name);
        std::fs::write(&path, text).map_err(|e| HarnessError::io(&path, e))?;
    }
    staging.commit()?;
    let c = &result.design.candidate;
    Ok(format!(
        "tune {config}: {} rad/s, {}; damping {:.3}; -> {}",
        c.bandwidth_rad_s,
        c.afb.label(),
        result.design.damping[0],
        out.display()
    ))
}
