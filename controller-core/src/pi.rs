//! PI regulator with output limit and conditional-integration anti-windup.
//!
//! ```text
//! u = clamp(Kp·e + I + ff, −limit, +limit)
//! I ← clamp(I + Ki·Ts·e, −limit, +limit)   only if the unclamped output is inside the
//!                                           limit or e drives it back towards the limit
//! ```
//! Anti-windup is conditional integration (integrator clamping): the integrator stops while
//! the output is saturated and the error would push it further into saturation, and the
//! integral itself never exceeds the output limit. The integral is kept in Q32.32 so a
//! small Ki·Ts (the current loop's is ≈ 0.025) still integrates sub-LSB errors.
//!
//! [`PiCoefficients::update_with_offset`] judges the saturation on the output plus a term
//! added after the regulator (the velocity loop passes the acceleration-feedback term), so the
//! integrator also holds when it is the sum that sits at the torque limit, and clamps the
//! output so that the sum, not the regulator alone, meets the limit. With a headroom h
//! (`PiCoefficients::update_with_offset_within`) the output may reach h beyond that
//! bound while the regulator asks for more, so that a downstream term that changes after
//! the regulator ran (the acceleration feedback, recomputed every current tick) by less
//! than h cannot take the sum off the limit. The headroom holds no state: the integral's
//! anti-windup is the same, and the output leaves the bound as soon as Kp·e + I + ff does.

use fixed::types::I32F32;

use crate::per_unit::{Gain, Pu, TickGain, mul_gain, sat_i32};

/// PI coefficients (Q-formats: `kp` Q16.16, `ki_ts` Q8.24, `limit` Q16.16).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PiCoefficients {
    /// Proportional gain \[output pu per error pu\].
    pub kp: Gain,
    /// Integral gain times the tick period, Ki·Ts \[output pu per error pu per tick\].
    pub ki_ts: TickGain,
    /// Symmetric output limit \[pu\], > 0.
    pub limit: Pu,
}

/// A PI regulator's linear form: its coefficients as f64, read from the stored bits
/// ([`PiCoefficients::linear`]). Without the clamps and the roundings a step is
///
/// ```text
/// I ← I + ki_ts·e;   u = kp·e + ff + I
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PiLinear {
    /// Kp \[output pu per error pu\].
    pub kp: f64,
    /// Ki·Ts \[output pu per error pu per tick\].
    pub ki_ts: f64,
}

/// PI state: the integral \[output pu\], Q32.32.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PiState {
    /// Integrator \[output pu\].
    pub integral: I32F32,
    /// Whether the last output was clamped (for logging).
    pub saturated: bool,
}

impl PiCoefficients {
    /// The linear form ([`PiLinear`]): Kp and Ki·Ts as f64, exactly the stored Q16.16 and
    /// Q8.24 values.
    ///
    /// ```
    /// use controller_core::pi::PiCoefficients;
    /// use controller_core::per_unit::{Pu, Gain, TickGain};
    /// let c = PiCoefficients { kp: Gain::from_num(2), ki_ts: TickGain::from_num(0.5), limit: Pu::from_num(10) };
    /// assert_eq!((c.linear().kp, c.linear().ki_ts), (2.0, 0.5));
    /// ```
    #[must_use]
    pub fn linear(&self) -> PiLinear {
        PiLinear {
            kp: self.kp.to_num(),
            ki_ts: self.ki_ts.to_num(),
        }
    }

    /// One regulator step for error `e` and feed-forward `ff`; returns the clamped output.
    ///
    /// ```
    /// use controller_core::pi::{PiCoefficients, PiState};
    /// use controller_core::per_unit::{Pu, Gain, TickGain};
    /// let c = PiCoefficients { kp: Gain::from_num(2), ki_ts: TickGain::from_num(0.5), limit: Pu::from_num(10) };
    /// let mut s = PiState::default();
    /// let u = c.update(&mut s, Pu::from_num(1), Pu::ZERO);
    /// assert_eq!(u, Pu::from_num(2.5)); // Kp·e + Ki·Ts·e (integrate first, then output)
    /// ```
    #[inline]
    pub fn update(&self, state: &mut PiState, e: Pu, ff: Pu) -> Pu {
        self.step::<true>(state, e, ff, Pu::ZERO, [self.abs_limit(), 0])
    }

    /// |limit| as raw bits (saturating): a negative limit in hand-made coefficients cannot
    /// invert the clamp.
    #[inline(always)]
    pub(crate) fn abs_limit(&self) -> i32 {
        self.limit.to_bits().saturating_abs()
    }

    /// [`PiCoefficients::update`] with `abs_limit` = [`PiCoefficients::abs_limit`] resolved
    /// by the caller once, at configuration (the controller's ticks).
    #[inline(always)]
    pub(crate) fn update_within(&self, state: &mut PiState, e: Pu, ff: Pu, abs_limit: i32) -> Pu {
        self.step::<true>(state, e, ff, Pu::ZERO, [abs_limit, 0])
    }

    /// [`PiCoefficients::update_with_offset`] with `abs_limit` =
    /// [`PiCoefficients::abs_limit`] resolved by the caller once, at configuration, and the
    /// output bound widened by `headroom` (raw Q16.16 bits, taken as 0 when negative; module
    /// docs): the output is clamped to `[−limit − off − headroom, limit − off + headroom]`.
    #[inline(always)]
    pub(crate) fn update_with_offset_within(
        &self,
        state: &mut PiState,
        e: Pu,
        ff: Pu,
        offset: Pu,
        limit_headroom: [i32; 2],
    ) -> Pu {
        self.step::<false>(state, e, ff, offset, limit_headroom)
    }

    /// As [`PiCoefficients::update`], with the anti-windup decision taken on
    /// `Kp·e + I + ff + offset`, where `offset` is added to the output downstream (and
    /// clamped together with it there). The returned output does not include `offset`; it is
    /// clamped to `[−limit − offset, limit − offset]` (offset bounded to ±limit), so the
    /// downstream sum can always reach either limit.
    ///
    /// ```
    /// use controller_core::pi::{PiCoefficients, PiState};
    /// use controller_core::per_unit::{Pu, Gain, TickGain};
    /// let c = PiCoefficients { kp: Gain::from_num(1), ki_ts: TickGain::from_num(0.1), limit: Pu::from_num(2) };
    /// let mut s = PiState::default();
    /// // The downstream sum is already at the limit: the integrator holds.
    /// c.update_with_offset(&mut s, Pu::from_num(0.5), Pu::ZERO, Pu::from_num(2));
    /// assert_eq!(s.integral, 0);
    /// ```
    #[inline(always)]
    pub fn update_with_offset(&self, state: &mut PiState, e: Pu, ff: Pu, offset: Pu) -> Pu {
        self.step::<false>(state, e, ff, offset, [self.abs_limit(), 0])
    }

    /// [`PiCoefficients::update_with_offset`]; `ZERO_OFFSET` when the caller passes an offset
    /// of 0 ([`PiCoefficients::update`]), whose clamp to ±limit (limit ≥ 0) is 0 itself, so
    /// the 32-bit form leaves it out.
    #[inline(always)]
    fn step<const ZERO_OFFSET: bool>(
        &self,
        state: &mut PiState,
        e: Pu,
        ff: Pu,
        offset: Pu,
        [abs_limit, headroom]: [i32; 2],
    ) -> Pu {
        // |limit| (`abs_limit`), so a negative limit in hand-made coefficients cannot invert
        // the clamp.
        let limit = abs_limit;
        // Integral increment in Q.40 (Q16.16 · Q8.24) → Q.32.
        let inc = (i64::from(e.to_bits()) * i64::from(self.ki_ts.to_bits()) + (1 << 7)) >> 8;
        let p = mul_gain(e, self.kp).to_bits();
        let (ff, offset) = (ff.to_bits(), offset.to_bits());
        let i_now = state.integral.to_bits();
        // Range argument for the 32-bit form: when p, ff, offset and limit lie in
        // [−2^29, 2^29) and so does the integral's whole part I ≫ 16 (the bits of I from
        // 2^45 up all the sign), every sum below is under 2^31 in magnitude: the four-term
        // trial sum, the three-term output (I ≫ 16 is then either the old one or clamped to
        // ±limit) and the clamp bounds (|limit ± off| ≤ 2^30). So the 32-bit sums are the
        // 64-bit ones exactly, and the output needs no saturation. `x ^ (x >> 31)` is x for
        // x ≥ 0 and −x − 1 below, so the OR of them is below 2^29 exactly when each x is in
        // range. Outside the range (never with the shipped drives' limits and signals), the
        // 64-bit form.
        let mag = |x: i32| x ^ (x >> 31);
        // The headroom (≥ 0; below 2^29 in range) widens the bounds to under 3·2^29.
        let headroom = headroom.max(0);
        if (mag(p) | mag(ff) | mag(offset) | limit | headroom) < 1 << 29
            && i_now >> 45 == i_now >> 63
        {
            let i_whole = (i_now >> 16) as i32;
            let u_trial = p + ff + offset + i_whole;
            let pushing_out = (u_trial >= limit && inc > 0) || (u_trial <= -limit && inc < 0);
            let i_next = self.integrate(i_now, inc, limit, pushing_out);
            state.integral = I32F32::from_bits(i_next);
            let u = p + ff + (i_next >> 16) as i32;
            let off = if ZERO_OFFSET {
                0
            } else {
                offset.max(-limit).min(limit)
            };
            let u_clamped = u.max(-limit - off - headroom).min(limit - off + headroom);
            state.saturated = u_clamped != u;
            return Pu::from_bits(u_clamped);
        }
        self.update_wide(state, [p, ff, offset, limit, headroom], inc)
    }

    /// [`PiCoefficients::update_with_offset`] in 64 bits, for terms outside the 32-bit
    /// form's range (out of line: it never runs with the shipped drives).
    #[cold]
    #[inline(never)]
    fn update_wide(&self, state: &mut PiState, terms: [i32; 5], inc: i64) -> Pu {
        let [p, ff, offset, limit, headroom] = terms;
        let i_now = state.integral.to_bits();
        let u_trial = i64::from(p) + i64::from(ff) + i64::from(offset) + (i_now >> 16);
        let pushing_out =
            (u_trial >= i64::from(limit) && inc > 0) || (u_trial <= -i64::from(limit) && inc < 0);
        let i_next = self.integrate(i_now, inc, limit, pushing_out);
        state.integral = I32F32::from_bits(i_next);
        let u = i64::from(p) + i64::from(ff) + (i_next >> 16);
        // Clamp so that u + offset, the reference downstream, spans the whole ±limit: a
        // downstream term that opposes the output (the AFB term braking an acceleration the
        // drive is saturated for) must not take usable torque away. The offset is bounded
        // to ±limit first, so the output stays within ±2·limit.
        // max/min rather than clamp: clamp carries a (never taken) panic branch.
        // In 32 bits: 0 ≤ limit ≤ i32::MAX, so −limit is an i32 too.
        let off = i64::from(offset.max(-limit).min(limit));
        let h = i64::from(headroom);
        let u_clamped = u
            .max(-i64::from(limit) - off - h)
            .min(i64::from(limit) - off + h);
        state.saturated = u_clamped != u;
        Pu::from_bits(sat_i32(u_clamped))
    }

    /// The integral after a step: held while `pushing_out`, else I + inc clamped to
    /// ±limit (Q32.32).
    #[inline(always)]
    fn integrate(&self, i_now: i64, inc: i64, limit: i32, pushing_out: bool) -> i64 {
        if pushing_out {
            i_now
        } else {
            let lim64 = i64::from(limit) << 16;
            // |I| ≤ 2^47 and |inc| ≤ 2^54: the plain sum cannot overflow.
            (i_now + inc).max(-lim64).min(lim64)
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::indexing_slicing)]
    use super::{PiCoefficients, PiState};
    use crate::per_unit::{Gain, Pu, TickGain, mul_gain, sat_i32};
    use fixed::types::I32F32;

    /// The step in 64 bits throughout: the reference the 32-bit form must equal.
    fn reference(c: &PiCoefficients, s: &mut PiState, e: Pu, ff: Pu, offset: Pu, h: i32) -> Pu {
        let limit = c.limit.to_bits().saturating_abs();
        let lim64 = i64::from(limit) << 16;
        let inc = (i64::from(e.to_bits()) * i64::from(c.ki_ts.to_bits()) + (1 << 7)) >> 8;
        let p = mul_gain(e, c.kp).to_bits();
        let i_now = s.integral.to_bits();
        let u_trial =
            i64::from(p) + i64::from(ff.to_bits()) + i64::from(offset.to_bits()) + (i_now >> 16);
        let pushing_out =
            (u_trial >= i64::from(limit) && inc > 0) || (u_trial <= -i64::from(limit) && inc < 0);
        let i_next = if pushing_out {
            i_now
        } else {
            (i_now + inc).max(-lim64).min(lim64)
        };
        s.integral = I32F32::from_bits(i_next);
        let u = i64::from(p) + i64::from(ff.to_bits()) + (i_next >> 16);
        let off = i64::from(offset.to_bits().max(-limit).min(limit));
        let h = i64::from(h.max(0));
        let u_clamped = u
            .max(-i64::from(limit) - off - h)
            .min(i64::from(limit) - off + h);
        s.saturated = u_clamped != u;
        Pu::from_bits(sat_i32(u_clamped))
    }

    /// A xorshift64 sequence from `seed`.
    fn xorshift(mut x: u64) -> impl FnMut() -> u64 {
        move || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x
        }
    }

    /// A word from `v`: one of `edges`, or a random word of 30, 20 or 32 significant bits.
    fn pick(v: u64, edges: &[i32]) -> i32 {
        match (v >> 60) % 4 {
            0 => edges[(v % edges.len() as u64) as usize],
            1 => (v as i32) >> 2,
            2 => (v as i32) >> 12,
            _ => v as i32,
        }
    }

    /// Random coefficients, edges included.
    fn coefficients(next: &mut impl FnMut() -> u64, edges: &[i32]) -> PiCoefficients {
        PiCoefficients {
            kp: Gain::from_bits(pick(next(), edges)),
            ki_ts: TickGain::from_bits(pick(next(), edges)),
            limit: Pu::from_bits(pick(next(), edges)),
        }
    }

    /// The 32-bit form gives the 64-bit one's output and state, inside its range, at its
    /// edges and beyond them, with and without a headroom.
    #[test]
    fn update_matches_the_64_bit_form() {
        let mut next = xorshift(0x2545_F491_4F6C_DD1D);
        let edges = [
            0,
            1,
            -1,
            (1 << 29) - 1,
            1 << 29,
            -(1 << 29),
            -(1 << 29) - 1,
            i32::MAX,
            i32::MIN,
        ];
        for k in 0..200_000u32 {
            let r = next();
            let pick = |v: u64| pick(v, &edges);
            let c = coefficients(&mut next, &edges);
            let (e, ff, off) = (
                Pu::from_bits(pick(next())),
                Pu::from_bits(pick(next())),
                Pu::from_bits(pick(next())),
            );
            let integral = match r % 4 {
                0 => i64::from(pick(next())) << 16,
                1 => (next() as i64) >> 17,
                2 => (next() as i64) >> 18,
                _ => i64::from(pick(next())),
            };
            let s0 = PiState {
                integral: I32F32::from_bits(integral),
                saturated: k % 2 == 0,
            };
            let h = if k % 3 == 0 { 0 } else { pick(next()) };
            let (mut a, mut b) = (s0, s0);
            let ua = if h == 0 && k % 2 == 0 {
                c.update_with_offset(&mut a, e, ff, off)
            } else {
                c.update_with_offset_within(&mut a, e, ff, off, [c.abs_limit(), h])
            };
            let ub = reference(&c, &mut b, e, ff, off, h);
            assert_eq!(
                (ua, a),
                (ub, b),
                "{c:?} {s0:?} e {e:?} ff {ff:?} off {off:?} headroom {h}"
            );
        }
    }

    /// `update` (the zero-offset form, its offset clamp left out) equals
    /// `update_with_offset` with a zero offset.
    #[test]
    fn update_equals_a_zero_offset() {
        let mut next = xorshift(0x9E37_79B9_7F4A_7C15);
        let edges = [0, 1, -1, 1 << 29, -(1 << 29), i32::MAX, i32::MIN];
        for k in 0..200_000u32 {
            let pick = |v: u64| pick(v, &edges);
            let c = coefficients(&mut next, &edges);
            let (e, ff) = (Pu::from_bits(pick(next())), Pu::from_bits(pick(next())));
            let s0 = PiState {
                integral: I32F32::from_bits(if k % 2 == 0 {
                    i64::from(pick(next())) << 16
                } else {
                    (next() as i64) >> 17
                }),
                saturated: k % 3 == 0,
            };
            let (mut a, mut b) = (s0, s0);
            assert_eq!(
                (c.update(&mut a, e, ff), a),
                (c.update_with_offset(&mut b, e, ff, Pu::ZERO), b),
                "{c:?} {s0:?} e {e:?} ff {ff:?}"
            );
        }
    }

    /// The headroom: a saturated regulator asks up to `headroom` beyond the bound, so the
    /// downstream sum stays at the limit when the downstream term drops by less than the
    /// headroom after the regulator ran (and leaves it when it drops by more); the integral
    /// holds either way, and a regulator inside the bound is not affected.
    #[test]
    fn the_headroom_keeps_a_saturated_sum_at_the_limit() {
        let c = PiCoefficients {
            kp: Gain::from_num(10),
            ki_ts: TickGain::from_num(0.01),
            limit: Pu::from_num(2),
        };
        let h = Pu::from_num(0.3).to_bits();
        let afb_held = Pu::from_num(-0.2);
        let lim = c.abs_limit();
        let (mut plain, mut wide) = (PiState::default(), PiState::default());
        let e = Pu::from_num(1); // Kp·e = 10 pu: far beyond the limit
        let u_plain = c.update_with_offset_within(&mut plain, e, Pu::ZERO, afb_held, [lim, 0]);
        let u_wide = c.update_with_offset_within(&mut wide, e, Pu::ZERO, afb_held, [lim, h]);
        assert_eq!(u_plain, Pu::from_num(2.2));
        assert_eq!(u_wide, Pu::from_num(2.5));
        assert_eq!(
            (plain.integral, wide.integral),
            (I32F32::ZERO, I32F32::ZERO)
        );
        // The AFB term has since fallen by 0.25 pu: the sum (clamped to ±2) stays at the
        // limit only with the headroom; by 0.35 pu it leaves it either way.
        let sum = |u: Pu, afb: f64| u.saturating_add(Pu::from_num(afb)).min(Pu::from_num(2));
        assert!(sum(u_plain, -0.45) < Pu::from_num(2));
        assert_eq!(sum(u_wide, -0.45), Pu::from_num(2));
        assert!(sum(u_wide, -0.55) < Pu::from_num(2));
        // Inside the bound the headroom changes nothing.
        let (mut a, mut b) = (PiState::default(), PiState::default());
        let small = Pu::from_num(0.01);
        assert_eq!(
            c.update_with_offset_within(&mut a, small, Pu::ZERO, afb_held, [lim, 0]),
            c.update_with_offset_within(&mut b, small, Pu::ZERO, afb_held, [lim, h])
        );
    }

    /// The linear form's step, I ← I + ki_ts·e, u = kp·e + ff + I, from the regulator's own
    /// integral, is the fixed-point step away from the clamps: the integral to the rounding
    /// of the increment (2^−33 pu), the output to 1.5 LSB (Kp·e rounded, ±½ LSB, the
    /// integral's whole part taken by truncation, < 1 LSB), each plus the f64 sums' own
    /// rounding.
    #[test]
    fn the_linear_step_is_the_fixed_point_step_away_from_the_clamps() {
        let mut next = xorshift(0x1234_5678_9ABC_DEF1);
        let lsb = 2f64.powi(-16);
        // The f64 sums' own rounding (values below 2^7: ulp 2^−46).
        let f64_noise = 2f64.powi(-40);
        // A value in ±`span` from the top bits of a random word.
        let mut uniform = |span: f64| ((next() >> 11) as f64 / 2f64.powi(53) * 2.0 - 1.0) * span;
        for _ in 0..100_000 {
            let c = PiCoefficients {
                kp: Gain::from_num(uniform(100.0)),
                ki_ts: TickGain::from_num(uniform(100.0)),
                limit: Pu::from_num(1000),
            };
            let (e, ff) = (Pu::from_num(uniform(1.0)), Pu::from_num(uniform(1.0)));
            let integral = I32F32::from_num(uniform(10.0));
            let mut s = PiState {
                integral,
                saturated: false,
            };
            let u = c.update(&mut s, e, ff);
            let lin = c.linear();
            let mut i_lin: f64 = integral.to_num();
            i_lin += e.to_num::<f64>() * lin.ki_ts;
            let u_lin = lin.kp * e.to_num::<f64>() + ff.to_num::<f64>() + i_lin;
            assert!(!s.saturated);
            assert!(
                (s.integral.to_num::<f64>() - i_lin).abs() <= 2f64.powi(-33) + f64_noise,
                "{c:?} e {e} integral {integral}"
            );
            assert!(
                (u.to_num::<f64>() - u_lin).abs() <= 1.5 * lsb + f64_noise,
                "{c:?} e {e} ff {ff} integral {integral}: {u} vs {u_lin}"
            );
        }
    }
}
