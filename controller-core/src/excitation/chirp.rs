//! The logarithmic chirp: its design (start increment and growth factor from the band and
//! the sweep time) and its tick (phase accumulator and the Q1.30 sine).

use super::{ExcitationParams, ExcitationState, Kind, MAX_DURATION_S, check};
use crate::error::ConfigError;

/// Design a chirp from `start_hz` to `end_hz` over `duration_s` at the tick rate `rate_hz`.
pub(super) fn design(
    start_hz: f32,
    end_hz: f32,
    duration_s: f32,
    rate_hz: f32,
    p: ExcitationParams,
) -> Result<Kind, ConfigError> {
    let nyquist = rate_hz / 2.0;
    check(start_hz, 0.0, nyquist, p.start_or_bits)?;
    check(end_hz, start_hz, nyquist, p.end_or_hold)?;
    if end_hz >= nyquist {
        return Err(ConfigError::AboveNyquist {
            param: p.end_or_hold,
            value: end_hz,
            nyquist,
        });
    }
    check(duration_s, 0.0, MAX_DURATION_S, p.duration_or_periods)?;
    let n = f64::from(duration_s) * f64::from(rate_hz);
    if n < 1.0 {
        return Err(ConfigError::OutOfRange {
            param: p.duration_or_periods,
            value: duration_s,
            min: 1.0 / rate_hz,
            max: MAX_DURATION_S,
            min_exclusive: false,
        });
    }
    let two64 = 18_446_744_073_709_551_616.0;
    let start = f64::from(start_hz) / f64::from(rate_hz) * two64;
    let r_minus_1 = crate::cfgmath::exp(crate::cfgmath::ln(f64::from(end_hz / start_hz)) / n) - 1.0;
    Ok(Kind::Chirp {
        start_increment: start as u64,
        growth: (r_minus_1 * 4_294_967_296.0 + 0.5) as u32,
        ticks: n as u32,
    })
}

/// One chirp tick: the Q1.30 sample at the current phase, then the phase and its increment
/// advanced (Δφ ← Δφ + Δφ·(r − 1)).
#[inline(always)]
pub(super) fn step(s: &mut ExcitationState, start_increment: u64, growth: u32) -> i32 {
    if s.increment_or_held == 0 {
        s.increment_or_held = start_increment;
    }
    let phase = s.phase_or_register;
    let inc = s.increment_or_held;
    // Δφ·(r − 1) as two 32×32 products: (hi·g) + (lo·g ≫ 32), turns·2^64.
    let g = u64::from(growth);
    let step = (inc >> 32) * g + (((inc & 0xFFFF_FFFF) * g) >> 32);
    s.increment_or_held = inc.saturating_add(step);
    s.phase_or_register = phase.wrapping_add((inc >> 32) as u32);
    sine_q30(phase)
}

/// sin(2π·phase/2^32) in Q1.30, from a 7th-order odd polynomial on the quarter wave.
fn sine_q30(phase: u32) -> i32 {
    // Quadrant from the top two bits; x ∈ [0, 1) the position in the quarter, Q0.31.
    let quadrant = phase >> 30;
    let frac = (phase << 2) >> 1; // Q0.31
    let x = if quadrant & 1 == 1 {
        (1u32 << 31) - frac
    } else {
        frac
    };
    // sin(π/2·x) ≈ x·(c1 + x²·(c3 + x²·(c5 + x²·c7))), c_n = ±(π/2)^n/n!, Q2.30.
    let x = i64::from(x); // Q0.31
    let x2 = (x * x) >> 31; // Q0.31
    let mut acc = C7;
    acc = C5 + ((acc * x2) >> 31);
    acc = C3 + ((acc * x2) >> 31);
    acc = C1 + ((acc * x2) >> 31);
    let y = (acc * x) >> 31; // Q2.30
    let y = y.min(1 << 30);
    if quadrant >= 2 { -(y as i32) } else { y as i32 }
}

/// Round an f64 to Q2.30 bits (compile time).
const fn q30(v: f64) -> i64 {
    let scaled = v * 1_073_741_824.0;
    if scaled >= 0.0 {
        (scaled + 0.5) as i64
    } else {
        (scaled - 0.5) as i64
    }
}

/// π/2.
const H: f64 = core::f64::consts::FRAC_PI_2;
/// (π/2)^n/n!, signs alternating, in Q2.30: the Taylor coefficients of sin(π/2·x).
const C1: i64 = q30(H);
const C3: i64 = q30(-H * H * H / 6.0);
const C5: i64 = q30(H * H * H * H * H / 120.0);
const C7: i64 = q30(-H * H * H * H * H * H * H / 5040.0);

#[cfg(test)]
mod tests {
    use super::super::tests::{NAMES, ok};
    use super::super::*;
    use super::*;

    #[test]
    fn polynomial_coefficients_are_the_taylor_series() {
        let h = core::f64::consts::FRAC_PI_2;
        let q = |v: f64| (v * f64::from(1 << 30)).round() as i64;
        assert_eq!(C1, q(h));
        assert_eq!(C3, q(-h.powi(3) / 6.0));
        assert_eq!(C5, q(h.powi(5) / 120.0));
        assert_eq!(C7, q(-h.powi(7) / 5040.0));
    }

    #[test]
    fn sine_is_within_its_stated_error() {
        let mut worst: f64 = 0.0;
        for k in 0..=65_536u32 {
            let phase = k.wrapping_mul(65_536).wrapping_add(k % 977);
            let want = (core::f64::consts::TAU * f64::from(phase) / 4_294_967_296.0).sin();
            let got = f64::from(sine_q30(phase)) / f64::from(1 << 30);
            worst = worst.max((got - want).abs());
        }
        assert!(worst < 1.6e-4, "{worst}");
    }

    /// Instantaneous frequency of the fixed-point chirp against f0·(f1/f0)^(t/T), and its
    /// samples against the f64 chirp's sine of the same phase.
    #[test]
    fn chirp_sweeps_logarithmically() {
        let rate = 4000.0;
        let (f0, f1, t) = (2.0f32, 800.0f32, 5.0f32);
        let cfg = ExcitationConfig {
            waveform: Waveform::Chirp {
                start_hz: f0,
                end_hz: f1,
                duration_s: t,
            },
            amplitude_pu: 0.2,
            injection: Injection::TorqueReference,
        };
        let e = ok(Excitation::new(&cfg, rate, NAMES));
        assert_eq!(e.ticks(), 20_000);
        let mut s = ExcitationState::default();
        let mut phase_ref = 0.0f64; // turns
        let mut worst_sample: f64 = 0.0;
        for k in 0..e.ticks() {
            let y = e.next(&mut s).to_num::<f64>();
            let want = 0.2 * (core::f64::consts::TAU * phase_ref).sin();
            worst_sample = worst_sample.max((y - want).abs());
            let f = f64::from(f0) * (f64::from(f1 / f0)).powf(f64::from(k) / 20_000.0);
            phase_ref += f / f64::from(rate);
            phase_ref -= phase_ref.floor();
            // The increment after tick k, as a frequency.
            let f_fixed = s.increment_or_held as f64 / 2f64.powi(64) * f64::from(rate);
            let f_want = f * (f64::from(f1 / f0)).powf(1.0 / 20_000.0);
            assert!(
                (f_fixed / f_want - 1.0).abs() < 1e-4,
                "{k}: {f_fixed} vs {f_want}"
            );
        }
        // Phase drift of the integer accumulator stays a small fraction of a turn.
        assert!(worst_sample < 0.2 * 0.02, "{worst_sample}");
        assert_eq!(e.next(&mut s), Pu::ZERO);
    }
}
