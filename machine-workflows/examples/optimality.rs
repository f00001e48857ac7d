//! How close `tune`'s choice comes to the best design of a grid run in the nonlinear loop.
//!
//! ```text
//! cargo run --release -p machine-workflows --example optimality -- [MACHINE ...]
//! ```
//! (machines by name or path; by default `table1` and `dyno`).
//!
//! For each machine: every [`STRIDE`]-th candidate of `tune`'s grid (`[tune]` of
//! `configs/grids.toml`, every bandwidth, with AFB and without) runs `fig6` in the nonlinear
//! loop and is scored by `tune`'s objective against the machine file's own drive. The grid's
//! best is the lowest J among the designs within `tune`'s budgets: velocity-loop margins
//! (phase ≥ 40°, gain ≥ 6 dB, on the linear model), torque noise within the budget, stable
//! and no fault; among those, the ones no worse than the file's own drive in peak droop and
//! peak shaft torque come first, as in `tune` (when there are any). Then `tune
//! --max-bandwidth` runs as the command does (with AFB and without) and its chosen design is
//! compared.
//!
//! The criteria, fixed before the runs: at least [`MIN_DESIGNS`] designs run in the loop;
//! the chosen design's J is at most (1 + [`TOLERANCE`]) × the grid's best; and the chosen
//! kind (with AFB or without) is the kind of the grid's best. The example prints one line
//! per machine and exits 1 when a criterion fails on any of them.

use machine_workflows::tune::{
    self,
    objective::{Reference, Score},
    Candidate, Constraints, Judged,
};
use rayon::prelude::*;
use std::process::ExitCode;

/// Every this many candidates of `tune`'s grid run in the loop.
const STRIDE: usize = 4;
/// The fewest designs the grid must run in the loop.
const MIN_DESIGNS: usize = 200;
/// How far above the grid's best the chosen J may be (a fraction).
const TOLERANCE: f64 = 0.05;

/// One machine's result.
struct Outcome {
    run: usize,
    within: usize,
    best: (Judged, Score),
    chosen: (Candidate, f64, bool),
}

fn within_margins(j: &Judged, k: &Constraints) -> bool {
    j.margins[0] >= k.min_phase_margin_deg && j.margins[1] >= k.min_gain_margin_db
}

fn grid_and_choice(config: &str) -> sim_engine::error::Result<Outcome> {
    let k = Constraints::default();
    let grid = sim_engine::config::tune_grid()?;
    let all = tune::candidates(&grid, &grid.bandwidths_rad_s);
    let sample: Vec<Candidate> = all.iter().step_by(STRIDE).copied().collect();
    let judged = tune::judge_grid(config, &sample, &k)?;
    let fig6 = sim_engine::resolve("fig6", Some(config), &[])?;
    let reference = Reference::of(&fig6, k.max_torque_noise_pu)?;
    let runs: Vec<(Judged, Score)> = judged
        .par_iter()
        .filter_map(|j| {
            let s = Score::run(&fig6, &reference, &j.candidate).ok()?;
            Some((j.clone(), s))
        })
        .collect();
    let within: Vec<&(Judged, Score)> = runs
        .iter()
        .filter(|(j, s)| s.within_budget && within_margins(j, &k))
        .collect();
    let any_no_worse = within.iter().any(|(_, s)| s.no_worse);
    let best = within
        .iter()
        .filter(|(_, s)| s.no_worse || !any_no_worse)
        .min_by(|a, b| a.1.objective.total_cmp(&b.1.objective))
        .map(|(j, s)| (j.clone(), *s))
        .ok_or_else(|| {
            sim_engine::error::HarnessError::NoDesign(format!(
                "{config}: none of the {} designs run is within the budgets",
                runs.len()
            ))
        })?;
    let pair = tune::pair::design_both(config, None, &k)?;
    let (chosen, _) = pair.chosen();
    let r = &chosen.result;
    Ok(Outcome {
        run: runs.len(),
        within: within.len(),
        best,
        chosen: (r.design.candidate, r.score.objective, pair.afb_chosen()),
    })
}

fn kind(afb: bool) -> &'static str {
    if afb {
        "with AFB"
    } else {
        "without AFB"
    }
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let machines = if args.is_empty() {
        vec!["table1".to_string(), "dyno".to_string()]
    } else {
        args
    };
    let mut failed = false;
    for m in &machines {
        match grid_and_choice(m) {
            Ok(o) => {
                let (bj, bs) = &o.best;
                let bc = &bj.candidate;
                let (cc, cj, cafb) = &o.chosen;
                let best_afb = bc.afb.mode != controller_core::AfbMode::Off;
                let ratio = cj / bs.objective;
                let ok = o.run >= MIN_DESIGNS && ratio <= 1.0 + TOLERANCE && best_afb == *cafb;
                failed |= !ok;
                println!(
                    "{m}: {} designs run in the loop, {} within the budgets; grid's best J \
                     {:.3} ({} rad/s, {}, {}, no worse than the file's drive: {}; smallest \
                     damping {:.3} engaged, {:.3} apart, on the linear model: {}); tune chose \
                     J {cj:.3} ({} rad/s, {}, {}): {:.1} % above the best -> {}",
                    o.run,
                    o.within,
                    bs.objective,
                    bc.bandwidth_rad_s,
                    bc.afb.label(),
                    kind(best_afb),
                    bs.no_worse,
                    bj.damping[0],
                    bj.damping[1],
                    if bj.feasible {
                        "meets every constraint of tune"
                    } else {
                        "misses a constraint of tune"
                    },
                    cc.bandwidth_rad_s,
                    cc.afb.label(),
                    kind(*cafb),
                    100.0 * (ratio - 1.0),
                    if ok { "within the criteria" } else { "FAILED" }
                );
            }
            Err(e) => {
                failed = true;
                println!("{m}: {e}");
            }
        }
    }
    if failed {
        ExitCode::FAILURE
    } else {
        ExitCode::SUCCESS
    }
}
