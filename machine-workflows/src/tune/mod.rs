//! `hil-harness tune`: design the acceleration feedback, the estimator and (with
//! `--max-bandwidth`) the velocity bandwidth of a machine from its config, on the linear
//! model of the whole loop ([`crate::linear`]), then prove the design in the nonlinear loop.
//!
//! 1. Every candidate of the grid (`[tune]` of `configs/grids.toml`: form, Ka, filter,
//!    acceleration source, observer bandwidth, and the velocity bandwidth when asked for
//!    the maximum) is judged on the
//!    linear model, with the gears engaged and, on a machine with lost motion, apart:
//!    - smallest damping ≥ `min_damping` in both; with a notch on the torque reference
//!      (`[drive.notch]`), the poles within [`notch_band`] are judged apart: those are
//!      the resonance the notch leaves to the machine (and the notch's own pair), and
//!      they must keep [`NOTCH_BAND_DAMPING_SHARE`] of the machine's own damping of its
//!      resonance ([`machine_resonance_damping`]);
//!    - velocity-loop phase margin ≥ 40° and gain margin ≥ 6 dB;
//!    - torque noise from encoder quantization ≤ `max_noise_pu`.
//! 2. The candidates that pass are ranked by the stiffness above the velocity bandwidth:
//!    the weakest |τ_L/θl| over ω_v … 10·ω_v, where a load-torque disturbance moves the
//!    load most (with `--max-bandwidth`, the highest bandwidth first).
//! 3. In that order, each is run in the nonlinear loop with this config on `fig6` (a move
//!    with a load step), `shock` (a 150 % step at speed) and the sweep's probe. The first
//!    that is stable in all three without a fault, and quiet on the probe, is the design.
//!    A design that fails is refused and the next one is tried.
//! 4. The design's damping is measured in the nonlinear loop ([`damping`]: load steps with
//!    the gears engaged, the dominant mode fitted) against the model's, and `tune.md` gets
//!    the Bode plot and the pole map ([`plots`]) and, per bandwidth, which constraint
//!    stopped the search ([`summary`]).

pub mod damping;
pub mod grid;
pub mod machines;
pub mod output;
pub mod pair;
pub mod plots;
pub mod summary;

pub use grid::{candidates, without_afb, Candidate};

use crate::linear::{for_gains, Break, LoopModel};
use plant_host::analysis::Gears;
use rayon::prelude::*;
use serde::Serialize;
use sim_engine::config::{resolve, Grid, RunConfig};
use sim_engine::engine::runner::regulator_gains;
use sim_engine::engine::runner::run_scenario;
use sim_engine::error::{HarnessError, Result};
use sim_engine::output::Staging;
use std::path::Path;

/// The constraints of a design.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
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

/// A candidate judged on the linear model.
#[derive(Debug, Clone, Serialize)]
pub struct Judged {
    /// The candidate.
    pub candidate: Candidate,
    /// Smallest damping, engaged and (with lost motion) apart; with a notch, of the poles
    /// outside its band ([`notch_band`]).
    pub damping: [f64; 2],
    /// With a notch: the smallest damping of the poles inside its band, engaged or apart
    /// (the resonance the notch leaves to the machine, and the notch's own poles).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub notch_band_damping: Option<f64>,
    /// Velocity-loop phase margin \[deg\] and gain margin \[dB\], engaged.
    pub margins: [f64; 2],
    /// Quantization torque noise \[pu RMS\].
    pub noise_pu: f64,
    /// The weakest dynamic stiffness |τ_L/θl| over ω_v … 10·ω_v \[pu torque per pu·s\].
    pub stiffness: f64,
    /// Meets every constraint.
    pub feasible: bool,
}

/// Share of the machine's own damping of its resonance that the poles in a notch's band
/// must keep: the loop may take at most half of it away.
pub const NOTCH_BAND_DAMPING_SHARE: f64 = 0.5;

/// The band of natural frequencies \[Hz\] where a notch (`centre_hz`, `width_hz`) leaves
/// the modes to the machine: the centre ± one width (twice its −3 dB band, so that a mode
/// a few per cent off the centre, where an identified resonance may be, still counts).
#[must_use]
pub fn notch_band(n: &controller_core::NotchConfig) -> (f64, f64) {
    let (c, w) = (f64::from(n.centre_hz), f64::from(n.width_hz));
    (c - w, c + w)
}

/// The damping ratio of the machine's engaged resonance mode on its own (motor free, no
/// loop): ζ·√(1 + Jl/Jm) for the shaft's ζ (defined at the anti-resonance).
#[must_use]
pub fn machine_resonance_damping(cfg: &RunConfig) -> f64 {
    let m = &cfg.plant.mechanics;
    m.shaft_damping_ratio * (1.0 + m.load_inertia_s / m.motor_inertia_s).sqrt()
}

/// The smallest damping of `model`: of all poles without a notch; with one, (outside its
/// band, inside it).
fn damping_of(cfg: &RunConfig, model: &LoopModel) -> (f64, Option<f64>) {
    match &cfg.drive.notch {
        None => (model.smallest_damping(), None),
        Some(n) => {
            let (outside, inside) = model.smallest_damping_split(notch_band(n));
            (outside, Some(inside))
        }
    }
}

fn judge(fig6: &RunConfig, c: &Candidate, k: &Constraints) -> Result<Judged> {
    let mut cfg = fig6.clone();
    c.apply(&mut cfg.drive);
    // The one design of this candidate; both contact states are modelled from it.
    let gains = regulator_gains(&cfg)?;
    let engaged = for_gains(&cfg, &gains, Gears::Engaged)?;
    let (engaged_damping, mut in_band) = damping_of(&cfg, &engaged);
    let apart = if has_lost_motion(&cfg) {
        let (d, b) = damping_of(&cfg, &for_gains(&cfg, &gains, Gears::Apart)?);
        in_band = in_band.zip(b).map(|(x, y)| x.min(y));
        d
    } else {
        f64::INFINITY
    };
    let damping = [engaged_damping, apart];
    let band_floor = NOTCH_BAND_DAMPING_SHARE * machine_resonance_damping(&cfg);
    let m = engaged.margins(Break::VelocityRegulator);
    let noise_pu = engaged.quantization_torque_rms();
    let w = c.bandwidth_rad_s / (2.0 * std::f64::consts::PI);
    let band = plant_host::analysis::log_space(w, 10.0 * w, 16);
    let stiffness = engaged
        .stiffness(&band)
        .into_iter()
        .fold(f64::INFINITY, f64::min);
    let feasible = damping.iter().all(|d| *d >= k.min_damping)
        && in_band.is_none_or(|d| d >= band_floor)
        && m.phase_margin_deg >= k.min_phase_margin_deg
        && m.gain_margin_db >= k.min_gain_margin_db
        && noise_pu <= k.max_noise_pu;
    Ok(Judged {
        candidate: *c,
        damping,
        notch_band_damping: in_band,
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
    /// Its oscillation verdict (`summary.json`'s `oscillation.kind`).
    pub oscillation: sim_engine::engine::metrics::OscillationKind,
    /// Its spectral peak \[Hz\].
    pub oscillation_freq_hz: f64,
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

/// The scenarios of [`VERIFY`] on `config`, each read once.
fn bases(config: &str) -> Result<Vec<RunConfig>> {
    VERIFY
        .iter()
        .map(|s| resolve(s, Some(config), &[]))
        .collect()
}

fn verify(bases: &[RunConfig], c: &Candidate) -> Result<Vec<Verification>> {
    VERIFY
        .iter()
        .zip(bases)
        .map(|(s, base)| {
            let mut cfg = base.clone();
            c.apply(&mut cfg.drive);
            if *s == "sweep" {
                // The probe runs in speed mode, as the sweep runs it.
                cfg.drive.position_bandwidth_rad_s = 0.0;
            }
            let m = run_scenario(&cfg)?.metrics;
            let quiet = *s != "sweep" || m.limit_cycle_torque_pu < crate::sweep::QUIET_TORQUE_PU;
            Ok(Verification {
                scenario: s,
                stable: m.stable,
                oscillation: m.oscillation.kind,
                oscillation_freq_hz: m.oscillation.freq_hz,
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
    /// The constraints it was tuned to.
    pub constraints: Constraints,
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
    /// Per velocity bandwidth: the constraints met, the best damping and stiffness.
    pub per_bandwidth: Vec<summary::AtBandwidth>,
    /// Its damping measured in the nonlinear loop against the model's
    /// ([`damping::measure`]); `None` until [`tune`] has run it, or when it found nothing
    /// to fit ([`TuneResult::no_oscillatory_mode`]).
    pub step: Option<damping::StepFit>,
    /// The loop's load-step response was measured and has no decaying oscillatory mode:
    /// no damping can be fitted to it.
    pub no_oscillatory_mode: bool,
}

/// How far the damping fitted to the nonlinear loop's step response may be from the
/// model's smallest damping (the acceptance figure of `tune`; `tests/tune_table1.rs`).
pub const DAMPING_TOLERANCE: f64 = 0.05;

fn has_lost_motion(cfg: &RunConfig) -> bool {
    cfg.plant.mechanics.backlash_deg > 0.0
}

/// Judges every candidate of `grid` on the linear model of `config`'s `fig6` (module
/// docs, step 1); a candidate the model cannot be built for is left out.
pub fn judge_grid(config: &str, grid: &[Candidate], k: &Constraints) -> Result<Vec<Judged>> {
    let fig6 = resolve(VERIFY[0], Some(config), &[])?;
    let pb = sim_engine::progress::bar(grid.len() as u64, "tune");
    let judged = grid
        .par_iter()
        .filter_map(|c| {
            pb.inc(1);
            judge(&fig6, c, k).ok()
        })
        .collect();
    pb.finish_and_clear();
    Ok(judged)
}

/// Searches `grid`, ranks and verifies (module docs).
pub fn search(config: &str, grid: &[Candidate], k: &Constraints) -> Result<TuneResult> {
    choose(config, judge_grid(config, grid, k)?, k)
}

/// Ranks the candidates `judged` on `config` and verifies them in the nonlinear loop
/// (module docs, steps 2-3).
pub fn choose(config: &str, mut judged: Vec<Judged>, k: &Constraints) -> Result<TuneResult> {
    let bases = bases(config)?;
    let total = judged.len();
    let all = judged.clone();
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
        // A design the drive cannot hold (a coefficient out of its fixed-point format) is
        // passed over, as one that fails in the loop.
        let Ok(runs) = verify(&bases, &j.candidate) else {
            continue;
        };
        if runs.iter().all(|r| r.passed) {
            return Ok(TuneResult {
                config: config.into(),
                constraints: *k,
                judged: total,
                feasible,
                per_bandwidth: summary::per_bandwidth(&all, &refused, k),
                refused,
                design: j,
                verification: runs,
                step: None,
                no_oscillatory_mode: false,
            });
        }
        refused.push((j, runs));
    }
    Err(HarnessError::NoDesign(format!(
        "none of the {total} designs tried meets the constraints on the linear model and is \
         stable in the loop ({feasible} met the constraints on the linear model)"
    )))
}

/// A finished design: what [`search`] chose, with its damping measured in the loop.
#[derive(Debug, Clone)]
pub struct Tuned {
    /// The search's result, [`TuneResult::step`] filled in.
    pub result: TuneResult,
    /// `fig6` on the config as given.
    pub base: RunConfig,
    /// `fig6` with the design applied.
    pub tuned: RunConfig,
}

/// The velocity bandwidths to search: `target_bandwidth` alone, or all of `grid`'s.
pub fn bandwidths(grid: &Grid, target_bandwidth: Option<f64>) -> Result<Vec<f64>> {
    match target_bandwidth {
        Some(w) if w.is_finite() && w > 0.0 => Ok(vec![w]),
        Some(w) => Err(HarnessError::config(
            "--target-bandwidth",
            format!("{w}: must be a positive number of rad/s"),
        )),
        None => Ok(grid.bandwidths_rad_s.clone()),
    }
}

/// Searches (module docs, steps 1-3) and measures the chosen design's damping (step 4).
pub fn design(
    config: &str,
    target_bandwidth: Option<f64>,
    constraints: &Constraints,
) -> Result<Tuned> {
    let grid = sim_engine::config::tune_grid()?;
    let bws = bandwidths(&grid, target_bandwidth)?;
    // judge_grid resolves the config first, so a bad one is reported before the search.
    let judged = judge_grid(config, &candidates(&grid, &bws), constraints)?;
    design_from(config, judged, constraints)
}

/// [`design`] from candidates already judged on `config` ([`judge_grid`]).
pub fn design_from(config: &str, judged: Vec<Judged>, constraints: &Constraints) -> Result<Tuned> {
    let base: RunConfig = resolve("fig6", Some(config), &[])?;
    let mut result = choose(config, judged, constraints)?;
    let mut tuned = base.clone();
    result.design.candidate.apply(&mut tuned.drive);
    let gains = regulator_gains(&tuned)?;
    let engaged = for_gains(&tuned, &gains, Gears::Engaged)?;
    result.step = damping::measure_if_oscillatory(&tuned, &engaged)?;
    result.no_oscillatory_mode = result.step.is_none();
    Ok(Tuned {
        result,
        base,
        tuned,
    })
}

/// Writes the design's files into `dir` (module docs, and [`write_files`]).
pub fn write_design(dir: &Path, t: &Tuned) -> Result<()> {
    let gains = regulator_gains(&t.tuned)?;
    let engaged = for_gains(&t.tuned, &gains, Gears::Engaged)?;
    let apart = if has_lost_motion(&t.tuned) {
        Some(for_gains(&t.tuned, &gains, Gears::Apart)?)
    } else {
        None
    };
    write_files(dir, &t.result, &t.base, &t.tuned, &engaged, apart.as_ref())
}

/// The one-line summary of a design.
#[must_use]
pub fn summary_line(t: &Tuned, out: &Path) -> String {
    let r = &t.result;
    let c = &r.design.candidate;
    let verified: Vec<String> = r
        .verification
        .iter()
        .map(|v| {
            format!(
                "{} {} at {:.1} Hz",
                v.scenario,
                v.oscillation.word(),
                v.oscillation_freq_hz
            )
        })
        .collect();
    format!(
        "tune {}: {} rad/s, {}; damping {:.3} (fitted in the loop {}); verified: {}; -> {}",
        r.config,
        c.bandwidth_rad_s,
        c.afb.label(),
        r.design.damping[0],
        match (&r.step, r.no_oscillatory_mode) {
            (Some(f), _) => format!("{:.3}", f.fitted.damping()),
            (None, true) => "-: no decaying oscillatory mode".into(),
            (None, false) => "-".into(),
        },
        verified.join(", "),
        out.display()
    )
}

/// `hil-harness tune`.
pub fn tune(
    config: &str,
    target_bandwidth: Option<f64>,
    constraints: &Constraints,
    out: &Path,
) -> Result<String> {
    // The output directory is checked before the design's runs.
    let staging = Staging::new(out)?;
    let t = design(config, target_bandwidth, constraints)?;
    write_design(staging.dir(), &t)?;
    staging.commit()?;
    Ok(summary_line(&t, out))
}

/// The figures, `drive.toml` (the machine file with the tuned drive), `tune.md` and
/// `tune.json` into `dir`.
fn write_files(
    dir: &Path,
    result: &TuneResult,
    base: &RunConfig,
    tuned: &RunConfig,
    engaged: &LoopModel,
    apart: Option<&LoopModel>,
) -> Result<()> {
    let nyquist_hz = 0.5 * f64::from(tuned.drive.velocity_rate_hz);
    let images = plots::write(dir, engaged, apart, nyquist_hz)?;
    let json = serde_json::to_string_pretty(result)
        .map_err(|e| HarnessError::io(dir.join("tune.json"), e))?;
    let drive = output::drive_toml(&tuned.drive)?;
    let files = [
        ("tune.md", output::markdown(result, &drive, &images)),
        (
            "drive.toml",
            output::merged_config(&base.config_path, &base.drive, &tuned.drive)?,
        ),
        ("tune.json", json + "\n"),
    ];
    for (name, text) in files {
        let path = dir.join(name);
        std::fs::write(&path, text).map_err(|e| HarnessError::io(&path, e))?;
    }
    Ok(())
}
