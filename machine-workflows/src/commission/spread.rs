//! The run-to-run spread of the machine file's own drive on the machine: its `fig6` figures
//! with the load step moved over [`STEP_OFFSETS_S`], so that a design counts as worse than
//! that drive in a figure only beyond the figure's noise ([`super::CRITERION`]).

use crate::tune;
use sim_engine::config::RunConfig;
use sim_engine::error::Result;

/// The offsets of the load step \[s\] at which the machine file's own drive runs `fig6` on
/// the machine, to measure each figure's run-to-run spread (its range over them): every
/// 20 ms within ±0.1 s of the scenario's step (0 is the scenario itself). With lost motion
/// and a quantized encoder the machine at speed is never quite at rest, so the state a step
/// meets depends on when it comes.
pub const STEP_OFFSETS_S: [f64; 11] = [
    -0.10, -0.08, -0.06, -0.04, -0.02, 0.0, 0.02, 0.04, 0.06, 0.08, 0.10,
];

/// The file's own drive's figures over the load step's timing ([`STEP_OFFSETS_S`]).
#[derive(Clone, Debug, serde::Serialize)]
pub struct Spread {
    /// The offsets of the load step \[s\].
    pub offsets_s: Vec<f64>,
    /// The figures of the file's own drive on the machine at each offset.
    pub runs: Vec<tune::objective::Figures>,
    /// The range (largest − smallest) of peak droop \[pu\], peak shaft torque \[pu\],
    /// recovery time \[s\] and torque noise \[pu RMS\] over the offsets.
    pub range: [f64; 4],
}

impl Spread {
    /// Runs `fig6` (the machine file's own drive on the machine) at each offset.
    pub(super) fn measure(fig6: &RunConfig) -> Result<Self> {
        use rayon::prelude::*;
        let runs = STEP_OFFSETS_S
            .par_iter()
            .map(|&dt| tune::objective::Figures::run(&shifted(fig6.clone(), dt)))
            .collect::<Result<Vec<_>>>()?;
        let range = |f: &dyn Fn(&tune::objective::Figures) -> Option<f64>| {
            let v: Vec<f64> = runs
                .iter()
                .filter_map(f)
                .filter(|x| x.is_finite())
                .collect();
            let hi = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            let lo = v.iter().copied().fold(f64::INFINITY, f64::min);
            if hi >= lo {
                hi - lo
            } else {
                0.0
            }
        };
        let range = [
            range(&|f| f.peak_droop_pu),
            range(&|f| f.peak_shaft_torque_pu),
            range(&|f| f.recovery_s),
            range(&|f| Some(f.torque_noise_rms_pu)),
        ];
        Ok(Self {
            offsets_s: STEP_OFFSETS_S.to_vec(),
            runs,
            range,
        })
    }
}

/// `cfg` with its load steps `dt` later (and a profile that starts late, the explicit
/// metric windows and the run's end with them; a ramp that starts at 0 stays). Also the
/// report's step-timing section's shift.
pub fn shifted(mut cfg: RunConfig, dt: f64) -> RunConfig {
    let s = &mut cfg.scenario;
    for l in &mut s.load {
        l.t_s += dt;
    }
    if s.profile.start_s > 0.0 {
        s.profile.start_s += dt;
    }
    for w in [
        &mut s.metrics.ripple_window_s,
        &mut s.metrics.overshoot_window_s,
        &mut s.metrics.stable_window_s,
    ]
    .into_iter()
    .flatten()
    {
        w.iter_mut().for_each(|t| *t += dt);
    }
    s.duration_s += dt;
    cfg
}
