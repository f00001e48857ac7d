//! The nonlinear verification of a design (module docs of [`super`], step 3): `fig6`, a
//! 150 % shock and the sweep's probe, each stable and without a fault, the probe quiet too.
//! [`retarget`] puts another scored candidate in place of a design, verified the same way.

use super::{design_from, judge_grid, Candidate, Constraints, Tuned};
use serde::Serialize;
use sim_engine::config::{resolve, RunConfig};
use sim_engine::engine::runner::run_scenario;
use sim_engine::error::Result;

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

impl Verification {
    /// Why the run fails (`None` when it passes): the fault, the instability with its
    /// oscillation, or the probe's chatter against the sweep's quiet threshold.
    #[must_use]
    pub fn failure(&self) -> Option<String> {
        if self.passed {
            return None;
        }
        let mut why = Vec::new();
        if self.faulted {
            why.push(match self.oscillation {
                sim_engine::engine::metrics::OscillationKind::Tripped { fault } => {
                    format!("latched `{fault}`")
                }
                other => format!("faulted ({})", other.word()),
            });
        } else if !self.stable {
            why.push(format!(
                "unstable ({} at {:.1} Hz)",
                self.oscillation.word(),
                self.oscillation_freq_hz
            ));
        }
        if self.scenario == "sweep" && self.limit_cycle_torque_pu >= crate::sweep::QUIET_TORQUE_PU {
            why.push(format!(
                "torque chatter {:.3} pu (quiet below {} pu)",
                self.limit_cycle_torque_pu,
                crate::sweep::QUIET_TORQUE_PU
            ));
        }
        Some(format!("{}: {}", self.scenario, why.join(", ")))
    }
}

/// Scenarios a design must pass: a move with a load step, a 150 % shock, and the sweep's
/// probe (ramp, load on and off, unloaded at speed), on which it must also be quiet.
pub const VERIFY: [&str; 3] = ["fig6", "shock", "sweep"];

/// The scenarios of [`VERIFY`] on `config`, each read once.
pub(super) fn bases(config: &str) -> Result<Vec<RunConfig>> {
    VERIFY
        .iter()
        .map(|s| resolve(s, Some(config), &[]))
        .collect()
}

pub(super) fn verify(bases: &[RunConfig], c: &Candidate) -> Result<Vec<Verification>> {
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

/// `t` with its design replaced by `c` (one of the candidates `t`'s search scored), judged,
/// scored and verified on `config` as [`design_from`] does, its damping measured; `t`'s
/// record of the search (candidates judged, scored and refused, per bandwidth) kept. An
/// error when `c` leaves the budgets or fails its verification.
pub fn retarget(config: &str, t: &Tuned, c: &Candidate, k: &Constraints) -> Result<Tuned> {
    let judged = judge_grid(config, std::slice::from_ref(c), k)?;
    let mut new = design_from(config, judged, k)?;
    let (r, n) = (&t.result, &mut new.result);
    n.config.clone_from(&r.config);
    n.judged = r.judged;
    n.feasible = r.feasible;
    n.refused.clone_from(&r.refused);
    n.scored.clone_from(&r.scored);
    n.per_bandwidth.clone_from(&r.per_bandwidth);
    Ok(new)
}
