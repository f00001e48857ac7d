//! Gain and phase margins of a sampled loop gain.

use nalgebra::Complex;
use std::f64::consts::PI;

/// Points of the margins' log grid, from [`GRID_LO_HZ`] to just below the Nyquist frequency.
pub const GRID_POINTS: usize = 800;
/// The grid's lowest frequency \[Hz\].
pub const GRID_LO_HZ: f64 = 0.01;
/// The coarse pass of [`refined`] evaluates every this many grid points.
pub const COARSE_STRIDE: usize = 5;
/// A coarse interval whose phase, or ln |L|, changes by more than this \[rad\] is
/// evaluated in full (as are its neighbours).
pub const TURN_RAD: f64 = 0.3;

/// How far the phase `p` \[rad\] is from the nearest −180° (mod 360°) \[rad\].
fn off_half_turn(p: f64) -> f64 {
    let x = (p - PI).rem_euclid(2.0 * PI);
    x.min(2.0 * PI - x)
}

/// The margins' log grid for a loop sampled every `period_s`: [`GRID_POINTS`] from
/// [`GRID_LO_HZ`] to 0.999 × the Nyquist frequency.
#[must_use]
pub fn margin_grid(period_s: f64) -> Vec<f64> {
    plant_host::analysis::log_space(GRID_LO_HZ, 0.5 / period_s * 0.999, GRID_POINTS)
}

/// The response `at` on `freqs` where it matters for the margins: at every
/// [`COARSE_STRIDE`]-th point (and the last), and at every point of each coarse interval
/// where it turns (a phase change or a change of ln |L| over [`TURN_RAD`], |L| crossing 1,
/// the phase crossing −180°) or turns back near a crossing (a coarse point where the phase
/// or ln |L| has an extremum within 2 × [`TURN_RAD`] of −180° or of 0: the response could
/// cross and come back between two coarse points), and of that interval's neighbours. Returns the frequencies
/// evaluated, increasing, and the response at each.
pub fn refined(freqs: &[f64], at: impl Fn(f64) -> Complex<f64>) -> (Vec<f64>, Vec<Complex<f64>>) {
    let n = freqs.len();
    let mut coarse: Vec<usize> = (0..n).step_by(COARSE_STRIDE.max(1)).collect();
    if n > 0 && coarse.last() != Some(&(n - 1)) {
        coarse.push(n - 1);
    }
    let value = |i: usize| freqs.get(i).map_or(Complex::new(f64::NAN, 0.0), |f| at(*f));
    let coarse_l: Vec<Complex<f64>> = coarse.iter().map(|i| value(*i)).collect();
    let turn = |p: f64| ((p + PI) / (2.0 * PI)).floor();
    let phase = unwrap_phases(&coarse_l);
    let gain: Vec<f64> = coarse_l.iter().map(|v| v.norm().ln()).collect();
    let mut turns: Vec<bool> = coarse_l
        .windows(2)
        .zip(phase.windows(2))
        .zip(gain.windows(2))
        .map(|((l, p), g)| match (l, p, g) {
            ([a, b], [pa, pb], [ga, gb]) => {
                !(a.norm().is_finite() && b.norm().is_finite() && ga.is_finite() && gb.is_finite())
                    || (pb - pa).abs() > TURN_RAD
                    || (gb - ga).abs() > TURN_RAD
                    || (*ga >= 0.0) != (*gb >= 0.0)
                    || turn(*pa) != turn(*pb)
            }
            _ => true,
        })
        .collect();
    // Where the phase or the gain turns back near its crossing level, it may cross and
    // come back between two coarse points: both intervals at that point are evaluated.
    let extremum = |v: &[f64], k: usize, near: &dyn Fn(f64) -> bool| match v.get(k - 1..=k + 1) {
        Some([a, b, c]) => (b - a) * (c - b) <= 0.0 && near(*b),
        _ => false,
    };
    for k in 1..coarse_l.len().saturating_sub(1) {
        if extremum(&phase, k, &|p| off_half_turn(p) < 2.0 * TURN_RAD)
            || extremum(&gain, k, &|g| g.abs() < 2.0 * TURN_RAD)
        {
            for q in [k - 1, k] {
                if let Some(t) = turns.get_mut(q) {
                    *t = true;
                }
            }
        }
    }
    let mut f = Vec::with_capacity(n);
    let mut l = Vec::with_capacity(n);
    for (k, pair) in coarse.windows(2).enumerate() {
        let [i, j] = [
            pair.first().copied().unwrap_or(0),
            pair.get(1).copied().unwrap_or(0),
        ];
        let full = [k.wrapping_sub(1), k, k + 1]
            .iter()
            .any(|q| turns.get(*q).copied().unwrap_or(false));
        f.push(freqs.get(i).copied().unwrap_or(f64::NAN));
        l.push(
            coarse_l
                .get(k)
                .copied()
                .unwrap_or(Complex::new(f64::NAN, 0.0)),
        );
        if full {
            for q in i + 1..j {
                f.push(freqs.get(q).copied().unwrap_or(f64::NAN));
                l.push(value(q));
            }
        }
    }
    if let (Some(i), Some(v)) = (coarse.last(), coarse_l.last()) {
        f.push(freqs.get(*i).copied().unwrap_or(f64::NAN));
        l.push(*v);
    }
    (f, l)
}

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
