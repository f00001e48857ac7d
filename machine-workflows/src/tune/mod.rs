//! `hil-harness tune`: design the acceleration feedback, the estimator and (with
//! `--max-bandwidth`) the velocity bandwidth of a machine from its config, on the linear
//! model of the whole loop ([`crate::linear`]), then prove the design in the nonlinear loop.
//!
//! 1. Every candidate of the grid (`[tune]` of `configs/grids.toml`: form, Ka, filter,
//!    acceleration source, observer bandwidth, and the velocity bandwidth when asked for
//!    the maximum) is judged on the
//!    linear model, with the gears engaged and, on a machine with lost motion, apart:
//!    - smallest damping ≥ `min_damping` in both; without a notch, on a machine that damps
//!      its own resonance less, the engaged poles near it need only keep the machine's own
//!      damping ([`resonance_band`]); with a notch on the torque reference
//!      (`[drive.notch]`), the poles within [`notch_band`] are judged apart: those are
//!      the resonance the notch leaves to the machine (and the notch's own pair), and
//!      they must keep [`NOTCH_BAND_DAMPING_SHARE`] of the machine's own damping of its
//!      resonance ([`machine_resonance_damping`]);
//!    - velocity-loop phase margin ≥ 40° and gain margin ≥ 6 dB;
//!    - torque noise from encoder quantization ≤ `max_noise_pu`.
//! 2. Of the candidates that pass, up to [`SCORED_PER_BANDWIDTH`] per bandwidth
//!    ([`shortlist`]: spread over their ranking by the stiffness above the velocity
//!    bandwidth, the weakest |τ_L/θl| over ω_v … 10·ω_v) are run on `fig6` (a move with a
//!    load step) and scored by the objective ([`objective`]: droop, shaft torque and
//!    recovery after the step against the file's own drive, within a torque-noise budget).
//! 3. In the order of the objective, those within the budgets are run in the nonlinear
//!    loop on `fig6`, `shock` (a 150 % step at speed) and the sweep's probe. The first that
//!    is stable in all three without a fault, and quiet on the probe, is the design; one
//!    that fails is refused and the next one is tried. `tune` does this with AFB and
//!    without ([`pair`]) and writes the lower objective as `drive.toml`, the other as
//!    `runner-up.toml` ([`write_pair`]).
//! 4. The design's damping is measured in the nonlinear loop ([`damping`]: load steps with
//!    the gears engaged, the dominant mode fitted) against the model's, and `tune.md` gets
//!    the Bode plot and the pole map ([`plots`]) and, per bandwidth, which constraint
//!    stopped the search ([`summary`]).

pub mod bands;
pub mod damping;
pub mod grid;
pub mod machines;
pub mod objective;
pub mod output;
pub mod pair;
pub mod plots;
pub mod summary;
mod verify;
mod write;

use bands::damping_of;
pub use bands::{
    machine_resonance_damping, machine_resonance_hz, notch_band, resonance_band,
    NOTCH_BAND_DAMPING_SHARE, RESONANCE_BAND_SHARE,
};
pub use grid::{candidates, without_afb, Candidate};
pub use verify::retarget;
use verify::{bases, verify};
pub use verify::{Verification, VERIFY};
pub use write::{write_design, write_pair, write_pair_as, PairFiles, TUNE_FILES};

use crate::linear::{for_gains, Break};
use plant_host::analysis::Gears;
use rayon::prelude::*;
use serde::Serialize;
use sim_engine::config::{resolve, Grid, RunConfig};
use sim_engine::engine::runner::regulator_gains;
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
    /// Largest torque noise in the nonlinear `fig6` run \[pu RMS\] (`--max-torque-noise-pu`);
    /// `None`: the default rule of [`objective::Reference::of`].
    pub max_torque_noise_pu: Option<f64>,
}

impl Default for Constraints {
    fn default() -> Self {
        Self {
            min_damping: 0.3,
            min_phase_margin_deg: 40.0,
            min_gain_margin_db: 6.0,
            max_noise_pu: 0.2,
            max_torque_noise_pu: None,
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
    /// Without a notch, on a machine whose own resonance damping is below the floor: the
    /// smallest damping of the engaged poles within [`resonance_band`] (infinite if none),
    /// which must keep the machine's own; `damping[0]` is then of the poles outside it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub resonance_band_damping: Option<f64>,
    /// Velocity-loop phase margin \[deg\] and gain margin \[dB\], engaged.
    pub margins: [f64; 2],
    /// Quantization torque noise \[pu RMS\].
    pub noise_pu: f64,
    /// The weakest dynamic stiffness |τ_L/θl| over ω_v … 10·ω_v \[pu torque per pu·s\].
    pub stiffness: f64,
    /// Meets every constraint.
    pub feasible: bool,
}

fn judge(fig6: &RunConfig, c: &Candidate, k: &Constraints) -> Result<Judged> {
    let mut cfg = fig6.clone();
    c.apply(&mut cfg.drive);
    judge_as(&cfg, *c, k)
}

/// `cfg`'s drive as it is, judged on the linear model of `cfg` by the constraints `k` as
/// every candidate is (module docs, step 1): e.g. a machine file's own drive, to be set
/// beside the designs. Its [`Judged::candidate`] is the drive's velocity bandwidth and AFB.
pub fn judge_drive(cfg: &RunConfig, k: &Constraints) -> Result<Judged> {
    judge_as(cfg, Candidate::of(&cfg.drive), k)
}

fn judge_as(cfg: &RunConfig, c: Candidate, k: &Constraints) -> Result<Judged> {
    // The one design of this candidate; both contact states are modelled from it.
    let gains = regulator_gains(cfg)?;
    let engaged = for_gains(cfg, &gains, Gears::Engaged)?;
    let (engaged_damping, mut in_band) = damping_of(cfg, &engaged);
    let apart = if has_lost_motion(cfg) {
        let (d, b) = damping_of(cfg, &for_gains(cfg, &gains, Gears::Apart)?);
        in_band = in_band.zip(b).map(|(x, y)| x.min(y));
        d
    } else {
        f64::INFINITY
    };
    // Without a notch, the poles near the machine's resonance are held to its own damping.
    let (engaged_damping, resonance_band_damping) = match resonance_band(cfg, k.min_damping) {
        Some(band) => {
            let (outside, inside) = engaged.smallest_damping_split(band);
            (outside, Some(inside))
        }
        None => (engaged_damping, None),
    };
    let damping = [engaged_damping, apart];
    let band_floor = NOTCH_BAND_DAMPING_SHARE * machine_resonance_damping(cfg);
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
        && resonance_band_damping.is_none_or(|d| d >= machine_resonance_damping(cfg))
        && m.phase_margin_deg >= k.min_phase_margin_deg
        && m.gain_margin_db >= k.min_gain_margin_db
        && noise_pu <= k.max_noise_pu;
    Ok(Judged {
        candidate: c,
        damping,
        notch_band_damping: in_band,
        resonance_band_damping,
        margins: [m.phase_margin_deg, m.gain_margin_db],
        noise_pu,
        stiffness,
        feasible,
    })
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
    /// The default drive's figures and the budgets ([`objective`]).
    pub reference: objective::Reference,
    /// The design's figures and objective on `fig6`.
    pub score: objective::Score,
    /// Every candidate run on `fig6` to be scored, in the order of their objective.
    pub scored: Vec<Scored>,
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

/// At most this many feasible candidates of one velocity bandwidth are run in the loop
/// to be scored: on Table 1, 125 of the 128 feasible ones (its most at one bandwidth is 34).
pub const SCORED_PER_BANDWIDTH: usize = 32;

/// A candidate run on `fig6` and scored ([`objective`]).
#[derive(Debug, Clone, Serialize)]
pub struct Scored {
    /// The candidate.
    pub candidate: Candidate,
    /// Its figures and objective.
    pub score: objective::Score,
}

/// The feasible candidates of `judged` to score in the loop: per velocity bandwidth, all of
/// them up to [`SCORED_PER_BANDWIDTH`], and beyond that as many spread evenly over their
/// ranking by stiffness, the stiffest first.
#[must_use]
pub fn shortlist(judged: &[Judged]) -> Vec<Judged> {
    let mut bws: Vec<f64> = judged.iter().map(|j| j.candidate.bandwidth_rad_s).collect();
    bws.sort_by(f64::total_cmp);
    bws.dedup();
    let mut out = Vec::new();
    for bw in bws {
        let mut at: Vec<&Judged> = judged
            .iter()
            .filter(|j| j.feasible && j.candidate.bandwidth_rad_s == bw)
            .collect();
        at.sort_by(|a, b| b.stiffness.total_cmp(&a.stiffness));
        let n = at.len();
        let take = n.min(SCORED_PER_BANDWIDTH);
        out.extend(
            (0..take)
                .filter_map(|i| at.get(i * n / take.max(1)))
                .map(|j| (*j).clone()),
        );
    }
    out
}

/// Chooses among the candidates `judged` on `config` (module docs, steps 2-3): the
/// [`shortlist`] of the feasible ones is run on `fig6` and scored ([`objective`]); those
/// within the budgets are verified, those no worse than the default drive in droop and
/// shaft torque first, each group in the order of its objective, and the first that passes
/// is the design.
pub fn choose(config: &str, judged: Vec<Judged>, k: &Constraints) -> Result<TuneResult> {
    let bases = bases(config)?;
    let fig6 = bases
        .first()
        .ok_or_else(|| HarnessError::Backend("no fig6".into()))?;
    let reference = objective::Reference::of(fig6, k.max_torque_noise_pu)?;
    let total = judged.len();
    let feasible = judged.iter().filter(|j| j.feasible).count();
    // A candidate the drive cannot hold (a coefficient out of its fixed-point format) is
    // passed over, as one that fails in the loop.
    let mut runs: Vec<(Judged, objective::Score)> = shortlist(&judged)
        .into_par_iter()
        .filter_map(|j| {
            let s = objective::Score::run(fig6, &reference, &j.candidate).ok()?;
            Some((j, s))
        })
        .collect();
    runs.sort_by(|(a, x), (b, y)| {
        objective::better_first(x.rank(), y.rank())
            .then(
                b.candidate
                    .bandwidth_rad_s
                    .total_cmp(&a.candidate.bandwidth_rad_s),
            )
            .then(b.stiffness.total_cmp(&a.stiffness))
    });
    let scored: Vec<Scored> = runs
        .iter()
        .map(|(j, s)| Scored {
            candidate: j.candidate,
            score: *s,
        })
        .collect();
    let within = runs.iter().filter(|(_, s)| s.within_budget).count();
    let mut refused = Vec::new();
    for (j, score) in runs.into_iter().filter(|(_, s)| s.within_budget) {
        let Ok(verification) = verify(&bases, &j.candidate) else {
            continue;
        };
        if verification.iter().all(|r| r.passed) {
            return Ok(TuneResult {
                config: config.into(),
                constraints: *k,
                judged: total,
                feasible,
                per_bandwidth: summary::per_bandwidth(&judged, &refused, k),
                refused,
                design: j,
                reference,
                score,
                scored,
                verification,
                step: None,
                no_oscillatory_mode: false,
            });
        }
        refused.push((j, verification));
    }
    // The best of the refused designs, and what its verification showed.
    let best = refused.first().map_or_else(String::new, |(j, runs)| {
        let why: Vec<String> = runs.iter().filter_map(Verification::failure).collect();
        format!(
            "; the best of the {} verified, {} at {} rad/s, failed {}",
            refused.len(),
            j.candidate.afb.label(),
            j.candidate.bandwidth_rad_s,
            why.join("; ")
        )
    });
    Err(HarnessError::NoDesign(format!(
        "none of the {total} designs tried meets the constraints on the linear model, stays \
         within the budgets in the loop and passes verification ({feasible} met the \
         constraints on the linear model, {} were run in the loop, {within} of them within \
         the budgets: torque noise <= {:.4} pu, stable, no fault, a load-step response{best})",
        scored.len(),
        reference.max_torque_noise_pu
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
        "tune {}: {} rad/s, {}; damping {:.3}{} (fitted in the loop {}); verified: {}; -> {}",
        r.config,
        c.bandwidth_rad_s,
        c.afb.label(),
        r.design.damping[0],
        r.design
            .resonance_band_damping
            .map_or_else(String::new, |d| format!(
                " away from the machine's resonance, {d:.3} near it"
            )),
        match (&r.step, r.no_oscillatory_mode) {
            (Some(f), _) => format!("{:.3}", f.fitted.damping()),
            (None, true) => "-: no decaying oscillatory mode".into(),
            (None, false) => "-".into(),
        },
        verified.join(", "),
        out.display()
    )
}

/// `hil-harness tune`: both designs ([`pair::design_both`]), the chosen one's files and
/// the runner-up's machine file ([`write_pair`]). Where no design without AFB meets the
/// constraints but one with AFB does, that one's files alone, `tune.md` saying why there is
/// no runner-up.
pub fn tune(
    config: &str,
    target_bandwidth: Option<f64>,
    constraints: &Constraints,
    out: &Path,
) -> Result<String> {
    objective::check_budget(constraints.max_torque_noise_pu)?;
    // The output directory is checked before the design's runs.
    let staging = Staging::new(out)?;
    let line = match pair::designs_from(config, None, target_bandwidth, constraints)? {
        pair::Designs::Both(p) => {
            write_pair(staging.dir(), &p)?;
            pair_line(&p, out)
        }
        pair::Designs::WithAfbOnly { with, without_afb } => {
            write::write_afb_only(staging.dir(), &with, &without_afb)?;
            format!(
                "{}; no design without AFB meets the constraints, so this one has no runner-up \
                 (tune.md)",
                summary_line(&with, out)
            )
        }
    };
    staging.commit()?;
    Ok(line)
}

/// The one-line summary of a pair: the chosen design's [`summary_line`] and both
/// objectives.
#[must_use]
pub fn pair_line(p: &pair::Pair, out: &Path) -> String {
    let (chosen, _) = p.chosen();
    format!(
        "{}; J {:.3} with AFB, {:.3} without (default drive 3): chose {}{}",
        summary_line(chosen, out),
        p.with.result.score.objective,
        p.without.result.score.objective,
        if p.afb_chosen() {
            "with AFB"
        } else {
            "without AFB"
        },
        if p.on_machine_afb.is_some() {
            " by the objective on the machine"
        } else {
            ""
        }
    )
}
