//! `hil-harness sweep`: the largest stable velocity bandwidth of each plant, without
//! acceleration feedback and with it. "With" is the best design found over a grid of
//! gain fraction, filter corner and estimator (not a single hand-picked design). The
//! probe run is `configs/scenarios/sweep.toml` in speed mode (position loop off), and
//! "stable" is the run's `stable` metric. A bandwidth counts only if every grid point
//! below it is stable too.

use crate::config::resolve;
use crate::error::{HarnessError, Result};
use crate::output::Staging;
use crate::plot::{save, Figure, Legend, Panel, Series};
use crate::runner::run_scenario;
use rayon::prelude::*;
use serde::Serialize;
use std::fmt::Write as _;
use std::path::Path;

/// Torque chatter (pu RMS, above ~5 Hz, unloaded at speed) below which a stable point
/// also counts as quiet: a drive engineer would hear and reject more than 0.1 pu.
pub const QUIET_TORQUE_PU: f64 = 0.1;

/// Plants swept.
pub const PLANTS: [&str; 2] = ["table1", "printing-press"];

/// Velocity bandwidths tried (rad/s).
pub const BANDWIDTHS_RAD_S: [f64; 17] = [
    1.5, 3.0, 5.0, 10.0, 20.0, 30.0, 45.0, 60.0, 94.2, 120.0, 140.0, 190.0, 250.0, 350.0, 500.0,
    700.0, 1000.0,
];

/// One acceleration-feedback design of the grid.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct AfbDesign {
    /// `off`, `plain` or `error`.
    pub mode: &'static str,
    /// Ka / J_total.
    pub gain_fraction: f64,
    /// Low-pass filter kind: `first_order` or `second_order` (Q = 0.707).
    pub filter: &'static str,
    /// Filter corner (Hz).
    pub filter_corner_hz: f64,
    /// `observer` or `differentiation`.
    pub source: &'static str,
    /// Observer bandwidth (Hz) when the source is the observer; 0 = the drive's default.
    pub observer_hz: f64,
}

impl AfbDesign {
    /// No acceleration feedback.
    pub const OFF: Self = Self {
        mode: "off",
        gain_fraction: 0.0,
        filter: "none",
        filter_corner_hz: 0.0,
        source: "observer",
        observer_hz: 0.0,
    };

    /// Short label.
    pub fn label(&self) -> String {
        if self.mode == "off" && self.observer_hz > 0.0 {
            format!("no AFB, observer {}Hz", self.observer_hz)
        } else if self.mode == "off" {
            "no AFB".into()
        } else {
            let observer = if self.observer_hz > 0.0 {
                format!(" {}Hz", self.observer_hz)
            } else {
                String::new()
            };
            format!(
                "{} Ka={}J {}-order {}Hz {}{observer}",
                self.mode,
                self.gain_fraction,
                if self.filter == "first_order" {
                    "1st"
                } else {
                    "2nd"
                },
                self.filter_corner_hz,
                self.source
            )
        }
    }

    /// The `--set` overrides of this design.
    pub fn sets(&self) -> Vec<String> {
        let mut s = vec![format!("drive.accel_feedback.mode={}", self.mode)];
        if self.mode != "off" {
            s.push(format!(
                "drive.accel_feedback.gain_fraction={}",
                self.gain_fraction
            ));
            s.push(format!("drive.accel_feedback.filter={}", self.filter));
            s.push(format!(
                "drive.accel_feedback.filter_corner_hz={}",
                self.filter_corner_hz
            ));
            s.push(format!("drive.accel_feedback.source={}", self.source));
        }
        // The observer also gives the velocity feedback, with AFB or without.
        if self.observer_hz > 0.0 {
            s.push(format!("drive.observer.bandwidth_hz={}", self.observer_hz));
        }
        s
    }
}

/// Filters tried: (kind, corner Hz).
pub const FILTERS: [(&str, f64); 6] = [
    ("first_order", 25.0),
    ("first_order", 50.0),
    ("first_order", 100.0),
    ("first_order", 250.0),
    ("second_order", 100.0),
    ("second_order", 250.0),
];

/// Gains tried (Ka / J_total).
pub const GAINS: [f64; 5] = [0.25, 0.5, 1.0, 2.0, 4.0];

/// Observer bandwidths tried when the observer is the acceleration source (Hz).
pub const OBSERVER_HZ: [f64; 2] = [75.0, 150.0];

/// The run without AFB that is the same drive as `d` without its AFB: the observer (which
/// also gives the velocity feedback) at `d`'s bandwidth, or at the drive's default.
pub fn without_afb_of(d: &AfbDesign) -> AfbDesign {
    let default_hz = f64::from(controller_core::config::defaults::OBSERVER.bandwidth_hz);
    let hz = if d.observer_hz > 0.0 && d.observer_hz != default_hz {
        d.observer_hz
    } else {
        0.0
    };
    AfbDesign {
        observer_hz: hz,
        ..AfbDesign::OFF
    }
}

/// The grid of designs: error-form AFB over source (differentiation, or the observer at
/// each bandwidth) × gain × filter, and without AFB at each observer bandwidth the AFB
/// designs use ([`without_afb_of`]).
pub fn designs() -> Vec<AfbDesign> {
    let mut v = vec![AfbDesign::OFF];
    for hz in OBSERVER_HZ {
        let off = without_afb_of(&AfbDesign {
            observer_hz: hz,
            ..AfbDesign::OFF
        });
        if !v.contains(&off) {
            v.push(off);
        }
    }
    let sources = [("differentiation", 0.0)]
        .into_iter()
        .chain(OBSERVER_HZ.iter().map(|hz| ("observer", *hz)));
    for (source, observer_hz) in sources {
        for gain_fraction in GAINS {
            for (filter, filter_corner_hz) in FILTERS {
                v.push(AfbDesign {
                    mode: "error",
                    gain_fraction,
                    filter,
                    filter_corner_hz,
                    source,
                    observer_hz,
                });
            }
        }
    }
    v
}

/// One sweep point.
#[derive(Clone, Debug, Serialize)]
pub struct SweepPoint {
    /// Plant config name.
    pub plant: String,
    /// Design label.
    pub design: String,
    /// The design (its fields are written out below for the CSV).
    #[serde(skip)]
    pub afb: AfbDesign,
    /// AFB mode.
    pub mode: &'static str,
    /// Ka / J_total.
    pub gain_fraction: f64,
    /// Filter kind.
    pub filter: &'static str,
    /// Filter corner (Hz).
    pub filter_corner_hz: f64,
    /// Acceleration source.
    pub source: &'static str,
    /// Observer bandwidth (Hz), 0 = default.
    pub observer_hz: f64,
    /// Velocity bandwidth (rad/s).
    pub bandwidth_rad_s: f64,
    /// The run's `stable` metric.
    pub stable: bool,
    /// Standard deviation of speed error in the stability window (pu).
    pub oscillation_pu: f64,
    /// Torque ripple RMS in the loaded window (pu).
    pub torque_ripple_rms_pu: f64,
    /// Motor-torque chatter in the stability window (pu).
    pub limit_cycle_torque_pu: f64,
    /// Stable and the torque chatter below [`QUIET_TORQUE_PU`].
    pub quiet: bool,
    /// The controller faulted.
    pub faulted: bool,
    /// Error text if the configuration was rejected (e.g. a gain does not fit).
    pub error: String,
}

/// The best result per plant.
#[derive(Clone, Debug, Serialize)]
pub struct SweepResult {
    /// Plant.
    pub plant: String,
    /// Largest stable bandwidth without acceleration feedback (rad/s); 0 if none.
    pub without_afb_rad_s: f64,
    /// Largest stable bandwidth over all AFB designs (rad/s).
    pub with_afb_rad_s: f64,
    /// The design that achieved it.
    pub best_design: String,
    /// Largest quiet bandwidth without AFB (rad/s).
    pub quiet_without_afb_rad_s: f64,
    /// Largest quiet bandwidth over all AFB designs (rad/s).
    pub quiet_with_afb_rad_s: f64,
    /// The design that achieved it.
    pub best_quiet_design: String,
}

/// Largest bandwidth with every grid point up to it passing `ok`.
pub fn largest(points: &[&SweepPoint], ok: fn(&SweepPoint) -> bool) -> f64 {
    let mut sorted: Vec<&&SweepPoint> = points.iter().collect();
    sorted.sort_by(|a, b| a.bandwidth_rad_s.total_cmp(&b.bandwidth_rad_s));
    let mut best = 0.0;
    for p in sorted {
        if !ok(p) {
            break;
        }
        best = p.bandwidth_rad_s;
    }
    best
}

/// Largest bandwidth with every grid point up to it stable.
pub fn largest_stable(points: &[&SweepPoint]) -> f64 {
    largest(points, |p| p.stable)
}

/// The probe run of one grid point. A run without AFB uses the regulator gains of the
/// plant's default AFB design at the same bandwidth and observer bandwidth, bit for bit;
/// with the PI sized for J_total (`velocity_pi_inertia = "total"`) those are the gains of
/// every design of the grid with that observer (`the_run_without_afb_has_the_gains_of_
/// every_design` below), so one run without AFB per bandwidth and observer is the
/// same-gains comparison for all of them.
pub fn point_config(
    plant: &str,
    design: &AfbDesign,
    bw: f64,
    base_sets: &[String],
) -> Result<crate::config::RunConfig> {
    let mut sets = base_sets.to_vec();
    sets.push("drive.position_bandwidth_rad_s=0".into());
    sets.push(format!("drive.velocity_bandwidth_rad_s={bw}"));
    if design.mode == "off" {
        let mut afb_sets = sets.clone();
        afb_sets.extend(design.sets().into_iter().filter(|s| s.contains("observer")));
        let afb = resolve("sweep", Some(plant), &afb_sets)?;
        sets.extend(design.sets());
        let mut cfg = resolve("sweep", Some(plant), &sets)?;
        crate::config::borrow_gains(
            &mut cfg,
            &format!("{plant}'s default AFB design at {bw} rad/s"),
            &afb.drive,
        )?;
        Ok(cfg)
    } else {
        sets.extend(design.sets());
        resolve("sweep", Some(plant), &sets)
    }
}

fn run_point(plant: &str, design: &AfbDesign, bw: f64, base_sets: &[String]) -> SweepPoint {
    let mut point = SweepPoint {
        plant: plant.into(),
        design: design.label(),
        afb: design.clone(),
        mode: design.mode,
        gain_fraction: design.gain_fraction,
        filter: design.filter,
        filter_corner_hz: design.filter_corner_hz,
        source: design.source,
        observer_hz: design.observer_hz,
        bandwidth_rad_s: bw,
        stable: false,
        oscillation_pu: f64::NAN,
        torque_ripple_rms_pu: f64::NAN,
        limit_cycle_torque_pu: f64::NAN,
        quiet: false,
        faulted: false,
        error: String::new(),
    };
    match point_config(plant, design, bw, base_sets).and_then(|cfg| run_scenario(&cfg)) {
        Ok(out) => {
            point.stable = out.metrics.stable;
            point.oscillation_pu = out.metrics.oscillation_pu;
            point.torque_ripple_rms_pu = out.metrics.torque_ripple_rms_pu;
            point.limit_cycle_torque_pu = out.metrics.limit_cycle_torque_pu;
            point.quiet = out.metrics.stable && out.metrics.limit_cycle_torque_pu < QUIET_TORQUE_PU;
            point.faulted = out.metrics.faulted;
        }
        Err(e) => point.error = e.to_string(),
    }
    point
}

/// Runs the whole grid in parallel; `base_sets` are applied to every run.
pub fn sweep_points(
    plants: &[&str],
    bandwidths: &[f64],
    designs: &[AfbDesign],
    base_sets: &[String],
) -> Vec<SweepPoint> {
    let jobs: Vec<(&str, &AfbDesign, f64)> = plants
        .iter()
        .flat_map(|p| {
            designs
                .iter()
                .flat_map(move |d| bandwidths.iter().map(move |b| (*p, d, *b)))
        })
        .collect();
    let pb = crate::progress::bar(jobs.len() as u64, "sweep");
    let points: Vec<SweepPoint> = jobs
        .par_iter()
        .map(|(p, d, b)| {
            let r = run_point(p, d, *b, base_sets);
            pb.inc(1);
            r
        })
        .collect();
    pb.finish_and_clear();
    points
}

/// Reduces the grid to one result per plant.
pub fn results(points: &[SweepPoint], plants: &[&str], designs: &[AfbDesign]) -> Vec<SweepResult> {
    plants
        .iter()
        .map(|plant| {
            let of = |d: &AfbDesign| -> Vec<&SweepPoint> {
                points
                    .iter()
                    .filter(|p| p.plant == *plant && p.afb == *d)
                    .collect()
            };
            // Without AFB: the best of the runs without AFB (one per observer bandwidth).
            let offs = designs.iter().filter(|d| d.mode == "off");
            let without = offs
                .clone()
                .map(|d| largest_stable(&of(d)))
                .fold(0.0, f64::max);
            let quiet_without = offs
                .map(|d| largest(&of(d), |p| p.quiet))
                .fold(0.0, f64::max);
            let mut best = (0.0, String::from("none"));
            let mut best_quiet = (0.0, String::from("none"));
            for d in designs.iter().filter(|d| d.mode != "off") {
                let bw = largest_stable(&of(d));
                if bw > best.0 {
                    best = (bw, d.label());
                }
                let q = largest(&of(d), |p| p.quiet);
                if q > best_quiet.0 {
                    best_quiet = (q, d.label());
                }
            }
            SweepResult {
                plant: (*plant).into(),
                without_afb_rad_s: without,
                with_afb_rad_s: best.0,
                best_design: best.1,
                quiet_without_afb_rad_s: quiet_without,
                quiet_with_afb_rad_s: best_quiet.0,
                best_quiet_design: best_quiet.1,
            }
        })
        .collect()
}

fn write_csv(points: &[SweepPoint], path: &Path) -> Result<()> {
    let mut w = csv::Writer::from_path(path).map_err(|e| HarnessError::io(path, e))?;
    for p in points {
        w.serialize(p).map_err(|e| HarnessError::io(path, e))?;
    }
    w.flush().map_err(|e| HarnessError::io(path, e))
}

/// The sweep figure: per plant, the torque chatter (unloaded, at speed) against
/// bandwidth without AFB and with the best quiet design, stable and unstable points apart,
/// with the quiet threshold.
pub fn figure(points: &[SweepPoint], results: &[SweepResult]) -> Figure {
    let panels = results
        .iter()
        .map(|r| {
            let curve = |label: &str, stable: bool| -> Vec<(f64, f64)> {
                points
                    .iter()
                    .filter(|p| p.plant == r.plant && p.design == label && p.stable == stable)
                    .filter(|p| p.limit_cycle_torque_pu.is_finite())
                    .map(|p| (p.bandwidth_rad_s, p.limit_cycle_torque_pu.max(1e-4)))
                    .collect()
            };
            let best = r.best_quiet_design.as_str();
            let (lo, hi) = BANDWIDTHS_RAD_S
                .iter()
                .fold((f64::MAX, 0.0f64), |a, x| (a.0.min(*x), a.1.max(*x)));
            Panel {
                title: format!(
                    "{}: quiet up to {} rad/s without AFB, {} with; stable up to {} / {}",
                    r.plant,
                    r.quiet_without_afb_rad_s,
                    r.quiet_with_afb_rad_s,
                    r.without_afb_rad_s,
                    r.with_afb_rad_s
                ),
                y_label: "torque chatter (pu RMS)".into(),
                series: vec![
                    Series::markers("no AFB, stable", curve("no AFB", true)),
                    Series::markers("no AFB, unstable", curve("no AFB", false)),
                    Series::markers(format!("{best}, stable"), curve(best, true)),
                    Series::markers(format!("{best}, unstable"), curve(best, false)),
                    Series::line(
                        "quiet threshold",
                        vec![(lo, QUIET_TORQUE_PU), (hi, QUIET_TORQUE_PU)],
                    ),
                ],
                log_x: true,
                log_y: true,
                legend: Legend::UpperLeft,
            }
        })
        .collect();
    Figure {
        x_label: "velocity bandwidth (rad/s)".into(),
        panels,
    }
}

/// `hil-harness sweep` into a staging directory; returns the results and a text summary.
pub fn sweep_into(dir: &Path) -> Result<(Vec<SweepResult>, String)> {
    let designs = designs();
    let points = sweep_points(&PLANTS, &BANDWIDTHS_RAD_S, &designs, &[]);
    let results = results(&points, &PLANTS, &designs);
    write_csv(&points, &dir.join("sweep.csv"))?;
    let mut w = csv::Writer::from_path(dir.join("sweep_summary.csv"))
        .map_err(|e| HarnessError::io(dir, e))?;
    for r in &results {
        w.serialize(r).map_err(|e| HarnessError::io(dir, e))?;
    }
    w.flush().map_err(|e| HarnessError::io(dir, e))?;
    save(&figure(&points, &results), &dir.join("sweep"))?;
    let mut text = String::new();
    for r in &results {
        let _ = writeln!(
            text,
            "{}: largest stable velocity bandwidth {} rad/s without AFB, {} rad/s with ({}); \
             largest quiet (torque chatter < {QUIET_TORQUE_PU} pu) {} rad/s without, {} rad/s with ({})",
            r.plant,
            r.without_afb_rad_s,
            r.with_afb_rad_s,
            r.best_design,
            r.quiet_without_afb_rad_s,
            r.quiet_with_afb_rad_s,
            r.best_quiet_design
        );
    }
    let _ = writeln!(
        text,
        "{} closed-loop runs on {} threads",
        points.len(),
        rayon::current_num_threads()
    );
    let errors = points.iter().filter(|p| !p.error.is_empty()).count();
    if errors > 0 {
        let _ = writeln!(text, "{errors} grid points were rejected by the configuration checks (see sweep.csv `error`)");
    }
    Ok((results, text))
}

/// `hil-harness sweep`.
pub fn sweep(out: &Path) -> Result<String> {
    let staging = Staging::new(out)?;
    let (_, text) = sweep_into(staging.dir())?;
    staging.commit()?;
    Ok(text)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn point(bw: f64, stable: bool) -> SweepPoint {
        SweepPoint {
            plant: "p".into(),
            design: "d".into(),
            afb: AfbDesign::OFF,
            mode: "off",
            gain_fraction: 0.0,
            filter: "none",
            filter_corner_hz: 0.0,
            source: "observer",
            observer_hz: 0.0,
            bandwidth_rad_s: bw,
            stable,
            oscillation_pu: 0.0,
            torque_ripple_rms_pu: 0.0,
            limit_cycle_torque_pu: 0.0,
            quiet: stable,
            faulted: false,
            error: String::new(),
        }
    }

    #[test]
    fn largest_stable_stops_at_the_first_unstable_point() {
        let pts = [
            point(30.0, true),
            point(10.0, true),
            point(60.0, false),
            point(90.0, true),
        ];
        let refs: Vec<&SweepPoint> = pts.iter().collect();
        assert_eq!(largest_stable(&refs), 30.0);
        let none = [point(10.0, false), point(30.0, true)];
        let refs: Vec<&SweepPoint> = none.iter().collect();
        assert_eq!(largest_stable(&refs), 0.0);
    }

    #[test]
    fn the_run_without_afb_has_the_gains_of_every_design() {
        for plant in PLANTS {
            for bw in [10.0, 94.2] {
                for d in designs().iter().filter(|d| d.mode != "off") {
                    let off = point_config(plant, &without_afb_of(d), bw, &[]).unwrap();
                    let g_off = crate::runner::regulator_gains(&off).unwrap();
                    assert_eq!(g_off.ka, 0.0);
                    let Ok(on) = point_config(plant, d, bw, &[]) else {
                        continue; // rejected by the configuration checks (see sweep.csv)
                    };
                    let g = crate::runner::regulator_gains(&on).unwrap();
                    assert!(
                        crate::runner::same_regulator_gains(&g_off, &g),
                        "{plant} {bw} rad/s {}:\n{g_off:?}\n{g:?}",
                        d.label()
                    );
                }
            }
        }
    }

    #[test]
    fn the_design_grid_holds_off_and_every_combination() {
        let d = designs();
        let offs = d.iter().filter(|x| x.mode == "off").count();
        assert_eq!(offs, OBSERVER_HZ.len(), "one per observer bandwidth");
        assert_eq!(
            d.len(),
            offs + (1 + OBSERVER_HZ.len()) * GAINS.len() * FILTERS.len()
        );
        // Every AFB design has its run without AFB in the grid.
        assert!(d.iter().all(|x| d.contains(&without_afb_of(x))));
        let labels: std::collections::BTreeSet<String> = d.iter().map(AfbDesign::label).collect();
        assert_eq!(labels.len(), d.len(), "labels must be unique");
    }
}
