//! The paper's Sec. II claim with the paper's own estimator: "the velocity and
//! acceleration signals were found by differentiation", and "if the acceleration signal
//! was not fed back to the controller, the system would become unstable".
//!
//! The map, once per encoder resolution of [`ENCODER_INTERPOLATIONS`] (Table 1's 4096
//! counts, and the same encoder interpolated): `fig6` with differentiated velocity (first-order filter at each corner of
//! [`VELOCITY_CORNERS_HZ`]) and differentiated acceleration for the AFB path (first-order
//! filter at each corner of [`AFB_CORNERS_HZ`]), the drive's default AFB gain and form.
//! At each velocity corner the loop runs without AFB at the regulator gains of the AFB
//! design (bit for bit, [`sim_engine::config::borrow_gains`]); with AFB off the AFB filter is
//! not used, so one run without AFB per velocity corner covers every AFB corner. "Stable"
//! is fig6's `stable` metric. Every cell is reported; no point is picked from the map.

use controller_core::{AfbMode, Estimator, FilterConfig};
use rayon::prelude::*;
use serde::Serialize;
use sim_engine::config::{borrow_gains, resolve, RunConfig};
use sim_engine::engine::metrics::OscillationKind;
use sim_engine::engine::runner::run_scenario;
use sim_engine::error::{HarnessError, Result};
use sim_engine::plot::{save, Figure, Legend, Panel, Series};
use std::fmt::Write as _;
use std::path::Path;

mod text;
pub use text::{summary_text, table};

/// Velocity-feedback filter corners (Hz, first order at the velocity rate).
pub const VELOCITY_CORNERS_HZ: [f64; 9] = [10.0, 15.0, 25.0, 35.0, 50.0, 75.0, 100.0, 150.0, 250.0];

/// Acceleration-feedback filter corners (Hz, first order at the AFB rate).
pub const AFB_CORNERS_HZ: [f64; 6] = [10.0, 25.0, 50.0, 100.0, 200.0, 400.0];

/// Sin/cos interpolation factors of the 4096-count encoder (1 = Table 1's plain counts).
/// The following-error trip is kept at the same angle (Table 1's counts × factor).
pub const ENCODER_INTERPOLATIONS: [u32; 2] = [1, 16];

/// The scenario the map repeats.
pub const SCENARIO: &str = "fig6";

/// One cell of the map (or, with `afb = false`, the row's run without AFB).
#[derive(Clone, Debug, Serialize)]
pub struct MapPoint {
    /// Encoder interpolation factor.
    pub encoder_interpolation: u32,
    /// Acceleration feedback on.
    pub afb: bool,
    /// Velocity filter corner (Hz).
    pub velocity_corner_hz: f64,
    /// AFB filter corner (Hz); 0 for the run without AFB.
    pub afb_corner_hz: f64,
    /// fig6's `stable` metric.
    pub stable: bool,
    /// fig6's `stable_by_speed`: the criterion without the oscillation verdict.
    pub stable_by_speed: bool,
    /// The oscillation verdict; empty if not run.
    pub oscillation: Option<OscillationKind>,
    /// Its spectral peak (Hz).
    pub oscillation_freq_hz: f64,
    /// Its torque amplitude (pu).
    pub oscillation_amplitude_pu: f64,
    /// Speed-error oscillation in the stability window (pu).
    pub oscillation_pu: f64,
    /// Motor-torque chatter in the stability window (pu).
    pub limit_cycle_torque_pu: f64,
    /// Shaft-torque ripple after the load step (pu).
    pub shaft_torque_ripple_rms_pu: f64,
    /// Time the torque command spent at its limit (s).
    pub torque_saturated_s: f64,
    /// The controller faulted.
    pub faulted: bool,
    /// Velocity Kp the run used (identical with and without AFB).
    pub kp_vel: f64,
    /// Error text if the configuration was rejected.
    pub error: String,
}

/// The map's scenario with the encoder interpolated `interpolation` times: a plant key, so
/// it goes through the file's value tree (the drive then counts what the plant delivers).
pub fn base_config(interpolation: u32) -> Result<RunConfig> {
    resolve(
        SCENARIO,
        None,
        &[format!("sensors.encoder_interpolation={interpolation}")],
    )
}

/// The AFB run of a cell: differentiated velocity and acceleration behind first-order
/// filters at the two corners, the following-error trip at one motor revolution on every
/// encoder (the map's runaway cells trip there, as they always have; the drive's default is
/// a quarter revolution).
pub fn afb_config(base: &RunConfig, velocity_corner_hz: f64, afb_corner_hz: f64) -> RunConfig {
    let mut cfg = base.clone();
    let d = &mut cfg.drive;
    d.faults.following_error_rev = 1.0;
    d.velocity_estimator = Estimator::Differentiation;
    d.velocity_filter = FilterConfig::FirstOrder {
        corner_hz: velocity_corner_hz as f32,
    };
    d.accel_feedback.source = Estimator::Differentiation;
    d.accel_feedback.filter = FilterConfig::FirstOrder {
        corner_hz: afb_corner_hz as f32,
    };
    cfg
}

/// The run without AFB of a row, at the gains of the row's AFB design.
pub fn no_afb_config(base: &RunConfig, velocity_corner_hz: f64) -> Result<RunConfig> {
    let first = AFB_CORNERS_HZ.first().copied().unwrap_or(100.0);
    let afb = afb_config(base, velocity_corner_hz, first);
    let mut cfg = afb.clone();
    cfg.drive.accel_feedback.mode = AfbMode::Off;
    borrow_gains(
        &mut cfg,
        &format!("{SCENARIO} with differentiation, velocity filter {velocity_corner_hz} Hz"),
        &afb.drive,
    )?;
    Ok(cfg)
}

fn run_cell(
    base: &Result<RunConfig>,
    interpolation: u32,
    velocity_corner_hz: f64,
    afb_corner_hz: Option<f64>,
) -> MapPoint {
    let mut p = MapPoint {
        encoder_interpolation: interpolation,
        afb: afb_corner_hz.is_some(),
        velocity_corner_hz,
        afb_corner_hz: afb_corner_hz.unwrap_or(0.0),
        stable: false,
        stable_by_speed: false,
        oscillation: None,
        oscillation_freq_hz: f64::NAN,
        oscillation_amplitude_pu: f64::NAN,
        oscillation_pu: f64::NAN,
        limit_cycle_torque_pu: f64::NAN,
        shaft_torque_ripple_rms_pu: f64::NAN,
        torque_saturated_s: f64::NAN,
        faulted: false,
        kp_vel: f64::NAN,
        error: String::new(),
    };
    let cfg = match (base, afb_corner_hz) {
        (Err(e), _) => Err(HarnessError::Backend(e.to_string())),
        (Ok(b), Some(fa)) => Ok(afb_config(b, velocity_corner_hz, fa)),
        (Ok(b), None) => no_afb_config(b, velocity_corner_hz),
    };
    let run = cfg.and_then(|c| {
        let g = sim_engine::engine::runner::regulator_gains(&c)?;
        run_scenario(&c).map(|o| (g, o))
    });
    match run {
        Ok((g, out)) => {
            let m = &out.metrics;
            p.stable = m.stable;
            p.stable_by_speed = m.stable_by_speed;
            p.oscillation = Some(m.oscillation.kind);
            p.oscillation_freq_hz = m.oscillation.freq_hz;
            p.oscillation_amplitude_pu = m.oscillation.amplitude_pu;
            p.oscillation_pu = m.oscillation_pu;
            p.limit_cycle_torque_pu = m.limit_cycle_torque_pu;
            p.shaft_torque_ripple_rms_pu = m.shaft_torque_ripple_rms_pu;
            p.faulted = m.faulted;
            p.torque_saturated_s = m.torque_saturated_s;
            p.kp_vel = f64::from(g.kp_vel);
        }
        Err(e) => p.error = e.to_string(),
    }
    p
}

/// Runs the whole map in parallel.
pub fn map_points() -> Vec<MapPoint> {
    let jobs: Vec<(u32, f64, Option<f64>)> = ENCODER_INTERPOLATIONS
        .iter()
        .flat_map(|n| {
            VELOCITY_CORNERS_HZ.iter().flat_map(move |fv| {
                std::iter::once((*n, *fv, None))
                    .chain(AFB_CORNERS_HZ.iter().map(move |fa| (*n, *fv, Some(*fa))))
            })
        })
        .collect();
    // One resolved scenario per encoder; every cell clones it and sets its fields.
    let bases: Vec<(u32, Result<RunConfig>)> = ENCODER_INTERPOLATIONS
        .iter()
        .map(|n| (*n, base_config(*n)))
        .collect();
    let pb = sim_engine::progress::bar(jobs.len() as u64, "sec2 map");
    let points = jobs
        .par_iter()
        .map(|(n, fv, fa)| {
            let base = bases.iter().find(|(m, _)| m == n).map(|(_, b)| b);
            let missing = Err(HarnessError::Backend("no base".into()));
            let r = run_cell(base.unwrap_or(&missing), *n, *fv, *fa);
            pb.inc(1);
            r
        })
        .collect();
    pb.finish_and_clear();
    points
}

/// What the map says, counted.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct MapSummary {
    /// Velocity corners at which the loop without AFB is unstable.
    pub unstable_without_hz: Vec<f64>,
    /// The same by `stable_by_speed` alone (without the oscillation verdict).
    pub unstable_without_by_speed_hz: Vec<f64>,
    /// AFB cells in those rows, and how many of them are stable.
    pub cells_where_unstable_without: usize,
    /// Of those, stable with AFB.
    pub stable_with_where_unstable_without: usize,
    /// AFB cells in rows where the loop without AFB is stable.
    pub cells_where_stable_without: usize,
    /// Of those, unstable with AFB (AFB makes a stable loop unstable).
    pub unstable_with_where_stable_without: usize,
}

/// The points of the map at one encoder interpolation factor.
pub fn at(points: &[MapPoint], interpolation: u32) -> Vec<MapPoint> {
    points
        .iter()
        .filter(|p| p.encoder_interpolation == interpolation)
        .cloned()
        .collect()
}

/// Counts one map (the points of one encoder, [`at`]).
pub fn summarize(points: &[MapPoint]) -> MapSummary {
    let mut s = MapSummary::default();
    for fv in VELOCITY_CORNERS_HZ {
        let run = points.iter().find(|p| !p.afb && p.velocity_corner_hz == fv);
        let without = run.is_some_and(|p| p.stable);
        if !without {
            s.unstable_without_hz.push(fv);
        }
        if !run.is_some_and(|p| p.stable_by_speed) {
            s.unstable_without_by_speed_hz.push(fv);
        }
        for p in points
            .iter()
            .filter(|p| p.afb && p.velocity_corner_hz == fv)
        {
            if without {
                s.cells_where_stable_without += 1;
                s.unstable_with_where_stable_without += usize::from(!p.stable);
            } else {
                s.cells_where_unstable_without += 1;
                s.stable_with_where_unstable_without += usize::from(p.stable);
            }
        }
    }
    s
}

/// One map as a chart panel: each AFB cell by the stability with and without AFB.
fn panel(points: &[MapPoint], interpolation: u32) -> Panel {
    let without = |fv: f64| {
        points
            .iter()
            .find(|p| !p.afb && p.velocity_corner_hz == fv)
            .is_some_and(|p| p.stable)
    };
    let pick = |with: bool, wo: bool| -> Vec<(f64, f64)> {
        points
            .iter()
            .filter(|p| p.afb && p.stable == with && without(p.velocity_corner_hz) == wo)
            .map(|p| (p.velocity_corner_hz, p.afb_corner_hz))
            .collect()
    };
    Panel {
            title: format!(
                "Sec. II map: {SCENARIO}, differentiated velocity and acceleration, same gains, encoder x{interpolation}"
            ),
            y_label: "AFB filter corner (Hz)".into(),
            series: vec![
                Series::markers("unstable without AFB, stable with", pick(true, false)),
                Series::markers("unstable without AFB, unstable with", pick(false, false)),
                Series::markers("stable without AFB, stable with", pick(true, true)),
                Series::markers("stable without AFB, unstable with", pick(false, true)),
            ],
            log_x: true,
            log_y: true,
            legend: Legend::UpperLeft,
    }
}

/// The maps as a chart, one panel per encoder.
pub fn figure(points: &[MapPoint]) -> Figure {
    Figure {
        x_label: "velocity filter corner (Hz)".into(),
        panels: ENCODER_INTERPOLATIONS
            .iter()
            .map(|n| panel(&at(points, *n), *n))
            .collect(),
    }
}

/// Runs the map into `dir` (`sec2.csv`, `sec2-map.png|svg`); returns the points.
pub fn map_into(dir: &Path) -> Result<Vec<MapPoint>> {
    let points = map_points();
    let path = dir.join("sec2.csv");
    let mut w = csv::Writer::from_path(&path).map_err(|e| HarnessError::io(&path, e))?;
    for p in &points {
        w.serialize(p).map_err(|e| HarnessError::io(&path, e))?;
    }
    w.flush().map_err(|e| HarnessError::io(&path, e))?;
    save(&figure(&points), &dir.join("sec2-map"))?;
    Ok(points)
}

/// `hil-harness sec2-map`.
pub fn sec2(out: &Path) -> Result<String> {
    let cpr = resolve(SCENARIO, None, &[])?.plant.mechanics.encoder_cpr;
    sim_engine::output::staged(out, |dir| {
        let points = map_into(dir)?;
        let mut text = String::new();
        for n in ENCODER_INTERPOLATIONS {
            let m = at(&points, n);
            let _ = write!(
                text,
                "\nEncoder {cpr} counts x {n}:\n\n{}\n{}\n",
                table(&m),
                summary_text(&m)
            );
        }
        let path = dir.join("sec2-map.md");
        std::fs::write(&path, &text).map_err(|e| HarnessError::io(&path, e))?;
        Ok(text)
    })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn p(afb: bool, fv: f64, fa: f64, stable: bool) -> MapPoint {
        MapPoint {
            encoder_interpolation: 1,
            afb,
            velocity_corner_hz: fv,
            afb_corner_hz: fa,
            stable,
            stable_by_speed: stable,
            oscillation: None,
            oscillation_freq_hz: 0.0,
            oscillation_amplitude_pu: 0.0,
            oscillation_pu: 0.0,
            limit_cycle_torque_pu: 0.0,
            shaft_torque_ripple_rms_pu: 0.0,
            torque_saturated_s: 0.0,
            faulted: false,
            kp_vel: 0.0,
            error: String::new(),
        }
    }

    #[test]
    fn the_summary_counts_both_directions() {
        let pts = [
            p(false, 10.0, 0.0, false),
            p(true, 10.0, 10.0, true),
            p(true, 10.0, 25.0, false),
            p(false, 15.0, 0.0, true),
            p(true, 15.0, 10.0, false),
        ];
        let s = summarize(&pts);
        // 25 Hz onwards have no run at all: unstable without (a missing run is no evidence
        // of stability), with no AFB cells.
        assert_eq!(s.unstable_without_hz.first(), Some(&10.0));
        assert!(!s.unstable_without_hz.contains(&15.0));
        assert_eq!(s.cells_where_unstable_without, 2);
        assert_eq!(s.stable_with_where_unstable_without, 1);
        assert_eq!(s.cells_where_stable_without, 1);
        assert_eq!(s.unstable_with_where_stable_without, 1);
    }

    /// The confirming rerun of a run without AFB (the oscillation rule's step 5) borrows
    /// its gains from the AFB design counting the finer encoder: the gains are those of
    /// the same map's run at that encoder, bit for bit.
    #[test]
    fn the_confirming_rerun_of_a_run_without_afb_has_the_finer_encoders_gains() {
        use sim_engine::engine::metrics::oscillation::CONFIRM_INTERPOLATION;
        use sim_engine::engine::runner::{finer_encoder, regulator_gains, same_regulator_gains};
        let coarse = no_afb_config(&base_config(1).unwrap(), 100.0).unwrap();
        let fine = finer_encoder(&coarse).unwrap();
        let direct = no_afb_config(&base_config(CONFIRM_INTERPOLATION).unwrap(), 100.0).unwrap();
        let (g, d) = (
            regulator_gains(&fine).unwrap(),
            regulator_gains(&direct).unwrap(),
        );
        assert_eq!(g.cfg.encoder_cpr, d.cfg.encoder_cpr);
        assert!(same_regulator_gains(&g, &d), "{g:?}\n{d:?}");
    }

    #[test]
    fn the_run_without_afb_has_the_gains_of_its_afb_design() {
        for (n, fv) in ENCODER_INTERPOLATIONS
            .iter()
            .flat_map(|n| VELOCITY_CORNERS_HZ.iter().map(move |fv| (*n, *fv)))
        {
            let base = base_config(n).unwrap();
            assert_eq!(base.drive.encoder_cpr, base.plant.counts_per_rev());
            let off = no_afb_config(&base, fv).unwrap();
            let g_off = sim_engine::engine::runner::regulator_gains(&off).unwrap();
            assert_eq!(g_off.ka, 0.0);
            for fa in AFB_CORNERS_HZ {
                let on = afb_config(&base, fv, fa);
                let g_on = sim_engine::engine::runner::regulator_gains(&on).unwrap();
                assert!(g_on.ka > 0.0);
                assert!(
                    sim_engine::engine::runner::same_regulator_gains(&g_off, &g_on),
                    "{fv} Hz / {fa} Hz"
                );
            }
        }
    }
}
