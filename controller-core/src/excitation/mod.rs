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
use crate::per_unit::{Pu, sat_shr};

mod chirp;
mod prbs;

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
            } => chirp::design(start_hz, end_hz, duration_s, rate_hz, p)?,
            Waveform::Prbs {
                bits,
                hold_ticks,
                periods,
            } => prbs::design(bits, hold_ticks, periods, p)?,
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
            } => chirp::step(s, start_increment, growth),
            Kind::Prbs {
                taps, mask, hold, ..
            } => prbs::step(s, taps, mask, hold),
        };
        // amplitude (Q16.16) × waveform (Q1.30), rounded: |result| ≤ |amplitude|.
        let p = i64::from(self.amplitude.to_bits()) * i64::from(wave_q30);
        Pu::from_bits(sat_shr::<30>(p + (1 << 29)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    pub(super) const NAMES: ExcitationParams = ExcitationParams {
        amplitude_pu: "excitation.amplitude_pu",
        start_or_bits: "excitation.start_hz",
        end_or_hold: "excitation.end_hz",
        duration_or_periods: "excitation.duration_s",
    };

    pub(super) fn ok<T>(r: Result<T, ConfigError>) -> T {
        match r {
            Ok(v) => v,
            Err(e) => unreachable!("{e}"),
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
