//! The user's objective, by which `tune` chooses among the designs that meet the
//! constraints: how a load step moves the machine, against the drive the machine file ships.
//!
//! After the load step of `fig6` (a move with a load step, on the machine file):
//!
//! J = peak droop / its reference + peak shaft torque / its reference + recovery time / its
//! reference,
//!
//! where each reference is the same figure of the same run with the file's own `[drive]`
//! unchanged (the default drive, whose J is therefore 3). Lower is better; a design with
//! J < 3 does better than the default drive by the sum of the three ratios.
//!
//! A run with no figure (no load step seen, or a speed error that never recovers) has
//! J = +∞: it is never chosen. When the default drive itself never recovers, its recovery
//! time is taken as the whole response window after the step (to the next load change or
//! the end of the run: a lower bound of it) to normalize the others, and its own J is +∞.
//! A default drive without a droop or a shaft-torque figure (no load step in the run), or
//! with a zero one, cannot normalize anything: the objective is then an error naming the
//! figure.
//!
//! Budgets a design must stay within, besides the linear constraints of
//! [`super::Constraints`]:
//! - `torque_noise_rms_pu` of the same run (the motor torque above the velocity bandwidth)
//!   at most [`super::Constraints::max_torque_noise_pu`]: `--max-torque-noise-pu`, or by default
//!   the larger of [`NOISE_FACTOR`] × the default drive's own and [`NOISE_FLOOR_PU`];
//! - stable and not faulted in that run (and in `tune`'s verification runs).
//!
//! J trades the three figures against each other, but a user who swaps drives expects
//! neither the droop nor the shaft torque to get worse. So among the designs within the
//! budgets, those no worse than the default drive in peak droop and in peak shaft torque
//! ([`Reference::worse`] empty, [`Score::no_worse`]) come first, by J, and the others only
//! after them; a design chosen from the others is reported as worse, by how much.

use super::Candidate;
use serde::Serialize;
use sim_engine::config::RunConfig;
use sim_engine::engine::metrics::Metrics;
use sim_engine::engine::runner::run_scenario;
use sim_engine::error::{HarnessError, Result};

/// The scenario the objective is measured on.
pub const SCENARIO: &str = "fig6";

/// The default noise budget is this many times the default drive's own torque noise.
pub const NOISE_FACTOR: f64 = 2.0;

/// The smallest default noise budget \[pu RMS\]: 1 % of rated torque. A drive whose own
/// noise is almost nothing (the printing press's default drive: 0.0005 pu on `fig6`) would
/// otherwise forbid any design faster than itself; 0.01 pu is a twentieth of the
/// quantization-noise ceiling the linear constraints already accept (0.2 pu).
pub const NOISE_FLOOR_PU: f64 = 0.01;

/// The flag that sets the noise budget.
pub const NOISE_FLAG: &str = "--max-torque-noise-pu";

/// The figures of one `fig6` run the objective reads.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Figures {
    /// Largest speed deviation after the load step \[pu\].
    pub peak_droop_pu: Option<f64>,
    /// Largest |shaft torque| after the load step \[pu\].
    pub peak_shaft_torque_pu: Option<f64>,
    /// Time until the deviation stays under 10 % of its peak \[s\].
    pub recovery_s: Option<f64>,
    /// Motor torque above the velocity bandwidth, RMS \[pu\].
    pub torque_noise_rms_pu: f64,
    /// The run's `stable`.
    pub stable: bool,
    /// A fault latched.
    pub faulted: bool,
}

impl Figures {
    /// The figures of `m`.
    #[must_use]
    pub fn of(m: &Metrics) -> Self {
        Self {
            peak_droop_pu: m.peak_droop_pu,
            peak_shaft_torque_pu: m.peak_shaft_torque_pu,
            recovery_s: m.recovery_s,
            torque_noise_rms_pu: m.torque_noise_rms_pu,
            stable: m.stable,
            faulted: m.faulted,
        }
    }

    /// Runs `fig6` (the scenario on the machine file, drive as given).
    pub fn run(fig6: &RunConfig) -> Result<Self> {
        Ok(Self::of(&run_scenario(fig6)?.metrics))
    }
}

/// The default drive's figures and the budget they set.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Reference {
    /// `fig6` with the file's `[drive]`.
    pub default_drive: Figures,
    /// What each term is divided by: the default drive's peak droop \[pu\], peak shaft
    /// torque \[pu\] and recovery time \[s\] (when it never recovers: the response window).
    pub norms: [f64; 3],
    /// The torque-noise budget \[pu RMS\].
    pub max_torque_noise_pu: f64,
    /// Whether the budget was given (`--max-torque-noise-pu`) or is the default rule.
    pub budget_given: bool,
    /// The run-to-run spread of the default drive's peak droop and peak shaft torque \[pu\]
    /// (`commission` measures it over the load step's timing; 0 on the model): a design
    /// is worse than the default drive in one of them only by more than this
    /// ([`Reference::worse`]).
    pub spread: [f64; 2],
}

fn needed(name: &str, v: Option<f64>) -> Result<f64> {
    match v {
        Some(x) if x.is_finite() && x > 0.0 => Ok(x),
        other => Err(HarnessError::config(
            "objective",
            format!(
                "the default drive's {name} on `{SCENARIO}` is {}: the objective normalizes \
                 by it, so it must be a positive number (does the scenario have a load step?)",
                other.map_or_else(|| "none".to_string(), |x| x.to_string())
            ),
        )),
    }
}

/// Checks a noise budget given on the command line: finite and > 0.
pub fn check_budget(max_torque_noise_pu: Option<f64>) -> Result<()> {
    match max_torque_noise_pu {
        Some(v) if !(v.is_finite() && v > 0.0) => Err(HarnessError::config(
            NOISE_FLAG,
            format!("{v}: must be a finite number > 0 (pu RMS of rated torque)"),
        )),
        _ => Ok(()),
    }
}

impl Reference {
    /// Runs the default drive (`fig6` as resolved on the machine file) and sets the budget:
    /// `max_torque_noise_pu`, or by default max([`NOISE_FACTOR`] × its noise,
    /// [`NOISE_FLOOR_PU`]). An error when the default drive's run has no figure to
    /// normalize by.
    pub fn of(fig6: &RunConfig, max_torque_noise_pu: Option<f64>) -> Result<Self> {
        check_budget(max_torque_noise_pu)?;
        let w = fig6.metric_windows();
        let window_s = w
            .step_time_s
            .map(|t| w.step_end_s.unwrap_or(fig6.scenario.duration_s) - t);
        Self::from_figures(Figures::run(fig6)?, window_s, max_torque_noise_pu)
    }

    /// [`Reference::of`] from the default drive's figures already measured; `window_s`, the
    /// response window after the step, stands for a recovery that never came.
    pub fn from_figures(
        default_drive: Figures,
        window_s: Option<f64>,
        max_torque_noise_pu: Option<f64>,
    ) -> Result<Self> {
        check_budget(max_torque_noise_pu)?;
        let norms = [
            needed("peak droop", default_drive.peak_droop_pu)?,
            needed("peak shaft torque", default_drive.peak_shaft_torque_pu)?,
            needed("recovery time", default_drive.recovery_s.or(window_s))?,
        ];
        Ok(Self {
            default_drive,
            norms,
            max_torque_noise_pu: max_torque_noise_pu.unwrap_or_else(|| {
                (NOISE_FACTOR * default_drive.torque_noise_rms_pu).max(NOISE_FLOOR_PU)
            }),
            budget_given: max_torque_noise_pu.is_some(),
            spread: [0.0; 2],
        })
    }

    /// This reference with the measured run-to-run spread of the default drive's peak
    /// droop and peak shaft torque ([`Reference::spread`]; a negative or NaN one is 0).
    #[must_use]
    pub fn with_spread(mut self, spread: [f64; 2]) -> Self {
        self.spread = spread.map(|x| if x > 0.0 { x } else { 0.0 });
        self
    }

    /// J of `f` (module docs): +∞ when a figure is missing.
    #[must_use]
    pub fn objective(&self, f: &Figures) -> f64 {
        let [d, s, r] = self.norms;
        let ratio = |x: Option<f64>, n: f64| match x {
            Some(x) if x.is_finite() && n > 0.0 => x / n,
            _ => f64::INFINITY,
        };
        ratio(f.peak_droop_pu, d) + ratio(f.peak_shaft_torque_pu, s) + ratio(f.recovery_s, r)
    }

    /// The budgets `f` breaks, in words (empty: within every budget).
    #[must_use]
    pub fn broken(&self, f: &Figures) -> Vec<String> {
        let mut v = Vec::new();
        if !f.stable {
            v.push("unstable".to_string());
        }
        if f.faulted {
            v.push("faulted".to_string());
        }
        if f.torque_noise_rms_pu.is_nan() || f.torque_noise_rms_pu > self.max_torque_noise_pu {
            v.push(format!(
                "torque noise {:.4} pu > {:.4} pu",
                f.torque_noise_rms_pu, self.max_torque_noise_pu
            ));
        }
        if !self.objective(f).is_finite() {
            v.push("no load-step figure (no step seen, or never recovered)".to_string());
        }
        v
    }

    /// The figures in which `f` is worse than the default drive, in words (empty: no worse
    /// in peak droop and in peak shaft torque). Worse is above the default drive's figure by
    /// more than its run-to-run spread ([`Reference::spread`]).
    #[must_use]
    pub fn worse(&self, f: &Figures) -> Vec<String> {
        let mut v = Vec::new();
        let d = &self.default_drive;
        for ((name, x, reference), spread) in [
            ("peak droop", f.peak_droop_pu, d.peak_droop_pu),
            (
                "peak shaft torque",
                f.peak_shaft_torque_pu,
                d.peak_shaft_torque_pu,
            ),
        ]
        .into_iter()
        .zip(self.spread)
        {
            if let (Some(x), Some(r)) = (x, reference) {
                if x > r + spread {
                    let beyond = if spread > 0.0 {
                        format!(", beyond its spread of {spread:.4} pu")
                    } else {
                        String::new()
                    };
                    v.push(format!(
                        "{name} {x:.4} pu > the default drive's {r:.4} pu (+{:.1} %{beyond})",
                        100.0 * (x / r - 1.0)
                    ));
                }
            }
        }
        v
    }

    /// The budgets and the objective, in words, for `tune.md` and `commission.md`.
    #[must_use]
    pub fn describe(&self) -> String {
        let d = &self.default_drive;
        let [nd, ns, nr] = self.norms;
        let [sd, ss] = self.spread;
        format!(
            "The objective: after `{SCENARIO}`'s load step, J = peak droop / {nd:.4} pu + peak \
             shaft torque / {ns:.4} pu + recovery time / {nr:.4} s, each divided by the same \
             figure of the machine file's own `[drive]` (the default drive, J = 3){}; lower \
             is better, and a run without one of the figures (no step seen, never recovered) \
             has J = ∞. Budgets: torque noise above the velocity bandwidth ≤ {:.4} pu RMS \
             ({}); stable and no fault in `{SCENARIO}` and in the verification runs; and the \
             linear constraints below. Of the designs within the budgets, those no worse than \
             the default drive in peak droop ({:.4} pu) and in peak shaft torque ({:.4} pu) \
             are preferred, by J; another is chosen only when none of them passes, and is \
             reported as worse{}.",
            if d.recovery_s.is_none() {
                format!(
                    "; the default drive never recovers within the {nr:.3} s after the step, \
                     so that window stands for its recovery time and its own J is ∞"
                )
            } else {
                String::new()
            },
            self.max_torque_noise_pu,
            if self.budget_given {
                NOISE_FLAG.to_string()
            } else {
                format!(
                    "the larger of {NOISE_FACTOR} × the default drive's {:.4} pu and \
                     {NOISE_FLOOR_PU} pu",
                    d.torque_noise_rms_pu
                )
            },
            d.peak_droop_pu.unwrap_or(f64::NAN),
            d.peak_shaft_torque_pu.unwrap_or(f64::NAN),
            if sd + ss > 0.0 {
                format!(
                    ". Worse means worse beyond the noise: above the default drive's figure by \
                     more than that figure's run-to-run spread ({sd:.4} pu in peak droop, \
                     {ss:.4} pu in peak shaft torque)"
                )
            } else {
                String::new()
            }
        )
    }
}

/// The order designs are ranked in, the better first: the higher `class` (how far a design
/// qualifies: no worse than the default drive above worse than it, on the machine also
/// within the budgets above out of them), then the lower J. `tune`'s ranking, the choice
/// between the two kinds and `commission`'s ranking on the machine all use it.
#[must_use]
pub fn better_first(a: (u8, f64), b: (u8, f64)) -> std::cmp::Ordering {
    b.0.cmp(&a.0).then(a.1.total_cmp(&b.1))
}

/// One candidate run on `fig6` and scored.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Score {
    /// Its figures.
    pub figures: Figures,
    /// J (module docs).
    pub objective: f64,
    /// Within every budget of [`Reference::broken`].
    pub within_budget: bool,
    /// No worse than the default drive in peak droop and in peak shaft torque
    /// ([`Reference::worse`]).
    pub no_worse: bool,
}

impl Score {
    /// Scores `f` against `r`.
    #[must_use]
    pub fn of(r: &Reference, f: Figures) -> Self {
        Self {
            figures: f,
            objective: r.objective(&f),
            within_budget: r.broken(&f).is_empty(),
            no_worse: r.worse(&f).is_empty(),
        }
    }

    /// Its key for [`better_first`]: no worse than the default drive, then J.
    #[must_use]
    pub fn rank(&self) -> (u8, f64) {
        (u8::from(self.no_worse), self.objective)
    }

    /// Runs `c` on `fig6` and scores it.
    pub fn run(fig6: &RunConfig, r: &Reference, c: &Candidate) -> Result<Self> {
        let mut cfg = fig6.clone();
        c.apply(&mut cfg.drive);
        Ok(Self::of(r, Figures::run(&cfg)?))
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn the_higher_class_ranks_first_then_the_lower_objective() {
        use std::cmp::Ordering::{Equal, Greater, Less};
        assert_eq!(better_first((2, 5.0), (1, 1.0)), Less);
        assert_eq!(better_first((0, 1.0), (1, 5.0)), Greater);
        assert_eq!(better_first((1, 2.0), (1, 3.0)), Less);
        assert_eq!(better_first((1, 3.0), (1, 2.0)), Greater);
        assert_eq!(better_first((1, 2.0), (1, 2.0)), Equal);
        // A run with no figure (J = +inf) ranks after every finite one of its class.
        assert_eq!(better_first((1, f64::INFINITY), (1, 9.0)), Greater);
    }

    fn figures(droop: Option<f64>, shaft: f64, rec: Option<f64>, noise: f64) -> Figures {
        Figures {
            peak_droop_pu: droop,
            peak_shaft_torque_pu: Some(shaft),
            recovery_s: rec,
            torque_noise_rms_pu: noise,
            stable: true,
            faulted: false,
        }
    }

    #[test]
    fn the_default_drive_scores_three_and_halving_every_figure_scores_one_and_a_half() {
        let d = figures(Some(0.01), 0.8, Some(0.2), 0.1);
        let r = Reference::from_figures(d, None, None).unwrap();
        assert!((r.objective(&d) - 3.0).abs() < 1e-12);
        let half = figures(Some(0.005), 0.4, Some(0.1), 0.1);
        assert!((r.objective(&half) - 1.5).abs() < 1e-12);
        assert_eq!(r.max_torque_noise_pu, 0.2);
    }

    #[test]
    fn a_missing_figure_is_an_infinite_objective_and_out_of_budget() {
        let r =
            Reference::from_figures(figures(Some(0.01), 0.8, Some(0.2), 0.0), None, None).unwrap();
        assert_eq!(r.max_torque_noise_pu, NOISE_FLOOR_PU);
        let never = figures(Some(0.01), 0.8, None, 0.001);
        assert_eq!(r.objective(&never), f64::INFINITY);
        assert!(!Score::of(&r, never).within_budget);
        let noisy = figures(Some(0.01), 0.8, Some(0.2), 0.02);
        assert!(r.objective(&noisy).is_finite());
        assert!(!Score::of(&r, noisy).within_budget);
    }

    #[test]
    fn a_lower_objective_bought_with_more_shaft_torque_or_droop_is_worse() {
        let r =
            Reference::from_figures(figures(Some(0.01), 0.8, Some(0.2), 0.01), None, None).unwrap();
        // J = 0.5 + 1.01 + 0.25 < 3, but the shaft torque is 1 % above the default's.
        let shaft = figures(Some(0.005), 0.808, Some(0.05), 0.01);
        assert!(r.objective(&shaft) < 3.0);
        let worse = r.worse(&shaft);
        assert_eq!(worse.len(), 1, "{worse:?}");
        assert!(worse[0].contains("peak shaft torque 0.8080 pu") && worse[0].contains("+1.0 %"));
        let s = Score::of(&r, shaft);
        assert!(s.within_budget && !s.no_worse);
        let droop = figures(Some(0.0101), 0.4, Some(0.05), 0.01);
        assert!(r.worse(&droop)[0].starts_with("peak droop"));
        // Equal to the default drive's is no worse.
        assert!(Score::of(&r, figures(Some(0.01), 0.8, Some(0.1), 0.01)).no_worse);
    }

    #[test]
    fn worse_is_worse_beyond_the_spread() {
        let r = Reference::from_figures(figures(Some(0.01), 0.8, Some(0.2), 0.01), None, None)
            .unwrap()
            .with_spread([0.0005, 0.01]);
        // Within the spread of each figure: no worse.
        let near = figures(Some(0.0105), 0.81, Some(0.2), 0.01);
        assert!(r.worse(&near).is_empty(), "{:?}", r.worse(&near));
        let beyond = figures(Some(0.0106), 0.811, Some(0.2), 0.01);
        let w = r.worse(&beyond);
        assert_eq!(w.len(), 2, "{w:?}");
        assert!(w[0].starts_with("peak droop") && w[0].contains("beyond its spread of 0.0005"));
        assert!(r.describe().contains("worse beyond the noise"));
        // No spread: any excess is worse, as before.
        let plain =
            Reference::from_figures(figures(Some(0.01), 0.8, Some(0.2), 0.01), None, None).unwrap();
        assert_eq!(plain.worse(&near).len(), 2);
        assert!(!plain.describe().contains("beyond the noise"));
        assert_eq!(plain.with_spread([f64::NAN, -1.0]).spread, [0.0, 0.0]);
    }

    #[test]
    fn a_reference_without_a_load_step_and_a_bad_budget_are_errors_naming_the_key() {
        let e = Reference::from_figures(figures(None, 0.8, Some(0.2), 0.1), Some(1.0), None)
            .unwrap_err();
        assert!(e.to_string().contains("peak droop"), "{e}");
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let e = check_budget(Some(bad)).unwrap_err().to_string();
            assert!(e.contains(NOISE_FLAG) && e.contains("> 0"), "{e}");
        }
        let r = Reference::from_figures(figures(Some(0.01), 0.8, Some(0.2), 0.1), None, Some(0.05));
        assert_eq!(r.unwrap().max_torque_noise_pu, 0.05);
    }

    #[test]
    fn a_default_drive_that_never_recovers_is_normalized_by_the_window_and_scores_infinity() {
        let never = figures(Some(0.01), 0.8, None, 0.1);
        assert!(Reference::from_figures(never, None, None).is_err());
        let r = Reference::from_figures(never, Some(1.0), None).unwrap();
        assert_eq!(r.norms, [0.01, 0.8, 1.0]);
        assert_eq!(r.objective(&never), f64::INFINITY);
        let good = figures(Some(0.01), 0.8, Some(0.25), 0.1);
        assert!((r.objective(&good) - 2.25).abs() < 1e-12);
        assert!(r.describe().contains("never recovers"));
    }
}
