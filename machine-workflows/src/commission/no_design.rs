//! When no design meets the constraints: `commission.md` holds the identification's place
//! (`identify/`, `identified.toml`), the designs that came closest and how far each misses
//! each constraint, and the command exits with [`sim_engine::error::NO_DESIGN_EXIT_CODE`].

use crate::tune::{Constraints, Judged};
use std::fmt::Write as _;

/// How far `j` misses each constraint of `k`: (constraint, have, need), relative shortfall.
pub(super) fn misses(j: &Judged, k: &Constraints) -> Vec<(String, f64)> {
    let mut out = Vec::new();
    let mut check = |name: &str, have: f64, need: f64, at_least: bool| {
        let short = if at_least {
            (need - have) / need.abs().max(1e-12)
        } else {
            (have - need) / need.abs().max(1e-12)
        };
        if short > 0.0 || have.is_nan() {
            let cmp = if at_least { "≥" } else { "≤" };
            out.push((format!("{name} {have:.3} (needs {cmp} {need})"), short));
        }
    };
    let labels = ["damping, gears engaged", "damping, gears apart"];
    for (label, d) in labels.iter().zip(j.damping) {
        check(label, d, k.min_damping, true);
    }
    check(
        "phase margin [deg]",
        j.margins[0],
        k.min_phase_margin_deg,
        true,
    );
    check("gain margin [dB]", j.margins[1], k.min_gain_margin_db, true);
    check("torque noise [pu]", j.noise_pu, k.max_noise_pu, false);
    out
}

/// The largest relative shortfall of `j` (0 when it meets every constraint above).
fn worst(j: &Judged, k: &Constraints) -> f64 {
    misses(j, k)
        .iter()
        .map(|(_, s)| if s.is_finite() { *s } else { f64::INFINITY })
        .fold(0.0, f64::max)
}

/// The `n` designs of `judged` whose worst shortfall is smallest, closest first.
pub(super) fn closest<'a>(judged: &'a [Judged], k: &Constraints, n: usize) -> Vec<&'a Judged> {
    let mut all: Vec<&Judged> = judged.iter().collect();
    all.sort_by(|a, b| worst(a, k).total_cmp(&worst(b, k)));
    all.truncate(n);
    all
}

/// `commission.md` for a machine on which no design met the constraints; `reason` is the
/// search's own account.
pub(super) fn markdown(config: &str, judged: &[Judged], k: &Constraints, reason: &str) -> String {
    let mut md = format!(
        "# Commissioning of {config}: no design\n\nThe machine was identified \
         ([identify/identify.md](identify/identify.md); the machine file with the measured \
         `[plant]`: `identified.toml`), but no design meets the constraints: {reason}. No \
         drive file is written, and nothing here is to be flashed.\n\nConstraints: smallest \
         damping {}, phase margin {} deg, gain margin {} dB, quantization torque noise at \
         most {} pu RMS (linear model of the loop on the identified machine).\n\n\
         ## The designs that came closest\n\n| bandwidth (rad/s) | design | misses |\n\
         |---|---|---|\n",
        k.min_damping, k.min_phase_margin_deg, k.min_gain_margin_db, k.max_noise_pu
    );
    for j in closest(judged, k, 5) {
        let m: Vec<String> = misses(j, k).into_iter().map(|(s, _)| s).collect();
        let m = if m.is_empty() {
            "none on the linear model; refused in the nonlinear loop".to_string()
        } else {
            m.join("; ")
        };
        let _ = writeln!(
            md,
            "| {} | {} | {m} |",
            j.candidate.bandwidth_rad_s,
            j.candidate.afb.label()
        );
    }
    md
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;
    use crate::tune::Candidate;

    fn judged(damping: f64, pm: f64, noise: f64) -> Judged {
        Judged {
            candidate: Candidate {
                bandwidth_rad_s: 30.0,
                afb: crate::sweep::AfbDesign::OFF,
            },
            damping: [damping, 0.5],
            notch_band_damping: None,
            resonance_band_damping: None,
            margins: [pm, 10.0],
            noise_pu: noise,
            stiffness: 1.0,
            feasible: false,
        }
    }

    /// Each shortfall is named with the value it has and the one it needs, and the design
    /// missing by the least comes first.
    #[test]
    fn the_closest_design_is_the_one_missing_by_the_least() {
        let k = Constraints::default();
        let far = judged(0.07, 40.0, 0.1);
        let near = judged(0.28, 35.0, 0.25);
        let list = [far.clone(), near.clone()];
        let c = closest(&list, &k, 1);
        assert_eq!(c[0].damping, near.damping);
        let m = misses(&near, &k);
        let names: Vec<&str> = m.iter().map(|(s, _)| s.as_str()).collect();
        assert_eq!(names.len(), 3, "{names:?}");
        assert!(names[0].starts_with("damping, gears engaged 0.280 (needs ≥ 0.3)"));
        assert!(names[1].starts_with("phase margin [deg] 35.000 (needs ≥ 40)"));
        assert!(names[2].starts_with("torque noise [pu] 0.250 (needs ≤ 0.2)"));
        assert!((worst(&far, &k) - (0.3 - 0.07) / 0.3).abs() < 1e-12);
    }
}
