//! The gains of each comparison, the table of all runs, and the loop's speed.

use super::section::Section;
use super::{get, Runs, COMPARISONS, SCENARIOS};
use sim_engine::engine::runner::RunOutput;
use sim_engine::error::Result;
use sim_engine::run::fmt_opt;
use std::fmt::Write as _;

/// The gains a comparison runs at, in words, and whether they are bit-identical.
pub fn gains_line(runs: &Runs, afb: &str, off: &str) -> Result<String> {
    let (ca, _) = get(runs, afb)?;
    let (co, _) = get(runs, off)?;
    let ga = sim_engine::engine::runner::regulator_gains(ca)?;
    let go = sim_engine::engine::runner::regulator_gains(co)?;
    Ok(format!(
        "`{off}` runs at the regulator gains of {} (Kp = {:.4}, Ki = {:.4}, Kpp = {:.4}; \
         bit-identical to `{afb}`'s: {}); `{afb}` adds Ka = {:.4} s",
        co.gains_of.as_ref().map_or_else(
            || "its own design".to_string(),
            |g| format!("`{}`", g.source)
        ),
        go.kp_vel,
        go.ki_vel,
        go.kpp,
        if sim_engine::engine::runner::same_regulator_gains(&ga, &go) {
            "yes"
        } else {
            "**no**"
        },
        ga.ka
    ))
}

/// Which gains each comparison uses.
pub fn gains(runs: &Runs) -> Result<Section> {
    let mut body = String::from("| AFB run | run without AFB | gains |\n|---|---|---|\n");
    for (afb, off) in COMPARISONS {
        let _ = writeln!(body, "| {afb} | {off} | {} |", gains_line(runs, afb, off)?);
    }
    let (c6, _) = get(runs, "fig6")?;
    let _ = write!(
        body,
        "\nThe velocity PI is sized for {:?} (`drive.velocity_pi_inertia`). The sweep's runs \
         without AFB use the gains of each plant's default AFB design at the same bandwidth \
         and observer bandwidth; the stiffness run without AFB uses those of the stiffness \
         scenario's default AFB design; each row of the Sec. II map runs without AFB at the \
         gains of that row's AFB design.",
        c6.drive.velocity_pi_inertia
    );
    Ok(Section::text("The gains of each comparison", body))
}

fn summary_line(name: &str, gains_of: &str, kp: f64, o: &RunOutput) -> String {
    let m = &o.metrics;
    format!(
        "| {name} | {gains_of} | {kp:.3} | {} | {:.4} | {:.4} | {:.4} | {} | {} | {} | {:.3} | \
         {:.1} | {:.1} |",
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

/// Every run's metrics in one table.
pub fn all_runs(runs: &Runs) -> Result<Section> {
    let mut body = String::from(
        "| scenario | gains of | Kp | stable | speed-error oscillation (pu) | motor-torque \
         ripple (pu) | shaft-torque ripple (pu) | droop (pu) | overshoot (pu) | settling (s) | \
         saturated (s) | max twist (counts) | shaft ripple (Hz) |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|---|",
    );
    for name in SCENARIOS {
        let (c, o) = get(runs, name)?;
        let g = sim_engine::engine::runner::regulator_gains(c)?;
        let gains_of = c
            .gains_of
            .as_ref()
            .map_or("own design", |g| g.source.as_str());
        let _ = write!(
            body,
            "\n{}",
            summary_line(name, gains_of, f64::from(g.kp_vel), o)
        );
    }
    Ok(Section::text("All runs", body))
}

/// Simulated time against loop time, and the whole reproduction's wall time.
pub fn speed(runs: &Runs, elapsed_s: f64) -> Result<Section> {
    let (mut sim, mut wall) = (0.0, 0.0);
    for name in SCENARIOS {
        let (_, o) = get(runs, name)?;
        sim += o.sim_time_s;
        wall += o.wall_time_s;
    }
    let (c6, _) = get(runs, "fig6")?;
    Ok(Section::text(
        "Speed",
        format!(
            "The {} scenario runs simulated {sim:.1} s of closed loop ({} Hz current / {} Hz \
             velocity ticks, exact plant integration between events) in {wall:.3} s of loop \
             time on one core each: {:.0}x real time. The whole reproduction took \
             {elapsed_s:.1} s. The criterion benchmark (`cargo bench -p host-bench --bench \
             closed_loop`) measures the same loop.",
            SCENARIOS.len(),
            c6.drive.current_rate_hz,
            c6.drive.velocity_rate_hz,
            sim / wall.max(1e-12)
        ),
    ))
}
