//! The design with acceleration feedback and the design without it by the same
//! constraints, and the nonlinear run that compares them: what `commission` verifies on a
//! machine and `reproduce` reports for the shipped machines, written once here.
//!
//! Each is chosen by the objective ([`super::objective`]) among the candidates of its kind
//! at the bandwidths searched; the no-AFB design, when none passes there, among those at
//! the bandwidths of `tune`'s grid below the highest of them.

use super::bandwidths;
use super::objective::Figures;
use super::{candidates, design_from, judge_grid, without_afb, Candidate, Constraints};
use super::{Judged, Tuned};
use controller_core::AfbMode;
use serde::Serialize;
use sim_engine::config::{borrow_gains, Grid, RunConfig};
use sim_engine::engine::metrics::OscillationKind;
use sim_engine::engine::runner::run_scenario;
use sim_engine::error::HarnessError;
use sim_engine::error::Result;

/// The two designs of one machine.
#[derive(Debug, Clone)]
pub struct Pair {
    /// Tuned with AFB (its damping measured in the loop).
    pub with: Tuned,
    /// The no-AFB design by the same constraints (its damping measured in the loop).
    pub without: Tuned,
    /// Set by `commission`, which runs both designs on the machine itself: whether the one
    /// with AFB has the lower objective there. It then decides instead of the model.
    pub on_machine_afb: Option<bool>,
}

/// The bandwidths the no-AFB design is searched at, for an AFB search at `bws` on `grid`
/// (module docs), ascending and each once.
#[must_use]
pub fn no_afb_bandwidths(grid: &Grid, bws: &[f64]) -> Vec<f64> {
    let top = bws.iter().copied().fold(0.0, f64::max);
    let mut v: Vec<f64> = bws
        .iter()
        .copied()
        .chain(grid.bandwidths_rad_s.iter().copied().filter(|w| *w < top))
        .collect();
    v.sort_by(f64::total_cmp);
    v.dedup();
    v
}

/// Tunes `config` with AFB and without it by the same constraints, each chosen by the
/// objective ([`super::objective`]); [`Pair::chosen`] is the better of the two.
pub fn design_both(
    config: &str,
    target_bandwidth: Option<f64>,
    constraints: &Constraints,
) -> Result<Pair> {
    design_both_from(config, None, target_bandwidth, constraints)
}

fn named(config: &str, kind: &str, e: HarnessError) -> HarnessError {
    match e {
        HarnessError::NoDesign(m) => HarnessError::NoDesign(format!("{config} {kind}: {m}")),
        other => other,
    }
}

/// [`design_both`], with the candidates already judged on `config`
/// ([`super::judge_grid`] of [`candidates`] at [`bandwidths`]`(target_bandwidth)`) when
/// `judged` is given. The AFB design is searched among those with AFB; the no-AFB design
/// among those without it, and, when none of them passes, at the bandwidths of the grid
/// below ([`no_afb_bandwidths`]).
pub fn design_both_from(
    config: &str,
    judged: Option<Vec<Judged>>,
    target_bandwidth: Option<f64>,
    constraints: &Constraints,
) -> Result<Pair> {
    match designs_from(config, judged, target_bandwidth, constraints)? {
        Designs::Both(p) => Ok(*p),
        Designs::WithAfbOnly { without_afb, .. } => Err(HarnessError::NoDesign(without_afb)),
    }
}

/// What the two searches found: both designs, or one with AFB where no design without AFB
/// meets the constraints (a machine only acceleration feedback makes stiff enough).
#[derive(Debug, Clone)]
pub enum Designs {
    /// Both designs.
    Both(Box<Pair>),
    /// The design with AFB alone.
    WithAfbOnly {
        /// Tuned with AFB.
        with: Box<Tuned>,
        /// Why no design without AFB: the search's account, naming `config`.
        without_afb: String,
    },
}

/// [`design_both_from`] that keeps the design with AFB when the search without AFB finds
/// none (any other error, and a search with AFB that finds none, is the error).
pub fn designs_from(
    config: &str,
    judged: Option<Vec<Judged>>,
    target_bandwidth: Option<f64>,
    constraints: &Constraints,
) -> Result<Designs> {
    let grid = sim_engine::config::tune_grid()?;
    let bws = bandwidths(&grid, target_bandwidth)?;
    let judged = match judged {
        Some(j) => j,
        None => judge_grid(config, &candidates(&grid, &bws), constraints)?,
    };
    let (off, afb): (Vec<Judged>, Vec<Judged>) = judged
        .into_iter()
        .partition(|j| j.candidate.afb.mode == AfbMode::Off);
    let with = design_from(config, afb, constraints).map_err(|e| named(config, "with AFB", e))?;
    let without = match design_from(config, off, constraints) {
        Err(HarnessError::NoDesign(first)) => {
            let below: Vec<f64> = no_afb_bandwidths(&grid, &bws)
                .into_iter()
                .filter(|w| !bws.contains(w))
                .collect();
            if below.is_empty() {
                // No lower bandwidth to try: the search's own account stands.
                Err(HarnessError::NoDesign(first))
            } else {
                let lower = without_afb(&candidates(&grid, &below));
                let judged = judge_grid(config, &lower, constraints)?;
                design_from(config, judged, constraints).map_err(|e| match e {
                    HarnessError::NoDesign(m) => HarnessError::NoDesign(format!(
                        "at the searched bandwidths, {first}; below them, {m}"
                    )),
                    other => other,
                })
            }
        }
        other => other,
    }
    .map_err(|e| named(config, "without AFB", e));
    Ok(match without {
        Ok(without) => Designs::Both(Box::new(Pair {
            with,
            without,
            on_machine_afb: None,
        })),
        Err(HarnessError::NoDesign(why)) => Designs::WithAfbOnly {
            with: Box::new(with),
            without_afb: why,
        },
        Err(e) => return Err(e),
    })
}

impl Pair {
    /// Whether the design with AFB is the chosen one: on the machine when `commission` ran
    /// both there ([`Pair::on_machine_afb`]), else on the model (a tie keeps the simpler
    /// drive, without AFB).
    #[must_use]
    pub fn afb_chosen(&self) -> bool {
        self.on_machine_afb
            .unwrap_or_else(|| self.afb_chosen_on_model())
    }

    /// Whether the design with AFB is the better on the model it was tuned on: the one no
    /// worse than the default drive in droop and shaft torque when only one of them is
    /// ([`super::objective::Score::no_worse`]), else the lower objective.
    #[must_use]
    pub fn afb_chosen_on_model(&self) -> bool {
        let (w, wo) = (&self.with.result.score, &self.without.result.score);
        super::objective::better_first(w.rank(), wo.rank()).is_lt()
    }

    /// The chosen design and the runner-up (the best of the other kind).
    #[must_use]
    pub fn chosen(&self) -> (&Tuned, &Tuned) {
        if self.afb_chosen() {
            (&self.with, &self.without)
        } else {
            (&self.without, &self.with)
        }
    }
}

/// One design run in the nonlinear loop.
#[derive(Clone, Debug, Serialize)]
pub struct LoopRun {
    /// Which design.
    pub design: &'static str,
    /// The design's velocity bandwidth \[rad/s\].
    pub bandwidth_rad_s: f64,
    /// Its AFB, as `tune` labels it.
    pub afb: String,
    /// The scenario's `stable`.
    pub stable: bool,
    /// The oscillation verdict of the run (`summary.json`'s `oscillation.kind`).
    pub oscillation: OscillationKind,
    /// Its spectral peak \[Hz\].
    pub oscillation_freq_hz: f64,
    /// Its torque amplitude \[pu\].
    pub oscillation_amplitude_pu: f64,
    /// The scenario's `stable_by_speed`: the criterion without the oscillation verdict.
    pub stable_by_speed: bool,
    /// A fault latched.
    pub faulted: bool,
    /// Shaft-torque ripple after the load step \[pu\].
    pub shaft_torque_ripple_rms_pu: f64,
    /// Its dominant frequency: the peak of the shaft torque's spectrum in the machine's
    /// resonance band (the ring) \[Hz\].
    pub shaft_ripple_freq_hz: f64,
    /// Speed droop at the load step \[pu\] (none without a load step).
    pub load_step_droop_pu: Option<f64>,
    /// The figures the objective reads ([`super::objective`]).
    pub figures: Figures,
}

impl LoopRun {
    /// Runs `cfg` (a scenario on a machine) with `design`'s drive settings.
    pub fn run(mut cfg: RunConfig, label: &'static str, design: &Candidate) -> Result<Self> {
        design.apply(&mut cfg.drive);
        Self::measure(&cfg, label, design, design.afb.label())
    }

    /// Runs `cfg` with `design`'s drive settings and then its AFB turned off, at the same
    /// regulator gains (the AFB design's, bit for bit: [`borrow_gains`]): the design's
    /// bandwidth without what the AFB adds. An error when `design` has no AFB.
    pub fn run_same_gains_without_afb(
        mut cfg: RunConfig,
        label: &'static str,
        design: &Candidate,
    ) -> Result<Self> {
        design.apply(&mut cfg.drive);
        let afb_drive = cfg.drive;
        cfg.drive.accel_feedback.mode = AfbMode::Off;
        borrow_gains(&mut cfg, label, &afb_drive)?;
        let afb = format!("off, at the gains of {}", design.afb.label());
        Self::measure(&cfg, label, design, afb)
    }

    fn measure(
        cfg: &RunConfig,
        label: &'static str,
        design: &Candidate,
        afb: String,
    ) -> Result<Self> {
        let m = run_scenario(cfg)?.metrics;
        Ok(Self {
            design: label,
            bandwidth_rad_s: design.bandwidth_rad_s,
            afb,
            stable: m.stable,
            oscillation: m.oscillation.kind,
            oscillation_freq_hz: m.oscillation.freq_hz,
            oscillation_amplitude_pu: m.oscillation.amplitude_pu,
            stable_by_speed: m.stable_by_speed,
            faulted: m.faulted,
            shaft_torque_ripple_rms_pu: m.shaft_torque_ripple_rms_pu,
            shaft_ripple_freq_hz: m.shaft_ripple_freq_hz,
            load_step_droop_pu: m.load_step_droop_pu,
            figures: Figures::of(&m),
        })
    }

    /// The header of [`LoopRun::row`]'s table columns (after any leading columns).
    pub const HEADER: &'static str = "design | bandwidth (rad/s) | AFB | stable | oscillation \
        verdict | fault | shaft-torque ripple after the load step (pu) | its peak in the \
        resonance band (Hz) | droop (pu) |";
    /// The markdown separator of [`LoopRun::HEADER`]'s nine columns.
    pub const RULE: &'static str = "---|---|---|---|---|---|---|---|---|";

    /// The oscillation verdict and its frequency: `limit_cycle at 178.2 Hz`.
    #[must_use]
    pub fn verdict(&self) -> String {
        format!(
            "{} at {:.1} Hz",
            self.oscillation.word(),
            self.oscillation_freq_hz
        )
    }

    /// When the oscillation verdict decided this run's `stable` against the speed criterion
    /// alone: a sentence naming the verdict that did.
    #[must_use]
    pub fn moved_by_verdict(&self) -> Option<String> {
        (self.stable != self.stable_by_speed).then(|| {
            format!(
                "{}: the speed criterion alone says stable {}; the oscillation verdict, {} at \
                 {:.1} Hz, ±{:.3} pu, makes it {}",
                self.design,
                self.stable_by_speed,
                self.oscillation.word(),
                self.oscillation_freq_hz,
                self.oscillation_amplitude_pu,
                if self.stable { "stable" } else { "unstable" }
            )
        })
    }

    /// This run as the cells of [`LoopRun::HEADER`], each followed by `|`.
    #[must_use]
    pub fn row(&self) -> String {
        format!(
            " {} | {} | {} | {} | {} | {} | {:.4} | {:.1} | {} |",
            self.design,
            self.bandwidth_rad_s,
            self.afb,
            self.stable,
            self.verdict(),
            self.faulted,
            self.shaft_torque_ripple_rms_pu,
            self.shaft_ripple_freq_hz,
            self.load_step_droop_pu
                .map_or_else(|| "-".into(), |d| format!("{d:.4}"))
        )
    }
}

/// The criterion, fixed before any run: the AFB design is stable without a fault and
/// leaves less shaft-torque ripple after the load step than the no-AFB design tuned by
/// the same constraints.
pub const CRITERION: &str = "the AFB design is stable without a fault and leaves less \
    shaft-torque ripple after the load step than the no-AFB design tuned by the same \
    constraints";

/// Whether `with` passes [`CRITERION`] against `without`.
#[must_use]
pub fn afb_passes(with: &LoopRun, without: &LoopRun) -> bool {
    with.stable
        && !with.faulted
        && with.shaft_torque_ripple_rms_pu < without.shaft_torque_ripple_rms_pu
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;

    fn run(stable: bool, ripple: f64) -> LoopRun {
        LoopRun {
            design: "d",
            bandwidth_rad_s: 1.0,
            afb: String::new(),
            stable,
            oscillation: OscillationKind::Quantization,
            oscillation_freq_hz: 0.0,
            oscillation_amplitude_pu: 0.0,
            stable_by_speed: stable,
            faulted: false,
            shaft_torque_ripple_rms_pu: ripple,
            shaft_ripple_freq_hz: 0.0,
            load_step_droop_pu: None,
            figures: Figures {
                peak_droop_pu: None,
                peak_shaft_torque_pu: None,
                recovery_s: None,
                torque_noise_rms_pu: 0.0,
                stable,
                faulted: false,
            },
        }
    }

    #[test]
    fn the_criterion_needs_a_stable_afb_design_with_less_ripple() {
        assert!(afb_passes(&run(true, 0.1), &run(true, 0.2)));
        assert!(!afb_passes(&run(true, 0.2), &run(true, 0.1)));
        assert!(!afb_passes(&run(false, 0.1), &run(true, 0.2)));
    }

    #[test]
    fn no_afb_bandwidths_are_the_target_and_the_grid_below_it() {
        let grid = sim_engine::config::tune_grid().unwrap();
        let all = &grid.bandwidths_rad_s;
        let top = all[3];
        let v = no_afb_bandwidths(&grid, &[top]);
        assert_eq!(v.last().copied(), Some(top));
        assert_eq!(v.len(), 4);
        assert_eq!(no_afb_bandwidths(&grid, all), all.clone());
    }
}
