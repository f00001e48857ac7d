//! Why `tune` stops where it does: per velocity bandwidth of the grid, how many candidates
//! met each constraint on the linear model, the best damping and stiffness there, and how
//! many feasible ones the nonlinear loop refused.

use super::{Constraints, Judged, Verification};
use serde::Serialize;
use std::fmt::Write as _;

/// The candidates of one velocity bandwidth.
#[derive(Debug, Clone, Serialize)]
pub struct AtBandwidth {
    /// Velocity bandwidth \[rad/s\].
    pub bandwidth_rad_s: f64,
    /// Candidates judged (their drive designed).
    pub judged: usize,
    /// Meeting the damping floor, gears engaged and apart.
    pub damping_ok: usize,
    /// Meeting both velocity-loop margins.
    pub margins_ok: usize,
    /// Meeting the quantization-noise ceiling.
    pub noise_ok: usize,
    /// Meeting all of them.
    pub feasible: usize,
    /// Feasible but refused in the nonlinear loop (of those tried before the design).
    pub refused: usize,
    /// Largest smallest-damping (engaged) over the candidates that meet the margins and
    /// the noise ceiling: what the damping floor is compared with.
    pub best_damping: f64,
    /// The stiffest feasible candidate's weakest stiffness over ω_v … 10·ω_v (0 if none).
    pub best_feasible_stiffness: f64,
}

/// The table over `judged` (every candidate designed) and the refused designs.
#[must_use]
pub fn per_bandwidth(
    judged: &[Judged],
    refused: &[(Judged, Vec<Verification>)],
    k: &Constraints,
) -> Vec<AtBandwidth> {
    let mut bws: Vec<f64> = judged.iter().map(|j| j.candidate.bandwidth_rad_s).collect();
    bws.sort_by(f64::total_cmp);
    bws.dedup();
    bws.into_iter()
        .map(|bw| {
            let at: Vec<&Judged> = judged
                .iter()
                .filter(|j| j.candidate.bandwidth_rad_s == bw)
                .collect();
            let damping = |j: &Judged| j.damping.iter().all(|d| *d >= k.min_damping);
            let margins = |j: &Judged| {
                j.margins[0] >= k.min_phase_margin_deg && j.margins[1] >= k.min_gain_margin_db
            };
            let noise = |j: &Judged| j.noise_pu <= k.max_noise_pu;
            let count = |f: &dyn Fn(&Judged) -> bool| at.iter().filter(|j| f(j)).count();
            AtBandwidth {
                bandwidth_rad_s: bw,
                judged: at.len(),
                damping_ok: count(&damping),
                margins_ok: count(&margins),
                noise_ok: count(&noise),
                feasible: count(&|j| j.feasible),
                refused: refused
                    .iter()
                    .filter(|(j, _)| j.candidate.bandwidth_rad_s == bw)
                    .count(),
                best_damping: at
                    .iter()
                    .filter(|j| margins(j) && noise(j))
                    .map(|j| j.damping[0])
                    .fold(f64::NEG_INFINITY, f64::max),
                best_feasible_stiffness: at
                    .iter()
                    .filter(|j| j.feasible)
                    .map(|j| j.stiffness)
                    .fold(0.0, f64::max),
            }
        })
        .collect()
}

/// The table as markdown.
#[must_use]
pub fn markdown(rows: &[AtBandwidth], k: &Constraints) -> String {
    let mut s = format!(
        "## Per velocity bandwidth\n\n| ω_v (rad/s) | judged | damping ≥ {} | PM ≥ {}° and GM ≥ {} dB \
         | noise ≤ {} pu | feasible | refused in the loop | best damping (margins and noise met) \
         | stiffest feasible (pu per pu·s) |\n|---|---|---|---|---|---|---|---|---|\n",
        k.min_damping, k.min_phase_margin_deg, k.min_gain_margin_db, k.max_noise_pu
    );
    for r in rows {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {:.4e} |",
            r.bandwidth_rad_s,
            r.judged,
            r.damping_ok,
            r.margins_ok,
            r.noise_ok,
            r.feasible,
            r.refused,
            if r.best_damping.is_finite() {
                format!("{:.3}", r.best_damping)
            } else {
                "(none)".into()
            },
            r.best_feasible_stiffness
        );
    }
    s
}
