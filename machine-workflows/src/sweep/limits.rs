//! What set each limit of the sweep: the grid point that ended it, with its oscillation
//! verdict, and the limit the criterion without that verdict (`stable_by_speed`, the
//! `stable` of earlier versions) gives, so a limit the oscillation rule moved names the
//! point that moved it.

use super::{largest, SweepPoint};
use controller_core::AfbMode;

/// One side of a plant's result (without AFB, or the best AFB design) and what set it.
#[derive(Clone, Debug)]
pub struct Limit<'a> {
    /// Plant.
    pub plant: &'a str,
    /// With AFB (the best design) or without.
    pub afb: bool,
    /// Largest stable bandwidth over the side's designs (rad/s).
    pub limit_rad_s: f64,
    /// The same by `stable_by_speed` alone (rad/s).
    pub by_speed_rad_s: f64,
    /// The point that ended the limit: the first point above it, judged unstable, of the
    /// design that reached it (when the two criteria disagree: of the design that reached
    /// `by_speed_rad_s`, the point the oscillation verdict failed). `None` when no point
    /// above the limit exists.
    pub ended_by: Option<&'a SweepPoint>,
}

/// The side's designs on `plant`, each as its points.
fn per_design<'a>(points: &'a [SweepPoint], plant: &str, afb: bool) -> Vec<Vec<&'a SweepPoint>> {
    let mut labels: Vec<&str> = points
        .iter()
        .filter(|p| p.plant == plant && (p.afb.mode != AfbMode::Off) == afb)
        .map(|p| p.design.as_str())
        .collect();
    labels.sort_unstable();
    labels.dedup();
    labels
        .iter()
        .map(|l| {
            points
                .iter()
                .filter(|p| p.design == *l && p.plant == plant)
                .collect()
        })
        .collect()
}

/// The first point of `design` above `bw` that is not stable.
fn first_unstable_above<'a>(design: &[&'a SweepPoint], bw: f64) -> Option<&'a SweepPoint> {
    let mut above: Vec<&SweepPoint> = design
        .iter()
        .copied()
        .filter(|p| p.bandwidth_rad_s > bw && !p.stable)
        .collect();
    above.sort_by(|a, b| a.bandwidth_rad_s.total_cmp(&b.bandwidth_rad_s));
    above.first().copied()
}

/// The limit of one side of one plant ([`Limit`]).
pub fn limit<'a>(points: &'a [SweepPoint], plant: &'a str, afb: bool) -> Limit<'a> {
    let designs = per_design(points, plant, afb);
    let stable = |d: &[&SweepPoint]| largest(d, |p| p.stable);
    let by_speed = |d: &[&SweepPoint]| largest(d, |p| p.stable_by_speed);
    let limit_rad_s = designs.iter().map(|d| stable(d)).fold(0.0, f64::max);
    let by_speed_rad_s = designs.iter().map(|d| by_speed(d)).fold(0.0, f64::max);
    // The design whose limit is reported: the one the old criterion ranked highest when
    // the criteria disagree, else the one that reached the limit.
    let of = designs.iter().find(|d| {
        if by_speed_rad_s > limit_rad_s {
            by_speed(d) == by_speed_rad_s
        } else {
            stable(d) == limit_rad_s
        }
    });
    Limit {
        plant,
        afb,
        limit_rad_s,
        by_speed_rad_s,
        ended_by: of.and_then(|d| first_unstable_above(d, stable(d))),
    }
}

/// The points whose verdict the oscillation rule changed (`stable` ≠ `stable_by_speed`).
pub fn moved(points: &[SweepPoint]) -> Vec<&SweepPoint> {
    points
        .iter()
        .filter(|p| p.error.is_empty() && p.stable != p.stable_by_speed)
        .collect()
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use crate::sweep::AfbDesign;
    use sim_engine::engine::metrics::OscillationKind;

    fn point(bw: f64, stable: bool, by_speed: bool) -> SweepPoint {
        let mut p = SweepPoint::new("p", &AfbDesign::OFF, bw);
        p.stable = stable;
        p.stable_by_speed = by_speed;
        p.oscillation = Some(if stable {
            OscillationKind::Quantization
        } else {
            OscillationKind::LimitCycle
        });
        p
    }

    #[test]
    fn a_limit_the_verdict_moved_names_the_point_that_moved_it() {
        let pts = [
            point(100.0, true, true),
            point(200.0, true, true),
            point(350.0, false, true),
            point(500.0, false, false),
        ];
        let l = limit(&pts, "p", false);
        assert_eq!((l.limit_rad_s, l.by_speed_rad_s), (200.0, 350.0));
        assert_eq!(l.ended_by.unwrap().bandwidth_rad_s, 350.0);
        assert_eq!(moved(&pts).len(), 1);
        // Agreeing criteria: the point that ended it is the first unstable one.
        let same = [point(100.0, true, true), point(200.0, false, false)];
        let l = limit(&same, "p", false);
        assert_eq!((l.limit_rad_s, l.by_speed_rad_s), (100.0, 100.0));
        assert_eq!(l.ended_by.unwrap().bandwidth_rad_s, 200.0);
        assert!(moved(&same).is_empty());
        // No AFB design on the plant: nothing ended it.
        assert!(limit(&same, "p", true).ended_by.is_none());
    }
}
