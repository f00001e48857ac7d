//! The automatic notch of `commission`: whether the identified resonance is one the loop
//! cannot damp, and if so the notch placed on it.
//!
//! The rule, judged on the linear model of the identified machine (`tune`'s grid at the
//! bandwidths asked for, [`crate::tune::judge_grid`]):
//!
//! 1. No candidate meets the constraints. (If one does, the loop damps every mode by the
//!    constraints' floor and nothing changes.)
//! 2. The velocity loop without AFB that damps the engaged loop best (of the grid's
//!    observer bandwidths) still leaves its least-damped mode below the damping floor, and
//!    that mode's natural frequency is within [`AT_RESONANCE`] of the identified engaged
//!    resonance f_r = f_ar·√(1 + Jl/Jm): the velocity loop excites the resonance, and no
//!    AFB design mends that by the constraints (step 1). (A failure elsewhere, margins or
//!    noise or a slow mode, is not a notch's to fix. The AFB designs are not asked where
//!    their least-damped mode is: AFB moves the modes, so theirs need not be the
//!    resonance's.)
//! 3. The notch fits below the current rate's Nyquist frequency: f_r·(1 + [`WIDTH_SHARE`])
//!    below [`MAX_OF_NYQUIST`] of it.
//!
//! The notch is then centred on f_r, [`WIDTH_SHARE`]·f_r wide (−3 dB) and [`DEPTH_DB`]
//! deep, and the drive is tuned again with it: the loop gives up acting at the resonance,
//! which keeps the machine's own damping (`tune` judges the poles in the notch's band
//! against that, [`crate::tune::notch_band`]).

use crate::linear::for_gains;
use crate::tune::{Constraints, Judged};
use controller_core::NotchConfig;
use plant_host::analysis::Gears;
use serde::Serialize;
use sim_engine::config::RunConfig;
use sim_engine::engine::runner::regulator_gains;
use sim_engine::error::Result;

/// How far (a fraction of f_r) the least-damped mode may lie from the identified
/// resonance and still be it. The loop that excites a resonance also moves it (its gain
/// acts as a stiffness on the motor): on `tests/commission_notch.rs`'s machine the
/// unstable mode of the 300 rad/s loop sits 14 % above the identified 284.6 Hz. The
/// drive's own modes (velocity loop, observer) lie well below such a resonance.
pub const AT_RESONANCE: f64 = 0.25;
/// −3 dB width of the notch as a share of its centre. Its own poles then have a damping
/// of about half this (0.1), and its phase lag at a fifth of the centre stays below 3°.
pub const WIDTH_SHARE: f64 = 0.2;
/// Attenuation at the centre \[dB\]: a resonance peak of 1/(2ζ) ≈ 25 dB at ζ = 0.03 is
/// brought below the loop gain's level next to it.
pub const DEPTH_DB: f64 = 30.0;
/// Highest upper edge of the notch as a share of the current rate's Nyquist frequency.
pub const MAX_OF_NYQUIST: f64 = 0.8;

/// The figures of the best candidate without a notch, which decided.
#[derive(Clone, Debug, Serialize)]
pub struct Trigger {
    /// Candidates judged on the linear model without a notch.
    pub judged: usize,
    /// How many of them met the constraints.
    pub feasible: usize,
    /// The identified engaged resonance \[Hz\].
    pub resonance_hz: f64,
    /// The candidate without AFB with the highest smallest damping (engaged): its
    /// bandwidth \[rad/s\].
    pub bandwidth_rad_s: f64,
    /// Its AFB, as `tune` labels it.
    pub afb: String,
    /// Its smallest damping, engaged, and the natural frequency of that mode \[Hz\].
    pub least_damped: (f64, f64),
    /// Its velocity-loop phase margin \[deg\] and gain margin \[dB\].
    pub margins: [f64; 2],
    /// The damping floor of the constraints.
    pub min_damping: f64,
}

/// Whether a notch was placed, why, and where.
#[derive(Clone, Debug, Serialize)]
pub struct Decision {
    /// The notch placed (`None`: none).
    pub notch: Option<NotchConfig>,
    /// The reason, in words, from the figures.
    pub reason: String,
    /// The figures of the best candidate without a notch (when none met the constraints).
    pub trigger: Option<Trigger>,
}

impl Decision {
    fn none(reason: String, trigger: Option<Trigger>) -> Self {
        Self {
            notch: None,
            reason,
            trigger,
        }
    }
}

/// Decides on the notch (module docs) for the identified machine's `fig6` run and its
/// candidates `judged`, with the identified engaged resonance `resonance_hz`.
pub fn decide(
    fig6: &RunConfig,
    resonance_hz: f64,
    judged: &[Judged],
    k: &Constraints,
) -> Result<Decision> {
    if fig6.drive.notch.is_some() {
        return Ok(Decision::none(
            "the drive has a notch already ([drive.notch])".into(),
            None,
        ));
    }
    let feasible = judged.iter().filter(|j| j.feasible).count();
    if feasible > 0 {
        return Ok(Decision::none(
            format!(
                "{feasible} of the {} candidates meet the constraints without a notch",
                judged.len()
            ),
            None,
        ));
    }
    let Some(best) = judged
        .iter()
        .filter(|j| j.candidate.afb.mode == controller_core::AfbMode::Off)
        .max_by(|a, b| a.damping[0].total_cmp(&b.damping[0]))
    else {
        return Ok(Decision::none(
            "no candidate without AFB could be modelled".into(),
            None,
        ));
    };
    let mut cfg = fig6.clone();
    best.candidate.apply(&mut cfg.drive);
    let model = for_gains(&cfg, &regulator_gains(&cfg)?, Gears::Engaged)?;
    let (zeta, mode_hz) = model.least_damped();
    let trigger = Trigger {
        judged: judged.len(),
        feasible,
        resonance_hz,
        bandwidth_rad_s: best.candidate.bandwidth_rad_s,
        afb: best.candidate.afb.label(),
        least_damped: (zeta, mode_hz),
        margins: best.margins,
        min_damping: k.min_damping,
    };
    let nyquist = 0.5 * f64::from(fig6.drive.current_rate_hz);
    let (notch, reason) = verdict(&trigger, nyquist);
    Ok(Decision {
        notch,
        reason,
        trigger: Some(trigger),
    })
}

/// Steps 2 and 3 of the rule (module docs) on the best candidate's figures.
fn verdict(t: &Trigger, nyquist_hz: f64) -> (Option<NotchConfig>, String) {
    let (zeta, mode_hz) = t.least_damped;
    let f_r = t.resonance_hz;
    let floor = t.min_damping;
    if zeta >= floor {
        let why = format!(
            "no candidate meets the constraints, but the best damped one without AFB reaches ζ = \
             {zeta:.3} ≥ {floor:.2}: its margins or noise fail, which a notch does not mend"
        );
        return (None, why);
    }
    if (mode_hz / f_r - 1.0).abs() > AT_RESONANCE {
        let why = format!(
            "no candidate meets the constraints; the best damped one without AFB has its least-damped mode \
             (ζ = {zeta:.3}) at {mode_hz:.1} Hz, not at the identified resonance {f_r:.1} Hz"
        );
        return (None, why);
    }
    if f_r * (1.0 + WIDTH_SHARE) >= MAX_OF_NYQUIST * nyquist_hz {
        let why = format!(
            "the resonance the loop cannot damp ({f_r:.1} Hz) is too close to the current \
             rate's Nyquist frequency ({nyquist_hz:.0} Hz) for a notch"
        );
        return (None, why);
    }
    let notch = NotchConfig {
        centre_hz: f_r as f32,
        width_hz: (WIDTH_SHARE * f_r) as f32,
        depth_db: DEPTH_DB as f32,
    };
    let why = format!(
        "none of the {} candidates meets the constraints; the best damped one without AFB ({} rad/s, {}) \
         leaves its least-damped mode at ζ = {zeta:.3} < {floor:.2}, at {mode_hz:.1} Hz: the \
         identified resonance ({f_r:.1} Hz), which the loop cannot damp",
        t.judged, t.bandwidth_rad_s, t.afb
    );
    (Some(notch), why)
}
