//! identify's Bode plot: the phase unwrapped (the measured points on the fitted curve's
//! turn, not a turn away from it) and the fitted anti-resonance and resonance marked with
//! labelled vertical lines, in the figure and in `bode.svg`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use machine_workflows::identify::{identify, identify_machine, load, write::bode};
use sim_engine::plot::{Series, Style};

fn series<'a>(panel: &'a [Series], label: &str, style: Style) -> &'a Series {
    panel
        .iter()
        .find(|s| s.label == label && s.style == style)
        .unwrap_or_else(|| panic!("no {label} series"))
}

#[test]
fn the_bode_phase_is_unwrapped_and_the_fitted_resonances_are_marked() {
    // Table 1: a double integrator below the anti-resonance, so a phase near ±180° whose
    // principal value flips between +180° and −180° with the noise.
    let (base, spec) = load("table1", &[]).unwrap();
    let ident = identify_machine(&base, &spec).unwrap();
    let wb = f64::from(base.drive.base_speed_rpm) * std::f64::consts::TAU / 60.0;
    let fig = bode(&ident, &spec, wb);
    let phase = &fig.panels[1].series;
    let fitted = &series(phase, "fitted", Style::Line).points;
    let measured = &series(phase, "measured", Style::Markers).points;
    // The fitted curve: continuous, and starting as a position lags its torque.
    assert!((-360.0..=0.0).contains(&fitted[0].1), "{:?}", fitted[0]);
    for w in fitted.windows(2) {
        assert!((w[1].1 - w[0].1).abs() < 90.0, "a jump in the fit: {w:?}");
    }
    // The measured points on it: nine in ten within 30° of the fit at their frequency.
    let fit_at = |f: f64| {
        fitted
            .iter()
            .min_by(|a, b| (a.0 / f).ln().abs().total_cmp(&(b.0 / f).ln().abs()))
            .unwrap()
            .1
    };
    let near = measured
        .iter()
        .filter(|(f, p)| (p - fit_at(*f)).abs() < 30.0)
        .count();
    assert!(
        near * 10 >= measured.len() * 9,
        "{near} of {} measured points within 30° of the fit",
        measured.len()
    );
    let below_ar: Vec<f64> = measured
        .iter()
        .filter(|(f, _)| *f < 0.5 * ident.fit.fit.anti_resonance_hz)
        .map(|p| p.1)
        .collect();
    assert!(below_ar.len() > 10, "{below_ar:?}");
    assert!(
        below_ar.iter().all(|p| (-270.0..-90.0).contains(p)),
        "below the anti-resonance the phase is about −180°: {below_ar:?}"
    );
    // The marks: both frequencies, labelled on the magnitude panel, on every panel.
    let f_ar = ident.fit.fit.anti_resonance_hz;
    let f_r = ident.fit.fit.resonance_hz();
    for (k, panel) in fig.panels.iter().enumerate() {
        let marks: Vec<f64> = panel
            .series
            .iter()
            .filter(|s| s.style == Style::Vertical)
            .map(|s| s.points[0].0)
            .collect();
        assert_eq!(marks, [f_ar, f_r], "panel {k}");
    }
    let labels: Vec<&str> = fig.panels[0]
        .series
        .iter()
        .filter(|s| s.style == Style::Vertical)
        .map(|s| s.label.as_str())
        .collect();
    let ar_label = format!("fitted anti-resonance {f_ar:.2} Hz");
    let r_label = format!("fitted resonance {f_r:.2} Hz");
    assert_eq!(labels, [ar_label.as_str(), r_label.as_str()]);
    // The same labels in the written plot.
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("identify");
    identify("table1", &[], &out).unwrap();
    let svg = std::fs::read_to_string(out.join("bode.svg")).unwrap();
    for label in [&ar_label, &r_label] {
        assert!(svg.contains(&format!(">\n{label}\n</text>")), "{label}");
    }
}
