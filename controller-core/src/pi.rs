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
//! output so that the sum, not the regulator alone, meets the limit.

use fixed::types::I32F32;

use crate::per_unit::{mul_gain, sat_i32, Gain, Pu, TickGain};

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

/// PI state: the integral \[output pu\], Q32.32.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PiState {
    /// Integrator \[output pu\].
    pub integral: I32F32,
    /// Whether the last output was clamped (for logging).
    pub saturated: bool,
}

impl PiCoefficients {
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
        self.update_with_offset(state, e, ff, Pu::ZERO)
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
    #[inline]
    pub fn update_with_offset(&self, state: &mut PiState, e: Pu, ff: Pu, offset: Pu) -> Pu {
        // |limit| so a negative limit in hand-made coefficients cannot invert the clamp.
        let limit = self.limit.to_bits().saturating_abs();
        let lim64 = i64::from(limit) << 16;
        // Integral increment in Q.40 (Q16.16 · Q8.24) → Q.32.
        let inc = (i64::from(e.to_bits()) * i64::from(self.ki_ts.to_bits()) + (1 << 7)) >> 8;
        let p = mul_gain(e, self.kp).to_bits();
        let i_now = state.integral.to_bits();
        let u_trial =
            i64::from(p) + i64::from(ff.to_bits()) + i64::from(offset.to_bits()) + (i_now >> 16);
        let pushing_out =
            (u_trial >= i64::from(limit) && inc > 0) || (u_trial <= -i64::from(limit) && inc < 0);
        let i_next = if pushing_out {
            i_now
        } else {
            // |I| ≤ 2^47 and |inc| ≤ 2^54: the plain sum cannot overflow.
            (i_now + inc).max(-lim64).min(lim64)
        };
        state.integral = I32F32::from_bits(i_next);
        let u = i64::from(p) + i64::from(ff.to_bits()) + (i_next >> 16);
        // Clamp so that u + offset, the reference downstream, spans the whole ±limit: a
        // downstream term that opposes the output (the AFB term braking an acceleration the
        // drive is saturated for) must not take usable torque away. The offset is bounded
        // to ±limit first, so the output stays within ±2·limit.
        // max/min rather than clamp: clamp carries a (never taken) panic branch.
        // In 32 bits: 0 ≤ limit ≤ i32::MAX, so −limit is an i32 too.
        let off = i64::from(offset.to_bits().max(-limit).min(limit));
        let u_clamped = u.max(-i64::from(limit) - off).min(i64::from(limit) - off);
        state.saturated = u_clamped != u;
        Pu::from_bits(sat_i32(u_clamped))
    }
}
