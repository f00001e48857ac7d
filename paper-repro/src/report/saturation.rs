//! Where the shaft ripple of the saturated runs comes from: each run's ripple window split
//! into the part the scenario's event excites and the rest, for the shaft torque, the
//! torque reference and the AFB term, with the share of the window at the torque limit.
//! Four runs per scenario at the same gains: AFB as the dyno's machine file sets it (the
//! velocity regulator's headroom `accel_feedback.limit_headroom_fraction`, and the AFB filter
//! held at the limit, `accel_feedback.filter_at_limit`), AFB with the filter running on at
//! the limit (`<name>-filter-track`), AFB with the plain clamp (`<name>-no-headroom`), and
//! no AFB (`<name>-no-afb`).

use super::section::Section;
use super::{get, Runs};
use sim_engine::config::RunConfig;
use sim_engine::engine::metrics::ripple_in;
use sim_engine::engine::runner::RunOutput;
use sim_engine::engine::trace::TraceRow;
use sim_engine::error::Result;
use std::fmt::Write as _;

/// The saturated scenarios this section looks at.
pub const SCENARIOS: [&str; 2] = ["dyno-accel", "shock"];

/// Length of the first part of a window, the response to the event (s): about two periods
/// of the dyno's shaft ring (7 Hz).
const FIRST_PART_S: f64 = 0.2;

/// The run names of `scenario`: (label, run).
fn variants(scenario: &str) -> [(String, String); 4] {
    [
        ("AFB, headroom, filter held".into(), scenario.to_string()),
        (
            "AFB, headroom, filter tracks".into(),
            format!("{scenario}-filter-track"),
        ),
        ("AFB, plain clamp".into(), format!("{scenario}-no-headroom")),
        ("no AFB".into(), format!("{scenario}-no-afb")),
    ]
}

/// One row: the ripple of three signals in `win`, the shaft ripple's frequency and the
/// share of the window with the torque reference at its limit.
fn row(label: &str, part: &str, cfg: &RunConfig, out: &RunOutput, win: (f64, f64)) -> String {
    let rows = &out.trace.rows;
    let avg = cfg
        .scenario
        .metric_windows(f64::from(cfg.drive.torque_limit_pu))
        .ripple_average_s;
    let r = |f: fn(&TraceRow) -> f64| ripple_in(rows, win, avg, f);
    let (shaft, shaft_hz) = r(|t| t.shaft_torque_pu);
    let (torque, torque_hz) = r(|t| t.torque_cmd_pu);
    let (afb, afb_hz) = r(|t| t.accel_fb_pu);
    let limit = f64::from(cfg.drive.torque_limit_pu);
    let inside: Vec<&TraceRow> = rows
        .iter()
        .filter(|t| t.t_s >= win.0 && t.t_s <= win.1)
        .collect();
    let at_limit = inside
        .iter()
        .filter(|t| t.torque_cmd_pu.abs() >= limit * (1.0 - 1e-6))
        .count() as f64
        / inside.len().max(1) as f64;
    let hz = |f: Option<f64>| f.map_or_else(|| "-".to_string(), |f| format!("{f:.1}"));
    format!(
        "| {label} | {part} ({:.2}-{:.2} s) | {shaft:.4} | {} | {torque:.4} | {} | {afb:.4} | {} \
         | {:.0} % |",
        win.0,
        win.1,
        hz(shaft_hz),
        hz(torque_hz),
        hz(afb_hz),
        100.0 * at_limit
    )
}

/// The section.
pub fn section(runs: &Runs) -> Result<Section> {
    let mut body = format!(
        "Each scenario's ripple window (the one its shaft-torque ripple is measured over) is \
         split at {FIRST_PART_S} s after its start: the first part holds the ring the event \
         excites (the shock, or the start of the saturated acceleration), the second the \
         steady part (for `dyno-accel`, still at the limit; for `shock` the torque is at its \
         limit only in the first 0.1 s after the step, before the window, so each run's time \
         at the limit is given with its name). Ripple: the metrics' high-passed \
         RMS (pu) of the shaft torque, the torque reference and the AFB term, each with the \
         frequency of its spectral peak (Hz); \"at limit\": the share of the part with the \
         torque reference at the torque limit. The four runs of a scenario run at the same \
         regulator gains; they differ only in `drive.accel_feedback`.\n"
    );
    for scenario in SCENARIOS {
        let (c0, _) = get(runs, scenario)?;
        let w = c0
            .scenario
            .metric_windows(f64::from(c0.drive.torque_limit_pu))
            .ripple_window_s;
        let split = (w.0 + FIRST_PART_S).min(w.1);
        let _ = write!(
            body,
            "\n`{scenario}` (headroom {} of the {} pu limit):\n\n| run | part | shaft \
             ripple | Hz | torque-reference ripple | Hz | AFB-term ripple | Hz | at limit \
             |\n|---|---|---|---|---|---|---|---|---|\n",
            c0.drive.accel_feedback.limit_headroom_fraction, c0.drive.torque_limit_pu
        );
        for (label, name) in variants(scenario) {
            let (cfg, out) = get(runs, &name)?;
            let label = format!(
                "{label} ({:.3} s at the limit in the whole run)",
                out.metrics.torque_saturated_s
            );
            let _ = writeln!(body, "{}", row(&label, "first", cfg, out, (w.0, split)));
            let _ = writeln!(body, "{}", row(&label, "rest", cfg, out, (split, w.1)));
        }
    }
    body.push_str(
        "\nReading: with the plain clamp the velocity regulator's output is clamped so that \
         it plus the AFB term held at the velocity tick meets the limit, and the AFB term, \
         recomputed every current tick from the count-quantized estimate, then takes the \
         torque off the limit by its tick-to-tick change: the \"at limit\" share falls and \
         the AFB term's noise reaches the shaft. The headroom lets the regulator ask that \
         much beyond the limit while it is saturated, so the torque stays at the limit until \
         the regulator itself asks for less (`controller-core/src/pi.rs`; the figures for \
         other headroom values are in `docs/design.md`). In `shock` the torque is at its \
         limit only during the step itself; the plain clamp ends that sooner, and the shaft \
         ring that follows is in the first part. The AFB term's own noise, at the \
         estimate's count-rate tones, stays in the torque reference outside the limit (the \
         rest of `shock`): the headroom does not change it. The first two rows of each \
         scenario differ only in the AFB filter while the torque is at the limit: held (the \
         dyno's setting) its state stays as it was when the torque reached the limit; \
         tracking, it keeps running on the estimate while its output cannot reach the \
         machine (`docs/design.md`, \"The AFB filter at the limit\").\n",
    );
    let mut s = Section::text("Saturated runs: where the shaft ripple comes from", body);
    s.plots = vec!["saturation-compare.png".into()];
    Ok(s)
}
