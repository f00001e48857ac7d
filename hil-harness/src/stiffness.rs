//! `hil-harness stiffness`: dynamic stiffness |τ_L/θ| over frequency (the paper's Fig. 2
//! and Eq. 1), analytic and measured in the closed loop by injecting a sinusoidal load
//! torque, with and without acceleration feedback.
//!
//! Measured: at each frequency ω the run `configs/scenarios/stiffness.toml` is repeated
//! with `sine_load.freq_rad_s = ω`; after the transient has died out (5 s) the load speed
//! and the load torque are correlated with sin/cos over a whole number of periods, and
//! |τ_L/θ| = ω·|T̂_L|/|Ω̂_l| (θ in pu·s, the integral of pu speed). Analytic: Eq. 1,
//! |J·s² + Kp·s + Ki| at s = jω with J = J_total and the drive's designed Kp, Ki
//! (controller-core: Kp = ω_bw·J_loop, Ki = Kp·ω_bw/(4ζ²), J_loop = J_total + Ka with AFB
//! on); with acceleration feedback the inertia term becomes J + Ka·F(jω), F the feedback
//! filter (delays ignored: this is the idealised curve the measurement is compared with).

use crate::config::{resolve, RunConfig};
use crate::error::Result;
use crate::output::Staging;
use crate::plot::{save, Figure, Panel, Series};
use crate::runner::run_scenario;
use crate::trace::Trace;
use controller_core::{AfbMode, FilterConfig};
use rayon::prelude::*;
use serde::Serialize;
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
    /// Frequency (rad/s).
    pub freq_rad_s: f64,
    /// Measured |τ_L/θ| (pu torque per pu·s).
    pub measured: f64,
    /// Eq. 1 (with J + Ka·F(jω) when AFB is on).
    pub analytic: f64,
}

/// Complex number helpers (re, im).
fn cmul(a: (f64, f64), b: (f64, f64)) -> (f64, f64) {
    (a.0 * b.0 - a.1 * b.1, a.0 * b.1 + a.1 * b.0)
}

fn cdiv(a: (f64, f64), b: (f64, f64)) -> (f64, f64) {
    let d = b.0 * b.0 + b.1 * b.1;
    ((a.0 * b.0 + a.1 * b.1) / d, (a.1 * b.0 - a.0 * b.1) / d)
}

/// The AFB filter F(jω) (continuous-time equivalent of the drive's low-pass).
fn filter_response(f: FilterConfig, w: f64) -> (f64, f64) {
    match f {
        FilterConfig::None => (1.0, 0.0),
        FilterConfig::FirstOrder { corner_hz } => {
            let wc = 2.0 * PI * f64::from(corner_hz);
            cdiv((1.0, 0.0), (1.0, w / wc))
        }
        FilterConfig::SecondOrder { corner_hz, q } => {
            let wc = 2.0 * PI * f64::from(corner_hz);
            let s = (0.0, w);
            let s2 = cmul(s, s);
            let den = (
                s2.0 + wc * wc + wc / f64::from(q) * s.0,
                s2.1 + wc / f64::from(q) * s.1,
            );
            cdiv((wc * wc, 0.0), den)
        }
    }
}

/// Eq. 1 at ω for the drive of `cfg` (with AFB's J + Ka·F(jω) if it is on).
pub fn analytic(cfg: &RunConfig, w: f64) -> f64 {
    let d = &cfg.drive;
    let j = f64::from(d.total_inertia_s());
    // The drive's own gains: with AFB on, controller-core designs the PI for J_total + Ka.
    let (kp, ki) = match controller_core::design(d) {
        Ok(g) => (f64::from(g.kp_vel), f64::from(g.ki_vel)),
        Err(_) => return f64::NAN,
    };
    let j_eff = if d.accel_feedback.mode == AfbMode::Off {
        (j, 0.0)
    } else {
        let ka = f64::from(d.accel_feedback.gain_fraction) * j;
        let fr = filter_response(d.accel_feedback.filter, w);
        (j + ka * fr.0, ka * fr.1)
    };
    let s = (0.0, w);
    let s2 = cmul(s, s);
    let js2 = cmul(j_eff, s2);
    let re = js2.0 + ki;
    let im = js2.1 + kp * w;
    (re * re + im * im).sqrt()
}

/// Fundamental phasor (re, im) of `f(row)` at ω over the rows in [t0, t1).
fn phasor(
    trace: &Trace,
    f: impl Fn(&crate::trace::TraceRow) -> f64,
    w: f64,
    t0: f64,
    t1: f64,
) -> (f64, f64) {
    let mut acc = (0.0, 0.0);
    let mut n = 0usize;
    for r in trace.rows.iter().filter(|r| r.t_s >= t0 && r.t_s < t1) {
        let x = f(r);
        acc.0 += x * (w * r.t_s).cos();
        acc.1 -= x * (w * r.t_s).sin();
        n += 1;
    }
    let n = n.max(1) as f64;
    (2.0 * acc.0 / n, 2.0 * acc.1 / n)
}

fn measure(afb: bool, w: f64) -> Result<StiffnessPoint> {
    let period = 2.0 * PI / w;
    let periods = (1.0 / period).ceil().max(3.0);
    let window = periods * period;
    let start = 0.5;
    let duration = start + SETTLE_S + window;
    let mut sets = vec![
        format!("scenario.sine_load.freq_rad_s={w}"),
        format!("scenario.duration_s={duration}"),
    ];
    if !afb {
        sets.push("drive.accel_feedback.mode=off".into());
    }
    let cfg = resolve("stiffness", None, &sets)?;
    let out = run_scenario(&cfg)?;
    let (t1, t0) = (duration, duration - window);
    let torque = phasor(&out.trace, |r| r.load_torque_pu, w, t0, t1);
    let speed = phasor(&out.trace, |r| r.load_vel_pu, w, t0, t1);
    let mag = |c: (f64, f64)| (c.0 * c.0 + c.1 * c.1).sqrt();
    Ok(StiffnessPoint {
        afb,
        freq_rad_s: w,
        measured: w * mag(torque) / mag(speed).max(1e-12),
        analytic: analytic(&cfg, w),
    })
}

/// Measures every frequency with and without AFB, in parallel.
pub fn measure_all(freqs: &[f64]) -> Result<Vec<StiffnessPoint>> {
    let jobs: Vec<(bool, f64)> = [false, true]
        .iter()
        .flat_map(|a| freqs.iter().map(move |w| (*a, *w)))
        .collect();
    let pb = crate::progress::bar(jobs.len() as u64, "stiffness");
    let points: Result<Vec<StiffnessPoint>> = jobs
        .par_iter()
        .map(|(a, w)| {
            let r = measure(*a, *w);
            pb.inc(1);
            r
        })
        .collect();
    pb.finish_and_clear();
    points
}

/// The stiffness chart: analytic lines and measured markers, both designs.
pub fn figure(points: &[StiffnessPoint]) -> Figure {
    let pick = |afb: bool, measured: bool| -> Vec<(f64, f64)> {
        points
            .iter()
            .filter(|p| p.afb == afb)
            .map(|p| (p.freq_rad_s, if measured { p.measured } else { p.analytic }))
            .collect()
    };
    Figure {
        x_label: "frequency (rad/s)".into(),
        panels: vec![Panel {
            title: "Dynamic stiffness |load torque / position| (Fig. 2, Eq. 1)".into(),
            y_label: "pu torque per pu*s".into(),
            series: vec![
                Series::line("Eq. 1, no AFB", pick(false, false)),
                Series::markers("measured, no AFB", pick(false, true)),
                Series::line("Eq. 1 with J + Ka*F, AFB", pick(true, false)),
                Series::markers("measured, AFB", pick(true, true)),
            ],
            log_x: true,
            log_y: true,
        }],
    }
}

/// Writes `stiffness.csv` and the chart into `dir`; returns the points and a summary.
pub fn stiffness_into(dir: &Path) -> Result<(Vec<StiffnessPoint>, String)> {
    let points = measure_all(&FREQS_RAD_S)?;
    let path = dir.join("stiffness.csv");
    let mut w =
        csv::Writer::from_path(&path).map_err(|e| crate::error::HarnessError::io(&path, e))?;
    for p in &points {
        w.serialize(p)
            .map_err(|e| crate::error::HarnessError::io(&path, e))?;
    }
    w.flush()
        .map_err(|e| crate::error::HarnessError::io(&path, e))?;
    save(&figure(&points), &dir.join("stiffness"))?;
    let mut text = String::new();
    for w in FREQS_RAD_S {
        let get = |afb: bool| points.iter().find(|p| p.afb == afb && p.freq_rad_s == w);
        if let (Some(a), Some(b)) = (get(false), get(true)) {
            let _ = writeln!(
                text,
                "{w:>7} rad/s: no AFB {:.4} (Eq. 1 {:.4}), AFB {:.4} (ideal {:.4}), ratio {:.2}",
                a.measured,
                a.analytic,
                b.measured,
                b.analytic,
                b.measured / a.measured
            );
        }
    }
    Ok((points, text))
}

/// `hil-harness stiffness`.
pub fn stiffness(out: &Path) -> Result<String> {
    let staging = Staging::new(out)?;
    let (_, text) = stiffness_into(staging.dir())?;
    staging.commit()?;
    Ok(text)
}
