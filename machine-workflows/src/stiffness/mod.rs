//! `hil-harness stiffness`: dynamic stiffness |τ_L/θ| over frequency (the paper's Fig. 2
//! and Eq. 1), analytic and measured in the closed loop by injecting a sinusoidal load
//! torque, with and without acceleration feedback.
//!
//! Measured: at each frequency ω the run `configs/scenarios/stiffness.toml` is repeated
//! with `sine_load.freq_rad_s = ω`; after the transient has died out (5 s) the load speed
//! and the load torque are correlated with sin/cos over a whole number of periods, and
//! |τ_L/θ| = ω·|T̂_L|/|Ω̂_l| (θ in pu·s, the integral of pu speed).
//!
//! The run without AFB uses the regulator gains of the default AFB design bit for bit
//! ([`sim_engine::config::borrow_gains`]): the comparison is AFB on against AFB off at the same
//! Kp and Ki.
//!
//! Analytic: Eq. 1, |J·s² + Kp·s + Ki| at s = jω with J = J_total and the gains the run
//! uses; with acceleration feedback the inertia term becomes J + Ka·F(jω)·G(jω), F the
//! feedback filter and G the acceleration estimator's transfer function from the true
//! motor acceleration to the estimate ([`estimator_response`]). Delays are ignored: this
//! is the idealised curve the measurement is compared with, and it holds only below the
//! observer bandwidth.

pub mod machine;

use controller_core::{AfbMode, DriveConfig, Estimator, FilterConfig};
use num_complex::Complex64;
use rayon::prelude::*;
use serde::Serialize;
use sim_engine::config::{borrow_gains, resolve, RunConfig};
use sim_engine::engine::runner::run_scenario;
use sim_engine::engine::trace::Trace;
use sim_engine::error::{HarnessError, Result};
use sim_engine::plot::{save, Figure, Legend, Panel, Series};
use std::f64::consts::PI;
use std::fmt::Write as _;
use std::path::Path;

/// Frequencies measured (rad/s).
pub const FREQS_RAD_S: [f64; 13] = [
    0.3, 1.0, 2.0, 4.0, 10.0, 20.0, 40.0, 100.0, 200.0, 400.0, 700.0, 1000.0, 1500.0,
];

/// Settling time before the measurement window (s).
const SETTLE_S: f64 = 5.0;

/// One measured point.
#[derive(Clone, Debug, Serialize)]
pub struct StiffnessPoint {
    /// Acceleration feedback on.
    pub afb: bool,
    /// Acceleration source of the AFB path: `none` (AFB off), `observer` (the drive's
    /// default design) or `differentiation` (same design, differentiated encoder).
    pub source: &'static str,
    /// Frequency (rad/s).
    pub freq_rad_s: f64,
    /// Measured |τ_L/θ| (pu torque per pu·s).
    pub measured: f64,
    /// Eq. 1 (with J + Ka·F(jω) when AFB is on).
    pub analytic: f64,
    /// The run's `stable` metric (a point from an unstable or chattering loop is not a
    /// linear stiffness).
    pub stable: bool,
    /// Motor-torque chatter in the last 0.5 s (pu RMS, above ~5 Hz).
    pub limit_cycle_torque_pu: f64,
    /// |controller's acceleration estimate| / |true motor acceleration| at ω: how much of
    /// the load-driven acceleration the AFB path sees (1 = all of it).
    pub accel_est_ratio: f64,
}

/// The AFB filter F(jω) (continuous-time equivalent of the drive's low-pass).
fn filter_response(f: FilterConfig, w: f64) -> Complex64 {
    let one = Complex64::new(1.0, 0.0);
    match f {
        FilterConfig::None => one,
        FilterConfig::FirstOrder { corner_hz } => {
            let wc = 2.0 * PI * f64::from(corner_hz);
            one / Complex64::new(1.0, w / wc)
        }
        FilterConfig::SecondOrder { corner_hz, q } => {
            let wc = 2.0 * PI * f64::from(corner_hz);
            let s = Complex64::new(0.0, w);
            let den = s * s + Complex64::new(wc * wc, 0.0) + s * (wc / f64::from(q));
            Complex64::new(wc * wc, 0.0) / den
        }
    }
}

/// G(jω): the acceleration estimate over the true motor acceleration, for the AFB source
/// of `d`. Observer: the Ellis estimate (the change of the velocity estimate over the tick,
/// correction included) of a three-pole observer at ω_o = 2π·bandwidth_hz,
/// G(s) = (3ω_o²·s + ω_o³)/(s + ω_o)³. Differentiation: 1 (its delay is ignored).
pub fn estimator_response(d: &DriveConfig, w: f64) -> Complex64 {
    match d.accel_feedback.source {
        Estimator::Differentiation => Complex64::new(1.0, 0.0),
        Estimator::Observer => {
            let wo = 2.0 * PI * f64::from(d.observer.bandwidth_hz);
            let s_plus = Complex64::new(wo, w);
            Complex64::new(wo * wo * wo, 3.0 * wo * wo * w) / (s_plus * s_plus * s_plus)
        }
    }
}

/// Eq. 1 at ω for the run `cfg` (with AFB's J + Ka·F(jω)·G(jω) if it is on), with the
/// gains the run uses ([`sim_engine::engine::runner::regulator_gains`]).
pub fn analytic(cfg: &RunConfig, w: f64) -> f64 {
    let d = &cfg.drive;
    let j = f64::from(d.total_inertia_s());
    let Ok(g) = sim_engine::engine::runner::regulator_gains(cfg) else {
        return f64::NAN;
    };
    let (kp, ki) = (f64::from(g.kp_vel), f64::from(g.ki_vel));
    let j_eff = if d.accel_feedback.mode == AfbMode::Off {
        Complex64::new(j, 0.0)
    } else {
        let fg = filter_response(d.accel_feedback.filter, w) * estimator_response(d, w);
        Complex64::new(j, 0.0) + fg * f64::from(g.ka)
    };
    let s = Complex64::new(0.0, w);
    (j_eff * (s * s) + Complex64::new(ki, kp * w))
        .norm_sqr()
        .sqrt()
}

/// The stiffness run for the AFB `source` (`None`: AFB off) with the scenario overrides
/// `sets`: the default AFB design with that acceleration source, or, without, the same drive
/// with AFB off at the default AFB design's gains.
pub fn stiffness_config(source: Option<Estimator>, sets: &[String]) -> Result<RunConfig> {
    with_source(resolve("stiffness", None, sets)?, source)
}

/// `cfg` (the default AFB design) with the AFB `source`, or AFB off at its gains.
fn with_source(mut cfg: RunConfig, source: Option<Estimator>) -> Result<RunConfig> {
    match source {
        None => {
            let afb = cfg.drive;
            cfg.drive.accel_feedback.mode = AfbMode::Off;
            borrow_gains(&mut cfg, "stiffness (its default AFB design)", &afb)?;
        }
        Some(s) => cfg.drive.accel_feedback.source = s,
    }
    Ok(cfg)
}

/// The name of an AFB source in the CSV and the plots.
pub fn source_name(source: Option<Estimator>) -> &'static str {
    match source {
        None => "none",
        Some(Estimator::Observer) => "observer",
        Some(Estimator::Differentiation) => "differentiation",
    }
}

/// Fundamental phasor (re, im) of `f(row)` at ω over the rows in [t0, t1).
fn phasor(
    trace: &Trace,
    f: impl Fn(&sim_engine::engine::trace::TraceRow) -> f64,
    w: f64,
    t0: f64,
    t1: f64,
) -> (f64, f64) {
    let rows: Vec<&sim_engine::engine::trace::TraceRow> = trace
        .rows
        .iter()
        .filter(|r| r.t_s >= t0 && r.t_s < t1)
        .collect();
    // Remove the mean first: a 0.5 pu speed leaking through a window that is a whole
    // number of periods only to within one sample would swamp a 1e-4 pu response.
    let mean = rows.iter().map(|r| f(r)).sum::<f64>() / rows.len().max(1) as f64;
    let mut acc = (0.0, 0.0);
    let mut n = 0usize;
    for r in rows {
        let x = f(r) - mean;
        acc.0 += x * (w * r.t_s).cos();
        acc.1 -= x * (w * r.t_s).sin();
        n += 1;
    }
    let n = n.max(1) as f64;
    (2.0 * acc.0 / n, 2.0 * acc.1 / n)
}

/// The three drives compared: AFB off, the default AFB design, and the same design with
/// the acceleration from differentiation instead of the observer.
pub const SOURCES: [Option<Estimator>; 3] = [
    None,
    Some(Estimator::Observer),
    Some(Estimator::Differentiation),
];

/// Measures the stiffness of the `source` design (`None`: AFB off) at `w` rad/s.
pub fn measure(source: Option<Estimator>, w: f64) -> Result<StiffnessPoint> {
    measure_on(&resolve("stiffness", None, &[])?, source, w)
}

/// [`measure`] on the stiffness scenario `base`, read once for all points.
fn measure_on(base: &RunConfig, source: Option<Estimator>, w: f64) -> Result<StiffnessPoint> {
    let period = 2.0 * PI / w;
    let periods = (1.0 / period).ceil().max(3.0);
    let window = periods * period;
    let start = 0.5;
    let duration = start + SETTLE_S + window;
    let mut cfg = base.clone();
    let sine = cfg.scenario.sine_load.as_mut().ok_or_else(|| {
        HarnessError::config(
            "scenario.sine_load",
            "the stiffness scenario needs a sine load",
        )
    })?;
    sine.freq_rad_s = w;
    cfg.scenario.duration_s = duration;
    cfg.scenario.validate()?;
    let cfg = with_source(cfg, source)?;
    let out = run_scenario(&cfg)?;
    let (t1, t0) = (duration, duration - window);
    let torque = phasor(&out.trace, |r| r.load_torque_pu, w, t0, t1);
    let speed = phasor(&out.trace, |r| r.load_vel_pu, w, t0, t1);
    let mag = |c: (f64, f64)| (c.0 * c.0 + c.1 * c.1).sqrt();
    let motor_accel = w * mag(phasor(&out.trace, |r| r.motor_vel_pu, w, t0, t1));
    let accel_est = mag(phasor(&out.trace, |r| r.accel_est_pu_s, w, t0, t1));
    Ok(StiffnessPoint {
        afb: source.is_some(),
        source: source_name(source),
        freq_rad_s: w,
        measured: w * mag(torque) / mag(speed).max(1e-12),
        analytic: analytic(&cfg, w),
        stable: out.metrics.stable,
        limit_cycle_torque_pu: out.metrics.limit_cycle_torque_pu,
        accel_est_ratio: accel_est / motor_accel.max(1e-12),
    })
}

/// Measures every frequency with and without AFB, in parallel.
pub fn measure_all(freqs: &[f64]) -> Result<Vec<StiffnessPoint>> {
    let base = resolve("stiffness", None, &[])?;
    let jobs: Vec<(Option<Estimator>, f64)> = SOURCES
        .iter()
        .flat_map(|a| freqs.iter().map(move |w| (*a, *w)))
        .collect();
    let pb = sim_engine::progress::bar(jobs.len() as u64, "stiffness");
    let points: Result<Vec<StiffnessPoint>> = jobs
        .par_iter()
        .map(|(a, w)| {
            let r = measure_on(&base, *a, *w);
            pb.inc(1);
            r
        })
        .collect();
    pb.finish_and_clear();
    points
}

/// Eq. 1 for the stiffness scenario's drive, with the default AFB (observer) or without
/// it at the same gains, on a dense log grid from 0.2 to 2000 rad/s.
pub fn analytic_curve(afb: bool) -> Result<Vec<(f64, f64)>> {
    let cfg = stiffness_config(afb.then_some(Estimator::Observer), &[])?;
    Ok((0..=120)
        .map(|i| {
            let w = 0.2 * 10f64.powf(f64::from(i) / 30.0);
            (w, analytic(&cfg, w))
        })
        .collect())
}

/// The stiffness chart: analytic lines and measured markers, both designs.
pub fn figure(points: &[StiffnessPoint]) -> Figure {
    let pick = |source: &str, measured: bool| -> Vec<(f64, f64)> {
        points
            .iter()
            // A chattering loop has no linear stiffness: unstable points are left out (they
            // stay in stiffness.csv with `stable = false`).
            .filter(|p| p.source == source && p.stable)
            .map(|p| (p.freq_rad_s, if measured { p.measured } else { p.analytic }))
            .collect()
    };
    let diff = pick("differentiation", true);
    let diff_label = if diff.is_empty() {
        "measured, AFB (differentiation): unstable, not shown".to_string()
    } else {
        "measured, AFB (differentiation)".to_string()
    };
    // Ratio AFB / no AFB: measured per frequency, and the ideal curves' ratio.
    let ratio_of = |source: &str| -> Vec<(f64, f64)> {
        points
            .iter()
            .filter(|p| p.source == source && p.stable)
            .filter_map(|b| {
                points
                    .iter()
                    .find(|a| a.source == "none" && a.freq_rad_s == b.freq_rad_s)
                    .map(|a| (b.freq_rad_s, b.measured / a.measured))
            })
            .collect()
    };
    let ideal_ratio: Vec<(f64, f64)> = match (analytic_curve(false), analytic_curve(true)) {
        (Ok(off), Ok(on)) => off
            .iter()
            .zip(on.iter())
            .map(|(a, b)| (a.0, b.1 / a.1))
            .collect(),
        _ => Vec::new(),
    };
    Figure {
        x_label: "frequency (rad/s)".into(),
        panels: vec![
            Panel {
                title: "Dynamic stiffness |load torque / position| (Fig. 2, Eq. 1)".into(),
                y_label: "pu torque per pu*s".into(),
                series: vec![
                    Series::line(
                        "Eq. 1, no AFB",
                        analytic_curve(false).unwrap_or_else(|_| pick("none", false)),
                    ),
                    Series::markers("measured, no AFB", pick("none", true)),
                    Series::line(
                        "Eq. 1 with J + Ka*F*G, AFB",
                        analytic_curve(true).unwrap_or_else(|_| pick("observer", false)),
                    ),
                    Series::markers("measured, AFB (observer)", pick("observer", true)),
                    Series::markers(diff_label, diff),
                ],
                log_x: true,
                log_y: true,
                legend: Legend::Auto,
            },
            Panel {
                title: "Stiffness with AFB / without".into(),
                y_label: "ratio".into(),
                series: vec![
                    Series::line("ideal (Eq. 1 with J + Ka*F*G)", ideal_ratio),
                    Series::markers("measured, observer acceleration", ratio_of("observer")),
                    Series::markers(
                        "measured, differentiated acceleration (stable points)",
                        ratio_of("differentiation"),
                    ),
                ],
                log_x: true,
                log_y: false,
                legend: Legend::LowerLeft,
            },
        ],
    }
}

/// Writes `stiffness.csv` and the chart into `dir`; returns the points and a summary.
pub fn stiffness_into(dir: &Path) -> Result<(Vec<StiffnessPoint>, String)> {
    let points = measure_all(&FREQS_RAD_S)?;
    let path = dir.join("stiffness.csv");
    let mut w =
        csv::Writer::from_path(&path).map_err(|e| sim_engine::error::HarnessError::io(&path, e))?;
    for p in &points {
        w.serialize(p)
            .map_err(|e| sim_engine::error::HarnessError::io(&path, e))?;
    }
    w.flush()
        .map_err(|e| sim_engine::error::HarnessError::io(&path, e))?;
    save(&figure(&points), &dir.join("stiffness"))?;
    let mut text = String::new();
    for w in FREQS_RAD_S {
        let get = |source: &str| {
            points
                .iter()
                .find(|p| p.source == source && p.freq_rad_s == w)
        };
        if let (Some(a), Some(b), Some(c)) = (get("none"), get("observer"), get("differentiation"))
        {
            let _ = writeln!(
                text,
                "{w:>7} rad/s: no AFB {:.4} (Eq. 1 {:.4}), AFB observer {:.4} (ideal {:.4}), \
                 AFB differentiation {:.4}; ratios {:.2} / {:.2}",
                a.measured,
                a.analytic,
                b.measured,
                b.analytic,
                c.measured,
                b.measured / a.measured,
                c.measured / a.measured
            );
        }
    }
    Ok((points, text))
}

/// `hil-harness stiffness`.
pub fn stiffness(out: &Path) -> Result<String> {
    sim_engine::output::staged(out, |dir| stiffness_into(dir).map(|(_, text)| text))
}

#[cfg(test)]
mod tests {
    use super::*;

    // The hand-written (re, im) helpers num-complex replaced, kept here as the reference.
    fn cmul(a: (f64, f64), b: (f64, f64)) -> (f64, f64) {
        (a.0 * b.0 - a.1 * b.1, a.0 * b.1 + a.1 * b.0)
    }

    fn cdiv(a: (f64, f64), b: (f64, f64)) -> (f64, f64) {
        let d = b.0 * b.0 + b.1 * b.1;
        ((a.0 * b.0 + a.1 * b.1) / d, (a.1 * b.0 - a.0 * b.1) / d)
    }

    fn filter_by_hand(f: FilterConfig, w: f64) -> (f64, f64) {
        match f {
            FilterConfig::None => (1.0, 0.0),
            FilterConfig::FirstOrder { corner_hz } => {
                cdiv((1.0, 0.0), (1.0, w / (2.0 * PI * f64::from(corner_hz))))
            }
            FilterConfig::SecondOrder { corner_hz, q } => {
                let wc = 2.0 * PI * f64::from(corner_hz);
                let s2 = cmul((0.0, w), (0.0, w));
                let den = (s2.0 + wc * wc, s2.1 + wc / f64::from(q) * w);
                cdiv((wc * wc, 0.0), den)
            }
        }
    }

    fn observer_by_hand(wo: f64, w: f64) -> (f64, f64) {
        let s_plus = (wo, w);
        let den = cmul(cmul(s_plus, s_plus), s_plus);
        cdiv((wo * wo * wo, 3.0 * wo * wo * w), den)
    }

    #[test]
    fn num_complex_responses_match_hand_written_complex_arithmetic_bit_for_bit() {
        let filters = [
            FilterConfig::None,
            FilterConfig::FirstOrder { corner_hz: 100.0 },
            FilterConfig::SecondOrder {
                corner_hz: 40.0,
                q: 0.707,
            },
        ];
        for w in [0.5, 3.0, 20.0, 94.25, 400.0, 2500.0] {
            for f in filters {
                let (got, want) = (filter_response(f, w), filter_by_hand(f, w));
                assert_eq!(
                    (got.re.to_bits(), got.im.to_bits()),
                    (want.0.to_bits(), want.1.to_bits()),
                    "{f:?} at {w}"
                );
            }
            let wo = 2.0 * PI * 75.0;
            let s_plus = Complex64::new(wo, w);
            let got = Complex64::new(wo * wo * wo, 3.0 * wo * wo * w) / (s_plus * s_plus * s_plus);
            let want = observer_by_hand(wo, w);
            assert_eq!((got.re, got.im), want, "observer at {w}");
        }
    }
}
