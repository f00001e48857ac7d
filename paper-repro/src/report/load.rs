//! Load disturbances: the dyno acceleration (Fig. 9/10) and the shock loads (Fig. 11-13).

use super::facts::{fill, load_step_pu};
use super::runs::gains_line;
use super::section::{change, pct, verdict, Section};
use super::{get, Runs, DYNO_REDUCTION};
use sim_engine::engine::metrics::Metrics;
use sim_engine::engine::runner::RunOutput;
use sim_engine::error::Result;
use sim_engine::run::fmt_opt;

/// Fig. 9/10: the dyno accelerates with 150 % load, torque saturated.
pub fn dyno(runs: &Runs) -> Result<Section> {
    let (cd, d_on) = get(runs, "dyno-accel")?;
    let (_, d_off) = get(runs, "dyno-accel-no-afb")?;
    let (on, off) = (&d_on.metrics, &d_off.metrics);
    let red = 1.0 - on.shaft_torque_ripple_rms_pu / off.shaft_torque_ripple_rms_pu.max(1e-12);
    let okd = (DYNO_REDUCTION.0..=DYNO_REDUCTION.1).contains(&red);
    let mech = &cd.plant.mechanics;
    let end_speed = |o: &RunOutput| o.trace.rows.last().map_or(f64::NAN, |r| r.motor_vel_pu);
    Ok(Section::claim(
        fill(
            "Fig. 9 and Fig. 10: dyno, accelerate with {load} load in {accel_s} s, torque \
             saturated",
            cd,
        ),
        &[
            "dyno-accel-compare.png",
            "dyno-accel-no-afb/trace.png",
            "dyno-accel/trace.png",
        ],
        "Velocity bandwidth 100 rad/s, 1.03 s total inertia, no lost motion; the torque \
         saturates; about 10 Hz torque oscillation in the measured torque without acceleration \
         feedback, reduced in magnitude by 75-80 % with it.",
        format!(
            "dyno plant as assumed in `configs/machines/dyno.toml` (Jm {} s + Jl {} s, \
             coupling anti-resonance {} Hz, engaged resonance {:.1} Hz, backlash {} deg). \
             Shaft-torque ripple during the acceleration (the scenario's ripple window): {:.4} \
             pu RMS at about {:.1} Hz without AFB, {:.4} pu RMS at about {:.1} Hz with: {}. \
             Torque at its limit {:.2} s without / {:.2} s with; speed at the end of the run \
             {:.3} pu without, {:.3} pu with. {}.",
            mech.motor_inertia_s,
            mech.load_inertia_s,
            mech.anti_resonance_hz,
            mech.derived().resonance_rad_s / std::f64::consts::TAU,
            mech.backlash_deg,
            off.shaft_torque_ripple_rms_pu,
            off.shaft_ripple_freq_hz,
            on.shaft_torque_ripple_rms_pu,
            on.shaft_ripple_freq_hz,
            change(
                on.shaft_torque_ripple_rms_pu,
                off.shaft_torque_ripple_rms_pu
            ),
            off.torque_saturated_s,
            on.torque_saturated_s,
            end_speed(d_off),
            end_speed(d_on),
            gains_line(runs, "dyno-accel", "dyno-accel-no-afb")?
        ),
        format!(
            "{} (criterion: reduction of the shaft-torque ripple between {} and {}, the paper's \
             75-80 % with a margin for an assumed plant).",
            verdict(okd),
            pct(DYNO_REDUCTION.0),
            pct(DYNO_REDUCTION.1)
        ),
    )
    .row(
        "Fig. 9/10: AFB reduces the dyno's torque oscillation",
        "75-80 % less",
        format!(
            "shaft-torque ripple {:.4} pu with AFB, {:.4} pu without: {}",
            on.shaft_torque_ripple_rms_pu,
            off.shaft_torque_ripple_rms_pu,
            change(
                on.shaft_torque_ripple_rms_pu,
                off.shaft_torque_ripple_rms_pu
            )
        ),
        verdict(okd),
    ))
}

/// Fig. 11/12's criterion on a pair, `on` with AFB and `off` without at its gains: less
/// shaft-torque ripple with AFB than without.
pub(super) fn shock_calmer(on: &Metrics, off: &Metrics) -> bool {
    on.shaft_torque_ripple_rms_pu < off.shaft_torque_ripple_rms_pu
}

/// Fig. 11/12: a shock load at rated speed, with and without AFB at the same gains; `figures`
/// heads the title (the step and the bandwidth come from the scenario).
pub fn shock(runs: &Runs, afb: &str, off: &str, figures: &str) -> Result<Section> {
    let (ca, s_on) = get(runs, afb)?;
    let (_, s_off) = get(runs, off)?;
    let (on, offm) = (&s_on.metrics, &s_off.metrics);
    let step = load_step_pu(ca);
    let oks = shock_calmer(on, offm);
    let title = format!(
        "{figures}: {}",
        fill("{load} shock load at rated speed, {bw} rad/s", ca)
    );
    Ok(Section::claim(
        title,
        &["shock-compare.png"],
        "Acceleration feedback reduces the torque ripple after the shock.",
        format!(
            "load step {} pu at {} rad/s. Shaft-torque ripple after the step (from one averaging \
             length after it to the end): {:.4} pu without AFB, {:.4} pu with ({}); motor-torque \
             ripple {:.4} / {:.4} pu; droop {} / {} pu; torque at its limit {:.3} / {:.3} s. {}.",
            step,
            ca.drive.velocity_bandwidth_rad_s,
            offm.shaft_torque_ripple_rms_pu,
            on.shaft_torque_ripple_rms_pu,
            change(
                on.shaft_torque_ripple_rms_pu,
                offm.shaft_torque_ripple_rms_pu
            ),
            offm.torque_ripple_rms_pu,
            on.torque_ripple_rms_pu,
            fmt_opt(offm.load_step_droop_pu),
            fmt_opt(on.load_step_droop_pu),
            offm.torque_saturated_s,
            on.torque_saturated_s,
            gains_line(runs, afb, off)?
        ),
        format!(
            "{} (criterion: less shaft-torque ripple with AFB than without, at the same gains).",
            verdict(oks)
        ),
    )
    .row(
        fill(
            "Fig. 11/12: AFB reduces the ripple after a {load} shock at {bw} rad/s",
            ca,
        ),
        "less torque ripple with AFB",
        format!(
            "shaft-torque ripple {:.4} pu with AFB, {:.4} pu without",
            on.shaft_torque_ripple_rms_pu, offm.shaft_torque_ripple_rms_pu
        ),
        verdict(oks),
    ))
}

/// Fig. 13: the same shock at 30 rad/s.
pub fn shock_30(runs: &Runs) -> Result<Section> {
    let (c_off, s_off) = get(runs, "shock-no-afb")?;
    let (_, s30_on) = get(runs, "shock-30")?;
    let (c30, s30_off) = get(runs, "shock-30-no-afb")?;
    let (bw30, bw) = (
        c30.drive.velocity_bandwidth_rad_s,
        c_off.drive.velocity_bandwidth_rad_s,
    );
    let droop = |o: &RunOutput| o.metrics.load_step_droop_pu.unwrap_or(0.0);
    let ok30 = droop(s30_off) > droop(s_off)
        && s30_off.metrics.shaft_torque_ripple_rms_pu > s30_on.metrics.shaft_torque_ripple_rms_pu;
    Ok(Section::claim(
        format!("Fig. 13: the same shock at {bw30} rad/s"),
        &["shock-compare.png"],
        "At 30 rad/s the speed droops slightly when the shock is applied; the torque shows more \
         noise with acceleration feedback disabled.",
        format!(
            "droop {} pu at {bw30} rad/s vs {} pu at {bw} rad/s (AFB off); with AFB at {bw30} \
             rad/s {} pu. Shaft-torque ripple at {bw30} rad/s: {:.4} pu without AFB, {:.4} pu \
             with. {}.",
            fmt_opt(s30_off.metrics.load_step_droop_pu),
            fmt_opt(s_off.metrics.load_step_droop_pu),
            fmt_opt(s30_on.metrics.load_step_droop_pu),
            s30_off.metrics.shaft_torque_ripple_rms_pu,
            s30_on.metrics.shaft_torque_ripple_rms_pu,
            gains_line(runs, "shock-30", "shock-30-no-afb")?
        ),
        format!(
            "{} (criterion: more droop at {bw30} than at {bw} rad/s, and less shaft-torque \
             ripple with AFB at {bw30} rad/s).",
            verdict(ok30)
        ),
    )
    .row(
        format!("Fig. 13: at {bw30} rad/s the speed droops; more torque noise without AFB"),
        "slight droop; more torque noise without AFB",
        format!(
            "droop {} pu at {bw30} rad/s against {} pu at {bw} rad/s; shaft-torque ripple \
             {:.4} pu without AFB, {:.4} pu with",
            fmt_opt(s30_off.metrics.load_step_droop_pu),
            fmt_opt(s_off.metrics.load_step_droop_pu),
            s30_off.metrics.shaft_torque_ripple_rms_pu,
            s30_on.metrics.shaft_torque_ripple_rms_pu
        ),
        verdict(ok30),
    ))
}
