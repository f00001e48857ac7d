//! Spectra of a uniformly sampled window, for the oscillation verdict and the band RMS
//! figures: the peak of a Hann-windowed, zero-padded FFT, the share of the energy near
//! it, and the RMS of the part of a signal inside a frequency band.

use fft::Complex;
use std::f64::consts::PI;

type Complex64 = Complex<f64>;

/// Zero padding of the peak search: the FFT is this many times the window's length
/// (rounded up to a power of two), so the bins are T/16 apart before interpolation.
const PAD: usize = 16;

/// `x` less its least-squares straight line (a slow trend leaks into every bin).
pub(super) fn detrended(x: &[f64]) -> Vec<f64> {
    let n = x.len() as f64;
    if x.len() < 2 {
        return x.iter().map(|_| 0.0).collect();
    }
    let mean_k = (n - 1.0) / 2.0;
    let mean_x = x.iter().sum::<f64>() / n;
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for (k, v) in x.iter().enumerate() {
        let dk = k as f64 - mean_k;
        sxy += dk * (v - mean_x);
        sxx += dk * dk;
    }
    let slope = if sxx > 0.0 { sxy / sxx } else { 0.0 };
    x.iter()
        .enumerate()
        .map(|(k, v)| v - mean_x - slope * (k as f64 - mean_k))
        .collect()
}

fn forward(mut buf: Vec<Complex64>) -> Vec<Complex64> {
    fft::forward(&mut buf);
    buf
}

/// The one-sided power of `x` (detrended, Hann-windowed, zero-padded) at bins
/// `k·fs/len`, k = 0..=len/2, and the bin spacing (Hz).
fn padded_power(x: &[f64], fs_hz: f64) -> (Vec<f64>, f64) {
    let n = x.len();
    let len = (n * PAD).next_power_of_two().max(2);
    let d = detrended(x);
    let mut buf = vec![Complex64::new(0.0, 0.0); len];
    for (k, (b, v)) in buf.iter_mut().zip(&d).enumerate() {
        let hann = 0.5 - 0.5 * (2.0 * PI * k as f64 / n as f64).cos();
        *b = Complex64::new(v * hann, 0.0);
    }
    let power = forward(buf)
        .iter()
        .take(len / 2 + 1)
        .map(|c| c.norm_sqr())
        .collect();
    (power, fs_hz / len as f64)
}

/// The spectral peak of a window and how much of its energy lies near it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Peak {
    /// Frequency of the largest bin above `f_min_hz`, refined by a parabola through the
    /// log-power of it and its neighbours (Hz).
    pub freq_hz: f64,
    /// Energy within ±`half_band_hz` of the peak over the energy above `f_min_hz`.
    pub narrowband_fraction: f64,
}

/// The frequencies a peak search looks at: `lo_hz ..= hi_hz`, less the `skip` intervals.
#[derive(Clone, Copy, Debug)]
pub(super) struct Band<'a> {
    /// Lowest frequency (Hz).
    pub lo_hz: f64,
    /// Highest frequency (Hz); infinite = up to Nyquist.
    pub hi_hz: f64,
    /// Intervals (Hz) left out of the search and of both energies.
    pub skip: &'a [(f64, f64)],
}

impl Band<'_> {
    /// Everything from `lo_hz` up.
    pub const fn above(lo_hz: f64) -> Band<'static> {
        Band {
            lo_hz,
            hi_hz: f64::INFINITY,
            skip: &[],
        }
    }

    fn holds(&self, f: f64) -> bool {
        f >= self.lo_hz && f <= self.hi_hz && !self.skip.iter().any(|(a, b)| f >= *a && f <= *b)
    }
}

/// [`Peak`] of `x` sampled at `fs_hz`, over the frequencies of `band`; `None` for an empty
/// or silent window.
pub(super) fn peak(x: &[f64], fs_hz: f64, band: &Band, half_band_hz: f64) -> Option<Peak> {
    if x.len() < 4 || fs_hz <= 0.0 {
        return None;
    }
    let (p, df) = padded_power(x, fs_hz);
    let first = (band.lo_hz / df).ceil() as usize;
    let inside = |i: usize| band.holds(i as f64 * df);
    let (k, _) = p
        .iter()
        .enumerate()
        .skip(first)
        .filter(|(i, _)| inside(*i))
        .max_by(|a, b| a.1.total_cmp(b.1))?;
    let total: f64 = p
        .iter()
        .enumerate()
        .skip(first)
        .filter(|(i, _)| inside(*i))
        .map(|(_, v)| v)
        .sum();
    if total.is_nan() || total <= 0.0 {
        return None;
    }
    let at = |i: usize| p.get(i).copied().unwrap_or(0.0).max(1e-300).ln();
    let shift = match (k.checked_sub(1), p.get(k + 1)) {
        (Some(lo), Some(_)) => {
            let (a, b, c) = (at(lo), at(k), at(k + 1));
            let den = a - 2.0 * b + c;
            if den < 0.0 {
                (0.5 * (a - c) / den).clamp(-0.5, 0.5)
            } else {
                0.0
            }
        }
        _ => 0.0,
    };
    let freq_hz = (k as f64 + shift) * df;
    let near: f64 = p
        .iter()
        .enumerate()
        .skip(first)
        .filter(|(i, _)| inside(*i) && (*i as f64 * df - freq_hz).abs() <= half_band_hz)
        .map(|(_, v)| v)
        .sum();
    Some(Peak {
        freq_hz,
        narrowband_fraction: near / total,
    })
}

/// RMS of the part of `x` (detrended, no window) with frequencies in `[lo_hz, hi_hz]`,
/// by Parseval over the FFT's bins in the band (both signs of frequency).
pub(super) fn band_rms(x: &[f64], fs_hz: f64, lo_hz: f64, hi_hz: f64) -> f64 {
    let n = x.len();
    if n < 2 || fs_hz <= 0.0 {
        return 0.0;
    }
    let buf = detrended(x)
        .into_iter()
        .map(|v| Complex64::new(v, 0.0))
        .collect();
    let spectrum = forward(buf);
    let df = fs_hz / n as f64;
    let energy: f64 = spectrum
        .iter()
        .enumerate()
        .filter(|(k, _)| {
            // Bin k stands for +k·df below n/2 and for −(n−k)·df above it.
            let f = (*k).min(n - *k) as f64 * df;
            f >= lo_hz && f <= hi_hz && *k != 0
        })
        .map(|(_, c)| c.norm_sqr())
        .sum();
    (energy / (n as f64 * n as f64)).sqrt()
}

/// `x` (detrended) with the FFT bins outside `[lo_hz, hi_hz]` set to zero.
pub(super) fn band_passed(x: &[f64], fs_hz: f64, (lo_hz, hi_hz): (f64, f64)) -> Vec<f64> {
    let n = x.len();
    if n < 2 || fs_hz <= 0.0 {
        return x.to_vec();
    }
    let buf = detrended(x)
        .into_iter()
        .map(|v| Complex64::new(v, 0.0))
        .collect();
    let df = fs_hz / n as f64;
    let mut spectrum = forward(buf);
    for (k, c) in spectrum.iter_mut().enumerate() {
        let f = k.min(n - k) as f64 * df;
        if f < lo_hz || f > hi_hz {
            *c = Complex64::new(0.0, 0.0);
        }
    }
    fft::inverse(&mut spectrum);
    spectrum.iter().map(|c| c.re / n as f64).collect()
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn a_tone_peaks_at_its_frequency_and_is_narrowband() {
        let fs = 2000.0;
        let x: Vec<f64> = (0..1000)
            .map(|k| 0.3 * (2.0 * PI * 178.3 * k as f64 / fs).sin() + 1e-3 * k as f64)
            .collect();
        let p = peak(&x, fs, &Band::above(5.0), 4.0).unwrap();
        assert!((p.freq_hz - 178.3).abs() < 0.1, "{p:?}");
        assert!(p.narrowband_fraction > 0.95, "{p:?}");
    }

    #[test]
    fn band_rms_keeps_the_tone_inside_the_band_only() {
        let fs = 2000.0;
        let x: Vec<f64> = (0..2000)
            .map(|k| {
                let t = k as f64 / fs;
                (2.0 * PI * 3.0 * t).sin() + 0.2 * (2.0 * PI * 60.0 * t).sin()
            })
            .collect();
        let r = band_rms(&x, fs, 20.0, 100.0);
        assert!((r - 0.2 / 2f64.sqrt()).abs() < 1e-3, "{r}");
    }
}
