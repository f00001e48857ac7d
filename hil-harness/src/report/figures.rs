//! The comparison figures of the report: one signal of several runs per panel.

use super::{get, Runs};
use crate::engine::trace::TraceRow;
use crate::error::Result;
use crate::plot::{save, Figure, Panel, Series};
use std::path::Path;

/// One panel: a signal of several runs, each with its legend label.
struct PanelSpec {
    title: &'static str,
    y_label: &'static str,
    /// (legend label, scenario).
    runs: &'static [(&'static str, &'static str)],
    signal: fn(&TraceRow) -> f64,
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

/// The figures: (file name without extension, panels).
const FIGURES: &[(&str, &[PanelSpec])] = &[
    (
        "fig6-compare",
        &[
            PanelSpec {
                title: "Fig. 6: load speed",
                y_label: SPEED,
                runs: FIG6,
                signal: |r| r.load_vel_pu,
            },
            PanelSpec {
                title: "Fig. 7: motor torque (current)",
                y_label: TORQUE,
                runs: FIG6,
                signal: |r| r.current_pu,
            },
            PanelSpec {
                title: "Fig. 7: acceleration compensation signal",
                y_label: TORQUE,
                runs: &[("AFB on", "fig6")],
                signal: |r| r.accel_fb_pu,
            },
            PanelSpec {
                title: "AFB off at 1.5 rad/s: load speed",
                y_label: SPEED,
                runs: &[("AFB off, 1.5 rad/s", "fig6-low-bw")],
                signal: |r| r.load_vel_pu,
            },
        ],
    ),
    (
        "fig6-65k-compare",
        &[
            PanelSpec {
                title: "65,536 interpolated counts: load speed",
                y_label: SPEED,
                runs: FIG6_65K,
                signal: |r| r.load_vel_pu,
            },
            PanelSpec {
                title: "65,536 interpolated counts: shaft torque",
                y_label: TORQUE,
                runs: FIG6_65K,
                signal: |r| r.shaft_torque_pu,
            },
        ],
    ),
    (
        "dyno-accel-compare",
        &[
            PanelSpec {
                title: "Dyno acceleration, 150 % load: speed",
                y_label: SPEED,
                runs: DYNO,
                signal: |r| r.motor_vel_pu,
            },
            PanelSpec {
                title: "Dyno acceleration: transducer (shaft) torque",
                y_label: TORQUE,
                runs: DYNO,
                signal: |r| r.shaft_torque_pu,
            },
        ],
    ),
    (
        "shock-compare",
        &[
            PanelSpec {
                title: "150 % shock at rated speed, 100 rad/s: speed",
                y_label: SPEED,
                runs: SHOCK,
                signal: |r| r.motor_vel_pu,
            },
            PanelSpec {
                title: "100 rad/s: shaft torque",
                y_label: TORQUE,
                runs: SHOCK,
                signal: |r| r.shaft_torque_pu,
            },
            PanelSpec {
                title: "50 % shock at rated speed, 100 rad/s: shaft torque",
                y_label: TORQUE,
                runs: &[
                    ("AFB off, same gains", "shock-50-no-afb"),
                    ("AFB on", "shock-50"),
                ],
                signal: |r| r.shaft_torque_pu,
            },
            PanelSpec {
                title: "30 rad/s (Fig. 13): speed",
                y_label: SPEED,
                runs: SHOCK_30,
                signal: |r| r.motor_vel_pu,
            },
            PanelSpec {
                title: "30 rad/s (Fig. 13): shaft torque",
                y_label: TORQUE,
                runs: SHOCK_30,
                signal: |r| r.shaft_torque_pu,
            },
        ],
    ),
];

fn panel(runs: &Runs, spec: &PanelSpec) -> Result<Panel> {
    let mut series = Vec::with_capacity(spec.runs.len());
    for (label, name) in spec.runs {
        let (_, out) = get(runs, name)?;
        series.push(Series::line(*label, out.trace.series(spec.signal)));
    }
    Ok(Panel {
        title: spec.title.into(),
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
