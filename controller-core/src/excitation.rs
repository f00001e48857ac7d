//! Excitation for measuring the machine's frequency response in the loop: a logarithmic
//! chirp or a pseudo-random binary sequence (PRBS), added to the torque reference or the
//! velocity reference.
//!
//! Everything at tick time is integer arithmetic, so the sequence is the same, bit for
//! bit, on the host and on the Cortex-M.
//!
//! - **Chirp.** The phase φ is a `u32` in turns·2^32 and wraps by itself. Its increment
//!   Δφ (turns·2^64 per tick, a `u64`) grows by the factor r = (f1/f0)^(1/N) every tick,
//!   so the instantaneous frequency f0·r^k sweeps f0 → f1 in N ticks, evenly in log
//!   frequency. The update is Δφ ← Δφ + Δφ·(r − 1), with r − 1 in Q0.32 (a `u32`).
//!   The sine comes from a 7th-order odd polynomial on the quarter wave, Q1.30; its
//!   largest error is 1.6e-4 of the amplitude.
//! - **PRBS.** This is a maximal-length Fibonacci LFSR of `bits` (7..=20) bits. It has
//!   period 2^bits − 1 states, and each state is held for `hold_ticks` ticks. Its output is
//!   ±amplitude. The spectrum is flat within 3 dB up to about 0.44·fs/hold.
//!
//! The amplitude is a [`Pu`] (Q16.16) of torque or speed. The output is amplitude × the
//! Q1.30 waveform, rounded, so |output| ≤ |amplitude|.

use crate::error::ConfigError;
use crate::per_unit::{sat_i32, Pu};

/// Where the excitation enters the loop.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Injection {
    /// Added to the torque reference (after the velocity regulator): measures the plant.
    TorqueReference,
    /// Added to the velocity reference: measures the closed velocity loop.
    VelocityReference,
}

/// The waveform and its band.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Waveform {
    /// Logarithmic sweep from `start_hz` to `end_hz` over `duration_s`.
    Chirp {
        /// First frequency \[Hz\], > 0.
        start_hz: f32,
        /// Last frequency \[Hz\], above `start_hz` and below the Nyquist limit.
        end_hz: f32,
        /// Sweep time \[s\].
        duration_s: f32,
    },
    /// Maximal-length PRBS, `periods` whole periods.
    Prbs {
        /// LFSR length, 7..=20 bits.
        bits: u8,
        /// Ticks each bit is held, 1..=1000 (sets the band).
        hold_ticks: u16,
        /// Number of whole sequence periods, 1..=1000.
        periods: u16,
    },
}

/// The settings of an excitation (configuration, not state).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExcitationConfig {
    /// The waveform.
    pub waveform: Waveform,
    /// Peak amplitude \[pu\] of torque or speed, (0, 2].
    pub amplitude_pu: f32,
    /// Where it is added.
    pub injection: Injection,
}

/// Largest amplitude accepted \[pu\].
pub const MAX_AMPLITUDE_PU: f32 = 2.0;
/// Longest chirp \[s\].
pub const MAX_DURATION_S: f32 = 600.0;

/// Primitive polynomials x^n + Σ x^e + 1 for n = 7..=20, by their middle exponents e
/// (the standard tables of primitive trinomials and pentanomials; 0 ends a list).
const PRIMITIVE: [[u32; 3]; 14] = [
    [6, 0, 0],   // 7
    [6, 5, 4],   // 8
    [5, 0, 0],   // 9
    [7, 0, 0],   // 10
    [9, 0, 0],   // 11
    [6, 4, 1],   // 12
    [4, 3, 1],   // 13
    [5, 3, 1],   // 14
    [14, 0, 0],  // 15
    [15, 13, 4], // 16
    [14, 0, 0],  // 17
    [11, 0, 0],  // 18
    [6, 2, 1],   // 19
    [17, 0, 0],  // 20
];

/// The feedback mask of a right-shifting Fibonacci LFSR of `n` bits for a polynomial:
/// the output bit 0 stands for x^n, and each middle exponent e taps bit n − e.
fn taps(n: u32, middle: [u32; 3]) -> u32 {
    let tap = |e: u32| if e == 0 { 0 } else { 1 << (n - e) };
    let [a, b, c] = middle;
    1 | tap(a) | tap(b) | tap(c)
}

/// A designed excitation: integers only.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Excitation {
    kind: Kind,
    amplitude: Pu,
    injection: Injection,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Kind {
    Chirp {
        /// Δφ at the start, turns·2^64 per tick.
        start_increment: u64,
        /// r − 1, Q0.32.
        growth: u32,
        /// Sweep length in ticks.
        ticks: u32,
    },
    Prbs {
        taps: u32,
        mask: u32,
        hold: u16,
        /// Total ticks: periods·(2^bits − 1)·hold.
        ticks: u32,
    },
}

/// The excitation's state (plain data, loggable, reset = default).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ExcitationState {
    /// Ticks produced so far.
    pub tick: u32,
    /// Chirp: phase, turns·2^32. PRBS: LFSR register (0 = not started).
    pub phase_or_register: u32,
    /// Chirp: phase increment, turns·2^64 per tick. PRBS: ticks into the current bit.
    pub increment_or_held: u64,
}

/// The field paths an excitation's errors name.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExcitationParams {
    /// Path of `amplitude_pu`.
    pub amplitude_pu: &'static str,
    /// Path of `start_hz` (chirp) or `bits` (PRBS).
    pub start_or_bits: &'static str,
    /// Path of `end_hz` (chirp) or `hold_ticks` (PRBS).
    pub end_or_hold: &'static str,
    /// Path of `duration_s` (chirp) or `periods` (PRBS).
    pub duration_or_periods: &'static str,
}

fn check(v: f32, min: f32, max: f32, param: &'static str) -> Result<(), ConfigError> {
    if !v.is_finite() {
        return Err(ConfigError::NotFinite { param });
    }
    if v <= min || v > max {
        return Err(ConfigError::OutOfRange {
            param,
            value: v,
            min,
            max,
            min_exclusive: true,
        });
    }
    Ok(())
}

impl Excitation {
    /// Design for a tick rate `rate_hz` (the loop the excitation is added in).
    pub fn new(
        cfg: &ExcitationConfig,
        rate_hz: f32,
        p: ExcitationParams,
    ) -> Result<Self, ConfigError> {
        check(cfg.amplitude_pu, 0.0, MAX_AMPLITUDE_PU, p.amplitude_pu)?;
        let amplitude = Pu::from_num(cfg.amplitude_pu);
        let kind = match cfg.waveform {
            Waveform::Chirp {
                start_hz,
                end_hz,
                duration_s,
            } => {
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
                let r_minus_1 =
                    crate::cfgmath::exp(crate::cfgmath::ln(f64::from(end_hz / start_hz)) / n) - 1.0;
                Kind::Chirp {
                    start_increment: start as u64,
                    growth: (r_minus_1 * 4_294_967_296.0 + 0.5) as u32,
                    ticks: n as u32,
                }
            }
            Waveform::Prbs {
                bits,
                hold_ticks,
                periods,
            } => {
                let taps = bits
                    .checked_sub(7)
                    .and_then(|i| PRIMITIVE.get(usize::from(i)))
                    .map(|m| taps(u32::from(bits), *m))
                    .ok_or(ConfigError::OutOfRange {
                        param: p.start_or_bits,
                        value: f32::from(bits),
                        min: 7.0,
                        max: 20.0,
                        min_exclusive: false,
                    })?;
                check(f32::from(hold_ticks), 0.0, 1000.0, p.end_or_hold)?;
                check(f32::from(periods), 0.0, 1000.0, p.duration_or_periods)?;
                let length = (1u64 << bits) - 1;
                let ticks = length * u64::from(hold_ticks) * u64::from(periods);
                let ticks = u32::try_from(ticks).map_err(|_| ConfigError::OutOfRange {
                    param: p.duration_or_periods,
                    value: f32::from(periods),
                    min: 1.0,
                    max: (f64::from(u32::MAX) / (length as f64 * f64::from(hold_ticks))) as f32,
                    min_exclusive: false,
                })?;
                Kind::Prbs {
                    taps,
                    mask: (1u32 << bits) - 1,
                    hold: hold_ticks,
                    ticks,
                }
            }
        };
        Ok(Self {
            kind,
            amplitude,
            injection: cfg.injection,
        })
    }

    /// Where the output is added.
    #[must_use]
    pub fn injection(&self) -> Injection {
        self.injection
    }

    /// Length of the excitation in ticks; [`Excitation::next`] returns zero after it.
    #[must_use]
    pub fn ticks(&self) -> u32 {
        match self.kind {
            Kind::Chirp { ticks, .. } | Kind::Prbs { ticks, .. } => ticks,
        }
    }

    /// The next sample \[pu\]; zero once the excitation is over.
    ///
    /// ```
    /// use controller_core::excitation::*;
    /// let cfg = ExcitationConfig {
    ///     waveform: Waveform::Prbs { bits: 7, hold_ticks: 2, periods: 1 },
    ///     amplitude_pu: 0.1,
    ///     injection: Injection::TorqueReference,
    /// };
    /// let names = ExcitationParams {
    ///     amplitude_pu: "a", start_or_bits: "b", end_or_hold: "h", duration_or_periods: "p",
    /// };
    /// let e = Excitation::new(&cfg, 4000.0, names)?;
    /// let mut s = ExcitationState::default();
    /// let sum: i64 = (0..e.ticks()).map(|_| i64::from(e.next(&mut s).to_bits())).sum();
    /// // 64 ones and 63 zeros per period: the mean is one bit's worth, held 2 ticks.
    /// assert_eq!(sum, 2 * i64::from(controller_core::Pu::from_num(0.1).to_bits()));
    /// assert_eq!(e.next(&mut s), controller_core::Pu::ZERO);
    /// # Ok::<(), controller_core::ConfigError>(())
    /// ```
    #[inline]
    pub fn next(&self, s: &mut ExcitationState) -> Pu {
        if s.tick >= self.ticks() {
            return Pu::ZERO;
        }
        s.tick += 1;
        let wave_q30 = match self.kind {
            Kind::Chirp {
                start_increment,
                growth,
                ..
            } => {
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
            Kind::Prbs {
                taps, mask, hold, ..
            } => {
                if s.phase_or_register == 0 {
                    s.phase_or_register = mask; // any non-zero seed; all ones
                }
                let out = if s.phase_or_register & 1 == 1 {
                    1 << 30
                } else {
                    -(1 << 30)
                };
                s.increment_or_held += 1;
                if s.increment_or_held >= u64::from(hold) {
                    s.increment_or_held = 0;
                    // Fibonacci step: the new top bit is the parity of the tapped bits.
                    let r = s.phase_or_register;
                    let fb = (r & taps).count_ones() & 1;
                    s.phase_or_register = ((r >> 1) | (fb << (mask.count_ones() - 1))) & mask;
                }
                out
            }
        };
        // amplitude (Q16.16) × waveform (Q1.30), rounded: |result| ≤ |amplitude|.
        let p = i64::from(self.amplitude.to_bits()) * i64::from(wave_q30);
        Pu::from_bits(sat_i32((p + (1 << 29)) >> 30))
    }
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
    if quadrant >= 2 {
        -(y as i32)
    } else {
        y as i32
    }
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
    use super::*;

    const NAMES: ExcitationParams = ExcitationParams {
        amplitude_pu: "excitation.amplitude_pu",
        start_or_bits: "excitation.start_hz",
        end_or_hold: "excitation.end_hz",
        duration_or_periods: "excitation.duration_s",
    };

    fn ok<T>(r: Result<T, ConfigError>) -> T {
        match r {
            Ok(v) => v,
            Err(e) => unreachable!("{e}"),
        }
    }

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

    /// Every tap set is maximal: the register returns to its seed after exactly 2^n − 1
    /// steps and not before.
    #[test]
    fn every_prbs_length_is_maximal() {
        for bits in 7u8..=20 {
            let cfg = ExcitationConfig {
                waveform: Waveform::Prbs {
                    bits,
                    hold_ticks: 1,
                    periods: 1,
                },
                amplitude_pu: 1.0,
                injection: Injection::VelocityReference,
            };
            let e = ok(Excitation::new(&cfg, 4000.0, NAMES));
            let mut s = ExcitationState::default();
            let _ = e.next(&mut s);
            let seed = (1u32 << bits) - 1;
            let mut period = 1u32;
            while s.phase_or_register != seed {
                let _ = e.next(&mut s);
                period += 1;
                assert!(period <= e.ticks(), "{bits} bits: no return to the seed");
            }
            assert_eq!(period, (1 << bits) - 1, "{bits} bits");
        }
    }

    #[test]
    fn bad_settings_name_their_key() {
        let chirp = |a: f32, f0: f32, f1: f32, t: f32| ExcitationConfig {
            waveform: Waveform::Chirp {
                start_hz: f0,
                end_hz: f1,
                duration_s: t,
            },
            amplitude_pu: a,
            injection: Injection::TorqueReference,
        };
        let cases = [
            (chirp(0.0, 1.0, 10.0, 1.0), NAMES.amplitude_pu),
            (chirp(3.0, 1.0, 10.0, 1.0), NAMES.amplitude_pu),
            (chirp(f32::NAN, 1.0, 10.0, 1.0), NAMES.amplitude_pu),
            (chirp(0.1, 0.0, 10.0, 1.0), NAMES.start_or_bits),
            (chirp(0.1, 10.0, 5.0, 1.0), NAMES.end_or_hold),
            (chirp(0.1, 1.0, 2000.0, 1.0), NAMES.end_or_hold),
            (chirp(0.1, 1.0, 10.0, 0.0), NAMES.duration_or_periods),
            (chirp(0.1, 1.0, 10.0, 1e-5), NAMES.duration_or_periods),
            (chirp(0.1, 1.0, 10.0, 700.0), NAMES.duration_or_periods),
        ];
        for (c, key) in cases {
            match Excitation::new(&c, 4000.0, NAMES) {
                Err(e) => assert_eq!(e.param(), key, "{c:?}"),
                Ok(_) => unreachable!("{c:?} accepted"),
            }
        }
        let prbs = |bits: u8, hold: u16, periods: u16| ExcitationConfig {
            waveform: Waveform::Prbs {
                bits,
                hold_ticks: hold,
                periods,
            },
            amplitude_pu: 0.1,
            injection: Injection::TorqueReference,
        };
        for (c, key) in [
            (prbs(6, 1, 1), NAMES.start_or_bits),
            (prbs(21, 1, 1), NAMES.start_or_bits),
            (prbs(10, 0, 1), NAMES.end_or_hold),
            (prbs(10, 1001, 1), NAMES.end_or_hold),
            (prbs(10, 1, 0), NAMES.duration_or_periods),
            (prbs(20, 1000, 1000), NAMES.duration_or_periods),
        ] {
            match Excitation::new(&c, 4000.0, NAMES) {
                Err(e) => assert_eq!(e.param(), key, "{c:?}"),
                Ok(_) => unreachable!("{c:?} accepted"),
            }
        }
    }
}
