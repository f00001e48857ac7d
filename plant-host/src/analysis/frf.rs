//! Frequency response from recorded signals: Welch-averaged cross spectra, the H1
//! estimator and the coherence.
//!
//! For signals x (input) and y (output), cut into segments of `segment_len` samples that
//! overlap by half, each Hann-windowed and transformed:
//!
//!   Sxx = mean |X|²,  Syy = mean |Y|²,  Sxy = mean X̄·Y
//!   H1 = Sxy / Sxx,   γ² = |Sxy|² / (Sxx·Syy)
//!
//! H1 is unbiased by noise on the output. In a closed loop, noise on the input is
//! correlated with the output through the feedback, and H1(u → y) is biased towards the
//! inverse controller. [`closed_loop_response`] avoids this with the excitation r as the
//! instrument: G = H1(r → y) / H1(r → u). Noise that enters anywhere in the loop is
//! uncorrelated with r, so it averages out of both.

use super::MeasuredResponse;
use nalgebra::Complex;
use std::f64::consts::PI;

/// Why a response could not be estimated.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum FrfError {
    /// The signals differ in length.
    LengthMismatch,
    /// `segment_len` is not a power of two in 16..=2^20, or the record holds fewer than
    /// two segments of it.
    Segment {
        /// The segment length asked for.
        segment_len: usize,
        /// The record length.
        record_len: usize,
    },
    /// A sample is NaN or infinite.
    NotFinite,
}

impl std::fmt::Display for FrfError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::LengthMismatch => write!(f, "the recorded signals differ in length"),
            Self::Segment {
                segment_len,
                record_len,
            } => write!(
                f,
                "segment_len = {segment_len}: must be a power of two in 16..=1048576 with at \
                 least two segments in the {record_len}-sample record"
            ),
            Self::NotFinite => write!(f, "a recorded sample is not finite"),
        }
    }
}

impl std::error::Error for FrfError {}

/// Welch auto- and cross-spectra of a set of channels, one segment length.
struct Spectra {
    /// For each channel pair (a, b) asked for: mean conj(A)·B per bin.
    cross: Vec<Vec<Complex<f64>>>,
    segments: usize,
}

fn spectra(
    channels: &[&[f64]],
    pairs: &[(usize, usize)],
    segment_len: usize,
) -> Result<Spectra, FrfError> {
    let n = channels.first().map_or(0, |c| c.len());
    if channels.iter().any(|c| c.len() != n) {
        return Err(FrfError::LengthMismatch);
    }
    if !segment_len.is_power_of_two()
        || !(16..=1 << 20).contains(&segment_len)
        || n < segment_len * 3 / 2
    {
        return Err(FrfError::Segment {
            segment_len,
            record_len: n,
        });
    }
    if channels.iter().any(|c| c.iter().any(|v| !v.is_finite())) {
        return Err(FrfError::NotFinite);
    }
    let window: Vec<f64> = (0..segment_len)
        .map(|i| 0.5 - 0.5 * (2.0 * PI * i as f64 / segment_len as f64).cos())
        .collect();
    let bins = segment_len / 2;
    let mut cross = vec![vec![Complex::new(0.0, 0.0); bins]; pairs.len()];
    let hop = segment_len / 2;
    let mut segments = 0;
    let mut buffers: Vec<Vec<Complex<f64>>> = vec![Vec::new(); channels.len()];
    let mut start = 0;
    while start + segment_len <= n {
        for (buf, ch) in buffers.iter_mut().zip(channels) {
            let seg = ch.get(start..start + segment_len).unwrap_or(&[]);
            // Remove the segment's mean, so a drift or offset does not leak into bin 1.
            let mean = seg.iter().sum::<f64>() / segment_len as f64;
            buf.clear();
            buf.extend(
                seg.iter()
                    .zip(&window)
                    .map(|(v, w)| Complex::new((v - mean) * w, 0.0)),
            );
            fft::forward(buf);
        }
        for (acc, &(a, b)) in cross.iter_mut().zip(pairs) {
            let (Some(xa), Some(xb)) = (buffers.get(a), buffers.get(b)) else {
                continue;
            };
            for ((s, va), vb) in acc.iter_mut().zip(xa.iter().skip(1)).zip(xb.iter().skip(1)) {
                *s += va.conj() * vb;
            }
        }
        segments += 1;
        start += hop;
    }
    let scale = 1.0 / segments as f64;
    for acc in &mut cross {
        for s in acc.iter_mut() {
            *s *= scale;
        }
    }
    Ok(Spectra { cross, segments })
}

fn bin_freqs(segment_len: usize, rate_hz: f64) -> Vec<f64> {
    (1..=segment_len / 2)
        .map(|k| k as f64 * rate_hz / segment_len as f64)
        .collect()
}

fn coherence(sab: Complex<f64>, saa: Complex<f64>, sbb: Complex<f64>) -> f64 {
    let den = saa.re * sbb.re;
    if den > 0.0 {
        (sab.norm_sqr() / den).clamp(0.0, 1.0)
    } else {
        0.0
    }
}

fn ratio(num: Complex<f64>, den: Complex<f64>) -> Complex<f64> {
    if den.norm_sqr() > 0.0 {
        num / den
    } else {
        Complex::new(f64::NAN, f64::NAN)
    }
}

/// H1 = Sxy/Sxx from input `x` to output `y`, sampled at `rate_hz`.
///
/// ```
/// use plant_host::analysis::h1;
/// // y[k] = 2·x[k−1]: gain 2 at every frequency, phase −ω·T.
/// let x: Vec<f64> = (0..4096u32)
///     .map(|k| (k.wrapping_mul(2_654_435_761) % 1000) as f64 / 500.0 - 1.0)
///     .collect();
/// let y: Vec<f64> = std::iter::once(0.0).chain(x.iter().map(|v| 2.0 * v)).take(4096).collect();
/// let r = h1(&x, &y, 1000.0, 256).unwrap();
/// assert!(r.h.iter().all(|h| (h.norm() - 2.0).abs() < 0.05));
/// assert!(r.coherence.iter().all(|&g| g > 0.95));
/// ```
pub fn h1(
    x: &[f64],
    y: &[f64],
    rate_hz: f64,
    segment_len: usize,
) -> Result<MeasuredResponse, FrfError> {
    let s = spectra(&[x, y], &[(0, 0), (1, 1), (0, 1)], segment_len)?;
    let [sxx, syy, sxy] = [0, 1, 2].map(|i| s.cross.get(i).cloned().unwrap_or_default());
    let h = sxy.iter().zip(&sxx).map(|(&n, &d)| ratio(n, d)).collect();
    let coherence = sxy
        .iter()
        .zip(&sxx)
        .zip(&syy)
        .map(|((&xy, &xx), &yy)| coherence(xy, xx, yy))
        .collect();
    Ok(MeasuredResponse {
        freq_hz: bin_freqs(segment_len, rate_hz),
        h,
        coherence,
        segments: s.segments,
    })
}

/// The plant's response from `u` (its input, e.g. measured torque) to `y` (its output, e.g.
/// motor position) inside a closed loop excited by `r`: H1(r → y)/H1(r → u).
pub fn closed_loop_response(
    r: &[f64],
    u: &[f64],
    y: &[f64],
    rate_hz: f64,
    segment_len: usize,
) -> Result<MeasuredResponse, FrfError> {
    let s = spectra(
        &[r, u, y],
        &[(0, 0), (1, 1), (2, 2), (0, 1), (0, 2)],
        segment_len,
    )?;
    let [srr, suu, syy, sru, sry] =
        [0, 1, 2, 3, 4].map(|i| s.cross.get(i).cloned().unwrap_or_default());
    let h = sry.iter().zip(&sru).map(|(&n, &d)| ratio(n, d)).collect();
    let coherence = (0..srr.len())
        .map(|k| {
            let g = |sab: &[Complex<f64>], sbb: &[Complex<f64>]| match (
                sab.get(k),
                srr.get(k),
                sbb.get(k),
            ) {
                (Some(&ab), Some(&aa), Some(&bb)) => coherence(ab, aa, bb),
                _ => 0.0,
            };
            g(&sry, &syy).min(g(&sru, &suu))
        })
        .collect();
    Ok(MeasuredResponse {
        freq_hz: bin_freqs(segment_len, rate_hz),
        h,
        coherence,
        segments: s.segments,
    })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::indexing_slicing)]
    use super::*;

    /// A deterministic white-ish sequence in [−1, 1).
    fn noise(n: usize, seed: u64) -> Vec<f64> {
        let mut s = seed;
        (0..n)
            .map(|_| {
                s = s
                    .wrapping_mul(6_364_136_223_846_793_005)
                    .wrapping_add(1_442_695_040_888_963_407);
                (s >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
            })
            .collect()
    }

    /// A first-order discrete system y[k] = a·y[k−1] + (1 − a)·x[k]: H1 against its exact
    /// response, with output noise (which H1 ignores) and coherence below 1 where the noise
    /// dominates.
    #[test]
    fn h1_matches_a_known_discrete_system() {
        let n = 1 << 16;
        let a: f64 = 0.9;
        let x = noise(n, 1);
        let e = noise(n, 2);
        let mut y = vec![0.0; n];
        let mut prev = 0.0;
        for ((yk, xk), ek) in y.iter_mut().zip(&x).zip(&e) {
            prev = a * prev + (1.0 - a) * xk;
            *yk = prev + 0.05 * ek;
        }
        let r = h1(&x, &y, 1000.0, 1024).unwrap_or_else(|e| unreachable!("{e}"));
        assert_eq!(r.segments, 127);
        for ((f, h), g) in r.freq_hz.iter().zip(&r.h).zip(&r.coherence) {
            let z = Complex::from_polar(1.0, -2.0 * PI * f / 1000.0);
            let want = (1.0 - a) / (1.0 - a * z);
            if *f < 50.0 {
                assert!((h / want - 1.0).norm() < 0.03, "{f}: {h} vs {want}");
                assert!(*g > 0.9, "{f}: {g}");
            }
        }
        // Near Nyquist the system's output (gain 0.053) is comparable to the noise.
        assert!(r.coherence.last().is_some_and(|&g| g < 0.9));
    }

    /// In a loop u = r − k·y_m whose measured output y_m = y + n carries noise, the noise
    /// comes back through the feedback into u and H1(u → y_m) is biased towards −1/k;
    /// H1(r → y_m)/H1(r → u) recovers the plant.
    #[test]
    fn closed_loop_estimate_removes_the_feedback_bias() {
        let n = 1 << 16;
        let (a, k) = (0.95, 8.0);
        let r = noise(n, 3);
        let v = noise(n, 4);
        let (mut u, mut y) = (vec![0.0; n], vec![0.0; n]);
        let mut state = 0.0;
        for i in 0..n {
            let measured = state + 0.1 * v[i];
            let ui = r[i] - k * measured;
            state = a * state + (1.0 - a) * ui;
            u[i] = ui;
            y[i] = measured;
        }
        // Plant: y[k] = a·y[k−1] + (1 − a)·u[k−1] → G = (1 − a)·z⁻¹/(1 − a·z⁻¹).
        let plant = |f: f64| {
            let z = Complex::from_polar(1.0, -2.0 * PI * f / 1000.0);
            (1.0 - a) * z / (1.0 - a * z)
        };
        let cl =
            closed_loop_response(&r, &u, &y, 1000.0, 512).unwrap_or_else(|e| unreachable!("{e}"));
        let open = h1(&u, &y, 1000.0, 512).unwrap_or_else(|e| unreachable!("{e}"));
        // Below 50 Hz γ² ≈ 0.6 with 255 segments: each bin's random error is about
        // √((1 − γ²)/(2·255·γ²)) ≈ 0.04, so the mean over the band shows the bias.
        let band: Vec<usize> = (0..cl.freq_hz.len())
            .filter(|&i| cl.freq_hz[i] < 50.0)
            .collect();
        let mean_err = |h: &[Complex<f64>]| {
            band.iter()
                .map(|&i| (h[i] / plant(cl.freq_hz[i]) - 1.0).norm())
                .sum::<f64>()
                / band.len() as f64
        };
        let (e_cl, e_open) = (mean_err(&cl.h), mean_err(&open.h));
        assert!(e_cl < 0.1, "closed-loop estimate: mean error {e_cl}");
        assert!(
            e_open > 0.3,
            "H1(u → y) should be biased: mean error {e_open}"
        );
    }

    #[test]
    fn bad_records_are_errors() {
        let x = vec![0.0; 100];
        assert_eq!(h1(&x, &x[..99], 1.0, 16), Err(FrfError::LengthMismatch));
        assert!(matches!(
            h1(&x, &x, 1.0, 100),
            Err(FrfError::Segment { .. })
        ));
        assert!(matches!(
            h1(&x, &x, 1.0, 128),
            Err(FrfError::Segment { .. })
        ));
        let mut y = x.clone();
        y[5] = f64::NAN;
        assert_eq!(h1(&x, &y, 1.0, 16), Err(FrfError::NotFinite));
    }
}
