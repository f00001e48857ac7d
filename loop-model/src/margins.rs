//! Gain and phase margins of a sampled loop gain.

use nalgebra::Complex;
use std::f64::consts::PI;

/// Margins of a loop opened at one point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Margins {
    /// Gain margin \[dB\] at the first phase crossing of −180° above the crossover
    /// (infinite if there is none).
    pub gain_margin_db: f64,
    /// Phase margin \[deg\] at the gain crossover.
    pub phase_margin_deg: f64,
    /// Gain-crossover frequency \[Hz\].
    pub crossover_hz: f64,
    /// Frequency of the −180° crossing the gain margin is read at \[Hz\] (NaN if none).
    pub phase_crossover_hz: f64,
}

/// Gain and phase margins of a loop gain `l` sampled at increasing frequencies `freqs`
/// \[Hz\]: the phase margin at the first gain crossover (downwards through 1), the gain
/// margin the smallest at the −180° (mod 360°) crossings after it.
///
/// ```
/// use loop_model::margins::margins_of;
/// use nalgebra::Complex;
/// // L = K·e^(−sτ)/s, K = 10 rad/s, τ = 10 ms: crossover 10 rad/s, PM = 90° − 5.7°,
/// // the −180° crossing at π/(2τ) with |L| = 2Kτ/π: GM = 20·log10(π/(2Kτ)) = 17.9 dB.
/// let (k, tau) = (10.0, 0.01);
/// let f: Vec<f64> = (1..20_000).map(|i| i as f64 * 0.005).collect();
/// let l: Vec<Complex<f64>> = f.iter().map(|f| {
///     let s = Complex::new(0.0, 2.0 * std::f64::consts::PI * f);
///     (s * -tau).exp() * k / s
/// }).collect();
/// let m = margins_of(&f, &l);
/// assert!((m.phase_margin_deg - (90.0 - (k * tau).to_degrees())).abs() < 0.05);
/// assert!((m.crossover_hz - k / (2.0 * std::f64::consts::PI)).abs() < 1e-3);
/// let gm = 20.0 * (std::f64::consts::PI / (2.0 * k * tau)).log10();
/// assert!((m.gain_margin_db - gm).abs() < 0.01);
/// ```
#[must_use]
pub fn margins_of(freqs: &[f64], l: &[Complex<f64>]) -> Margins {
    let mut out = Margins {
        gain_margin_db: f64::INFINITY,
        phase_margin_deg: f64::INFINITY,
        crossover_hz: f64::NAN,
        phase_crossover_hz: f64::NAN,
    };
    let phase = unwrap_phases(l);
    let at = |v: &[f64], i: usize| v.get(i).copied().unwrap_or(f64::NAN);
    let mag = |i: usize| l.get(i).map_or(f64::NAN, |v| v.norm());
    let mut crossed = false;
    for i in 1..l.len() {
        let (a, b) = (mag(i - 1), mag(i));
        let (pa, pb) = (at(&phase, i - 1), at(&phase, i));
        let (fa, fb) = (at(freqs, i - 1), at(freqs, i));
        if !crossed && a >= 1.0 && b < 1.0 {
            let t = a.ln() / (a.ln() - b.ln());
            // 180° + ∠L, taken into (−180°, 180°]: the unwrapped phase carries whole turns.
            let pm = (180.0 + (pa + t * (pb - pa)).to_degrees()).rem_euclid(360.0);
            out.phase_margin_deg = if pm > 180.0 { pm - 360.0 } else { pm };
            out.crossover_hz = fa + t * (fb - fa);
            crossed = true;
        }
        // A crossing of −180° (mod 360°): (φ + π)/2π changes its integer part.
        let turn = |p: f64| ((p + PI) / (2.0 * PI)).floor();
        if crossed && turn(pa) != turn(pb) {
            let target = turn(pa.max(pb)) * 2.0 * PI - PI;
            let t = (target - pa) / (pb - pa);
            let g = a.ln() + t * (b.ln() - a.ln());
            let gm = -20.0 * g / std::f64::consts::LN_10;
            if gm < out.gain_margin_db {
                out.gain_margin_db = gm;
                out.phase_crossover_hz = fa + t * (fb - fa);
            }
        }
    }
    out
}

/// The phases of `l` \[rad\], unwrapped along the samples (no jump over π).
#[must_use]
pub fn unwrap_phases(l: &[Complex<f64>]) -> Vec<f64> {
    let mut out = Vec::with_capacity(l.len());
    let mut offset = 0.0;
    let mut last: Option<f64> = None;
    for v in l {
        let p = v.arg();
        if let Some(prev) = last {
            let mut d = p + offset - prev;
            while d > PI {
                offset -= 2.0 * PI;
                d -= 2.0 * PI;
            }
            while d < -PI {
                offset += 2.0 * PI;
                d += 2.0 * PI;
            }
        }
        let u = p + offset;
        out.push(u);
        last = Some(u);
    }
    out
}
