//! `tune`'s figures: the velocity loop's open-loop Bode plot with its margins marked, and
//! the closed-loop poles in the z-plane with the gears engaged and apart.

use crate::linear::margins::unwrap_phases;
use crate::linear::{Break, LoopModel};
use sim_engine::error::Result;
use sim_engine::plot::{save, save_sized, Figure, Legend, Panel, Series};
use std::path::Path;

/// Points of the Bode plot.
const BODE_POINTS: usize = 400;
/// Lowest frequency of the Bode plot \[Hz\].
const BODE_LOW_HZ: f64 = 0.1;

/// Stem of the Bode plot in DIR.
pub const BODE: &str = "tune-bode";
/// Stem of the pole map in DIR.
pub const POLES: &str = "tune-poles";

/// The Bode figure of `model`'s velocity loop (opened at the velocity regulator's output),
/// up to the velocity Nyquist frequency `nyquist_hz`.
#[must_use]
pub fn bode(model: &LoopModel, nyquist_hz: f64) -> Figure {
    let freqs = plant_host::analysis::log_space(BODE_LOW_HZ, nyquist_hz * 0.999, BODE_POINTS);
    let l = model.loop_gain(Break::VelocityRegulator, &freqs);
    let m = model.margins(Break::VelocityRegulator);
    let mut phase: Vec<f64> = unwrap_phases(&l).iter().map(|p| p.to_degrees()).collect();
    // Whole turns off, so that the curve starts in (−360°, 0°].
    let turns = phase.first().map_or(0.0, |p| (p / 360.0).ceil());
    for p in &mut phase {
        *p -= 360.0 * turns;
    }
    let db: Vec<(f64, f64)> = freqs
        .iter()
        .zip(&l)
        .map(|(f, v)| (*f, 20.0 * v.norm().log10()))
        .collect();
    let deg: Vec<(f64, f64)> = freqs.iter().copied().zip(phase.iter().copied()).collect();
    let at = |f: f64| {
        deg.iter()
            .min_by(|a, b| (a.0 - f).abs().total_cmp(&(b.0 - f).abs()))
            .map_or(f64::NAN, |p| p.1)
    };
    let phase_at_crossover = at(m.crossover_hz);
    let minus_180 = phase_at_crossover - m.phase_margin_deg;
    let mut gain = vec![Series::line("|L| (dB)", db)];
    let mut angle = vec![
        Series::line("∠L (deg)", deg),
        Series::line(
            format!("{minus_180:.0}°"),
            vec![(BODE_LOW_HZ, minus_180), (nyquist_hz, minus_180)],
        ),
    ];
    if m.crossover_hz.is_finite() {
        let label = format!(
            "crossover {:.2} Hz, phase margin {:.1}°",
            m.crossover_hz, m.phase_margin_deg
        );
        gain.push(Series::markers(label.clone(), vec![(m.crossover_hz, 0.0)]));
        angle.push(Series::markers(
            label,
            vec![(m.crossover_hz, phase_at_crossover)],
        ));
    }
    if m.gain_margin_db.is_finite() {
        gain.push(Series::markers(
            format!(
                "gain margin {:.1} dB at {:.1} Hz",
                m.gain_margin_db, m.phase_crossover_hz
            ),
            vec![(m.phase_crossover_hz, -m.gain_margin_db)],
        ));
    }
    Figure {
        x_label: "frequency (Hz)".into(),
        panels: vec![
            Panel {
                title: "Velocity loop opened at the regulator output, gears engaged: gain".into(),
                y_label: "|L| (dB)".into(),
                series: gain,
                log_x: true,
                legend: Legend::LowerLeft,
                ..Panel::default()
            },
            Panel {
                title: "phase".into(),
                y_label: "∠L (deg)".into(),
                series: angle,
                log_x: true,
                legend: Legend::LowerLeft,
                ..Panel::default()
            },
        ],
    }
}

/// The closed-loop poles of `engaged` and (on a machine with lost motion) `apart` in the
/// z-plane, with the unit circle.
#[must_use]
pub fn pole_map(engaged: &LoopModel, apart: Option<&LoopModel>) -> Figure {
    let circle = (0..=360)
        .map(|d| {
            let a = f64::from(d).to_radians();
            (a.cos(), a.sin())
        })
        .collect();
    let points = |m: &LoopModel| m.poles().iter().map(|p| (p.re, p.im)).collect();
    let mut series = vec![
        Series::line("unit circle", circle),
        Series::markers(
            format!(
                "gears engaged (smallest damping {:.3})",
                engaged.smallest_damping()
            ),
            points(engaged),
        ),
    ];
    if let Some(a) = apart {
        series.push(Series::markers(
            format!("gears apart (smallest damping {:.3})", a.smallest_damping()),
            points(a),
        ));
    }
    Figure {
        x_label: "Re z".into(),
        panels: vec![Panel {
            title: "Closed-loop poles, one velocity period".into(),
            y_label: "Im z".into(),
            series,
            legend: Legend::LowerLeft,
            ..Panel::default()
        }],
    }
}

/// Writes both figures into `dir` (PNG and SVG); returns the PNG names, for links.
pub fn write(
    dir: &Path,
    engaged: &LoopModel,
    apart: Option<&LoopModel>,
    nyquist_hz: f64,
) -> Result<[String; 2]> {
    save(&bode(engaged, nyquist_hz), &dir.join(BODE))?;
    save_sized(&pole_map(engaged, apart), &dir.join(POLES), (800, 800))?;
    Ok([format!("{BODE}.png"), format!("{POLES}.png")])
}
