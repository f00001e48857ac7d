//! The designs verified on the machine itself: `fig6` with each design's drive against the
//! plant of the machine file (not the identified one), the first [`ON_MACHINE_PER_KIND`]
//! of each kind tried, ranked by how they qualify there and their objective, and the
//! machine's choice between the two kinds.

use super::OnMachine;
use crate::tune::objective::better_first;
use crate::tune::{self, Constraints};
use sim_engine::config::{resolve, RunConfig};
use sim_engine::error::Result;

/// The drive of the file it was tuned on (`identified.toml`, or `notched.toml` with a notch
/// placed) on the plant of the machine file `config` with `sets`: where the designs are
/// verified, resolved once for all of them.
pub(super) fn verification_base(
    config: &str,
    sets: &[String],
    tuned_on: &str,
) -> Result<RunConfig> {
    let scenario = "fig6";
    let mut cfg = resolve(scenario, Some(tuned_on), &[])?;
    let machine = resolve(scenario, Some(config), sets)?;
    cfg.plant = machine.plant;
    cfg.config_path = machine.config_path;
    Ok(cfg)
}

/// `design`'s drive (`strip_notch`: with its notch taken out) on `base`
/// ([`verification_base`]).
pub(super) fn on_machine(
    base: &RunConfig,
    label: &'static str,
    design: &tune::Candidate,
    strip_notch: bool,
) -> Result<OnMachine> {
    let mut cfg = base.clone();
    if strip_notch {
        cfg.drive.notch = None;
    }
    OnMachine::run(cfg, label, design)
}

/// Designs of each kind tried on the machine: the first this many that the model ranks
/// within its budgets (the design `tune` chose on the model first).
pub const ON_MACHINE_PER_KIND: usize = 4;

/// One design tried on the machine: what the identified model predicted beside what the
/// machine measured.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Tried {
    /// "with AFB" or "without AFB".
    pub kind: &'static str,
    /// The design.
    pub candidate: tune::Candidate,
    /// Its `fig6` figures and objective on the identified model (the prediction).
    pub model: tune::objective::Score,
    /// The same run on the machine.
    pub machine: OnMachine,
    /// Its objective on the machine, against the file's own drive there.
    pub objective: f64,
    /// How it qualifies on the machine (`qualifies`).
    pub qualifies: u8,
    /// It became the design of its kind.
    pub taken: bool,
}

impl Tried {
    /// Its key for [`better_first`]: how it qualifies, then J on the machine.
    fn rank(&self) -> (u8, f64) {
        (self.qualifies, self.objective)
    }
}

/// How a run on the machine qualifies: 2 stable without a fault, within the budgets and no
/// worse than the file's own drive in peak droop and peak shaft torque; 1 only the first
/// part; 0 neither.
fn qualifies(reference: &tune::objective::Reference, r: &OnMachine) -> u8 {
    let within = r.stable && !r.faulted && reference.broken(&r.figures).is_empty();
    u8::from(within) * (1 + u8::from(reference.worse(&r.figures).is_empty()))
}

/// Tries the first [`ON_MACHINE_PER_KIND`] designs of each kind the model ranks within its
/// budgets on the machine `m`, and makes the one the machine ranks first (by
/// [`qualifies`], then the objective there) the design of its kind, if it passes `tune`'s
/// verification on the model (`config`, the file it was tuned on); else the next.
pub(super) fn try_on_machine(
    m: &RunConfig,
    config: &str,
    pair: &mut tune::pair::Pair,
    reference: &tune::objective::Reference,
    constraints: &Constraints,
) -> Result<Vec<Tried>> {
    let mut all = Vec::new();
    for (kind, t) in [
        ("with AFB", &mut pair.with),
        ("without AFB", &mut pair.without),
    ] {
        let r = &t.result;
        let refused = |c: &tune::Candidate| r.refused.iter().any(|(j, _)| j.candidate == *c);
        let mut tried = r
            .scored
            .iter()
            .filter(|s| s.score.within_budget && !refused(&s.candidate))
            .take(ON_MACHINE_PER_KIND)
            .map(|s| {
                let machine = on_machine(m, "tried", &s.candidate, false)?;
                Ok(Tried {
                    kind,
                    candidate: s.candidate,
                    model: s.score,
                    objective: reference.objective(&machine.figures),
                    qualifies: qualifies(reference, &machine),
                    machine,
                    taken: false,
                })
            })
            .collect::<Result<Vec<_>>>()?;
        let mut order: Vec<usize> = (0..tried.len()).collect();
        order.sort_by(|&a, &b| match (tried.get(a), tried.get(b)) {
            (Some(x), Some(y)) => better_first(x.rank(), y.rank()),
            _ => std::cmp::Ordering::Equal,
        });
        for i in order {
            let Some(x) = tried.get_mut(i) else { continue };
            if x.candidate == t.result.design.candidate {
                x.taken = true;
                break;
            }
            if let Ok(new) = tune::retarget(config, t, &x.candidate, constraints) {
                *t = new;
                x.taken = true;
                break;
            }
        }
        all.append(&mut tried);
    }
    Ok(all)
}

/// Both designs of `pair` on the machine `m` (the run [`try_on_machine`] made of a design
/// it took, else a new one), their objectives against `reference`, and the machine's choice
/// between them set on `pair` ([`tune::pair::Pair::on_machine_afb`]): of those stable,
/// without a fault and within the budget there, the better by [`better_first`]; the model's
/// choice only if neither is.
pub(super) fn both_on_machine(
    m: &RunConfig,
    pair: &mut tune::pair::Pair,
    reference: &tune::objective::Reference,
    tried: &[Tried],
) -> Result<([OnMachine; 2], [f64; 2])> {
    let run = |kind: &str, label: &'static str, t: &tune::Tuned| -> Result<OnMachine> {
        let design = &t.result.design.candidate;
        let taken = tried
            .iter()
            .find(|x| x.taken && x.kind == kind && x.candidate == *design);
        Ok(match taken {
            Some(x) => OnMachine {
                design: label,
                ..x.machine.clone()
            },
            None => on_machine(m, label, design, false)?,
        })
    };
    let runs = [
        run("with AFB", "tuned with AFB", &pair.with)?,
        run("without AFB", "tuned without AFB", &pair.without)?,
    ];
    let objective = [
        reference.objective(&runs[0].figures),
        reference.objective(&runs[1].figures),
    ];
    let (a, b) = (
        qualifies(reference, &runs[0]),
        qualifies(reference, &runs[1]),
    );
    pair.on_machine_afb =
        (a > 0 || b > 0).then(|| better_first((a, objective[0]), (b, objective[1])).is_lt());
    Ok((runs, objective))
}

/// The runs set beside the two designs on the machine `m`: with a notch placed
/// (`notched`), the chosen design with the notch taken out; and what AFB itself adds, the
/// AFB design of `pair` (chosen or not) at its gains without its AFB.
pub(super) fn comparisons(
    m: &RunConfig,
    pair: &tune::pair::Pair,
    notched: bool,
) -> Result<(Option<OnMachine>, Option<OnMachine>)> {
    let (chosen_tuned, _) = pair.chosen();
    let chosen_design = &chosen_tuned.result.design.candidate;
    let without_notch = if notched {
        Some(on_machine(
            m,
            "chosen, notch taken out",
            chosen_design,
            true,
        )?)
    } else {
        None
    };
    let same_gains_without_afb = match pair.with.result.design.candidate {
        d if d.afb.mode != controller_core::AfbMode::Off => {
            Some(OnMachine::run_same_gains_without_afb(
                m.clone(),
                "AFB design, same gains without AFB",
                &d,
            )?)
        }
        _ => None,
    };
    Ok((without_notch, same_gains_without_afb))
}

/// The verdict on the chosen design's run `chosen` on the machine, its objective there `j`:
/// whether it beats the file's own drive ([`super::CRITERION`]), and whether it passed
/// (that and, with a notch placed, [`super::NOTCH_CRITERION`] against `without_notch`).
pub(super) fn verdict(
    reference: &tune::objective::Reference,
    chosen: &OnMachine,
    j: f64,
    without_notch: Option<&OnMachine>,
) -> (bool, bool) {
    let beats_the_file =
        qualifies(reference, chosen) == 2 && j < reference.objective(&reference.default_drive);
    let passed = beats_the_file
        && without_notch
            .is_none_or(|n| chosen.shaft_torque_ripple_rms_pu < n.shaft_torque_ripple_rms_pu);
    (beats_the_file, passed)
}
