//! `tune`'s grid: candidates as typed drive settings (a velocity bandwidth and the sweep's
//! [`AfbDesign`]).

use crate::experiments::sweep::AfbDesign;
use controller_core::{AfbMode, DriveConfig, Estimator, FilterConfig, PiInertia};
use core::f32::consts::FRAC_1_SQRT_2;
use serde::Serialize;

/// Velocity bandwidths tried with `--max-bandwidth` \[rad/s\] (110: a step of about 15 %
/// between Table 1's 94.25 and 120, where Table 1's limit lies).
pub const BANDWIDTHS_RAD_S: [f64; 11] = [
    30.0, 45.0, 60.0, 94.25, 110.0, 120.0, 150.0, 200.0, 250.0, 350.0, 500.0,
];
/// Ka / J_total tried.
pub const GAINS: [f32; 4] = [0.25, 0.5, 1.0, 2.0];
/// AFB filters tried (second order: Q = 1/√2); 25 Hz is the sweep's lowest corner, the
/// best damped at Table 1's higher bandwidths.
pub const FILTERS: [FilterConfig; 7] = [
    FilterConfig::FirstOrder { corner_hz: 25.0 },
    FilterConfig::FirstOrder { corner_hz: 50.0 },
    FilterConfig::FirstOrder { corner_hz: 100.0 },
    FilterConfig::FirstOrder { corner_hz: 200.0 },
    FilterConfig::FirstOrder { corner_hz: 400.0 },
    FilterConfig::SecondOrder {
        corner_hz: 100.0,
        q: FRAC_1_SQRT_2,
    },
    FilterConfig::SecondOrder {
        corner_hz: 200.0,
        q: FRAC_1_SQRT_2,
    },
];
/// Observer bandwidths tried \[Hz\].
pub const OBSERVER_HZ: [f32; 4] = [75.0, 100.0, 150.0, 250.0];

/// One candidate: a velocity bandwidth and an acceleration-feedback design (the sweep's
/// [`AfbDesign`], observer bandwidth included).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Candidate {
    /// Velocity bandwidth \[rad/s\].
    pub bandwidth_rad_s: f64,
    /// The AFB design and the observer bandwidth.
    pub afb: AfbDesign,
}

impl Candidate {
    /// Sets this candidate's fields in `drive` (the velocity PI sized for J_total).
    pub fn apply(&self, drive: &mut DriveConfig) {
        drive.velocity_bandwidth_rad_s = self.bandwidth_rad_s as f32;
        drive.velocity_pi_inertia = PiInertia::Total;
        self.afb.apply(drive);
    }
}

/// The grid for the bandwidths `bws`: without AFB, and the error and plain forms over
/// [`GAINS`] × [`FILTERS`] × (observer, differentiation), at every observer bandwidth.
#[must_use]
pub fn candidates(bws: &[f64]) -> Vec<Candidate> {
    let mut v = Vec::new();
    for &bandwidth_rad_s in bws {
        for observer_hz in OBSERVER_HZ {
            let mut push = |afb: AfbDesign| {
                v.push(Candidate {
                    bandwidth_rad_s,
                    afb,
                })
            };
            push(AfbDesign {
                observer_hz,
                ..AfbDesign::OFF
            });
            for gain_fraction in GAINS {
                for source in [Estimator::Observer, Estimator::Differentiation] {
                    for mode in [AfbMode::Error, AfbMode::Plain] {
                        for filter in FILTERS {
                            push(AfbDesign {
                                mode,
                                gain_fraction,
                                filter,
                                source,
                                observer_hz,
                            });
                        }
                    }
                }
            }
        }
    }
    v
}

/// The candidates of `grid` without acceleration feedback: the "without AFB" design tuned
/// by the same constraints.
#[must_use]
pub fn without_afb(grid: &[Candidate]) -> Vec<Candidate> {
    grid.iter()
        .filter(|c| c.afb.mode == AfbMode::Off)
        .copied()
        .collect()
}
