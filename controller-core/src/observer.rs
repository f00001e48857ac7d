//! Luenberger state observer (G. Ellis, "Observers in Control Systems"): a rigid-body
//! model J·dω/dt = T_cmd + T_d driven by the torque command, corrected by the measured
//! position. States, in counts and ticks of the current loop (Ts):
//!
//! ```text
//! p  position [counts]           Q32.32, modulo 2^32 counts (only p_meas − p matters)
//! v  velocity [counts/tick]      Q32.32
//! d  disturbance acceleration [counts/tick²] (the torque the model lacks, over J), Q32.32
//! u  = T_cmd·k_u, k_u = Ts²·counts_per_pu_s / J_model   [counts/tick² per pu torque]
//!
//! predict:  p⁻ = p + v + (u + d)/2,   v⁻ = v + u + d,   d⁻ = d
//! correct:  e = p_meas − p⁻;  p = p⁻ + l1·e;  v = v⁻ + l2·e;  d = d⁻ + l3·e
//! accel:    â = v[n] − v[n−1] = u + d⁻ + l2·e        residual r = â − u = d⁻ + l2·e
//! ```
//! With l1 = 1 − θ³, l2 = 1.5·(1 − θ)²·(1 + θ), l3 = (1 − θ)³ all three observer poles sit
//! at z = θ = e^(−2π·f_o·Ts) (critically damped α-β-γ form; checked by the tests through
//! the characteristic polynomial). Outputs: velocity \[pu\], acceleration \[pu/s\],
//! load-torque estimate T_L = −J_model·d \[pu\].
//!
//! The acceleration is G. Ellis' estimate: the change of the velocity estimate over the
//! tick, the velocity correction l2·e included. For an acceleration a that the model does
//! not know (u = 0) it is â = G·a with, in continuous terms (l1 = 3ω_o, l2 = 3ω_o²,
//! l3 = ω_o³), G = (3ω_o²·s + ω_o³)/(s + ω_o)³: its error 1 − G falls like s², so â follows
//! the true acceleration up to about the observer bandwidth. With the torque known,
//! â = G·a + (1 − G)·u. The plain output u + d leaves out l2·e and has
//! G = ω_o³/(s + ω_o)³, whose error falls only like s; at 4096 CPR it passes less encoder
//! noise, but the acceleration the load causes reaches it only through the slow disturbance
//! state, so the observer does not offer it (`docs/design.md`).
//! `tests/it/estimator.rs` checks the fixed-point observer against the exact discrete
//! transfer function of this form.
//!
//! For the acceleration feedback the observer also gives the acceleration it predicts for
//! the coming tick under a torque T: â⁺ = T·k_u + r ([`Observer::predicted_acceleration_pu_s`]),
//! which lets [`crate::accel_feedback`] solve the loop T → model → â → T in closed form.

use crate::per_unit::{Coef, Gain, Pu, PuPerS, TickGain, mul_bits, mul_gain, sat_bits, sat_shr};
use fixed::types::I16F16;

/// Observer coefficients.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Observer {
    /// Position correction gain l1, Q2.30.
    pub l1: Coef,
    /// Velocity correction gain l2 \[per tick\], Q2.30.
    pub l2: Coef,
    /// Disturbance correction gain l3 \[per tick²\], Q2.30.
    pub l3: Coef,
    /// Torque to model acceleration, k_u \[counts/tick² per pu\], Q8.24.
    pub k_u: TickGain,
    /// Velocity scale \[pu per count/tick\], Q8.24.
    pub k_vel: TickGain,
    /// Acceleration scale \[pu/s per count/tick²\], Q16.16.
    pub k_acc: Gain,
    /// Load torque per pu/s of disturbance acceleration (= −J_model) \[pu·s\], Q16.16.
    pub k_load: Gain,
    /// The innovations the measured count cannot tell from zero
    /// ([`Observer::outside_count_interval`]).
    pub count_interval: CountInterval,
}

/// An observer's linear form: its coefficients as f64, read from the stored bits
/// ([`Observer::linear`]). In counts and ticks, without the roundings, with the plain
/// innovation (the count interval, a dead zone, is nonlinear and left out):
///
/// ```text
/// u = T·k_u;  p⁻ = p + v + (u + d)/2;  v⁻ = v + u + d;  e = p_meas − p⁻
/// p = p⁻ + l1·e;  v = v⁻ + l2·e;  d = d + l3·e;  r = d⁻ + l2·e;  â = u + r
/// velocity = v·k_vel [pu];  acceleration = â·k_acc [pu/s];  load torque = d·k_acc·k_load [pu]
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ObserverLinear {
    /// l1, l2, l3.
    pub l: [f64; 3],
    /// k_u \[counts/tick² per pu\].
    pub k_u: f64,
    /// Velocity scale \[pu per count/tick\].
    pub k_vel: f64,
    /// Acceleration scale \[pu/s per count/tick²\].
    pub k_acc: f64,
    /// Load torque per pu/s of disturbance acceleration \[pu·s\].
    pub k_load: f64,
}

/// The innovations e = n − p̂ \[counts, Q16.16\] that the count n cannot tell from zero:
/// e ∈ \[lo, hi\]. The position lies in \[n, n + 1), so the error to the middle of the
/// count is e + ½, and a half-width h > 0 around that middle is e ∈ \[−½ − h, −½ + h\]
/// ([`CountInterval::of`]). The plain innovation is \[0, 0\] ([`CountInterval::PLAIN`]):
/// nothing taken out, so a tick costs the same two compares either way.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CountInterval {
    /// Lower end \[counts\].
    pub lo: I16F16,
    /// Upper end \[counts\].
    pub hi: I16F16,
}

impl CountInterval {
    /// The plain innovation.
    pub const PLAIN: Self = Self {
        lo: I16F16::ZERO,
        hi: I16F16::ZERO,
    };

    /// The interval of half-width `h` \[counts\] around the middle of the count; `h` ≤ 0
    /// is [`CountInterval::PLAIN`].
    #[must_use]
    pub fn of(h: I16F16) -> Self {
        if h <= I16F16::ZERO {
            return Self::PLAIN;
        }
        let middle = I16F16::from_bits(-(1 << 15));
        Self {
            lo: middle.saturating_sub(h),
            hi: middle.saturating_add(h),
        }
    }
}

/// Observer state (plain data, reset = default).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ObserverState {
    /// Position estimate \[counts\], Q32.32 bits, wrapping modulo 2^32 counts: the observer
    /// only uses the innovation p_meas − p, which wrapping arithmetic gives exactly.
    pub p: i64,
    /// Velocity estimate \[counts/tick\], Q32.32 bits; `update` reads it saturated to ±2^60.
    pub v: i64,
    /// Disturbance acceleration estimate \[counts/tick²\], Q32.32 bits; `update` reads it
    /// saturated to ±2^60 (2^28 counts/tick²), the range its plain adds rely on.
    pub d: i64,
    /// Acceleration estimate over the last tick, â = v\[n\] − v\[n−1\] = u + d⁻ + l2·e
    /// \[counts/tick²\], Q32.32.
    pub acc: i64,
    /// The part of â the model's torque input does not explain, r = â − u = d⁻ + l2·e
    /// \[counts/tick²\], Q32.32.
    pub residual: i64,
    /// Whether the position has been initialised from a measurement.
    pub primed: bool,
}

/// Observer outputs for one tick.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ObserverEstimate {
    /// Velocity \[pu\].
    pub velocity_pu: Pu,
    /// Acceleration \[pu/s\] (change of the velocity estimate over the tick).
    pub acceleration_pu_s: PuPerS,
    /// Estimated load torque \[pu\] (positive brakes positive motion).
    pub load_torque_pu: Pu,
}

/// Q.32 acceleration in counts/tick² → Q12.20 bits (i32), saturating.
#[inline]
fn q32_to_q20(x: i64) -> i32 {
    sat_shr::<12>(x)
}

impl Observer {
    /// The linear form ([`ObserverLinear`]): every coefficient as f64, exactly the stored
    /// value.
    #[must_use]
    pub fn linear(&self) -> ObserverLinear {
        ObserverLinear {
            l: [self.l1, self.l2, self.l3].map(|l| l.to_num()),
            k_u: self.k_u.to_num(),
            k_vel: self.k_vel.to_num(),
            k_acc: self.k_acc.to_num(),
            k_load: self.k_load.to_num(),
        }
    }

    /// One observer step with the measured unwrapped position \[counts\] and the torque
    /// command applied over the last tick \[pu\]. Updates the state only; read the estimates
    /// with [`Observer::velocity_pu`], [`Observer::acceleration_pu_s`],
    /// [`Observer::load_torque_pu`] or [`Observer::estimate`] (each costs a multiply, so a
    /// tick reads only what it uses).
    ///
    /// ```
    /// use controller_core::observer::{Observer, ObserverState};
    /// use controller_core::per_unit::{Coef, Gain, Pu, TickGain};
    /// let o = Observer { l1: Coef::from_num(0.5), l2: Coef::from_num(0.1), l3: Coef::from_num(0.01),
    ///     k_u: TickGain::from_num(0.01), k_vel: TickGain::from_num(0.0586), k_acc: Gain::from_num(234),
    ///     k_load: Gain::from_num(-1), count_interval: controller_core::observer::CountInterval::PLAIN };
    /// let mut s = ObserverState::default();
    /// o.update(&mut s, 0, Pu::ZERO);
    /// assert_eq!(o.estimate(&s).velocity_pu, Pu::ZERO);
    /// ```
    #[inline(always)]
    pub fn update(&self, s: &mut ObserverState, position_counts: i64, torque_pu: Pu) {
        let p_meas = position_counts.wrapping_shl(32);
        if !s.primed {
            *s = ObserverState {
                p: p_meas,
                primed: true,
                ..ObserverState::default()
            };
        }
        // Ranges (Q.32 raw), which let the adds below wrap instead of saturate:
        //   |u| ≤ 2^54            (|T·k_u| ≤ 2^31·2^31 = 2^62, ≫ 8)
        //   |corr(l)| ≤ 2^48      (|e·l| ≤ 2^62, ≫ 14)
        //   |d| ≤ 2^60            (saturated there when read: 2^28 counts/tick², some 10^13
        //                          times the largest acceleration a drive can encoder-count)
        //   |v| ≤ 2^60            (likewise: 2^28 counts/tick; the velocity output saturates
        //                          from 2^47 on, so nothing read from it changes)
        // so |u + d|, |d + l2·e|, |u + d + l2·e| and |d + l3·e| are below 2^61 and
        // |v + u + d + l2·e| below 2^62: every add is exact, and the step is the saturating
        // one bit for bit while |v|, |d| < 2^60 (tests/it/ranges.rs). Beyond that (never
        // reached from a real encoder) v and d saturate at 2^60 instead of 2^63. States a
        // caller makes up beyond these ranges wrap in `predicted_acceleration_pu_s` (no
        // panic).
        // u [counts/tick², Q.32] = T (Q16.16) · k_u (Q8.24) = Q.40 → Q.32.
        let u = (i64::from(torque_pu.to_bits()) * i64::from(self.k_u.to_bits())) >> 8;
        let d = sat_bits::<61>(s.d);
        let v = sat_bits::<61>(s.v);
        let acc = u.wrapping_add(d);
        // Predict (position wraps modulo 2^32 counts by design).
        let p_pred = s.p.wrapping_add(v).wrapping_add(acc >> 1);
        let v_pred = v.wrapping_add(acc);
        // Innovation in counts, Q16.16, saturating (a huge error means a fault elsewhere).
        let e = self.outside_count_interval(sat_shr::<16>(p_meas.wrapping_sub(p_pred)));
        // Corrections: e (Q16.16) · l (Q2.30) = Q.46 → Q.32.
        let corr = |l: Coef| (i64::from(e) * i64::from(l.to_bits())) >> 14;
        let dv = corr(self.l2);
        s.p = p_pred.wrapping_add(corr(self.l1));
        s.v = v_pred.wrapping_add(dv);
        // â = v[n] − v[n−1] = u + d⁻ + l2·e, formed from its parts rather than as a
        // difference of the velocity states.
        s.residual = d.wrapping_add(dv);
        s.acc = u.wrapping_add(s.residual);
        s.d = d.wrapping_add(corr(self.l3));
    }

    /// The innovation `e` = n − p̂ \[counts, Q16.16\] as far as the count n tells
    /// ([`CountInterval`]): the part of it outside \[lo, hi\].
    ///
    /// ```
    /// use controller_core::observer::{CountInterval, Observer};
    /// use controller_core::per_unit::{Coef, Gain, TickGain};
    /// use fixed::types::I16F16;
    /// let mut o = Observer { l1: Coef::ZERO, l2: Coef::ZERO, l3: Coef::ZERO,
    ///     k_u: TickGain::ZERO, k_vel: TickGain::ZERO, k_acc: Gain::ZERO, k_load: Gain::ZERO,
    ///     count_interval: CountInterval::of(I16F16::from_num(0.5)) };
    /// let half = 1 << 15;
    /// // p̂ within the count: no correction; 0.25 count below it: 0.25 count.
    /// assert_eq!(o.outside_count_interval(-half), 0);
    /// assert_eq!(o.outside_count_interval(half / 2), half / 2);
    /// // 0.25 count above it (e = −1.25): −0.25 count.
    /// assert_eq!(o.outside_count_interval(-5 * half / 2), -half / 2);
    /// o.count_interval = CountInterval::PLAIN;
    /// assert_eq!(o.outside_count_interval(-half), -half);
    /// ```
    #[inline(always)]
    #[must_use]
    pub fn outside_count_interval(&self, e: i32) -> i32 {
        let CountInterval { lo, hi } = self.count_interval;
        // max, then min: no panic even for lo > hi (a made-up interval).
        e.saturating_sub(e.max(lo.to_bits()).min(hi.to_bits()))
    }

    /// Velocity estimate \[pu\].
    #[inline]
    #[must_use]
    pub fn velocity_pu(&self, s: &ObserverState) -> Pu {
        Pu::from_bits(mul_bits::<24>(sat_shr::<16>(s.v), self.k_vel.to_bits()))
    }

    /// Acceleration estimate over the last tick, â = Δv̂ (Ellis) \[pu/s\].
    /// Q12.20 counts/tick² · Q16.16 = Q.36 → Q16.16.
    #[inline]
    #[must_use]
    pub fn acceleration_pu_s(&self, s: &ObserverState) -> PuPerS {
        Pu::from_bits(mul_bits::<20>(q32_to_q20(s.acc), self.k_acc.to_bits()))
    }

    /// The acceleration the observer expects over the coming tick if the torque `torque_pu`
    /// is applied: â⁺ = T·k_u + r \[pu/s\]. T (Q16.16) · k_u (Q8.24) = Q.40 → Q.32 counts/tick²,
    /// plus r (Q.32), then as [`Observer::acceleration_pu_s`].
    ///
    /// ```
    /// use controller_core::observer::{Observer, ObserverState};
    /// use controller_core::per_unit::{Coef, Gain, Pu, TickGain};
    /// let o = Observer { l1: Coef::from_num(0.5), l2: Coef::from_num(0.1), l3: Coef::from_num(0.01),
    ///     k_u: TickGain::from_num(0.01), k_vel: TickGain::from_num(0.0586), k_acc: Gain::from_num(234),
    ///     k_load: Gain::from_num(-1), count_interval: controller_core::observer::CountInterval::PLAIN };
    /// let s = ObserverState::default();
    /// // 1 pu of torque: 0.01 counts/tick², 2.34 pu/s.
    /// let a = o.predicted_acceleration_pu_s(&s, Pu::from_num(1));
    /// assert!((a.to_num::<f64>() - 2.34).abs() < 1e-3);
    /// ```
    #[inline]
    #[must_use]
    pub fn predicted_acceleration_pu_s(&self, s: &ObserverState, torque_pu: Pu) -> PuPerS {
        // |u| ≤ 2^54 and |r| < 2^60 + 2^48 as `update` leaves it (see there): no overflow.
        let u = (i64::from(torque_pu.to_bits()) * i64::from(self.k_u.to_bits())) >> 8;
        let a = u.wrapping_add(s.residual);
        Pu::from_bits(mul_bits::<20>(q32_to_q20(a), self.k_acc.to_bits()))
    }

    /// Estimated load torque T_L = −J_model·d \[pu\] (positive brakes positive motion).
    #[inline]
    #[must_use]
    pub fn load_torque_pu(&self, s: &ObserverState) -> Pu {
        let d_pu_s = Pu::from_bits(mul_bits::<20>(q32_to_q20(s.d), self.k_acc.to_bits()));
        mul_gain(d_pu_s, self.k_load)
    }

    /// All three estimates.
    #[must_use]
    pub fn estimate(&self, s: &ObserverState) -> ObserverEstimate {
        ObserverEstimate {
            velocity_pu: self.velocity_pu(s),
            acceleration_pu_s: self.acceleration_pu_s(s),
            load_torque_pu: self.load_torque_pu(s),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::{CountInterval, Observer, ObserverState};
    use crate::per_unit::{Coef, Gain, Pu, TickGain};

    const LSB: f64 = 1.0 / 65536.0;
    const Q32: f64 = 4_294_967_296.0;

    /// One step of the linear form (its equations, [`super::ObserverLinear`]) from the
    /// observer's own state is the fixed-point step: each state to l_i·2^−16 counts (the
    /// innovation truncated to Q16.16) plus 2^−30 (the truncated products and halving), and
    /// each output to its scale times its input's truncation plus ½ LSB of rounding.
    #[test]
    fn the_linear_step_is_the_fixed_point_step() {
        // Poles at θ = e^(−2π·300/4000), the scales of 4096 CPR at 1000 rpm and 4 kHz.
        let theta = (-core::f64::consts::TAU * 300.0 / 4000.0).exp();
        let one_m = 1.0 - theta;
        let o = Observer {
            l1: Coef::from_num(1.0 - theta.powi(3)),
            l2: Coef::from_num(1.5 * one_m * one_m * (1.0 + theta)),
            l3: Coef::from_num(one_m.powi(3)),
            k_u: TickGain::from_num(0.0137),
            k_vel: TickGain::from_num(0.0586),
            k_acc: Gain::from_num(234.375),
            k_load: Gain::from_num(-0.125),
            count_interval: CountInterval::PLAIN,
        };
        let lin = o.linear();
        let [l1, l2, l3] = lin.l;
        let mut x = 0x9E37_79B9_7F4A_7C15u64;
        let mut uniform = |span: f64| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            ((x >> 11) as f64 / 2f64.powi(53) * 2.0 - 1.0) * span
        };
        for _ in 0..100_000 {
            let q32 = |v: f64| (v * Q32).round() as i64;
            let (p, v, d) = (uniform(1000.0), uniform(50.0), uniform(0.5));
            let mut s = ObserverState {
                p: q32(p),
                v: q32(v),
                d: q32(d),
                primed: true,
                ..ObserverState::default()
            };
            let (p, v, d) = (s.p as f64 / Q32, s.v as f64 / Q32, s.d as f64 / Q32);
            let torque = Pu::from_num(uniform(2.0));
            let n = (p + v + uniform(3.0)).round();
            o.update(&mut s, n as i64, torque);
            // The linear form's step.
            let u = torque.to_num::<f64>() * lin.k_u;
            let acc = u + d;
            let (p_pred, v_pred) = (p + v + 0.5 * acc, v + acc);
            let e = n - p_pred;
            let r = d + l2 * e;
            let want = [p_pred + l1 * e, v_pred + l2 * e, d + l3 * e, r, u + r];
            let got = [s.p, s.v, s.d, s.residual, s.acc].map(|b| b as f64 / Q32);
            let tol = [l1, l2, l3, l2, l2].map(|l| l / 65536.0 + 2f64.powi(-30));
            for (k, ((g, w), t)) in got.iter().zip(want).zip(tol).enumerate() {
                assert!((g - w).abs() <= t, "{k}: {got:?} vs {want:?}");
            }
            // The outputs, from the fixed-point state.
            let [v1, acc1, d1] = [s.v, s.acc, s.d].map(|b| b as f64 / Q32);
            let outputs = [
                (
                    o.velocity_pu(&s),
                    v1 * lin.k_vel,
                    lin.k_vel / 65536.0 + LSB / 2.0,
                ),
                (
                    o.acceleration_pu_s(&s),
                    acc1 * lin.k_acc,
                    lin.k_acc * 2f64.powi(-20) + LSB / 2.0,
                ),
                (
                    o.load_torque_pu(&s),
                    d1 * lin.k_acc * lin.k_load,
                    lin.k_load.abs() * (lin.k_acc * 2f64.powi(-20) + LSB / 2.0) + LSB / 2.0,
                ),
                (
                    o.predicted_acceleration_pu_s(&s, torque),
                    (u + s.residual as f64 / Q32) * lin.k_acc,
                    lin.k_acc * (2f64.powi(-32) + 2f64.powi(-20)) + LSB / 2.0,
                ),
            ];
            for (k, (fixed, linear, tol)) in outputs.into_iter().enumerate() {
                let fixed = fixed.to_num::<f64>();
                assert!(
                    (fixed - linear).abs() <= tol + 1e-12,
                    "output {k}: {fixed} vs {linear}"
                );
            }
        }
    }
}
