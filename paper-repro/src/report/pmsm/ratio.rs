//! The shaft-ripple ratio (with AFB / without) on the two motors: the pairs' table, the
//! criterion fixed before the runs ([`PMSM_RATIO_TOLERANCE`]), and the test of one
//! hypothesis for a difference: that it is the encoder's quantization limit cycle, not the
//! current loop ([`FINE_ENCODER_CPR`]).

use super::{PairRuns, MACHINES, PAIRS};
use crate::report::section::{pct, verdict};
use crate::report::step_timing::OFFSETS_S;
use crate::report::PMSM_RATIO_TOLERANCE;
use sim_engine::engine::metrics::Metrics;
use sim_engine::run::fmt_opt;
use std::fmt::Write as _;

/// The encoder of the hypothesis test: 2^20 counts per turn, where the position loop's
/// quantization no longer sets the torque ripple (Table 1's encoder has 4,096).
pub const FINE_ENCODER_CPR: u32 = 1 << 20;

/// The setting that gives both machine files the fine encoder (the drive's count follows
/// the plant's, as every machine key does).
pub(super) fn fine_sets() -> Vec<String> {
    vec![format!("plant.encoder_cpr={FINE_ENCODER_CPR}")]
}

/// The hypothesis test's paragraph and whether the hypothesis holds: the PMSM's ratio is
/// within [`PMSM_RATIO_TOLERANCE`] of the DC model's on every pair with the fine encoder.
pub(super) fn fine_text(fine: &[PairRuns]) -> (String, bool) {
    let (lines, verdicts) = ratio_lines(fine);
    let holds = !verdicts.is_empty() && verdicts.iter().all(|(_, ok)| *ok);
    let text = format!(
        "A hypothesis for the difference, with its criterion fixed before its runs: it is the \
         encoder's quantization limit cycle (`fig6` ends in the verdict `quantization` on both \
         motors), not the current loop. Test: the same pairs at the same timings with a \
         {FINE_ENCODER_CPR}-count encoder on both machine files (`--set \
         plant.encoder_cpr={FINE_ENCODER_CPR}`), where quantization no longer sets the ripple; \
         the hypothesis holds if the PMSM's ratio is then within {} of the DC model's on every \
         pair. With the fine encoder:\n\n{lines}\nThe hypothesis {}.\n",
        pct(PMSM_RATIO_TOLERANCE),
        if holds {
            "holds: without the limit cycle the PMSM's current loop keeps the DC model's AFB \
             ratio, and the difference at Table 1's encoder is the limit cycle's, which moves \
             with the smallest change of the loop (see the spread over the step's timing)"
        } else {
            "is refuted: the motors' ratios differ without the limit cycle too"
        }
    );
    (text, holds)
}

/// Shaft-torque ripple with AFB / without.
pub(super) fn ratio((a, b): &(Metrics, Metrics)) -> f64 {
    a.shaft_torque_ripple_rms_pu / b.shaft_torque_ripple_rms_pu.max(1e-12)
}

/// Whether the PMSM's ratio is within [`PMSM_RATIO_TOLERANCE`] of the DC model's (false for
/// a NaN).
pub fn within_tolerance(pmsm: f64, dc: f64) -> bool {
    (pmsm / dc - 1.0).abs() <= PMSM_RATIO_TOLERANCE
}

/// One line per pair and machine: the DC section's figures and criterion, and the ratio's
/// spread over the step's timing.
pub(super) fn pairs_table(pairs: &[PairRuns]) -> String {
    let mut t = String::from(
        "| pair | machine | gains bit-identical | stable with / without | overshoot (pu) | \
         shaft ripple with / without (pu) | ratio | ratio over the timings: median, range | \
         DC section's criterion |\n|---|---|---|---|---|---|---|---|---|\n",
    );
    for p in pairs {
        let Some((a, b)) = p.at_scenario() else {
            continue;
        };
        let s = p.spread();
        let failed = p.failures();
        let _ = writeln!(
            t,
            "| `{}` | {} | {} | {} / {} | {} | {:.4} / {:.4} | {:.3} | {:.3}, {:.3} to {:.3} | \
             {}{} |",
            p.scenario,
            p.machine,
            if p.same_gains { "yes" } else { "**no**" },
            a.stable,
            b.stable,
            fmt_opt(a.overshoot_pu),
            a.shaft_torque_ripple_rms_pu,
            b.shaft_torque_ripple_rms_pu,
            s.at_scenario,
            s.median,
            s.min,
            s.max,
            verdict(failed.is_empty()),
            if failed.is_empty() {
                String::new()
            } else {
                format!(" ({})", failed.join(", "))
            }
        );
    }
    t
}

/// The pair on the DC machine and on the PMSM.
pub(super) fn both<'a>(
    pairs: &'a [PairRuns],
    scenario: &str,
) -> Option<(&'a PairRuns, &'a PairRuns)> {
    let on = |machine: &str| {
        pairs
            .iter()
            .find(|p| p.scenario == scenario && p.machine == machine)
    };
    Some((on(MACHINES.first()?)?, on(MACHINES.get(1)?)?))
}

/// The PMSM's ratio against the DC model's, per pair: the criterion at the scenario's
/// timing, then the two spreads over the step's timing and the criterion offset by offset.
pub(super) fn ratio_lines(pairs: &[PairRuns]) -> (String, Vec<(&'static str, bool)>) {
    let mut text = String::new();
    let mut verdicts = Vec::new();
    for (scenario, _) in PAIRS {
        let Some((dc, pm)) = both(pairs, scenario) else {
            continue;
        };
        let ok = within_tolerance(pm.ratio(), dc.ratio());
        let (sd, sp) = (dc.spread(), pm.spread());
        let overlap = sp.min <= sd.max && sd.min <= sp.max;
        let pointwise = dc
            .by_offset
            .iter()
            .zip(&pm.by_offset)
            .filter(|(d, p)| within_tolerance(ratio(p), ratio(d)))
            .count();
        let _ = writeln!(
            text,
            "- `{scenario}`: ratio {:.3} on the PMSM against {:.3} on the DC model, {:+.0} % \
             ({}). Over the step's {} timings the DC ratio spans {:.3} to {:.3}, the PMSM's \
             {:.3} to {:.3} (medians {:.3} and {:.3}, {:+.0} %): the ranges {}. Timing by timing, the PMSM's ratio is within {} \
             of the DC model's at {pointwise} of {}.",
            pm.ratio(),
            dc.ratio(),
            100.0 * (pm.ratio() / dc.ratio() - 1.0),
            verdict(ok),
            OFFSETS_S.len(),
            sd.min,
            sd.max,
            sp.min,
            sp.max,
            sd.median,
            sp.median,
            100.0 * (sp.median / sd.median - 1.0),
            if overlap {
                "overlap, so part of the difference is the step's timing"
            } else {
                "do not overlap: the difference exceeds the figure's own spread"
            },
            pct(PMSM_RATIO_TOLERANCE),
            OFFSETS_S.len(),
        );
        verdicts.push((scenario, ok));
    }
    (text, verdicts)
}

#[cfg(test)]
#[allow(clippy::panic)]
mod tests {
    use super::*;
    use sim_engine::config::resolve;

    /// The hypothesis test changes the encoder and nothing else: the plant's and the
    /// drive's counts per turn both become the fine encoder's, on both motors.
    #[test]
    fn the_fine_encoder_reaches_the_plant_and_the_drive_of_both_machines() {
        for machine in MACHINES {
            for (scenario, _) in PAIRS {
                let base = resolve(scenario, Some(machine), &[]).unwrap_or_else(|e| panic!("{e}"));
                let fine = resolve(scenario, Some(machine), &fine_sets())
                    .unwrap_or_else(|e| panic!("{e}"));
                assert_eq!(fine.drive.encoder_cpr, FINE_ENCODER_CPR, "{machine}");
                assert_eq!(
                    fine.plant.mechanics.encoder_cpr, FINE_ENCODER_CPR,
                    "{machine}"
                );
                assert_ne!(base.drive.encoder_cpr, FINE_ENCODER_CPR, "{machine}");
                let mut back = fine.clone();
                back.drive.encoder_cpr = base.drive.encoder_cpr;
                back.plant.mechanics.encoder_cpr = base.plant.mechanics.encoder_cpr;
                assert_eq!(back.plant, base.plant, "{machine} {scenario}");
                assert_eq!(back.drive, base.drive, "{machine} {scenario}");
            }
        }
    }
}
