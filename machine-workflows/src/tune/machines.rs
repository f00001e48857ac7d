//! `tune` on the shipped machines, for `reproduce`: each machine tuned with AFB and without
//! it by the same constraints ([`super::pair`]), both designs' files written as `tune`
//! writes them, and both designs run on the machine's [`LOOP_SCENARIO`] (a move with a
//! load step) and judged by [`pair::CRITERION`].

use super::pair::{self, LoopRun, Pair};
use super::{write_design, Constraints, Judged};
use rayon::prelude::*;
use serde::Serialize;
use sim_engine::config::resolve;
use sim_engine::error::{HarnessError, Result};
use std::path::Path;
use std::time::Instant;

/// The machines `reproduce` tunes: Table 1, the printing-press stand and the dyno.
pub const MACHINES: [&str; 3] = ["table1", "printing-press", "dyno"];

/// The run both designs are compared on: a move with a load step.
pub const LOOP_SCENARIO: &str = "fig6";

/// The velocity bandwidths a machine is tuned at.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum Bandwidth {
    /// The highest of the grid that meets the constraints (`tune --max-bandwidth`).
    Max,
    /// The machine's own `drive.velocity_bandwidth_rad_s` (`tune --target-bandwidth`).
    FromConfig,
}

/// One machine tuned with and without AFB, and both designs in the loop.
#[derive(Clone, Debug, Serialize)]
pub struct MachineTune {
    /// The config's name.
    pub machine: String,
    /// How the bandwidth was chosen.
    pub bandwidth: Bandwidth,
    /// The bandwidth asked for \[rad/s\] (`None`: the highest that meets the constraints).
    pub target_bandwidth_rad_s: Option<f64>,
    /// The AFB design on the linear model.
    pub with: Judged,
    /// Its damping fitted to the nonlinear loop's step responses (`tune`'s step 4).
    pub with_fitted_damping: Option<f64>,
    /// The no-AFB design by the same constraints, on the linear model.
    pub without: Judged,
    /// Candidates judged on the linear model: with AFB, without.
    pub judged: [usize; 2],
    /// Both designs on [`LOOP_SCENARIO`]: with AFB, without.
    pub runs: [LoopRun; 2],
    /// [`pair::afb_passes`].
    pub passed: bool,
    /// The objective ([`super::objective`]) of the designs: with AFB, without.
    pub objective: [f64; 2],
    /// The design the objective chooses: "with AFB" or "without AFB".
    pub chosen: &'static str,
    /// Wall time of this machine's tuning and runs \[s\] (the machines run in parallel).
    pub wall_s: f64,
}

/// Tunes `machine` and runs both designs; returns the designs too, for their files.
pub fn tune_machine(
    machine: &str,
    bandwidth: Bandwidth,
    constraints: &Constraints,
) -> Result<(MachineTune, Pair)> {
    let t0 = Instant::now();
    let base = resolve(LOOP_SCENARIO, Some(machine), &[])?;
    let target = match bandwidth {
        Bandwidth::Max => None,
        Bandwidth::FromConfig => Some(f64::from(base.drive.velocity_bandwidth_rad_s)),
    };
    let pair = pair::design_both(machine, target, constraints)?;
    let (w, wo) = (&pair.with.result, &pair.without.result);
    let runs = [
        LoopRun::run(base.clone(), "tuned with AFB", &w.design.candidate)?,
        LoopRun::run(base, "tuned without AFB", &wo.design.candidate)?,
    ];
    let [a, b] = &runs;
    let passed = pair::afb_passes(a, b);
    let t = MachineTune {
        machine: machine.into(),
        bandwidth,
        target_bandwidth_rad_s: target,
        with: w.design.clone(),
        with_fitted_damping: w.step.as_ref().map(|f| f.fitted.damping()),
        without: wo.design.clone(),
        judged: [w.judged, wo.judged],
        runs,
        passed,
        objective: [w.score.objective, wo.score.objective],
        chosen: if pair.afb_chosen() {
            "with AFB"
        } else {
            "without AFB"
        },
        wall_s: t0.elapsed().as_secs_f64(),
    };
    Ok((t, pair))
}

/// Tunes `machines` in parallel and writes, into `dir`, `<machine>/` (the AFB design's
/// `tune.md`, `tune.json`, `drive.toml` and figures), `<machine>/no-afb/`
/// (the same for the no-AFB design) and `machines.json` (every [`MachineTune`]).
pub fn tune_into(
    dir: &Path,
    machines: &[&str],
    bandwidth: Bandwidth,
    constraints: &Constraints,
) -> Result<Vec<MachineTune>> {
    let done: Result<Vec<(MachineTune, Pair)>> = machines
        .par_iter()
        .map(|m| tune_machine(m, bandwidth, constraints))
        .collect();
    let mut found = Vec::new();
    for (t, pair) in done? {
        let mdir = dir.join(&t.machine);
        let no_afb = mdir.join("no-afb");
        std::fs::create_dir_all(&no_afb).map_err(|e| HarnessError::io(&no_afb, e))?;
        write_design(&mdir, &pair.with)?;
        write_design(&no_afb, &pair.without)?;
        found.push(t);
    }
    let path = dir.join("machines.json");
    let json = serde_json::to_string_pretty(&found).map_err(|e| HarnessError::io(&path, e))?;
    std::fs::write(&path, json + "\n").map_err(|e| HarnessError::io(&path, e))?;
    Ok(found)
}
