//! Velocity and acceleration by backward differences of the unwrapped encoder position.
//!
//! ```text
//! v[n] = (p[n] − p[n−1]) · k_vel          k_vel = 2π/(cpr·ω_b·Ts)     [pu per count]
//! a[n] = (Δp[n] − Δp[n−1]) · k_acc        k_acc = k_vel/Ts            [pu/s per count]
//! ```
//! Both are quantized to whole counts: at 4096 CPR, 1000 rpm and 0.5 ms one count of velocity is
//! 0.029 pu and one count of acceleration 58.6 pu/s (`docs/design.md`, "Encoder quantization").

use crate::per_unit::{Gain, Pu, PuPerS, TickGain, counts_to_pu, mul_gain, sat_i32};

/// Differentiator scale factors for one tick rate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Differentiator {
    /// Velocity per count of change per tick \[pu\], Q8.24.
    pub k_vel: TickGain,
    /// Acceleration per count of second difference \[pu/s\], Q16.16.
    pub k_acc: Gain,
}

/// A differentiator's linear form: its scales as f64, read from the stored bits
/// ([`Differentiator::linear`]). Once primed, without the roundings:
/// v = Δp·k_vel, a = (Δp − Δp_last)·k_acc.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DifferentiatorLinear {
    /// Velocity per count of change per tick \[pu\].
    pub k_vel: f64,
    /// Acceleration per count of second difference \[pu/s\].
    pub k_acc: f64,
}

/// Differentiator state.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DifferentiatorState {
    /// Last unwrapped position \[counts\].
    pub last_position: i64,
    /// Last first difference \[counts per tick\].
    pub last_delta: i32,
    /// Samples seen since reset, saturating at 2 (outputs are zero until primed).
    pub primed: u8,
}

impl Differentiator {
    /// The linear form ([`DifferentiatorLinear`]): both scales as f64, exactly the stored
    /// Q8.24 and Q16.16 values.
    ///
    /// ```
    /// use controller_core::differentiator::Differentiator;
    /// use controller_core::per_unit::{Gain, TickGain};
    /// let d = Differentiator { k_vel: TickGain::from_num(0.5), k_acc: Gain::from_num(10) };
    /// assert_eq!((d.linear().k_vel, d.linear().k_acc), (0.5, 10.0));
    /// ```
    #[must_use]
    pub fn linear(&self) -> DifferentiatorLinear {
        DifferentiatorLinear {
            k_vel: self.k_vel.to_num(),
            k_acc: self.k_acc.to_num(),
        }
    }

    /// Update with the unwrapped position \[counts\]; returns (velocity \[pu\], acceleration \[pu/s\]).
    ///
    /// ```
    /// use controller_core::differentiator::{Differentiator, DifferentiatorState};
    /// use controller_core::per_unit::{Gain, TickGain, Pu};
    /// let d = Differentiator { k_vel: TickGain::from_num(0.5), k_acc: Gain::from_num(10) };
    /// let mut s = DifferentiatorState::default();
    /// d.update(&mut s, 0);
    /// let (v, _) = d.update(&mut s, 4);
    /// assert_eq!(v, Pu::from_num(2));
    /// let (v, a) = d.update(&mut s, 10);
    /// assert_eq!((v, a), (Pu::from_num(3), Pu::from_num(20)));
    /// ```
    #[inline]
    pub fn update(&self, s: &mut DifferentiatorState, position_counts: i64) -> (Pu, PuPerS) {
        let delta = sat_i32(position_counts.wrapping_sub(s.last_position));
        let (delta, dd) = match s.primed {
            0 => (0, 0),
            1 => (delta, 0),
            _ => (delta, delta.saturating_sub(s.last_delta)),
        };
        s.primed = s.primed.saturating_add(1).min(2);
        s.last_position = position_counts;
        s.last_delta = delta;
        let v = counts_to_pu(delta, self.k_vel);
        let a = mul_gain(Pu::saturating_from_num(dd), self.k_acc);
        (v, a)
    }
}

#[cfg(test)]
mod tests {
    use super::{Differentiator, DifferentiatorState};
    use crate::per_unit::{Gain, TickGain};

    /// Once primed, the linear form's differences times its scales are the fixed-point
    /// outputs to ½ LSB (each product rounded once).
    #[test]
    fn the_linear_step_is_the_fixed_point_step_once_primed() {
        let d = Differentiator {
            k_vel: TickGain::from_num(0.029_296_875 * 1.37),
            k_acc: Gain::from_num(117.18),
        };
        let lin = d.linear();
        let mut s = DifferentiatorState::default();
        let (mut position, mut last) = (0i64, (0i64, 0i64));
        let mut x = 0x9E37_79B9_7F4A_7C15u64;
        for k in 0..100_000 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            position += (x as i64) >> 58; // ±32 counts: no output saturates
            let (v, a) = d.update(&mut s, position);
            let delta = position - last.0;
            if k >= 2 {
                let want = (
                    delta as f64 * lin.k_vel,
                    (delta - last.1) as f64 * lin.k_acc,
                );
                let tol = 0.5 / 65536.0 + 1e-12;
                assert!((v.to_num::<f64>() - want.0).abs() <= tol, "{v} vs {want:?}");
                assert!((a.to_num::<f64>() - want.1).abs() <= tol, "{a} vs {want:?}");
            }
            last = (position, delta);
        }
    }
}
