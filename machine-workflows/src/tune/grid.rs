//! `tune`'s candidates as typed drive settings (a velocity bandwidth and the sweep's
//! [`AfbDesign`]), made from `tune`'s grid (`[tune]` of `configs/grids.toml`,
//! [`sim_engine::config::grids`]).

use crate::sweep::AfbDesign;
use controller_core::{AfbMode, DriveConfig, Estimator, PiInertia};
use serde::Serialize;
use sim_engine::config::Grid;

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
    /// The candidate `drive` is: its velocity bandwidth and its AFB design (the observer at
    /// its own bandwidth).
    #[must_use]
    pub fn of(drive: &DriveConfig) -> Self {
        let afb = &drive.accel_feedback;
        Self {
            bandwidth_rad_s: f64::from(drive.velocity_bandwidth_rad_s),
            afb: AfbDesign {
                mode: afb.mode,
                gain_fraction: afb.gain_fraction,
                filter: afb.filter,
                source: afb.source,
                observer_hz: drive.observer.bandwidth_hz,
            },
        }
    }

    /// Sets this candidate's fields in `drive` (the velocity PI sized for J_total).
    pub fn apply(&self, drive: &mut DriveConfig) {
        drive.velocity_bandwidth_rad_s = self.bandwidth_rad_s as f32;
        drive.velocity_pi_inertia = PiInertia::Total;
        self.afb.apply(drive);
    }
}

/// The candidates of `grid` at the bandwidths `bws`: without AFB, and the error and plain
/// forms over `grid.gains` × `grid.filters` × (observer, differentiation), at every one of
/// `grid.observer_hz`.
#[must_use]
pub fn candidates(grid: &Grid, bws: &[f64]) -> Vec<Candidate> {
    let filters = grid.filter_configs();
    let mut v = Vec::new();
    for &bandwidth_rad_s in bws {
        for &observer_hz in &grid.observer_hz {
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
            for &gain_fraction in &grid.gains {
                for source in [Estimator::Observer, Estimator::Differentiation] {
                    for mode in [AfbMode::Error, AfbMode::Plain] {
                        for &filter in &filters {
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
