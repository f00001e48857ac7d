//! Low-pass filters on Q16.16 signals: first order (matched pole) and second order
//! (bilinear biquad, Direct Form I). Coefficients are Q2.30; the first-order state is
//! Q32.32 and the biquad keeps its rounding residual (error feedback), so neither has a
//! dead band at low corners.

use crate::config::FilterConfig;
use crate::error::ConfigError;
use crate::per_unit::{Coef, Pu, checked_q, sat_shr};
use crate::ranges::Range;
use crate::validate::check_filter;

/// Coefficients of a low-pass filter.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LowPass {
    /// Pass-through.
    None,
    /// y ← y + α·(x − y).
    FirstOrder {
        /// α = 1 − e^(−ω_c·Ts), Q2.30.
        alpha: Coef,
    },
    /// y = b0·x0 + b1·x1 + b2·x2 − a1·y1 − a2·y2 (low-pass: b1 = 2·b0, b2 = b0).
    SecondOrder {
        /// b0 (= b2, b1 = 2·b0), Q2.30.
        b0: Coef,
        /// a1, Q2.30.
        a1: Coef,
        /// a2, Q2.30.
        a2: Coef,
    },
}

/// Filter state (plain data, loggable, reset = default).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LowPassState {
    /// First order: output in Q32.32. Biquad: unused.
    pub y_q32: i64,
    /// Biquad inputs x\[n−1\], x\[n−2\] (Q16.16 bits).
    pub x: [i32; 2],
    /// Biquad outputs y\[n−1\], y\[n−2\] (Q16.16 bits).
    pub y: [i32; 2],
    /// Biquad rounding residual (Q.46 bits below the output LSB).
    pub residual: i64,
}

/// A low-pass filter's linear form: its coefficients as f64, read from the stored Q2.30
/// bits ([`LowPass::linear`]), and its step in f64 without the roundings, for loop models.
/// The state is `[x1, x2, y1, y2]` for the biquad, `[y, ..]` for the first order.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LowPassLinear {
    /// Pass-through.
    None,
    /// y ← y + α·(x − y).
    FirstOrder {
        /// α.
        alpha: f64,
    },
    /// y = b0·(x0 + 2·x1 + x2) − a1·y1 − a2·y2.
    SecondOrder {
        /// b0.
        b0: f64,
        /// a1.
        a1: f64,
        /// a2.
        a2: f64,
    },
}

impl LowPassLinear {
    /// (h, b0): the output's part from the past and the feed-through, y = h + b0·x, as
    /// [`LowPass::begin`].
    #[must_use]
    pub fn begin(&self, s: &[f64; 4]) -> (f64, f64) {
        match *self {
            Self::None => (0.0, 1.0),
            Self::FirstOrder { alpha } => ((1.0 - alpha) * s[0], alpha),
            Self::SecondOrder { b0, a1, a2 } => {
                (b0 * (2.0 * s[0] + s[1]) - a1 * s[2] - a2 * s[3], b0)
            }
        }
    }

    /// Completes a step begun with [`LowPassLinear::begin`] with input `x`, as
    /// [`LowPass::finish`]: advances the state and returns y.
    pub fn finish(&self, s: &mut [f64; 4], h: f64, x: f64) -> f64 {
        match *self {
            Self::None => x,
            Self::FirstOrder { alpha } => {
                s[0] = h + alpha * x;
                s[0]
            }
            Self::SecondOrder { b0, .. } => {
                let y = h + b0 * x;
                *s = [x, s[0], y, s[2]];
                y
            }
        }
    }

    /// One step with input `x`.
    ///
    /// ```
    /// use controller_core::filter::LowPassLinear;
    /// let f = LowPassLinear::FirstOrder { alpha: 0.5 };
    /// let mut s = [0.0; 4];
    /// assert_eq!((f.process(&mut s, 1.0), f.process(&mut s, 1.0)), (0.5, 0.75));
    /// ```
    pub fn process(&self, s: &mut [f64; 4], x: f64) -> f64 {
        let (h, _) = self.begin(s);
        self.finish(s, h, x)
    }
}

/// The f32 design of a filter, before quantization (for references and logging).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LowPassDesign {
    /// Pass-through.
    None,
    /// First order with α.
    FirstOrder {
        /// α.
        alpha: f32,
    },
    /// Biquad.
    SecondOrder {
        /// b0 = b2 (b1 = 2·b0).
        b0: f32,
        /// a1.
        a1: f32,
        /// a2.
        a2: f32,
    },
}

/// Design a low-pass filter for a tick rate. `corner` and `q` are the [`Range`] entries of
/// the setting (e.g. [`crate::ranges::AFB_FILTER_CORNER_HZ`]): they are checked here and name
/// the setting in an error.
pub fn design_low_pass(
    cfg: &FilterConfig,
    rate_hz: f32,
    corner: &Range,
    q: &Range,
) -> Result<LowPassDesign, ConfigError> {
    check_filter(cfg, rate_hz, corner, q)?;
    match *cfg {
        FilterConfig::None => Ok(LowPassDesign::None),
        FilterConfig::FirstOrder { corner_hz } => {
            let alpha = (1.0
                - crate::cfgmath::exp(
                    -core::f64::consts::TAU * f64::from(corner_hz) / f64::from(rate_hz),
                )) as f32;
            Ok(LowPassDesign::FirstOrder { alpha })
        }
        FilterConfig::SecondOrder { corner_hz, q } => {
            // Bilinear transform with the corner pre-warped: K = tan(π·f_c/f_s).
            let k = crate::cfgmath::tan(
                core::f64::consts::PI * f64::from(corner_hz) / f64::from(rate_hz),
            );
            let q = f64::from(q);
            let norm = 1.0 / (1.0 + k / q + k * k);
            Ok(LowPassDesign::SecondOrder {
                b0: (k * k * norm) as f32,
                a1: (2.0 * (k * k - 1.0) * norm) as f32,
                a2: ((1.0 - k / q + k * k) * norm) as f32,
            })
        }
    }
}

/// `y` limited to ±2^48 (the first-order state beyond its usual range; out of line).
#[cold]
#[inline(never)]
fn limit_q48(y: i64) -> i64 {
    // max/min rather than clamp: clamp carries a (never taken) panic branch.
    #[allow(clippy::manual_clamp)]
    y.max(-(1 << 48)).min(1 << 48)
}

impl LowPass {
    /// Quantize a design to Q2.30; `param` names the coefficient set in an overflow error.
    pub fn quantize(d: &LowPassDesign, param: &'static str) -> Result<Self, ConfigError> {
        let q = |v: f32| checked_q::<Coef>(v).ok_or(ConfigError::overflow::<Coef>(param, v));
        Ok(match *d {
            LowPassDesign::None => Self::None,
            LowPassDesign::FirstOrder { alpha } => Self::FirstOrder { alpha: q(alpha)? },
            LowPassDesign::SecondOrder { b0, a1, a2 } => Self::SecondOrder {
                b0: q(b0)?,
                a1: q(a1)?,
                a2: q(a2)?,
            },
        })
    }

    /// The linear form ([`LowPassLinear`]): the coefficients as f64, exactly the stored
    /// Q2.30 values.
    ///
    /// ```
    /// use controller_core::filter::{LowPass, LowPassLinear};
    /// use controller_core::per_unit::Coef;
    /// let f = LowPass::FirstOrder { alpha: Coef::from_num(0.25) };
    /// assert_eq!(f.linear(), LowPassLinear::FirstOrder { alpha: 0.25 });
    /// ```
    #[must_use]
    pub fn linear(&self) -> LowPassLinear {
        let f = |c: Coef| c.to_num::<f64>();
        match *self {
            Self::None => LowPassLinear::None,
            Self::FirstOrder { alpha } => LowPassLinear::FirstOrder { alpha: f(alpha) },
            Self::SecondOrder { b0, a1, a2 } => LowPassLinear::SecondOrder {
                b0: f(b0),
                a1: f(a1),
                a2: f(a2),
            },
        }
    }

    /// The direct feed-through b0 of the filter, y\[n\] = b0·x\[n\] + h\[n\] (1 for
    /// [`LowPass::None`], α for the first order, b0 for the biquad), Q2.30.
    ///
    /// ```
    /// use controller_core::filter::LowPass;
    /// use controller_core::per_unit::Coef;
    /// assert_eq!(LowPass::None.feedthrough(), Coef::ONE);
    /// ```
    #[inline(always)]
    #[must_use]
    pub fn feedthrough(&self) -> Coef {
        match *self {
            Self::None => Coef::ONE,
            Self::FirstOrder { alpha } => alpha,
            Self::SecondOrder { b0, .. } => b0,
        }
    }

    /// h + b0·x in Q.46 for an `h46` from [`LowPass::begin`] on this filter: the output of
    /// the step before its final rounding.
    ///
    /// Range argument for the plain (wrapping) add: with b0 in \[0, 1\] (raw 0..=2^30; every
    /// designed first-order α = 1 − e^(−ω·Ts) and the pass-through's 1) |b0·x| ≤ 2^61, and
    /// the first order's h = y·2^14 − α·y16 has |h| ≤ 2^62 for |y| ≤ 2^48 (as `begin`
    /// limits it): below 2^47, h = y16·(2^30 − α) + (y mod 2^16)·2^14, |h| < 2^61 + 2^30;
    /// above, y16 is saturated at ±2^31 and α·y16 only pulls h back towards zero from
    /// |y·2^14| ≤ 2^62. So |h + b0·x| < 2^63. A hand-made α outside \[0, 1\] and the biquad,
    /// whose h has no such bound, take the saturating add.
    ///
    /// ```
    /// use controller_core::filter::LowPass;
    /// use controller_core::per_unit::{Coef, Pu};
    /// let f = LowPass::FirstOrder { alpha: Coef::from_num(0.5) };
    /// assert_eq!(f.add_feedthrough(1 << 40, Pu::from_num(1)), (1 << 40) + (1 << 45));
    /// ```
    #[inline(always)]
    #[must_use]
    pub fn add_feedthrough(&self, h46: i64, x: Pu) -> i64 {
        let b0 = self.feedthrough().to_bits();
        let bx = i64::from(x.to_bits()) * i64::from(b0);
        let bounded = match *self {
            Self::None => true,
            Self::FirstOrder { .. } => (b0 as u32) <= 1 << 30,
            Self::SecondOrder { .. } => false,
        };
        if bounded {
            h46.wrapping_add(bx)
        } else {
            h46.saturating_add(bx)
        }
    }

    /// First half of a step: the part h\[n\] of this step's output that does not depend on
    /// this step's input, as raw Q.46 bits (Q16.16 signal × Q2.30 coefficient), and the
    /// feed-through b0. The state is not changed; [`LowPass::finish`] completes the step,
    /// y\[n\] = h\[n\] + b0·x\[n\], exactly as [`LowPass::process`] (which is the two halves).
    ///
    /// ```
    /// use controller_core::filter::{LowPass, LowPassState};
    /// use controller_core::per_unit::{Coef, Pu};
    /// let f = LowPass::FirstOrder { alpha: Coef::from_num(0.5) };
    /// let mut s = LowPassState::default();
    /// f.process(&mut s, Pu::from_num(1));
    /// let (h46, b0) = f.begin(&s);
    /// assert_eq!((h46 as f64) / 2f64.powi(46), 0.25); // (1 − α)·0.5
    /// assert_eq!(b0, Coef::from_num(0.5));
    /// ```
    #[inline(always)]
    #[must_use]
    pub fn begin(&self, s: &LowPassState) -> (i64, Coef) {
        match *self {
            Self::None => (0, Coef::ONE),
            Self::FirstOrder { alpha } => {
                // h = y − α·y16 in Q.46 (y Q32.32 ≪ 14; y16 = y in Q16.16, truncated), with y
                // limited to ±2^48 first so the shift cannot overflow (`finish` stores
                // |y| < 1.5·2^48, so the limit acts only in the last half bit of the range);
                // |α·y16| < 2^62. In range exactly when the bits above 2^48 are all the sign:
                // one high-word compare instead of two 64-bit ones on the usual path.
                let y = if s.y_q32 >> 48 == s.y_q32 >> 63 {
                    s.y_q32
                } else {
                    limit_q48(s.y_q32)
                };
                let y16 = sat_shr::<16>(y);
                let h = (y << 14) - i64::from(y16) * i64::from(alpha.to_bits());
                (h, alpha)
            }
            Self::SecondOrder { b0, a1, a2 } => {
                // h = b0·(2·x1 + x2) − a1·y1 − a2·y2 + residual, Q.46.
                let [x1, x2] = s.x;
                let [y1, y2] = s.y;
                let xs = 2 * i64::from(x1) + i64::from(x2);
                let h = i64::from(b0.to_bits())
                    .saturating_mul(xs)
                    .saturating_sub(i64::from(a1.to_bits()) * i64::from(y1))
                    .saturating_sub(i64::from(a2.to_bits()) * i64::from(y2))
                    .saturating_add(s.residual);
                (h, b0)
            }
        }
    }

    /// Second half of a step begun with [`LowPass::begin`] on the same state: adds b0·x,
    /// advances the state and returns y\[n\] (Q16.16).
    #[inline(always)]
    pub fn finish(&self, s: &mut LowPassState, h46: i64, x: Pu) -> Pu {
        match *self {
            Self::None => x,
            Self::FirstOrder { .. } => {
                // y (Q.46) = h + α·x; the state keeps Q32.32 (≫ 14, equal to y + (α·(x − y16) ≫ 14)).
                let y46 = self.add_feedthrough(h46, x);
                s.y_q32 = y46 >> 14;
                // |y46| < 2^63 ⇒ |y_q32| < 2^49: the rounding add cannot overflow.
                Pu::from_bits(sat_shr::<16>(s.y_q32.wrapping_add(1 << 15)))
            }
            Self::SecondOrder { .. } => {
                // DF1 in Q.46 with error feedback of the truncated bits.
                let x0 = x.to_bits();
                let acc = self.add_feedthrough(h46, x);
                let y0 = sat_shr::<30>(acc);
                s.residual = acc & ((1 << 30) - 1);
                s.x = [x0, s.x[0]];
                s.y = [y0, s.y[0]];
                Pu::from_bits(y0)
            }
        }
    }

    /// Filter one sample.
    ///
    /// ```
    /// use controller_core::filter::{LowPass, LowPassState};
    /// use controller_core::per_unit::{Coef, Pu};
    /// let f = LowPass::FirstOrder { alpha: Coef::from_num(0.5) };
    /// let mut s = LowPassState::default();
    /// assert_eq!(f.process(&mut s, Pu::from_num(1)), Pu::from_num(0.5));
    /// assert_eq!(f.process(&mut s, Pu::from_num(1)), Pu::from_num(0.75));
    /// ```
    #[inline]
    pub fn process(&self, s: &mut LowPassState, x: Pu) -> Pu {
        let (h46, _) = self.begin(s);
        self.finish(s, h46, x)
    }
}

#[cfg(test)]
mod tests {
    use super::{LowPass, LowPassLinear, LowPassState, design_low_pass};
    use crate::config::FilterConfig;
    use crate::per_unit::Pu;
    use crate::ranges as r;

    const LSB: f64 = 1.0 / 65536.0;
    /// The f64 arithmetic's own rounding (signals below 2^4: ulp 2^−48).
    const F64_NOISE: f64 = 1.0 / (1u64 << 40) as f64;

    fn designed(cfg: FilterConfig) -> LowPass {
        let d = design_low_pass(&cfg, 4000.0, &r::AFB_FILTER_CORNER_HZ, &r::AFB_FILTER_Q)
            .unwrap_or_else(|e| unreachable!("{e}"));
        LowPass::quantize(&d, "test").unwrap_or_else(|e| unreachable!("{e}"))
    }

    /// A sequence of inputs in ±4 pu (a xorshift64 sequence).
    fn inputs(n: usize) -> impl Iterator<Item = Pu> {
        let mut x = 0x2545_F491_4F6C_DD1Du64;
        (0..n).map(move |_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            Pu::from_bits((x as i32) >> 13)
        })
    }

    /// One step of the linear form from the filter's own state is its fixed-point step:
    /// the first order to α·LSB in the state (h uses the state truncated to Q16.16) and
    /// ½ LSB more in the rounded output; the biquad to 1 LSB (the output truncated, the
    /// residual of the last one fed back), over a random sequence of inputs.
    #[test]
    fn the_linear_step_is_the_fixed_point_step() {
        let first = |corner_hz| FilterConfig::FirstOrder { corner_hz };
        let second = |corner_hz, q| FilterConfig::SecondOrder { corner_hz, q };
        for f in [
            first(5.0),
            first(200.0),
            first(1500.0),
            second(20.0, 0.7),
            second(300.0, 2.0),
            second(1500.0, 0.5),
        ]
        .map(designed)
        {
            let lin = f.linear();
            let mut s = LowPassState::default();
            for x in inputs(20_000) {
                // The fixed-point state as the linear form's.
                let now = match lin {
                    LowPassLinear::FirstOrder { .. } => {
                        [s.y_q32 as f64 / 2f64.powi(32), 0.0, 0.0, 0.0]
                    }
                    _ => [s.x[0], s.x[1], s.y[0], s.y[1]].map(|v| f64::from(v) * LSB),
                };
                let mut next = now;
                let y_lin = lin.process(&mut next, x.to_num());
                let y = f.process(&mut s, x).to_num::<f64>();
                let bound = match lin {
                    LowPassLinear::FirstOrder { alpha } => {
                        let state = s.y_q32 as f64 / 2f64.powi(32);
                        assert!(
                            (state - next[0]).abs() <= alpha * LSB + 2f64.powi(-32) + F64_NOISE,
                            "{f:?} {now:?} {x}"
                        );
                        (0.5 + alpha) * LSB + 2f64.powi(-32) + F64_NOISE
                    }
                    _ => LSB + F64_NOISE,
                };
                assert!(
                    (y - y_lin).abs() <= bound,
                    "{f:?} {now:?} {x}: {y} vs {y_lin}"
                );
            }
        }
    }
}
