//! The sweep figure.

use super::{SweepPoint, SweepResult, QUIET_TORQUE_PU};
use sim_engine::plot::{Figure, Legend, Panel, Series};

/// The sweep figure: per plant, the torque chatter (unloaded, at speed) against
/// bandwidth without AFB and with the best quiet design, stable and unstable points apart,
/// with the quiet threshold across the grid's `bandwidths`.
pub fn figure(points: &[SweepPoint], results: &[SweepResult], bandwidths: &[f64]) -> Figure {
    let panels = results
        .iter()
        .map(|r| {
            let curve = |label: &str, stable: bool| -> Vec<(f64, f64)> {
                points
                    .iter()
                    .filter(|p| p.plant == r.plant && p.design == label && p.stable == stable)
                    .filter(|p| p.limit_cycle_torque_pu.is_finite())
                    .map(|p| (p.bandwidth_rad_s, p.limit_cycle_torque_pu.max(1e-4)))
                    .collect()
            };
            let best = r.best_quiet_design.as_str();
            let (lo, hi) = bandwidths
                .iter()
                .fold((f64::MAX, 0.0f64), |a, x| (a.0.min(*x), a.1.max(*x)));
            Panel {
                title: format!(
                    "{}: quiet up to {} rad/s without AFB, {} with; stable up to {} / {}",
                    r.plant,
                    r.quiet_without_afb_rad_s,
                    r.quiet_with_afb_rad_s,
                    r.without_afb_rad_s,
                    r.with_afb_rad_s
                ),
                y_label: "torque chatter (pu RMS)".into(),
                series: vec![
                    Series::markers("no AFB, stable", curve("no AFB", true)),
                    Series::markers("no AFB, unstable", curve("no AFB", false)),
                    Series::markers(format!("{best}, stable"), curve(best, true)),
                    Series::markers(format!("{best}, unstable"), curve(best, false)),
                    Series::line(
                        "quiet threshold",
                        vec![(lo, QUIET_TORQUE_PU), (hi, QUIET_TORQUE_PU)],
                    ),
                ],
                log_x: true,
                log_y: true,
                legend: Legend::UpperLeft,
            }
        })
        .collect();
    Figure {
        x_label: "velocity bandwidth (rad/s)".into(),
        panels,
    }
}
