//! The torque limit's share in the AFB ratios: each pair of the count-interval section
//! (h = 0) runs again with `drive.torque_limit_pu` raised by [`RAISED_FACTOR`], nothing
//! else changed (the overcurrent trip is a multiple of the limit and moves with it). A pair
//! whose runs reach the limit at the machine file's and not at the raised one shows what the
//! limit does to its ratio: while the torque reference sits at the limit, with AFB and
//! without, the motor gives the same torque and AFB has nothing to act on.

use super::count_interval::{Figure, PAIRS};
use super::section::Section;
use rayon::prelude::*;
use sim_engine::config::resolve;
use sim_engine::engine::metrics::Metrics;
use sim_engine::error::Result;
use std::fmt::Write as _;

/// The raised limit, as a multiple of the machine file's.
pub const RAISED_FACTOR: f32 = 2.0;

/// One pair at one limit: with AFB, without, and the limit \[pu\].
struct Runs {
    with: Metrics,
    without: Metrics,
    limit_pu: f32,
}

impl Runs {
    fn ratio(&self, x: Figure) -> f64 {
        x.of(&self.with) / x.of(&self.without).max(1e-12)
    }

    /// Whether either run's torque reference reaches the limit.
    fn saturated(&self) -> bool {
        self.with.torque_saturated_s > 0.0 || self.without.torque_saturated_s > 0.0
    }
}

/// What raising the limit shows for one pair.
#[derive(Debug, PartialEq, Eq)]
enum Reading {
    /// Neither limit is reached: the limit plays no part in the ratio.
    NeverAtLimit,
    /// Reached at the file's limit, not at the raised one: the ratio without the limit.
    LeavesTheLimit,
    /// Reached at both.
    StillAtLimit,
    /// Reached only at the raised limit (a run that overshoots further).
    OnlyRaised,
}

/// The reading from whether the pair's runs reach the limit at the file's limit and at
/// the raised one.
fn reading(at_shipped: bool, at_raised: bool) -> Reading {
    match (at_shipped, at_raised) {
        (false, false) => Reading::NeverAtLimit,
        (true, false) => Reading::LeavesTheLimit,
        (true, true) => Reading::StillAtLimit,
        (false, true) => Reading::OnlyRaised,
    }
}

/// Per pair: the runs at the machine file's limit and at the raised one.
fn run_grid() -> Result<Vec<(Runs, Runs)>> {
    PAIRS
        .par_iter()
        .map(|p| {
            let shipped_pu = resolve(p.scenario, p.config, &[])?.drive.torque_limit_pu;
            let at = |factor: f32| -> Result<Runs> {
                let (with, without) = p.run_with(|mut cfg| {
                    cfg.drive.torque_limit_pu *= factor;
                    cfg
                })?;
                Ok(Runs {
                    with,
                    without,
                    limit_pu: shipped_pu * factor,
                })
            };
            Ok((at(1.0)?, at(RAISED_FACTOR)?))
        })
        .collect()
}

/// The section.
pub fn section() -> Result<Section> {
    let grid = run_grid()?;
    let mut body = format!(
        "Each pair of the count-interval section (h = 0) runs again with \
         `drive.torque_limit_pu` at {RAISED_FACTOR}× its machine file's; nothing else changes \
         (the overcurrent trip, a multiple of the limit, moves with it). Figures with AFB / \
         without (ratio); the time the torque reference spends at its limit, with AFB / \
         without.\n\n\
         | pair | torque limit (pu) | at the limit (s) | shaft ripple (pu) | peak shaft torque \
         (pu) | motor-torque noise (pu RMS) |\n|---|---|---|---|---|---|\n"
    );
    for (p, pair) in PAIRS.iter().zip(&grid) {
        for r in [&pair.0, &pair.1] {
            let f = |x: Figure| {
                format!(
                    "{:.4} / {:.4} ({:.3})",
                    x.of(&r.with),
                    x.of(&r.without),
                    r.ratio(x)
                )
            };
            let _ = writeln!(
                body,
                "| {} | {} | {:.3} / {:.3} | {} | {} | {} |",
                p.label,
                r.limit_pu,
                r.with.torque_saturated_s,
                r.without.torque_saturated_s,
                f(Figure::ShaftRipple),
                f(Figure::PeakShaftTorque),
                f(Figure::TorqueNoise),
            );
        }
    }
    body.push_str("\nReading, per pair:\n\n");
    for (p, (shipped, raised)) in PAIRS.iter().zip(&grid) {
        let ripple = |r: &Runs| r.ratio(Figure::ShaftRipple);
        let line = match reading(shipped.saturated(), raised.saturated()) {
            Reading::NeverAtLimit => format!(
                "reaches neither limit; its shaft-ripple ratio ({:.3}) is the loop's, not the \
                 limit's",
                ripple(shipped)
            ),
            Reading::LeavesTheLimit => format!(
                "at {} pu the torque is at its limit for {:.3} s with AFB and {:.3} s without, \
                 and the shaft-ripple ratio is {:.3}; at {} pu neither run reaches it and the \
                 ratio is {:.3} (the run without AFB rings {:.1}× as much as at {} pu)",
                shipped.limit_pu,
                shipped.with.torque_saturated_s,
                shipped.without.torque_saturated_s,
                ripple(shipped),
                raised.limit_pu,
                ripple(raised),
                raised.without.shaft_torque_ripple_rms_pu
                    / shipped.without.shaft_torque_ripple_rms_pu.max(1e-12),
                shipped.limit_pu,
            ),
            Reading::StillAtLimit | Reading::OnlyRaised => format!(
                "reaches its limit at {} pu ({:.3} / {:.3} s); shaft-ripple ratio {:.3} at {} \
                 pu, {:.3} at {} pu",
                raised.limit_pu,
                raised.with.torque_saturated_s,
                raised.without.torque_saturated_s,
                ripple(shipped),
                shipped.limit_pu,
                ripple(raised),
                raised.limit_pu,
            ),
        };
        let _ = writeln!(body, "- {}: {line}.", p.label);
    }
    body.push_str(
        "\nWhile the torque reference is at its limit the motor gives the limit's torque with \
         AFB and without, so AFB changes nothing the shaft feels until the torque leaves it; \
         a pair that leaves the limit when it is raised shows the ratio AFB reaches on this \
         machine once the drive has the torque to answer the shock. A pair that reaches \
         neither limit and still rings more with AFB does so in its linear range: there the \
         lever is the estimate's count noise (the count-interval section).\n",
    );
    Ok(Section::text(
        "The torque limit: the ratios when the drive has the torque",
        body,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_pair_is_read_by_where_its_runs_meet_the_limit() {
        assert_eq!(reading(false, false), Reading::NeverAtLimit);
        assert_eq!(reading(true, false), Reading::LeavesTheLimit);
        assert_eq!(reading(true, true), Reading::StillAtLimit);
        assert_eq!(reading(false, true), Reading::OnlyRaised);
    }
}
