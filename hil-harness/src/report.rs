//! `hil-harness reproduce` (what `cargo run --release` does): every scenario, the sweep
//! and the stiffness measurement, then `REPORT.md` with one section per paper figure or
//! claim: the plot, the paper's statement, our measured figure, and whether they agree
//! and why. Verdicts come from fixed criteria written next to each check, never from
//! tuning a run.

use crate::commands::{fmt_opt, write_run};
use crate::config::{resolve, RunConfig};
use crate::error::{HarnessError, Result};
use crate::output::Staging;
use crate::plot::{save, Figure, Panel, Series};
use crate::runner::{run_scenario, RunOutput};
use crate::stiffness::StiffnessPoint;
use crate::sweep::SweepResult;
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

/// Scenarios `reproduce` runs, in report order.
pub const SCENARIOS: [&str; 10] = [
    "fig4",
    "fig6",
    "fig6-no-afb",
    "fig6-low-bw",
    "dyno-accel-no-afb",
    "dyno-accel",
    "shock-no-afb",
    "shock",
    "shock-30-no-afb",
    "shock-30",
];

type Runs = BTreeMap<String, (RunConfig, RunOutput)>;

fn get<'a>(runs: &'a Runs, name: &str) -> Result<&'a (RunConfig, RunOutput)> {
    runs.get(name)
        .ok_or_else(|| HarnessError::Backend(format!("scenario {name} did not run")))
}

/// Runs the scenarios in parallel with a progress bar.
pub fn run_all(names: &[&str]) -> Result<Runs> {
    let pb = crate::progress::bar(names.len() as u64, "scenarios");
    let results: Result<Vec<(String, (RunConfig, RunOutput))>> = names
        .par_iter()
        .map(|name| {
            let cfg = resolve(name, None, &[])?;
            let out = run_scenario(&cfg)?;
            pb.inc(1);
            Ok(((*name).to_string(), (cfg, out)))
        })
        .collect();
    pb.finish_and_clear();
    Ok(results?.into_iter().collect())
}

/// Overlays one signal of several runs.
fn compare(
    title: &str,
    y_label: &str,
    runs: &[(&str, &RunOutput)],
    f: fn(&crate::trace::TraceRow) -> f64,
) -> Panel {
    Panel {
        title: title.into(),
        y_label: y_label.into(),
        series: runs
            .iter()
            .map(|(label, out)| Series::line(*label, out.trace.series(f)))
            .collect(),
        ..Default::default()
    }
}

fn verdict(ok: bool) -> &'static str {
    if ok {
        "**agrees**"
    } else {
        "**does not agree**"
    }
}

fn pct(x: f64) -> String {
    format!("{:.0} %", 100.0 * x)
}

struct Report {
    text: String,
}

impl Report {
    fn section(
        &mut self,
        title: &str,
        plots: &[&str],
        paper: &str,
        measured: &str,
        assessment: &str,
    ) {
        let _ = writeln!(self.text, "\n## {title}\n");
        for p in plots {
            let _ = writeln!(self.text, "![{title}]({p})\n");
        }
        let _ = writeln!(self.text, "**Paper:** {paper}\n");
        let _ = writeln!(self.text, "**Measured:** {measured}\n");
        let _ = writeln!(self.text, "**Assessment:** {assessment}");
    }
}

fn summary_line(name: &str, o: &RunOutput) -> String {
    let m = &o.metrics;
    format!(
        "| {name} | {} | {:.4} | {:.4} | {:.4} | {} | {} | {} | {:.3} | {:.1} | {:.1} |",
        m.stable,
        m.oscillation_pu,
        m.torque_ripple_rms_pu,
        m.shaft_torque_ripple_rms_pu,
        fmt_opt(m.load_step_droop_pu),
        fmt_opt(m.overshoot_pu),
        fmt_opt(m.settling_s),
        m.torque_saturated_s,
        m.max_twist_counts,
        m.shaft_ripple_freq_hz,
    )
}

/// Writes every figure and `REPORT.md` into `dir`; returns a console summary.
pub fn reproduce_into(dir: &Path) -> Result<String> {
    let t0 = Instant::now();
    let runs = run_all(&SCENARIOS)?;
    for (name, (cfg, out)) in &runs {
        write_run(&dir.join(name), cfg, out)?;
    }
    let (sweep_results, sweep_text) = crate::sweep::sweep_into(&{
        let d = dir.join("sweep");
        std::fs::create_dir_all(&d).map_err(|e| HarnessError::io(&d, e))?;
        d
    })?;
    let (stiff, stiff_text) = crate::stiffness::stiffness_into(&{
        let d = dir.join("stiffness");
        std::fs::create_dir_all(&d).map_err(|e| HarnessError::io(&d, e))?;
        d
    })?;

    // Comparison figures.
    let (_, fig6) = get(&runs, "fig6")?;
    let (_, fig6n) = get(&runs, "fig6-no-afb")?;
    let (_, fig6l) = get(&runs, "fig6-low-bw")?;
    save(
        &Figure {
            x_label: "time (s)".into(),
            panels: vec![
                compare(
                    "Fig. 6: load speed",
                    "speed (pu)",
                    &[("AFB on", fig6), ("AFB off, same gains", fig6n)],
                    |r| r.load_vel_pu,
                ),
                compare(
                    "Fig. 7: motor torque (current)",
                    "torque (pu)",
                    &[("AFB on", fig6), ("AFB off, same gains", fig6n)],
                    |r| r.current_pu,
                ),
                compare(
                    "Fig. 7: acceleration compensation signal",
                    "torque (pu)",
                    &[("AFB on", fig6)],
                    |r| r.accel_fb_pu,
                ),
                compare(
                    "AFB off at 1.5 rad/s: load speed",
                    "speed (pu)",
                    &[("AFB off, 1.5 rad/s", fig6l)],
                    |r| r.load_vel_pu,
                ),
            ],
        },
        &dir.join("fig6-compare"),
    )?;
    let (_, dyn_on) = get(&runs, "dyno-accel")?;
    let (_, dyn_off) = get(&runs, "dyno-accel-no-afb")?;
    save(
        &Figure {
            x_label: "time (s)".into(),
            panels: vec![
                compare(
                    "Dyno acceleration, 150 % load: speed",
                    "speed (pu)",
                    &[("AFB off (Fig. 9)", dyn_off), ("AFB on (Fig. 10)", dyn_on)],
                    |r| r.motor_vel_pu,
                ),
                compare(
                    "Dyno acceleration: transducer (shaft) torque",
                    "torque (pu)",
                    &[("AFB off (Fig. 9)", dyn_off), ("AFB on (Fig. 10)", dyn_on)],
                    |r| r.shaft_torque_pu,
                ),
            ],
        },
        &dir.join("dyno-accel-compare"),
    )?;
    let (_, sh_on) = get(&runs, "shock")?;
    let (_, sh_off) = get(&runs, "shock-no-afb")?;
    let (_, sh30_on) = get(&runs, "shock-30")?;
    let (_, sh30_off) = get(&runs, "shock-30-no-afb")?;
    save(
        &Figure {
            x_label: "time (s)".into(),
            panels: vec![
                compare(
                    "150 % shock at rated speed, 100 rad/s: speed",
                    "speed (pu)",
                    &[("AFB off (Fig. 11)", sh_off), ("AFB on (Fig. 12)", sh_on)],
                    |r| r.motor_vel_pu,
                ),
                compare(
                    "100 rad/s: shaft torque",
                    "torque (pu)",
                    &[("AFB off (Fig. 11)", sh_off), ("AFB on (Fig. 12)", sh_on)],
                    |r| r.shaft_torque_pu,
                ),
                compare(
                    "30 rad/s (Fig. 13): speed",
                    "speed (pu)",
                    &[("AFB off", sh30_off), ("AFB on", sh30_on)],
                    |r| r.motor_vel_pu,
                ),
                compare(
                    "30 rad/s (Fig. 13): shaft torque",
                    "torque (pu)",
                    &[("AFB off", sh30_off), ("AFB on", sh30_on)],
                    |r| r.shaft_torque_pu,
                ),
            ],
        },
        &dir.join("shock-compare"),
    )?;

    let report = write_report(&runs, &sweep_results, &stiff, t0.elapsed().as_secs_f64())?;
    let path = dir.join("REPORT.md");
    std::fs::write(&path, report).map_err(|e| HarnessError::io(&path, e))?;
    Ok(format!("{sweep_text}{stiff_text}"))
}

fn write_report(
    runs: &Runs,
    sweep: &[SweepResult],
    stiff: &[StiffnessPoint],
    elapsed_s: f64,
) -> Result<String> {
    let mut r = Report {
        text: String::new(),
    };
    let _ = writeln!(
        r.text,
        "# stiffdrive: reproduction of \"Reducing the Effect of Load Torque Disturbances in Dual \
         Inertia Systems with Lost Motion\"\n\nGenerated by `cargo run --release` (`hil-harness \
         reproduce`). Every number below comes from the runs in this directory: the scenario \
         files are in `configs/scenarios/`, each run's `trace.csv` and `summary.json` are in \
         the folder of its name. Metric definitions: `hil-harness/README.md`. Verdicts use \
         the fixed criteria stated in each section; no run is tuned to match the paper."
    );

    // Fig. 4.
    let (c4, f4) = get(runs, "fig4")?;
    let gap_counts =
        c4.plant.mechanics.backlash_deg / 360.0 * f64::from(c4.plant.sensors.encoder_cpr);
    let m4 = &f4.metrics;
    let ok4 = m4.max_twist_counts >= 0.5 * gap_counts;
    r.section(
        "Fig. 4: resonance and lost motion in a trapezoidal profile",
        &["fig4/trace.png"],
        "A trapezoidal velocity command on the Table 1 plant (0.5 deg dead zone, about 6 counts at 4096 CPR) shows the resonance and the lost motion in the command - motor and motor - load position differences; when the torque is removed the inertias resonate.",
        &format!(
            "lost motion {gap_counts:.2} counts; largest |motor - load| {:.2} counts; largest |command - motor| {:.2} counts; shaft-torque ripple {:.3} pu RMS at about {:.0} Hz after the ramp; stable: {}.",
            m4.max_twist_counts, m4.max_following_error_counts, m4.shaft_torque_ripple_rms_pu, m4.shaft_ripple_freq_hz, m4.stable
        ),
        &format!(
            "{} (criterion: the motor - load difference spans at least half the lost motion, i.e. the gears separate and the twist is visible in counts). The position-difference panel is the paper's Fig. 4 signal set.",
            verdict(ok4)
        ),
    );

    // Fig. 6/7.
    let (c6, f6) = get(runs, "fig6")?;
    let m6 = &f6.metrics;
    let slight = |x: Option<f64>| x.is_some_and(|v| v > 0.0 && v <= 0.05);
    let ok6 = m6.stable && slight(m6.overshoot_pu);
    r.section(
        "Fig. 6 and Fig. 7: trapezoid to rated speed with a 50 % load step, acceleration feedback on",
        &["fig6/trace.png", "fig6-compare.png"],
        "At 1 s the velocity stops ramping and the load overshoots slightly; the 50 % load step at 1.5 s causes a slight oscillation. The compensation (acceleration feedback) signal is non-zero while accelerating.",
        &format!(
            "AFB design: {:?}, Ka = {} x J_total, filter {:?}, source {:?}, rate {:?}. Stable: {}; load overshoot after 1 s {} pu; droop after the step {} pu; settling {} s; motor-torque ripple {:.3} pu RMS; torque at its limit for {:.3} s; speed-error oscillation in the last 0.5 s {:.4} pu.",
            c6.drive.accel_feedback.mode, c6.drive.accel_feedback.gain_fraction, c6.drive.accel_feedback.filter, c6.drive.accel_feedback.source, c6.drive.accel_feedback.rate,
            m6.stable, fmt_opt(m6.overshoot_pu), fmt_opt(m6.load_step_droop_pu), fmt_opt(m6.settling_s), m6.torque_ripple_rms_pu, m6.torque_saturated_s, m6.oscillation_pu
        ),
        &format!(
            "{} (criterion: stable by the `stable` metric and an overshoot between 0 and 0.05 pu). {}",
            verdict(ok6),
            if m6.stable { "" } else { "The run fails the stability criterion: see the torque panel: with this acceleration-feedback design the torque command spends much of the time at its limit, the inner acceleration loop of design-notes Trap 1/Trap 2 (4096-count quantization amplified by the feedback gain)." }
        ),
    );

    // No AFB / low bandwidth.
    let (_, n6) = get(runs, "fig6-no-afb")?;
    let (_, l6) = get(runs, "fig6-low-bw")?;
    let okn = !n6.metrics.stable;
    r.section(
        "Sec. II: without acceleration feedback the system becomes unstable",
        &["fig6-no-afb/trace.png"],
        "If the acceleration signal was not fed back, the system would become unstable.",
        &format!(
            "same gains, AFB off: stable {}; speed-error oscillation in the last 0.5 s {:.4} pu; motor-torque ripple {:.3} pu RMS; droop {} pu; twist up to {:.1} counts.",
            n6.metrics.stable, n6.metrics.oscillation_pu, n6.metrics.torque_ripple_rms_pu, fmt_opt(n6.metrics.load_step_droop_pu), n6.metrics.max_twist_counts
        ),
        &format!(
            "{} (criterion: the `stable` metric is false). {}",
            verdict(okn),
            if okn { "The model reproduces the instability." } else {
                "The model does not reproduce it. A linear analysis of the engaged Table 1 plant is stable up to roughly 190 rad/s of velocity bandwidth (design notes), and in this model the nonlinear parts (0.5 deg lost motion, 4096-count quantization, torque and voltage limits) turn the 94 rad/s loop into a bounded chatter inside the lost motion, not a growing oscillation: the gears stay engaged under load and the speed error stays well inside the threshold. What the paper saw may come from effects this model leaves out (friction, compliance of the gearbox teeth, a different estimator), which is a finding, not something to tune towards."
            }
        ),
    );
    let okl = l6.metrics.stable;
    let oscillatory = l6.metrics.oscillation_pu > 0.005;
    let low_verdict = match (okl, oscillatory) {
        (true, true) => "**agrees**",
        (true, false) => "**partly agrees**",
        _ => "**does not agree**",
    };
    r.section(
        "Sec. II: at 1-2 rad/s velocity bandwidth stable but highly oscillatory",
        &["fig6-low-bw/trace.png"],
        "With the velocity loop bandwidth reduced to 1-2 rad/s the system could be stabilized, but would remain highly oscillatory.",
        &format!(
            "AFB off, 1.5 rad/s, speed mode: stable {}; droop after the 50 % step {} pu; settling {} s; speed-error oscillation in the last 2 s {:.4} pu; load overshoot {} pu.",
            l6.metrics.stable, fmt_opt(l6.metrics.load_step_droop_pu), fmt_opt(l6.metrics.settling_s), l6.metrics.oscillation_pu, fmt_opt(l6.metrics.overshoot_pu)
        ),
        &format!(
            "{low_verdict} (criteria: `stable`, and \"highly oscillatory\" as a speed-error oscillation above 0.005 pu in the last 2 s). {}",
            if oscillatory { "The loop is stable and rings." } else {
                "The loop is stable but not oscillatory in the model: a 1.5 rad/s loop simply droops by a quarter of rated speed and recovers over seconds (`fig6-compare.png`, bottom). The paper's oscillation at this bandwidth is not reproduced."
            }
        ),
    );

    // Dyno acceleration.
    let (cd, d_on) = get(runs, "dyno-accel")?;
    let (_, d_off) = get(runs, "dyno-accel-no-afb")?;
    let red = 1.0
        - d_on.metrics.shaft_torque_ripple_rms_pu
            / d_off.metrics.shaft_torque_ripple_rms_pu.max(1e-12);
    let okd = (0.6..=0.95).contains(&red);
    r.section(
        "Fig. 9 and Fig. 10: dyno, accelerate with 150 % load in 0.1 s, torque saturated",
        &["dyno-accel-compare.png", "dyno-accel-no-afb/trace.png", "dyno-accel/trace.png"],
        "Velocity bandwidth 100 rad/s, 1.03 s total inertia, no lost motion; the torque saturates; about 10 Hz torque oscillation in the measured torque without acceleration feedback, reduced in magnitude by 75-80 % with it.",
        &format!(
            "dyno plant as assumed in `configs/scenarios/plants/dyno.toml` (Jm 0.20 s + Jl 0.83 s, coupling anti-resonance {} Hz, no lost motion). Shaft-torque ripple during the acceleration (0.6-2.5 s, above ~5 Hz): {:.4} pu RMS at about {:.1} Hz without AFB, {:.4} pu RMS at about {:.1} Hz with: {}. Torque at its limit {:.2} s / {:.2} s.",
            cd.plant.mechanics.anti_resonance_hz,
            d_off.metrics.shaft_torque_ripple_rms_pu, d_off.metrics.shaft_ripple_freq_hz,
            d_on.metrics.shaft_torque_ripple_rms_pu, d_on.metrics.shaft_ripple_freq_hz,
            if red >= 0.0 { format!("reduced by {}", pct(red)) } else { format!("increased by {}", pct(-red)) },
            d_off.metrics.torque_saturated_s, d_on.metrics.torque_saturated_s
        ),
        &format!(
            "{} (criterion: reduction of the shaft-torque ripple between 60 % and 95 %, the paper's 75-80 % with a margin for an assumed plant). In the model the coupling rings when the torque steps into saturation, at the engaged resonance ({:.1} Hz for the assumed coupling), because a drive at its torque limit no longer regulates and leaves the motor free; it decays within a few tenths of a second with or without AFB, and the steady ripple after it is dominated by quantization chatter (hence the zero-crossing frequency above). With the error-form AFB the torque reference is the velocity regulator's output plus the AFB term, clamped together at the torque limit (controller-core clamps the regulator so that the sum can reach the limit); after the 0.1 s ramp the commanded acceleration is 0 while the motor still accelerates, so the AFB term brakes once the speed error no longer saturates the regulator ({:.2} s at the limit with AFB, {:.2} s without; speed at the end of the run {:.3} pu with AFB, {:.3} pu without).",
            verdict(okd),
            cd.plant.mechanics.derived().resonance_rad_s / std::f64::consts::TAU,
            d_on.metrics.torque_saturated_s,
            d_off.metrics.torque_saturated_s,
            d_on.trace.rows.last().map_or(f64::NAN, |r| r.motor_vel_pu),
            d_off.trace.rows.last().map_or(f64::NAN, |r| r.motor_vel_pu)
        ),
    );

    // Shock.
    let (_, s_on) = get(runs, "shock")?;
    let (_, s_off) = get(runs, "shock-no-afb")?;
    let (_, s30_on) = get(runs, "shock-30")?;
    let (_, s30_off) = get(runs, "shock-30-no-afb")?;
    let oks = s_on.metrics.shaft_torque_ripple_rms_pu < s_off.metrics.shaft_torque_ripple_rms_pu;
    r.section(
        "Fig. 11 and Fig. 12: 150 % shock load at rated speed, 100 rad/s",
        &["shock-compare.png"],
        "Acceleration feedback reduces the torque ripple after the shock.",
        &format!(
            "shaft-torque ripple after the step (0.1 s after it to the end): {:.4} pu without AFB, {:.4} pu with; motor-torque ripple {:.4} / {:.4} pu; droop {} / {} pu.",
            s_off.metrics.shaft_torque_ripple_rms_pu, s_on.metrics.shaft_torque_ripple_rms_pu,
            s_off.metrics.torque_ripple_rms_pu, s_on.metrics.torque_ripple_rms_pu,
            fmt_opt(s_off.metrics.load_step_droop_pu), fmt_opt(s_on.metrics.load_step_droop_pu)
        ),
        &format!("{} (criterion: less shaft-torque ripple with AFB).", verdict(oks)),
    );
    let droop = |o: &RunOutput| o.metrics.load_step_droop_pu.unwrap_or(0.0);
    let ok30 = droop(s30_off) > droop(s_off)
        && s30_off.metrics.shaft_torque_ripple_rms_pu > s30_on.metrics.shaft_torque_ripple_rms_pu;
    r.section(
        "Fig. 13: the same shock at 30 rad/s",
        &["shock-compare.png"],
        "At 30 rad/s the speed droops slightly when the shock is applied; the torque shows more noise with acceleration feedback disabled.",
        &format!(
            "droop {} pu at 30 rad/s vs {} pu at 100 rad/s (AFB off); with AFB at 30 rad/s {} pu. Shaft-torque ripple at 30 rad/s: {:.4} pu without AFB, {:.4} pu with.",
            fmt_opt(s30_off.metrics.load_step_droop_pu), fmt_opt(s_off.metrics.load_step_droop_pu), fmt_opt(s30_on.metrics.load_step_droop_pu),
            s30_off.metrics.shaft_torque_ripple_rms_pu, s30_on.metrics.shaft_torque_ripple_rms_pu
        ),
        &format!("{} (criterion: more droop at 30 than at 100 rad/s, and less shaft-torque ripple with AFB at 30 rad/s).", verdict(ok30)),
    );

    // Sweep.
    let mut sweep_text = String::new();
    for s in sweep {
        let _ = write!(
            sweep_text,
            "{}: stable up to {} rad/s without AFB and {} rad/s with (best: {}); quiet (torque chatter below {} pu) up to {} rad/s without and {} rad/s with (best: {}). ",
            s.plant,
            s.without_afb_rad_s,
            s.with_afb_rad_s,
            s.best_design,
            crate::sweep::QUIET_TORQUE_PU,
            s.quiet_without_afb_rad_s,
            s.quiet_with_afb_rad_s,
            s.best_quiet_design
        );
    }
    let pp = sweep.iter().find(|s| s.plant == "printing-press");
    let ratio_ok = pp.is_some_and(|s| {
        s.without_afb_rad_s > 0.0 && s.with_afb_rad_s >= 2.0 * s.without_afb_rad_s
    });
    let level_ok = pp.is_some_and(|s| s.without_afb_rad_s <= 60.0);
    let sweep_verdict = match (ratio_ok, level_ok) {
        (true, true) => "**agrees**",
        (true, false) => "**partly agrees**",
        _ => "**does not agree**",
    };
    r.section(
        "Sec. III-D: largest stable velocity bandwidth, printing-press stand (and Table 1)",
        &["sweep/sweep.png"],
        "Printing-press stand (1e6 CPR, 3:1 gearbox, 8:1 reflected inertia, ~150 counts lost motion): 140 rad/s with acceleration feedback, only 30 rad/s without before the system went unstable.",
        &format!(
            "{sweep_text}Probe run `configs/scenarios/sweep.toml` in speed mode; a bandwidth counts only if every grid point below it passes too. Grid: {:?} rad/s; AFB designs: error form, Ka/J_total in {:?}, filters {:?}, acceleration from differentiation or from the observer at {:?} Hz (every point in `sweep/sweep.csv`; points whose gains do not fit controller-core's fixed-point formats are rejected there and count as not achievable).",
            crate::sweep::BANDWIDTHS_RAD_S, crate::sweep::GAINS, crate::sweep::FILTERS, crate::sweep::OBSERVER_HZ
        ),
        &format!(
            "{sweep_verdict} (criteria: on the printing press the best AFB design reaches at least twice the stable bandwidth reached without, as the paper's 140 vs 30 rad/s; and the no-AFB limit is of the paper's order, at most 60 rad/s). Without acceleration feedback the modelled press stays stable far above the paper's 30 rad/s. The modelled press has a 1e6-count encoder (quantization 244x finer than Table 1's, so the torque chatter that limits Table 1 is absent), a 0.054 deg gap, no friction and no gear-tooth compliance, and its inertias and coupling are assumptions (`configs/printing-press.toml`); which of the real stand's effects set its 30 rad/s limit is not something this model can say. On Table 1 the quiet measure shows the paper's direction: the torque chatter stays below the threshold up to a higher bandwidth with AFB than without."
        ),
    );

    // Stiffness.
    let cfg_st = resolve("stiffness", None, &[])?;
    let bw = f64::from(cfg_st.drive.velocity_bandwidth_rad_s);
    let ratio_in = |source: &str, lo: f64, hi: f64| -> f64 {
        let v: Vec<f64> = stiff
            .iter()
            .filter(|p| p.source == "none" && p.freq_rad_s > lo && p.freq_rad_s <= hi)
            .filter_map(|a| {
                stiff
                    .iter()
                    .find(|b| b.source == source && b.freq_rad_s == a.freq_rad_s && b.stable)
                    .map(|b| b.measured / a.measured)
            })
            .collect();
        if v.is_empty() {
            f64::NAN
        } else {
            (v.iter().map(|x| x.ln()).sum::<f64>() / v.len() as f64).exp()
        }
    };
    let low = ratio_in("observer", 0.0, bw);
    let above = ratio_in("observer", 3.0 * bw, 1e9);
    let diff_stable = stiff
        .iter()
        .filter(|p| p.source == "differentiation")
        .all(|p| p.stable);
    let eq1_err = stiff
        .iter()
        .filter(|p| p.source == "none")
        .map(|p| (p.measured / p.analytic - 1.0).abs())
        .fold(0.0, f64::max);
    let okst = above > 1.2;
    let est_ratios: Vec<String> = stiff
        .iter()
        .filter(|p| p.source == "observer" && p.freq_rad_s >= bw)
        .map(|p| format!("{:.2} at {} rad/s", p.accel_est_ratio, p.freq_rad_s))
        .collect();
    r.section(
        "Fig. 2 and Eq. 1: dynamic stiffness; acceleration feedback adds stiffness above the velocity bandwidth",
        &["stiffness/stiffness.png"],
        "Stiffness tau_L/theta = Jp s^2 + Kp s + Ki (Eq. 1) with breaks at 1 and 10 rad/s (Fig. 2); acceleration feedback improves stiffness in the high-frequency region, typically above the velocity loop bandwidth.",
        &format!(
            "Fig. 2 gains (Kp = 11 J, Ki = 10 J, i.e. {bw} rad/s with damping 1.74) on the dyno plant with a stiff coupling: without AFB the measured stiffness follows Eq. 1 within {:.0} % from 0.3 to 1500 rad/s. With the drive's default AFB (observer acceleration) the stiffness is {low:.2}x higher below the velocity bandwidth, because controller-core designs the PI for J_total + Ka, and {above:.2}x above 3x the bandwidth, where the ideal J + Ka*F curve predicts up to 1.5x. Observer acceleration estimate / true acceleration: {}. The same design with differentiated acceleration is {} at 4096 counts (its points are left off the chart; see `stiffness/stiffness.csv`).",
            100.0 * eq1_err,
            est_ratios.join(", "),
            if diff_stable { "stable" } else { "not stable (torque chatter)" }
        ),
        &format!(
            "{} (criterion: AFB raises the measured stiffness above 3x the velocity bandwidth by more than 20 %). {}",
            verdict(okst),
            if okst { "" } else {
                "Why: the observer's acceleration estimate follows only part of the load-driven motor acceleration (column `accel_est_ratio` of `stiffness/stiffness.csv`: estimate over true acceleration at each frequency), so the AFB term it drives adds little inertia against a load disturbance. The paper's AFB differentiated position (its Sec. II: \"the velocity and acceleration signals were found by differentiation\"), which sees all of the acceleration, but at 4096 counts that path chatters in this model."
            }
        ),
    );

    // Table of all runs and speed.
    let _ = writeln!(
        r.text,
        "\n## All runs\n\n| scenario | stable | speed-error oscillation (pu) | motor-torque ripple (pu) | shaft-torque ripple (pu) | droop (pu) | overshoot (pu) | settling (s) | saturated (s) | max twist (counts) | shaft ripple (Hz) |\n|---|---|---|---|---|---|---|---|---|---|---|"
    );
    let mut sim = 0.0;
    let mut wall = 0.0;
    for name in SCENARIOS {
        let (_, o) = get(runs, name)?;
        sim += o.sim_time_s;
        wall += o.wall_time_s;
        let _ = writeln!(r.text, "{}", summary_line(name, o));
    }
    let _ = writeln!(
        r.text,
        "\n## Speed\n\nThe {} scenario runs simulated {sim:.1} s of closed loop (4 kHz current / 2 kHz velocity ticks, exact plant integration between events) in {wall:.3} s of loop time on one core each: {:.0}x real time. The whole reproduction took {elapsed_s:.1} s. The criterion benchmark (`cargo bench -p hil-harness`) measures the same loop.",
        SCENARIOS.len(),
        sim / wall.max(1e-12)
    );
    Ok(r.text)
}

/// `hil-harness reproduce`.
pub fn reproduce(out: &Path) -> Result<String> {
    let staging = Staging::keeping_others(out)?;
    let text = reproduce_into(staging.dir())?;
    // The PIL run needs QEMU and the ARM image, so `reproduce` does not start it; a run
    // left by `hil-harness pil --scenario fig6 --out out/pil-fig6` is reported, else a hint.
    let pil = crate::pil::report_section_or_hint(&out.join("pil-fig6"));
    let report_path = staging.dir().join("REPORT.md");
    let mut report =
        std::fs::read_to_string(&report_path).map_err(|e| HarnessError::io(&report_path, e))?;
    report.push('\n');
    report.push_str(&pil);
    std::fs::write(&report_path, report).map_err(|e| HarnessError::io(&report_path, e))?;
    staging.commit()?;
    Ok(format!("{text}report: {}", out.join("REPORT.md").display()))
}
