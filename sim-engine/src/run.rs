//! `hil-harness run`: one scenario into `DIR/trace.csv`, `DIR/summary.json` and
//! `DIR/trace.png|svg`.

use crate::config::{resolve, RunConfig};
use crate::engine::protection::FaultRecord;
use crate::engine::runner::{run_scenario, RunOutput};
use crate::engine::trace::Trace;
use crate::error::{HarnessError, Result};
use crate::output::Staging;
use crate::plot::{save, Figure, Panel, Series};
use std::path::Path;

/// The standard figure of a run: speeds, torques, position differences. The first panel's
/// title names the run (wrapped to the figure's width); a trip is a labelled vertical line
/// at its time on every panel.
pub fn trace_figure(trace: &Trace, title: &str, fault: Option<&FaultRecord>) -> Figure {
    let with_trip = |mut series: Vec<Series>| {
        if let Some(f) = fault {
            series.push(Series::vertical(trip_label(f), f.t_s));
        }
        series
    };
    let heading = match fault {
        Some(f) => format!("{title}; tripped: {} at {:.4} s", f.kind, f.t_s),
        None => title.to_string(),
    };
    Figure {
        x_label: "time (s)".into(),
        panels: vec![
            Panel {
                title: format!("{heading}\nSpeed"),
                y_label: "speed (pu)".into(),
                series: with_trip(vec![
                    Series::line("command", trace.series(|r| r.vel_cmd_pu)),
                    Series::line("motor", trace.series(|r| r.motor_vel_pu)),
                    Series::line("load", trace.series(|r| r.load_vel_pu)),
                ]),
                ..Default::default()
            },
            Panel {
                title: "Torque".into(),
                y_label: "torque (pu)".into(),
                series: with_trip(vec![
                    Series::line("torque command", trace.series(|r| r.torque_cmd_pu)),
                    Series::line("shaft torque", trace.series(|r| r.shaft_torque_pu)),
                    Series::line("acceleration feedback", trace.series(|r| r.accel_fb_pu)),
                    Series::line("load torque", trace.series(|r| r.load_torque_pu)),
                ]),
                ..Default::default()
            },
            Panel {
                title: "Command − motor position".into(),
                y_label: "counts".into(),
                series: with_trip(vec![Series::line(
                    "command − motor",
                    trace.series(|r| r.cmd_minus_motor_counts()),
                )]),
                ..Default::default()
            },
            Panel {
                title: "Motor − load position (lost motion and twist)".into(),
                y_label: "counts".into(),
                series: with_trip(vec![Series::line(
                    "motor − load",
                    trace.series(|r| r.motor_minus_load_counts()),
                )]),
                ..Default::default()
            },
        ],
    }
}

/// The label of a trip's line: "tripped: overcurrent at 0.0021 s".
pub fn trip_label(f: &FaultRecord) -> String {
    format!("tripped: {} at {:.4} s", f.kind, f.t_s)
}

/// Writes a run's files into `dir` (a staging directory or a subdirectory of one).
pub fn write_run(dir: &Path, cfg: &RunConfig, out: &RunOutput) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| HarnessError::io(dir, e))?;
    out.trace.write_csv(&dir.join("trace.csv"))?;
    let summary = out.summary(cfg);
    let json = serde_json::to_string_pretty(&summary)
        .map_err(|e| HarnessError::io(dir.join("summary.json"), e))?;
    let path = dir.join("summary.json");
    std::fs::write(&path, json + "\n").map_err(|e| HarnessError::io(&path, e))?;
    save(
        &trace_figure(&out.trace, &summary.title, out.fault.as_ref()),
        &dir.join("trace"),
    )?;
    Ok(())
}

/// `hil-harness run`.
pub fn run(scenario: &str, config: Option<&str>, sets: &[String], out: &Path) -> Result<String> {
    // Resolve, then check the output directory before the run (a refusal costs no
    // simulation); the staging directory is removed if the run fails.
    let cfg = resolve(scenario, config, sets)?;
    let staging = Staging::new(out)?;
    let result = run_scenario(&cfg)?;
    write_run(staging.dir(), &cfg, &result)?;
    staging.commit()?;
    let m = &result.metrics;
    let trip = result.fault.as_ref().map_or_else(String::new, |f| {
        format!(
            "TRIPPED: {} at {:.4} s (current tick {}); ",
            f.kind, f.t_s, f.tick
        )
    });
    Ok(format!(
        "{scenario}: {trip}stable={} verdict={} ripple={:.4} pu droop={} overshoot={} settling={} saturated={:.3} s; \
         {:.2} s simulated in {:.3} s ({:.0}x real time) -> {}",
        m.stable,
        m.oscillation.kind.verdict(),
        m.torque_ripple_rms_pu,
        fmt_opt(m.load_step_droop_pu),
        fmt_opt(m.overshoot_pu),
        fmt_opt(m.settling_s),
        m.torque_saturated_s,
        result.sim_time_s,
        result.wall_time_s,
        result.sim_time_s / result.wall_time_s.max(1e-9),
        out.display()
    ))
}

/// `Some(x)` as `x` with 4 decimals, `None` as `n/a`.
pub fn fmt_opt(v: Option<f64>) -> String {
    v.map_or_else(|| "n/a".to_string(), |x| format!("{x:.4}"))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]

    /// `summary.json`'s `peak_droop_pu` and `peak_shaft_torque_pu` are the figures a reader
    /// takes from `trace.csv` by their definitions: the largest |speed error − the mean
    /// error over the velocity-bandwidth period before the 1.5 s step| and the largest
    /// |shaft torque| from the step.
    #[test]
    fn peak_droop_and_peak_shaft_torque_are_those_of_the_trace_csv() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("fig6");
        super::run("fig6", None, &[], &out).unwrap();
        let summary: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap())
                .unwrap();
        let mut csv = csv::Reader::from_path(out.join("trace.csv")).unwrap();
        let head = csv.headers().unwrap().clone();
        let col = |name: &str| head.iter().position(|h| h == name).unwrap();
        let (t, cmd, vel, shaft) = (
            col("t_s"),
            col("vel_cmd_pu"),
            col("motor_vel_pu"),
            col("shaft_torque_pu"),
        );
        let rows: Vec<Vec<f64>> = csv
            .records()
            .map(|r| r.unwrap().iter().map(|v| v.parse().unwrap()).collect())
            .collect();
        let step = 1.5;
        // The error just before the step: the mean over one velocity-bandwidth period.
        let f_bw = summary["drive"]["velocity_bandwidth_rad_s"]
            .as_f64()
            .unwrap()
            / (2.0 * std::f64::consts::PI);
        let n = 2 * (0.5 / (f_bw * 5e-4)).round() as usize;
        let pre: Vec<&Vec<f64>> = rows.iter().filter(|r| r[t] < step).collect();
        let pre = &pre[pre.len() - n..];
        let e0 = pre.iter().map(|r| r[cmd] - r[vel]).sum::<f64>() / n as f64;
        let after = rows.iter().filter(|r| r[t] >= step);
        let droop = after
            .clone()
            .map(|r| (r[cmd] - r[vel] - e0).abs())
            .fold(0.0, f64::max);
        let peak_shaft = after.map(|r| r[shaft].abs()).fold(0.0, f64::max);
        assert_eq!(summary["peak_droop_pu"].as_f64().unwrap(), droop);
        assert_eq!(
            summary["peak_shaft_torque_pu"].as_f64().unwrap(),
            peak_shaft
        );
        assert!(droop > 1e-3 && peak_shaft > 0.5, "{droop} {peak_shaft}");
    }
}
