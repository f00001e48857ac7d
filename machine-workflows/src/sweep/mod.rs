//! `hil-harness sweep`: the largest stable velocity bandwidth of each plant, without
//! acceleration feedback and with it. "With" is the best design found over a grid of
//! gain fraction, filter corner and estimator (not a single hand-picked design): the grid
//! is `[sweep]` of `configs/grids.toml`. The probe run is `configs/scenarios/sweep.toml` in speed mode (position loop off), and
//! "stable" is the run's `stable` metric. A bandwidth counts only if every grid point
//! below it is stable too.

pub mod figure;
pub mod grid;
pub mod limits;

pub use grid::{designs, without_afb_of, AfbDesign};

use controller_core::AfbMode;
use grid::{filter_parts, word};
use rayon::prelude::*;
use serde::Serialize;
use sim_engine::config::{borrow_gains, resolve, RunConfig};
use sim_engine::engine::metrics::OscillationKind;
use sim_engine::engine::runner::run_scenario;
use sim_engine::error::{HarnessError, Result};
use sim_engine::plot::save;
use std::fmt::Write as _;
use std::path::Path;

/// Torque chatter (pu RMS, above ~5 Hz, unloaded at speed) below which a stable point
/// also counts as quiet: a drive engineer would hear and reject more than 0.1 pu.
pub const QUIET_TORQUE_PU: f64 = 0.1;

/// Plants swept.
pub const PLANTS: [&str; 2] = ["table1", "printing-press"];

/// The observer bandwidth of the drive's default design (Hz): a design at it is the
/// config's own observer.
pub fn default_observer_hz() -> f32 {
    controller_core::config::defaults::OBSERVER.bandwidth_hz
}

/// One sweep point.
#[derive(Clone, Debug, Serialize)]
pub struct SweepPoint {
    /// Plant config name.
    pub plant: String,
    /// Design label.
    pub design: String,
    /// The design.
    #[serde(skip)]
    pub afb: AfbDesign,
    /// The design's form, for the CSV.
    pub mode: String,
    /// Ka / J_total.
    pub gain_fraction: f32,
    /// Filter kind.
    pub filter: &'static str,
    /// Filter corner (Hz).
    pub filter_corner_hz: f32,
    /// Acceleration source.
    pub source: String,
    /// Observer bandwidth (Hz), 0 = the config's.
    pub observer_hz: f32,
    /// Velocity bandwidth (rad/s).
    pub bandwidth_rad_s: f64,
    /// The run's `stable` metric.
    pub stable: bool,
    /// The run's `stable_by_speed`: the criterion without the oscillation verdict.
    pub stable_by_speed: bool,
    /// The oscillation verdict (`summary.json`'s `oscillation.kind`); empty if not run.
    pub oscillation: Option<OscillationKind>,
    /// Its spectral peak (Hz).
    pub oscillation_freq_hz: f64,
    /// Its torque amplitude (pu).
    pub oscillation_amplitude_pu: f64,
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

/// The probe run of one grid point, from the plant's probe config `base` (the `sweep`
/// scenario on that plant). A run without AFB uses the regulator gains of the plant's
/// default AFB design at the same bandwidth and observer bandwidth, bit for bit; with the
/// PI sized for J_total (`velocity_pi_inertia = "total"`) those are the gains of every
/// design of the grid with that observer (`the_run_without_afb_has_the_gains_of_
/// every_design` below), so one run without AFB per bandwidth and observer is the
/// same-gains comparison for all of them.
pub fn point_from(base: &RunConfig, design: &AfbDesign, bw: f64) -> Result<RunConfig> {
    let mut cfg = base.clone();
    cfg.drive.position_bandwidth_rad_s = 0.0;
    cfg.drive.velocity_bandwidth_rad_s = bw as f32;
    if design.mode == AfbMode::Off {
        // The AFB design it borrows from: the config's, with this observer bandwidth.
        let mut afb = cfg.clone();
        if design.observer_hz > 0.0 {
            afb.drive.observer.bandwidth_hz = design.observer_hz;
        }
        design.apply(&mut cfg.drive);
        borrow_gains(
            &mut cfg,
            &format!("{}'s default AFB design at {bw} rad/s", base_plant(base)),
            &afb.drive,
        )?;
    } else {
        design.apply(&mut cfg.drive);
    }
    Ok(cfg)
}

/// The plant's name: its config file's stem.
fn base_plant(cfg: &RunConfig) -> String {
    cfg.config_path
        .file_stem()
        .map_or_else(String::new, |s| s.to_string_lossy().into_owned())
}

/// The probe config of `plant` with `base_sets` applied.
pub fn probe_config(plant: &str, base_sets: &[String]) -> Result<RunConfig> {
    resolve("sweep", Some(plant), base_sets)
}

/// [`point_from`] the probe config of `plant`.
pub fn point_config(
    plant: &str,
    design: &AfbDesign,
    bw: f64,
    base_sets: &[String],
) -> Result<RunConfig> {
    point_from(&probe_config(plant, base_sets)?, design, bw)
}

impl SweepPoint {
    /// The point of `design` at `bw` on `plant`, before its run.
    fn new(plant: &str, design: &AfbDesign, bw: f64) -> Self {
        let (filter, filter_corner_hz) = filter_parts(design.filter);
        Self {
            plant: plant.into(),
            design: design.label(),
            afb: *design,
            mode: word(design.mode),
            gain_fraction: design.gain_fraction,
            filter,
            filter_corner_hz,
            source: word(design.source),
            observer_hz: design.observer_hz,
            bandwidth_rad_s: bw,
            stable: false,
            stable_by_speed: false,
            oscillation: None,
            oscillation_freq_hz: f64::NAN,
            oscillation_amplitude_pu: f64::NAN,
            oscillation_pu: f64::NAN,
            torque_ripple_rms_pu: f64::NAN,
            limit_cycle_torque_pu: f64::NAN,
            quiet: false,
            faulted: false,
            error: String::new(),
        }
    }
}

fn run_point(base: &Result<RunConfig>, plant: &str, design: &AfbDesign, bw: f64) -> SweepPoint {
    let mut point = SweepPoint::new(plant, design, bw);
    let run = match base {
        Ok(base) => point_from(base, design, bw).and_then(|cfg| run_scenario(&cfg)),
        Err(e) => Err(HarnessError::Backend(e.to_string())),
    };
    match run {
        Ok(out) => {
            point.stable = out.metrics.stable;
            point.stable_by_speed = out.metrics.stable_by_speed;
            point.oscillation = Some(out.metrics.oscillation.kind);
            point.oscillation_freq_hz = out.metrics.oscillation.freq_hz;
            point.oscillation_amplitude_pu = out.metrics.oscillation.amplitude_pu;
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
    // Each plant's probe config is read once; every point clones it and sets its fields.
    let bases: Vec<(&str, Result<RunConfig>)> = plants
        .iter()
        .map(|p| (*p, probe_config(p, base_sets)))
        .collect();
    let base_of = |plant: &str| bases.iter().find(|(p, _)| *p == plant).map(|(_, b)| b);
    let pb = sim_engine::progress::bar(jobs.len() as u64, "sweep");
    let points: Vec<SweepPoint> = jobs
        .par_iter()
        .map(|(p, d, b)| {
            let r = match base_of(p) {
                Some(base) => run_point(base, p, d, *b),
                None => SweepPoint::new(p, d, *b),
            };
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
            let offs = designs.iter().filter(|d| d.mode == AfbMode::Off);
            let without = offs
                .clone()
                .map(|d| largest_stable(&of(d)))
                .fold(0.0, f64::max);
            let quiet_without = offs
                .map(|d| largest(&of(d), |p| p.quiet))
                .fold(0.0, f64::max);
            let mut best = (0.0, String::from("none"));
            let mut best_quiet = (0.0, String::from("none"));
            for d in designs.iter().filter(|d| d.mode != AfbMode::Off) {
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

/// `hil-harness sweep` into a staging directory; returns the points, the results and a
/// text summary.
pub fn sweep_into(dir: &Path) -> Result<(Vec<SweepPoint>, Vec<SweepResult>, String)> {
    let grid = sim_engine::config::sweep_grid()?;
    let designs = designs(&grid, default_observer_hz());
    let points = sweep_points(&PLANTS, &grid.bandwidths_rad_s, &designs, &[]);
    let results = results(&points, &PLANTS, &designs);
    write_csv(&points, &dir.join("sweep.csv"))?;
    let mut w = csv::Writer::from_path(dir.join("sweep_summary.csv"))
        .map_err(|e| HarnessError::io(dir, e))?;
    for r in &results {
        w.serialize(r).map_err(|e| HarnessError::io(dir, e))?;
    }
    w.flush().map_err(|e| HarnessError::io(dir, e))?;
    let figure = figure::figure(&points, &results, &grid.bandwidths_rad_s);
    save(&figure, &dir.join("sweep"))?;
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
    Ok((points, results, text))
}

/// `hil-harness sweep`.
pub fn sweep(out: &Path) -> Result<String> {
    sim_engine::output::staged(out, |dir| sweep_into(dir).map(|(_, _, text)| text))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn point(bw: f64, stable: bool) -> SweepPoint {
        SweepPoint {
            stable,
            quiet: stable,
            ..SweepPoint::new("p", &AfbDesign::OFF, bw)
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
        let grid = sim_engine::config::sweep_grid().unwrap();
        for plant in PLANTS {
            for bw in [10.0, 94.25] {
                for d in designs(&grid, default_observer_hz())
                    .iter()
                    .filter(|d| d.mode != AfbMode::Off)
                {
                    let off =
                        point_config(plant, &without_afb_of(d, default_observer_hz()), bw, &[])
                            .unwrap();
                    let g_off = sim_engine::engine::runner::regulator_gains(&off).unwrap();
                    assert_eq!(g_off.ka, 0.0);
                    let Ok(on) = point_config(plant, d, bw, &[]) else {
                        continue; // rejected by the configuration checks (see sweep.csv)
                    };
                    let g = sim_engine::engine::runner::regulator_gains(&on).unwrap();
                    assert!(
                        sim_engine::engine::runner::same_regulator_gains(&g_off, &g),
                        "{plant} {bw} rad/s {}:\n{g_off:?}\n{g:?}",
                        d.label()
                    );
                }
            }
        }
    }

    #[test]
    fn the_design_grid_holds_off_and_every_combination() {
        let hz = default_observer_hz();
        let grid = sim_engine::config::sweep_grid().unwrap();
        let d = designs(&grid, hz);
        let offs = d.iter().filter(|x| x.mode == AfbMode::Off).count();
        let observers = grid.observer_hz.len();
        assert_eq!(offs, observers, "one per observer bandwidth");
        assert_eq!(
            d.len(),
            offs + (1 + observers) * grid.gains.len() * grid.filters.len()
        );
        // Every AFB design has its run without AFB in the grid.
        assert!(d.iter().all(|x| d.contains(&without_afb_of(x, hz))));
        let labels: std::collections::BTreeSet<String> = d.iter().map(AfbDesign::label).collect();
        assert_eq!(labels.len(), d.len(), "labels must be unique");
    }
}
