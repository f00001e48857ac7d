//! The files of `identify`: `plant.toml` (the `[plant]` table of a machine file),
//! `identify.json` (each estimate with its standard error), `identify.md` and the Bode plot
//! `bode.png|svg` (measured and fitted).

use super::lost_motion::identified_mechanics;
use super::spec::IdentifySpec;
use super::twin::{self, Twin};
use super::Identification;
use nalgebra::Complex;
use plant_host::analysis::TwoInertiaFit;
use plant_host::MechanicsConfig;
use serde::Serialize;
use sim_engine::config::RunConfig;
use sim_engine::error::{HarnessError, Result};
use sim_engine::plot::{save, Figure, Legend, Panel, Series};
use std::fmt::Write as _;
use std::path::Path;

/// One estimate.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Estimate {
    /// Parameter (the `[plant]` key where there is one).
    pub name: &'static str,
    /// The estimate.
    pub value: f64,
    /// Its standard error (same unit; `null` where none is available).
    pub std_error: f64,
    /// Unit.
    pub unit: &'static str,
}

/// `identify.json`.
#[derive(Clone, Debug, Serialize)]
pub struct Report<'a> {
    /// The machine file.
    pub config: String,
    /// Where the records were taken: the simulated machine, or the board.
    pub measured_on: &'a str,
    /// The estimates.
    pub estimates: Vec<Estimate>,
    /// The fit's weighted RMS residual (about 1 when the model explains the data).
    pub fit_weighted_rms: f64,
    /// Frequency bins the fit used.
    pub fit_bins: usize,
    /// Welch segments averaged.
    pub segments: usize,
    /// Length of the record \[s\].
    pub record_s: f64,
    /// RMS torque-reference mismatch of the lost-motion fit \[pu\].
    pub lost_motion_rms_mismatch_pu: f64,
    /// The check on the twin: the raw estimates (`truth`), the twin's mean estimates, their
    /// spread and how far the bias moved on a second twin (`null` when no twin run gave a
    /// fit), in the order of `twin_parameters`.
    pub twin: Option<Twin>,
    /// The parameters of `twin`'s arrays.
    pub twin_parameters: [&'static str; twin::PARAMS],
    /// The measurement settings.
    pub settings: &'a IdentifySpec,
}

/// The estimates with their standard errors. The resonance's error is propagated from
/// f_r = f_ar·√(1 + Jl/Jm), the parameters' correlations left out.
pub fn estimates(base: &RunConfig, ident: &Identification) -> Vec<Estimate> {
    let (f, e) = (&ident.fit.fit, &ident.fit.std_error);
    let (jm, jl) = (f.motor_inertia_s, f.load_inertia_s);
    let share = 0.5 * jl / (jm + jl);
    let rel_r = ((e.anti_resonance_hz / f.anti_resonance_hz).powi(2)
        + share.powi(2) * ((e.motor_inertia_s / jm).powi(2) + (e.load_inertia_s / jl).powi(2)))
    .sqrt();
    let lm = &ident.lost_motion;
    let counts_per_deg = f64::from(base.drive.encoder_cpr) / 360.0;
    let est = |name, value, std_error, unit| Estimate {
        name,
        value,
        std_error,
        unit,
    };
    // A PMSM's motor calibration, measured first, under the machine-file keys.
    let mut v = ident
        .motor
        .as_ref()
        .map_or_else(Vec::new, super::motor::estimates);
    v.extend([
        est("motor_inertia_s", jm, e.motor_inertia_s, "s"),
        est("load_inertia_s", jl, e.load_inertia_s, "s"),
        est(
            "anti_resonance_hz",
            f.anti_resonance_hz,
            e.anti_resonance_hz,
            "Hz",
        ),
        est(
            "resonance_hz",
            f.resonance_hz(),
            f.resonance_hz() * rel_r,
            "Hz",
        ),
        est(
            "shaft_damping_ratio",
            f.shaft_damping_ratio,
            e.shaft_damping_ratio,
            "1",
        ),
        est(
            "viscous_pu",
            f.viscous_pu,
            e.viscous_pu,
            "pu torque per pu speed",
        ),
        est("delay_s", f.delay_s, e.delay_s, "s"),
        est("backlash_deg", lm.backlash_deg, lm.std_error_deg, "deg"),
        est(
            "backlash_counts",
            lm.backlash_deg * counts_per_deg,
            lm.std_error_deg * counts_per_deg,
            "counts",
        ),
    ]);
    v
}

/// `plant.toml`: the identified `[plant]` table.
#[derive(Serialize)]
struct PlantFile {
    plant: MechanicsConfig,
}

fn plant_toml(base: &RunConfig, ident: &Identification) -> Result<String> {
    let plant = identified_mechanics(base, &ident.fit.fit, ident.lost_motion.backlash_deg);
    let body = toml::to_string(&PlantFile { plant })
        .map_err(|e| HarnessError::Backend(format!("plant.toml: {e}")))?;
    Ok(format!(
        "# Identified by `hil-harness identify` from {} (base speed and encoder: the drive's).\n\
         # Only Bm + Bl shows in motor-side data; it is split evenly here.\n{body}",
        base.config_path.display()
    ))
}

/// `deg` made continuous: each value moved by whole turns to within 180° of the one before.
fn unwrapped(deg: impl IntoIterator<Item = f64>) -> Vec<f64> {
    let mut out: Vec<f64> = Vec::new();
    for d in deg {
        let v = match out.last() {
            Some(&prev) => nearest_turn(d, prev),
            None => d,
        };
        out.push(v);
    }
    out
}

/// `deg` moved by whole turns to the one nearest `near`.
fn nearest_turn(deg: f64, near: f64) -> f64 {
    deg + 360.0 * ((near - deg) / 360.0).round()
}

/// Points of the fitted curve on each decade between the measured bins' extremes.
const FIT_POINTS_PER_DECADE: f64 = 200.0;

/// The Bode plot: measured |θm/Tm| and phase (bins with γ² ≥ min_coherence as markers),
/// the fitted model as a line on a fine grid, the coherence, and the fitted anti-resonance
/// and resonance as labelled vertical lines. The phase is unwrapped: the fitted curve made
/// continuous along frequency and started in (−360°, 0°] (a position lags its torque), and
/// each measured point moved by whole turns to the one nearest the fitted curve at its
/// frequency, so noise never puts a point a turn away from the fit it matches.
pub fn bode(ident: &Identification, spec: &IdentifySpec, wb: f64) -> Figure {
    let fit = &ident.fit.fit;
    let measured = measured_bins(ident, spec);
    let curve = FittedCurve::new(fit, &measured, wb);
    Figure {
        x_label: "frequency (Hz)".into(),
        panels: vec![
            magnitude_panel(fit, &measured, &curve),
            phase_panel(fit, &measured, &curve, wb),
            coherence_panel(ident),
        ],
    }
}

/// The response's bins the fit used (γ² ≥ min_coherence, up to max_freq_hz, above 0 Hz):
/// (frequency \[Hz\], θm/Tm).
fn measured_bins(ident: &Identification, spec: &IdentifySpec) -> Vec<(f64, Complex<f64>)> {
    let r = &ident.response;
    let used = |i: usize| {
        r.coherence.get(i).is_some_and(|&g| g >= spec.min_coherence)
            && r.freq_hz.get(i).is_some_and(|&f| f <= spec.max_freq_hz)
    };
    r.freq_hz
        .iter()
        .zip(&r.h)
        .enumerate()
        .filter(|(i, (f, _))| used(*i) && **f > 0.0)
        .map(|(_, (&f, &h))| (f, h))
        .collect()
}

/// The phase of `h` \[deg\], in (−180°, 180°].
fn deg(h: Complex<f64>) -> f64 {
    h.arg().to_degrees()
}

/// The fitted model on a log grid from the lowest to the highest bin used, its phase
/// unwrapped.
struct FittedCurve {
    /// The grid \[Hz\].
    grid: Vec<f64>,
    /// The fitted θm/Tm at each frequency of `grid`.
    model: Vec<Complex<f64>>,
    /// Its phase \[deg\], continuous along `grid` and started in (−360°, 0°].
    phase: Vec<f64>,
}

impl FittedCurve {
    fn new(fit: &TwoInertiaFit, measured: &[(f64, Complex<f64>)], wb: f64) -> Self {
        let (lo, hi) = measured
            .iter()
            .fold((f64::INFINITY, 0.0_f64), |(a, b), &(f, _)| {
                (a.min(f), b.max(f))
            });
        let grid: Vec<f64> = if lo.is_finite() && hi > lo {
            let n = ((hi / lo).log10() * FIT_POINTS_PER_DECADE).ceil().max(2.0) as usize;
            (0..=n)
                .map(|k| lo * (hi / lo).powf(k as f64 / n as f64))
                .collect()
        } else {
            measured.iter().map(|&(f, _)| f).collect()
        };
        let model: Vec<Complex<f64>> = grid.iter().map(|&f| fit.response(f, wb)).collect();
        let mut phase = unwrapped(model.iter().map(|&h| deg(h)));
        if let Some(&first) = phase.first() {
            let shift = -360.0 * (first / 360.0).ceil();
            phase.iter_mut().for_each(|p| *p += shift);
        }
        Self { grid, model, phase }
    }

    /// The unwrapped fit at `f`: its raw phase there, on the turn of the nearest grid point.
    fn phase_at(&self, fit: &TwoInertiaFit, f: f64, wb: f64) -> f64 {
        let k = self.grid.partition_point(|&g| g < f);
        let near = [k.saturating_sub(1), k]
            .into_iter()
            .filter_map(|j| Some((self.grid.get(j)?, self.phase.get(j)?)))
            .min_by(|a, b| (a.0 / f).ln().abs().total_cmp(&(b.0 / f).ln().abs()))
            .map(|(_, &p)| p);
        let raw = deg(fit.response(f, wb));
        near.map_or(raw, |p| nearest_turn(raw, p))
    }
}

/// A panel of the Bode plot over a log frequency axis.
fn panel(title: &str, y: &str, series: Vec<Series>, log_y: bool) -> Panel {
    Panel {
        title: title.into(),
        y_label: y.into(),
        series,
        log_x: true,
        log_y,
        legend: Legend::LowerLeft,
    }
}

/// `v` with the fitted anti-resonance and resonance as vertical lines, `labelled` on the
/// magnitude panel only (the panels below share its frequencies; their lines stay
/// unlabelled, clear of the data).
fn with_marks(fit: &TwoInertiaFit, mut v: Vec<Series>, labelled: bool) -> Vec<Series> {
    let f_ar = fit.anti_resonance_hz;
    let f_r = fit.resonance_hz();
    let marks = [
        (format!("fitted anti-resonance {f_ar:.2} Hz"), f_ar),
        (format!("fitted resonance {f_r:.2} Hz"), f_r),
    ];
    v.extend(
        marks
            .into_iter()
            .filter(|(_, f)| f.is_finite() && *f > 0.0)
            .map(|(label, f)| Series::vertical(if labelled { label } else { String::new() }, f)),
    );
    v
}

/// |θm/Tm|: the bins used as markers, the fit as a line, the marks labelled.
fn magnitude_panel(
    fit: &TwoInertiaFit,
    measured: &[(f64, Complex<f64>)],
    curve: &FittedCurve,
) -> Panel {
    let series = vec![
        Series::markers(
            "measured",
            measured.iter().map(|&(f, h)| (f, h.norm())).collect(),
        ),
        Series::line(
            "fitted",
            curve
                .grid
                .iter()
                .zip(&curve.model)
                .map(|(&f, h)| (f, h.norm()))
                .collect(),
        ),
    ];
    panel(
        "Motor position / motor torque: magnitude",
        "rad per pu torque",
        with_marks(fit, series, true),
        true,
    )
}

/// The phase, unwrapped: each bin used on the turn nearest the fit at its frequency.
fn phase_panel(
    fit: &TwoInertiaFit,
    measured: &[(f64, Complex<f64>)],
    curve: &FittedCurve,
    wb: f64,
) -> Panel {
    let series = vec![
        Series::markers(
            "measured",
            measured
                .iter()
                .map(|&(f, h)| (f, nearest_turn(deg(h), curve.phase_at(fit, f, wb))))
                .collect(),
        ),
        Series::line(
            "fitted",
            curve
                .grid
                .iter()
                .copied()
                .zip(curve.phase.iter().copied())
                .collect(),
        ),
    ];
    panel(
        "Phase (unwrapped)",
        "deg",
        with_marks(fit, series, false),
        false,
    )
}

/// The coherence of every bin.
fn coherence_panel(ident: &Identification) -> Panel {
    let r = &ident.response;
    let series = vec![Series::markers(
        "coherence",
        r.freq_hz
            .iter()
            .zip(&r.coherence)
            .map(|(&f, &g)| (f, g))
            .collect(),
    )];
    panel(
        "Coherence",
        "coherence",
        with_marks(&ident.fit.fit, series, false),
        false,
    )
}

fn markdown(
    base: &RunConfig,
    spec: &IdentifySpec,
    ident: &Identification,
    est: &[Estimate],
) -> String {
    let mut md = String::new();
    let _ = writeln!(md, "# Identification of {}\n", base.config_path.display());
    let _ = writeln!(md, "Measured on {}.\n", ident.measured_on);
    let _ = writeln!(
        md,
        "Frequency response θm/Tm from a PRBS of ±{} pu on the torque reference ({} bits, \
         {} periods, {:.1} s used after {} s settling) under a {} pu rig preload; H1 with \
         Welch averaging over {} segments of {} samples, the excitation as the instrument. \
         Fit over {} bins with coherence ≥ {} up to {} Hz (weighted RMS residual {:.2}). \
         Lost motion from the reversal test (±{} pu rig torque reversed every {} s), fitted \
         by simulating the test on the identified model ({} simulations, RMS torque \
         mismatch {:.4} pu).\n",
        spec.amplitude_pu,
        spec.prbs_bits,
        spec.prbs_periods,
        ident.record_s,
        spec.settle_s,
        spec.preload_pu,
        ident.response.segments,
        spec.segment_len,
        ident.fit.bins,
        spec.min_coherence,
        spec.max_freq_hz,
        ident.fit.weighted_rms,
        spec.reversal_torque_pu,
        spec.reversal_hold_s,
        ident.lost_motion.evaluations,
        ident.lost_motion.rms_mismatch_pu,
    );
    md.push_str(&calibration_text(ident));
    md.push_str("| parameter | estimate | standard error | unit |\n|---|---|---|---|\n");
    for e in est {
        let _ = writeln!(
            md,
            "| {} | {:.6} | {:.2e} | {} |",
            e.name, e.value, e.std_error, e.unit
        );
    }
    md.push_str(&twin_table(ident));
    md.push_str("\n![Bode plot: measured and fitted](bode.png)\n\n`plant.toml` holds the `[plant]` table; `identify.json` every estimate.\n");
    md
}

/// A PMSM's motor calibration: how it was measured and the `[drive.pmsm]` it gives (empty
/// for a DC machine).
fn calibration_text(ident: &Identification) -> String {
    let Some(m) = &ident.motor else {
        return String::new();
    };
    format!(
        "First the motor calibration (the inverter alone, `machine-workflows/src/calibrate/`): \
         two α current levels for the phase resistance, a pseudo-random ±square wave on α and \
         β for the d and q inductances, then the voltage vector turned forwards and back for \
         the encoder's direction, counts per electrical turn and offset. The measurement \
         above ran with the drive using them (rotor lag behind the turning vector {:.2}° \
         electrical, cancelled by the two directions). As `[drive.pmsm]` (with \
         `[drive] winding_resistance_pu = {}`; `commission` writes them into `drive.toml`):\n\n\
         ```toml\n[drive.pmsm]\npole_pairs = {}\nd_inductance_pu_s = {}\n\
         q_inductance_pu_s = {}\nencoder_offset_elec_deg = {}\nencoder_reversed = {}\n```\n\n",
        m.sweep_lag_elec_deg,
        m.winding_resistance_pu.value as f32,
        m.pole_pairs,
        m.d_inductance_pu_s.value as f32,
        m.q_inductance_pu_s.value as f32,
        m.encoder_offset_elec_deg.value as f32,
        m.encoder_reversed,
    )
}

/// The check on the twin, as a table: what the fit gave, what the same fit gave on a twin
/// with those mechanics, and the estimate with the twin's bias taken out.
fn twin_table(ident: &Identification) -> String {
    let Some(t) = &ident.twin else {
        return "\nThe check on a simulated twin gave no fit: the estimates above are the raw \
                fit's.\n"
            .into();
    };
    let (fit, lm) = (&ident.fit.fit, &ident.lost_motion);
    let reported = [
        fit.motor_inertia_s,
        fit.load_inertia_s,
        fit.anti_resonance_hz,
        fit.shaft_damping_ratio,
        fit.viscous_pu,
        fit.delay_s,
        lm.backlash_deg,
    ];
    let mut md = format!(
        "\nThe estimates above have the method's own bias taken out: the same measurement and \
         fit, run {} times (noise seeds) on a simulated twin whose mechanics are the raw fit, \
         miss those mechanics by the bias shown; the standard errors include the twin's spread \
         and how much the bias moved on a second twin (`docs/tuning.md`).\n\n\
         | parameter | raw fit | twin's estimate of it | spread | bias moved | reported |\n\
         |---|---|---|---|---|---|\n",
        t.runs
    );
    for (j, name) in twin::NAMES.iter().enumerate() {
        let at = |a: &[f64; twin::PARAMS]| a.get(j).copied().unwrap_or(f64::NAN);
        let _ = writeln!(
            md,
            "| {name} | {:.6} | {:.6} | {:.2e} | {:.2e} | {:.6} |",
            at(&t.truth),
            at(&t.mean),
            at(&t.spread),
            at(&t.variation),
            at(&reported)
        );
    }
    md
}

/// Writes every file into `dir` (a staging directory).
pub fn write_all(
    dir: &Path,
    base: &RunConfig,
    spec: &IdentifySpec,
    ident: &Identification,
) -> Result<()> {
    let est = estimates(base, ident);
    let put = |name: &str, text: &str| {
        let path = dir.join(name);
        std::fs::write(&path, text).map_err(|e| HarnessError::io(&path, e))
    };
    put("plant.toml", &plant_toml(base, ident)?)?;
    let report = Report {
        config: base.config_path.display().to_string(),
        measured_on: &ident.measured_on,
        estimates: est.clone(),
        fit_weighted_rms: ident.fit.weighted_rms,
        fit_bins: ident.fit.bins,
        segments: ident.response.segments,
        record_s: ident.record_s,
        lost_motion_rms_mismatch_pu: ident.lost_motion.rms_mismatch_pu,
        twin: ident.twin,
        twin_parameters: twin::NAMES,
        settings: spec,
    };
    let json = serde_json::to_string_pretty(&report)
        .map_err(|e| HarnessError::io(dir.join("identify.json"), e))?;
    put("identify.json", &(json + "\n"))?;
    put("identify.md", &markdown(base, spec, ident, &est))?;
    let wb = f64::from(base.drive.base_speed_rpm) * std::f64::consts::TAU / 60.0;
    save(&bode(ident, spec, wb), &dir.join("bode"))?;
    Ok(())
}
