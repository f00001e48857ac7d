//! Fig. 4 (resonance and lost motion) and Fig. 6/7 (trapezoid with a load step), at the
//! Table 1 encoder and interpolated.

use super::facts::fill;
use super::runs::gains_line;
use super::section::{change, verdict, Section};
use super::{get, Runs, SLIGHT_OVERSHOOT_PU};
use sim_engine::engine::metrics::Metrics;
use sim_engine::error::Result;
use sim_engine::run::fmt_opt;

/// Fig. 4: the gears separate and the twist is visible in counts.
pub fn fig4(runs: &Runs) -> Result<Section> {
    let (c4, f4) = get(runs, "fig4")?;
    let cpr = c4.plant.counts_per_rev();
    let gap_counts = c4.plant.mechanics.backlash_deg / 360.0 * f64::from(cpr);
    let m4 = &f4.metrics;
    let ok4 = m4.max_twist_counts >= 0.5 * gap_counts;
    Ok(Section::claim(
        "Fig. 4: resonance and lost motion in a trapezoidal profile",
        &["fig4/trace.png"],
        "A trapezoidal velocity command on the Table 1 plant shows the resonance and the lost \
         motion in the command - motor and motor - load position differences; when the torque \
         is removed the inertias resonate.",
        format!(
            "lost motion {} deg = {gap_counts:.2} counts at {cpr} counts/rev; largest |motor - \
             load| {:.2} counts; largest |command - motor| {:.2} counts; shaft-torque ripple \
             {:.3} pu RMS at about {:.0} Hz after the ramp; stable: {}.",
            c4.plant.mechanics.backlash_deg,
            m4.max_twist_counts,
            m4.max_following_error_counts,
            m4.shaft_torque_ripple_rms_pu,
            m4.shaft_ripple_freq_hz,
            m4.stable
        ),
        format!(
            "{} (criterion: the motor - load difference spans at least half the lost motion, \
             i.e. the gears separate and the twist is visible in counts). The \
             position-difference panel is the paper's Fig. 4 signal set.",
            verdict(ok4)
        ),
    )
    .row(
        "Fig. 4: the gears separate; the twist shows in counts",
        "resonance and lost motion visible in the position differences",
        format!(
            "largest |motor - load| {:.2} counts against {gap_counts:.2} counts of lost motion",
            m4.max_twist_counts
        ),
        verdict(ok4),
    ))
}

/// Fig. 6/7's criterion on a pair, `ma` with AFB and `mo` without at its gains: what fails
/// of "stable by the `stable` metric, an overshoot above 0 and at most
/// [`SLIGHT_OVERSHOOT_PU`], and a shaft-torque ripple with AFB no higher than without"
/// (empty: the pair agrees).
pub(super) fn fig6_failures(ma: &Metrics, mo: &Metrics) -> Vec<&'static str> {
    let slight = ma
        .overshoot_pu
        .is_some_and(|v| v > 0.0 && v <= SLIGHT_OVERSHOOT_PU);
    let calmer = ma.shaft_torque_ripple_rms_pu <= mo.shaft_torque_ripple_rms_pu;
    [
        (!ma.stable, "not stable"),
        (!slight, "overshoot outside the band"),
        (!calmer, "more shaft-torque ripple with AFB than without"),
    ]
    .iter()
    .filter(|(f, _)| *f)
    .map(|(_, t)| *t)
    .collect()
}

/// Fig. 6/7 for one AFB run and its run without AFB at the same gains.
pub fn fig6(runs: &Runs, afb: &str, off: &str, what: &str, figure: &str) -> Result<Section> {
    let (ca, fa) = get(runs, afb)?;
    let (_, fo) = get(runs, off)?;
    let (ma, mo) = (&fa.metrics, &fo.metrics);
    let failed = fig6_failures(ma, mo);
    let ok = failed.is_empty();
    let sens = &ca.plant.sensors;
    let afb_cfg = &ca.drive.accel_feedback;
    let section = Section::claim(
        format!(
            "{} ({what}, {} counts/rev)",
            fill(
                "Fig. 6 and Fig. 7: trapezoid to rated speed with a {load} load step, \
                 acceleration feedback on",
                ca
            ),
            ca.plant.counts_per_rev()
        ),
        &[&format!("{afb}/trace.png"), figure],
        "At 1 s the velocity stops ramping and the load overshoots slightly; the 50 % load \
         step at 1.5 s causes a slight oscillation. The compensation (acceleration feedback) \
         signal is non-zero while accelerating.",
        format!(
            "encoder {} counts/rev x {} interpolation. AFB design: {:?}, Ka = {} x J_total, \
             filter {:?}, source {:?}, rate {:?}. Stable: {}; load overshoot after the ramp {} \
             pu; droop after the step {} pu; settling {} s; torque at its limit for {:.3} s. \
             Shaft-torque ripple after the step {:.4} pu with AFB, {:.4} pu without at the same \
             gains (`{off}`, stable: {}): {}. Motor-torque ripple {:.4} / {:.4} pu. {}.",
            ca.plant.mechanics.encoder_cpr,
            sens.encoder_interpolation,
            afb_cfg.mode,
            afb_cfg.gain_fraction,
            afb_cfg.filter,
            afb_cfg.source,
            afb_cfg.rate,
            ma.stable,
            fmt_opt(ma.overshoot_pu),
            fmt_opt(ma.load_step_droop_pu),
            fmt_opt(ma.settling_s),
            ma.torque_saturated_s,
            ma.shaft_torque_ripple_rms_pu,
            mo.shaft_torque_ripple_rms_pu,
            mo.stable,
            change(ma.shaft_torque_ripple_rms_pu, mo.shaft_torque_ripple_rms_pu),
            ma.torque_ripple_rms_pu,
            mo.torque_ripple_rms_pu,
            gains_line(runs, afb, off)?
        ),
        format!(
            "{} (criterion: stable by the `stable` metric, an overshoot above 0 and at most \
             {SLIGHT_OVERSHOOT_PU} pu, and a shaft-torque ripple with AFB no higher than without \
             it at the same gains){}",
            verdict(ok),
            if ok {
                ".".to_string()
            } else {
                format!("; failed: {}.", failed.join(", "))
            }
        ),
    );
    Ok(fig6_row(section, what, ma, mo, ok))
}

/// Fig. 6/7's row of the claims table.
fn fig6_row(s: Section, what: &str, ma: &Metrics, mo: &Metrics, ok: bool) -> Section {
    s.row(
        format!("Fig. 6/7 ({what}): slight overshoot; AFB calms the load step"),
        "slight overshoot after the ramp; slight oscillation after the 50 % step",
        format!(
            "overshoot {} pu; shaft-torque ripple {:.4} pu with AFB, {:.4} pu without; \
             verdict {} at {:.1} Hz",
            fmt_opt(ma.overshoot_pu),
            ma.shaft_torque_ripple_rms_pu,
            mo.shaft_torque_ripple_rms_pu,
            ma.oscillation.kind.word(),
            ma.oscillation.freq_hz
        ),
        verdict(ok),
    )
}
