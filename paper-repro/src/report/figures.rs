//! The comparison figures of the report: one signal of several runs per panel.

use super::facts::fill;
use super::{get, Runs};
use sim_engine::engine::trace::TraceRow;
use sim_engine::error::Result;
use sim_engine::plot::{save, Figure, Panel, Series};
use std::path::Path;

/// One panel: a signal of several runs, each with its legend label. The title and the
/// labels may hold the placeholders of [`fill`], taken from the config of the panel's
/// first run (for a title) or of the labelled run.
struct PanelSpec {
    title: &'static str,
    y_label: &'static str,
    /// (legend label, scenario).
    runs: &'static [(&'static str, &'static str)],
    signal: fn(&TraceRow) -> f64,
}

const fn spec(
    title: &'static str,
    y_label: &'static str,
    runs: &'static [(&'static str, &'static str)],
    signal: fn(&TraceRow) -> f64,
) -> PanelSpec {
    PanelSpec {
        title,
        y_label,
        runs,
        signal,
    }
}

const SPEED: &str = "speed (pu)";
const TORQUE: &str = "torque (pu)";
const FIG6: &[(&str, &str)] = &[("AFB on", "fig6"), ("AFB off, same gains", "fig6-no-afb")];
const FIG6_65K: &[(&str, &str)] = &[
    ("AFB on", "fig6-65k"),
    ("AFB off, same gains", "fig6-65k-no-afb"),
];
const DYNO: &[(&str, &str)] = &[
    ("AFB off (Fig. 9)", "dyno-accel-no-afb"),
    ("AFB on (Fig. 10)", "dyno-accel"),
];
const SHOCK: &[(&str, &str)] = &[
    ("AFB off (Fig. 11)", "shock-no-afb"),
    ("AFB on (Fig. 12)", "shock"),
];
const SHOCK_30: &[(&str, &str)] = &[("AFB off", "shock-30-no-afb"), ("AFB on", "shock-30")];

const SHOCK_50: &[(&str, &str)] = &[
    ("AFB off, same gains", "shock-50-no-afb"),
    ("AFB on", "shock-50"),
];
const DYNO_SAT: &[(&str, &str)] = &[
    ("AFB, headroom, filter held", "dyno-accel"),
    ("AFB, headroom, filter tracks", "dyno-accel-filter-track"),
    ("AFB, plain clamp", "dyno-accel-no-headroom"),
    ("no AFB", "dyno-accel-no-afb"),
];
const SHOCK_SAT: &[(&str, &str)] = &[
    ("AFB, headroom, filter held", "shock"),
    ("AFB, headroom, filter tracks", "shock-filter-track"),
    ("AFB, plain clamp", "shock-no-headroom"),
    ("no AFB", "shock-no-afb"),
];
const FIG6_ON: &[(&str, &str)] = &[("AFB on", "fig6")];
const LOW_BW: &[(&str, &str)] = &[("AFB off, {bw} rad/s", "fig6-low-bw")];

/// The figures: (file name without extension, panels).
#[rustfmt::skip] // a table: one panel a line
const FIGURES: &[(&str, &[PanelSpec])] = &[
    ("fig6-compare", &[
        spec("Fig. 6: load speed", SPEED, FIG6, |r| r.load_vel_pu),
        spec("Fig. 7: motor torque (current)", TORQUE, FIG6, |r| r.current_pu),
        spec("Fig. 7: acceleration compensation signal", TORQUE, FIG6_ON, |r| r.accel_fb_pu),
        spec("AFB off at {bw} rad/s: load speed", SPEED, LOW_BW, |r| r.load_vel_pu),
    ]),
    ("fig6-65k-compare", &[
        spec("{counts} counts/rev: load speed", SPEED, FIG6_65K, |r| r.load_vel_pu),
        spec("{counts} counts/rev: shaft torque", TORQUE, FIG6_65K, |r| r.shaft_torque_pu),
    ]),
    ("dyno-accel-compare", &[
        spec("Dyno acceleration, {load} load: speed", SPEED, DYNO, |r| r.motor_vel_pu),
        spec("Dyno acceleration: transducer (shaft) torque", TORQUE, DYNO, |r| r.shaft_torque_pu),
    ]),
    ("shock-compare", &[
        spec("{load} shock at rated speed, {bw} rad/s: speed", SPEED, SHOCK, |r| r.motor_vel_pu),
        spec("{bw} rad/s: shaft torque", TORQUE, SHOCK, |r| r.shaft_torque_pu),
        spec("{load} shock at rated speed, {bw} rad/s: shaft torque", TORQUE, SHOCK_50, |r| r.shaft_torque_pu),
        spec("{bw} rad/s (Fig. 13): speed", SPEED, SHOCK_30, |r| r.motor_vel_pu),
        spec("{bw} rad/s (Fig. 13): shaft torque", TORQUE, SHOCK_30, |r| r.shaft_torque_pu),
    ]),
    ("saturation-compare", &[
        spec("Dyno acceleration, {load} load: torque reference", TORQUE, DYNO_SAT, |r| r.torque_cmd_pu),
        spec("Dyno acceleration: shaft torque", TORQUE, DYNO_SAT, |r| r.shaft_torque_pu),
        spec("{load} shock at rated speed: torque reference", TORQUE, SHOCK_SAT, |r| r.torque_cmd_pu),
        spec("{load} shock at rated speed: shaft torque", TORQUE, SHOCK_SAT, |r| r.shaft_torque_pu),
    ]),
];

fn panel(runs: &Runs, spec: &PanelSpec) -> Result<Panel> {
    let mut series = Vec::with_capacity(spec.runs.len());
    let mut title = spec.title.to_string();
    for (i, (label, name)) in spec.runs.iter().enumerate() {
        let (cfg, out) = get(runs, name)?;
        if i == 0 {
            title = fill(spec.title, cfg);
        }
        series.push(Series::line(
            fill(label, cfg),
            out.trace.series(spec.signal),
        ));
    }
    Ok(Panel {
        title,
        y_label: spec.y_label.into(),
        series,
        ..Default::default()
    })
}

/// Writes every comparison figure into `dir` (SVG and PNG).
pub fn write_all(runs: &Runs, dir: &Path) -> Result<()> {
    for (file, specs) in FIGURES {
        let panels = specs
            .iter()
            .map(|s| panel(runs, s))
            .collect::<Result<Vec<_>>>()?;
        save(
            &Figure {
                x_label: "time (s)".into(),
                panels,
            },
            &dir.join(file),
        )?;
    }
    Ok(())
}
