//! Acceleration feedback ("inertia stabilization", paper Fig. 5 and 7).
//!
//! ```text
//! Plain:  afb = −Ka·F(â)
//! Error:  afb = +Ka·F(a_cmd − â)      (Rockwell US 7,141,946)
//! ```
//! `afb` \[pu torque\] is added to the torque reference P (velocity PI plus feed-forward),
//! T = clamp(P + afb, ±limit), and is itself clamped to ±limit. Ka \[s\] is Q16.16, the
//! filter F Q2.30 (see [`crate::filter`]).
//!
//! # The loop inside the controller, solved in closed form
//!
//! With the acceleration from the state observer, â contains the model's own response to
//! the torque command: â = u + r with u = T/J_model (T the torque applied over the tick)
//! and r the residual the measurement drives ([`crate::observer`]). Fed back with Ka, the
//! command T enters its own estimate: T → u → â → F → T. Evaluated one tick late (the
//! torque of the last tick in â) this loop is closed inside the
//! controller, whatever the machine does, and with a first-order F (y ← y + α·(x − y)) it is
//! y\[n\] = (1 − α − α·Ka/J)·y\[n−1\]: stable only for Ka/J_model < (2 − α)/α (3.04, 1.52,
//! 0.77 × J_total at 50, 100, 200 Hz and 4 kHz with J_model = Jm).
//!
//! Here the estimate is taken for the torque being commanded now, â⁺(T) = T/J_model + r
//! ([`crate::observer::Observer::predicted_acceleration_pu_s`], r the residual the
//! measurement drives), and the equation is solved for T. Every filter here has a direct
//! feed-through b0 (1 for none, α for the first order, b0 for the biquad):
//! F(x)\[n\] = b0·x\[n\] + h\[n\], with h\[n\] from the past only
//! ([`crate::filter::LowPass::begin`]). With c = 0 (plain) or c = a_cmd (error),
//! k = Ka/J_model, and x(T) = c − â⁺(T) the filter input for a torque T, so that
//! x(T) = x(P) − (T − P)/J_model:
//!
//! ```text
//! T − P = Ka·(h + b0·x(T)) = Ka·(h + b0·x(P)) − b0·k·(T − P)
//! ⇒ afb = T − P = g·Ka·(h + b0·x(P)),     g = 1/(1 + b0·k)
//! ```
//! i.e. evaluate the filter input at the torque P without the AFB term, and scale by
//! g·Ka instead of Ka. For F = 1 (b0 = 1, h = 0) and the plain form this is the
//! disturbance-observer form T = J/(J + Ka)·P − Ka/(J + Ka)·J·r (Hori's resonance-ratio
//! control). For the first order: afb = Ka·((1 − α)·y\[n−1\] + α·x(P))/(1 + α·k). Afterwards
//! the filter step is completed with x(T) for the T actually applied (after the clamps), so
//! the estimate and the filter always describe the torque that was commanded.
//!
//! What is left is the loop through the machine. With a rigid body whose inertia is the
//! model's, r is independent of T (the model and the measurement cancel) and
//! T = P/(1 + k·F): a stable filter for every Ka ≥ 0 (pole (1 − α)/(1 + α·k) for the first
//! order). With the gears engaged (plant J_total or the two-mass shaft, model Jm)
//! r = G·(a − u) still depends on T; that loop runs through the plant. A skeleton of the
//! tick with a first-order current loop (`tests/it/afb_skeleton.rs`) finds it stable up to
//! Ka = 1000·J_total for rigid Jm, rigid J_total and the Table 1 two-mass shaft: as Ka
//! grows, g·Ka → J_model/b0 and the closed form tends to a fixed controller, so Ka buys
//! inertia, not instability, as long as J_model is at most the inertia the motor drives
//! (a J_total model on the separated motor is unstable). The linear model of the whole loop,
//! with the real current regulator and winding (`tests/it/afb_loop.rs`), agrees in speed
//! mode; with the position loop it finds a slow mode that limits Ka to 7–11·J_total for
//! 25–400 Hz filters, far above the one-tick-late limit. In practice Ka is limited by the
//! count noise the estimate passes (`tests/it/accel_loop.rs`).
//!
//! With the acceleration from differentiation there is no model term, and the plain update
//! [`AccelerationFeedback::update`] is used.

use crate::config::AfbMode;
use crate::filter::{LowPass, LowPassLinear, LowPassState};
use crate::per_unit::{Gain, Pu, PuPerS, mul_gain, sat_round_shr};

/// Acceleration feedback coefficients.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AccelerationFeedback {
    /// Form of the feedback.
    pub mode: AfbMode,
    /// Ka \[pu torque per pu/s\].
    pub ka: Gain,
    /// Low-pass filter on the acceleration or acceleration error.
    pub filter: LowPass,
    /// Output limit \[pu torque\]; also the limit of the torque reference T = P + afb.
    pub limit: Pu,
    /// Closed form: g·Ka with g = 1/(1 + b0·Ka/J_model) \[pu torque per pu/s\], Q16.16.
    pub ka_closed: Gain,
}

/// Acceleration feedback's linear form: its coefficients as f64, read from the stored bits
/// ([`AccelerationFeedback::linear`]). Without the clamps and the roundings, with x the
/// filter input (c − â, module docs):
///
/// ```text
/// measured acceleration:  afb = ka·F(x)
/// closed form:            afb = ka_closed·(h + b0·x(P)), the filter step completed with x(T)
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AfbLinear {
    /// Ka \[pu torque per pu/s\].
    pub ka: f64,
    /// The closed form's g·Ka \[pu torque per pu/s\].
    pub ka_closed: f64,
    /// The filter F.
    pub filter: LowPassLinear,
}

impl AccelerationFeedback {
    /// The linear form ([`AfbLinear`]): Ka, g·Ka and the filter as f64, exactly the stored
    /// values.
    ///
    /// ```
    /// use controller_core::accel_feedback::AccelerationFeedback;
    /// use controller_core::filter::{LowPass, LowPassLinear};
    /// use controller_core::per_unit::{Gain, Pu};
    /// use controller_core::AfbMode;
    /// let afb = AccelerationFeedback { mode: AfbMode::Plain, ka: Gain::from_num(0.5),
    ///     filter: LowPass::None, limit: Pu::from_num(2), ka_closed: Gain::from_num(0.25) };
    /// let l = afb.linear();
    /// assert_eq!((l.ka, l.ka_closed, l.filter), (0.5, 0.25, LowPassLinear::None));
    /// ```
    #[must_use]
    pub fn linear(&self) -> AfbLinear {
        AfbLinear {
            ka: self.ka.to_num(),
            ka_closed: self.ka_closed.to_num(),
            filter: self.filter.linear(),
        }
    }

    /// One step with an acceleration `a_meas` that does not contain the torque command
    /// (differentiation): returns the torque term \[pu\] to add to the torque reference.
    ///
    /// ```
    /// use controller_core::accel_feedback::AccelerationFeedback;
    /// use controller_core::filter::{LowPass, LowPassState};
    /// use controller_core::per_unit::{Gain, Pu};
    /// use controller_core::AfbMode;
    /// let afb = AccelerationFeedback { mode: AfbMode::Plain, ka: Gain::from_num(0.5),
    ///     filter: LowPass::None, limit: Pu::from_num(2), ka_closed: Gain::ZERO };
    /// let mut s = LowPassState::default();
    /// assert_eq!(afb.update(&mut s, Pu::from_num(1), Pu::ZERO), Pu::from_num(-0.5));
    /// ```
    #[inline]
    pub fn update(&self, s: &mut LowPassState, a_meas: PuPerS, a_cmd: PuPerS) -> Pu {
        let x = match self.mode {
            AfbMode::Off => return Pu::ZERO,
            AfbMode::Plain => a_meas.saturating_neg(),
            AfbMode::Error => a_cmd.saturating_sub(a_meas),
        };
        let filtered = self.filter.process(s, x);
        let lim = self.abs_limit();
        mul_gain(filtered, self.ka).max(-lim).min(lim)
    }

    /// One step in closed form with the observer's acceleration (module docs): `p` is the
    /// torque reference without the AFB term \[pu\], `predict(T)` the observer's â⁺ for a
    /// torque T \[pu/s\]. Returns the AFB term; T = clamp(p + afb).
    ///
    /// ```
    /// use controller_core::accel_feedback::AccelerationFeedback;
    /// use controller_core::filter::{LowPass, LowPassState};
    /// use controller_core::per_unit::{Gain, Pu};
    /// use controller_core::AfbMode;
    /// // Ka = J_model = 0.5, F = 1: g = 1/2, g·Ka = 0.25.
    /// let afb = AccelerationFeedback { mode: AfbMode::Plain, ka: Gain::from_num(0.5),
    ///     filter: LowPass::None, limit: Pu::from_num(2), ka_closed: Gain::from_num(0.25) };
    /// let mut s = LowPassState::default();
    /// let a = afb.update_closed(&mut s, Pu::from_num(1), Pu::ZERO, |t| t * 2);
    /// assert_eq!(a, Pu::from_num(-0.5)); // T = 0.5: â⁺ = 1 pu/s, −Ka·â⁺ = −0.5 ✓
    /// ```
    #[inline]
    pub fn update_closed(
        &self,
        s: &mut LowPassState,
        p: Pu,
        a_cmd: PuPerS,
        predict: impl Fn(Pu) -> PuPerS,
    ) -> Pu {
        let c = match self.mode {
            AfbMode::Off => return Pu::ZERO,
            AfbMode::Plain => PuPerS::ZERO,
            AfbMode::Error => a_cmd,
        };
        self.update_closed_from(s, p, c, predict)
    }

    /// [`AccelerationFeedback::update_closed`] with the form already resolved (`self.mode` is
    /// not read): `c` is the command part of the filter input x = c − â, 0 for the plain form
    /// and a_cmd for the error form. A controller picks it once from its settings.
    ///
    /// ```
    /// use controller_core::accel_feedback::AccelerationFeedback;
    /// use controller_core::filter::{LowPass, LowPassState};
    /// use controller_core::per_unit::{Gain, Pu};
    /// use controller_core::AfbMode;
    /// let afb = AccelerationFeedback { mode: AfbMode::Plain, ka: Gain::from_num(0.5),
    ///     filter: LowPass::None, limit: Pu::from_num(2), ka_closed: Gain::from_num(0.25) };
    /// let mut s = LowPassState::default();
    /// let a = afb.update_closed_from(&mut s, Pu::from_num(1), Pu::ZERO, |t| t * 2);
    /// assert_eq!(a, Pu::from_num(-0.5));
    /// ```
    #[inline(always)]
    pub fn update_closed_from(
        &self,
        s: &mut LowPassState,
        p: Pu,
        c: PuPerS,
        predict: impl Fn(Pu) -> PuPerS,
    ) -> Pu {
        self.update_closed_torque::<false>(s, p, c, predict, self.abs_limit())
            .0
    }

    /// |limit| from the raw bits: the same value as `Pu::saturating_abs`, in fewer
    /// instructions (a conditional saturating subtract).
    #[inline(always)]
    pub(crate) fn abs_limit(&self) -> Pu {
        Pu::from_bits(self.limit.to_bits().saturating_abs())
    }

    /// [`AccelerationFeedback::update_closed_from`], returning with the AFB term the torque
    /// T = clamp(p + afb, ±|limit|) the filter step was completed with; `lim` is
    /// [`AccelerationFeedback::abs_limit`], resolved by the caller (the controller, at
    /// configuration). With `HOLD` the filter keeps its state on a step whose torque is at
    /// the limit ([`crate::AfbFilterAtLimit::Hold`]).
    #[inline(always)]
    pub(crate) fn update_closed_torque<const HOLD: bool>(
        &self,
        s: &mut LowPassState,
        p: Pu,
        c: PuPerS,
        predict: impl Fn(Pu) -> PuPerS,
        lim: Pu,
    ) -> (Pu, Pu) {
        // One branch on the filter kind: inside each arm the kind is a constant, so the
        // filter's own dispatch in begin, add_feedthrough and finish folds away.
        match self.filter {
            f @ LowPass::None => self.closed_step::<HOLD>(f, s, p, c, predict, lim),
            f @ LowPass::FirstOrder { .. } => self.closed_step::<HOLD>(f, s, p, c, predict, lim),
            f @ LowPass::SecondOrder { .. } => self.closed_step::<HOLD>(f, s, p, c, predict, lim),
        }
    }

    /// The closed-form step for the filter `filter` (= `self.filter`).
    #[inline(always)]
    fn closed_step<const HOLD: bool>(
        &self,
        filter: LowPass,
        s: &mut LowPassState,
        p: Pu,
        c: PuPerS,
        predict: impl Fn(Pu) -> PuPerS,
        lim: Pu,
    ) -> (Pu, Pu) {
        // afb = g·Ka·(h + b0·x(P)): h and b0·x in Q.46 (Q16.16 · Q2.30), rounded to Q16.16,
        // times g·Ka (Q16.16).
        let (h46, _) = filter.begin(s);
        let x_p = c.saturating_sub(predict(p));
        let inner46 = filter.add_feedthrough(h46, x_p);
        let inner = Pu::from_bits(sat_round_shr::<30>(inner46));
        let afb = mul_gain(inner, self.ka_closed).max(-lim).min(lim);
        // Complete the filter step with the input for the torque actually applied, or,
        // with `HOLD`, leave the state as it was when that torque is at the limit (clamped,
        // or the AFB term itself at it).
        let t = p.saturating_add(afb).max(-lim).min(lim);
        if !HOLD || (t != lim && t != -lim) {
            filter.finish(s, h46, c.saturating_sub(predict(t)));
        }
        (afb, t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::per_unit::Coef;

    /// First-order filter (α = 0.25), g·Ka = 0.4, limit 1 pu; the tests' observer model
    /// predicts an acceleration of twice the torque.
    fn afb() -> AccelerationFeedback {
        let alpha = Coef::from_num(0.25);
        AccelerationFeedback {
            mode: AfbMode::Plain,
            ka: Gain::from_num(0.5),
            filter: LowPass::FirstOrder { alpha },
            limit: Pu::ONE,
            ka_closed: Gain::from_num(0.4),
        }
    }

    fn step(s: &mut LowPassState, p: f32, hold: bool) -> (Pu, Pu) {
        let (a, p) = (afb(), Pu::from_num(p));
        let predict = |t: Pu| t * 2;
        if hold {
            a.update_closed_torque::<true>(s, p, PuPerS::ZERO, predict, Pu::ONE)
        } else {
            a.update_closed_torque::<false>(s, p, PuPerS::ZERO, predict, Pu::ONE)
        }
    }

    #[test]
    fn a_held_filter_keeps_its_state_only_while_the_torque_is_clamped() {
        // Wind the filter up off the limit: the held and the tracking forms are one.
        let (mut held, mut tracked) = (LowPassState::default(), LowPassState::default());
        for p in [0.3, 0.5, -0.2, 0.4] {
            assert_eq!(step(&mut held, p, true), step(&mut tracked, p, false));
            assert_eq!(held, tracked);
        }
        assert_ne!(held, LowPassState::default());
        // At the limit (p far beyond it) the tracking filter moves on, the held one stays.
        let before = held;
        for _ in 0..3 {
            let (_, t_held) = step(&mut held, 5.0, true);
            let (_, t_tracked) = step(&mut tracked, 5.0, false);
            assert_eq!((t_held, t_tracked), (Pu::ONE, Pu::ONE));
        }
        assert_eq!(held, before);
        assert_ne!(tracked, before);
        // Back off the limit, the held filter resumes from the state it had entering it.
        let mut fresh = before;
        assert_eq!(step(&mut held, 0.1, true), step(&mut fresh, 0.1, false));
        assert_eq!(held, fresh);
    }

    /// One step of the linear form from the block's own filter state is its fixed-point
    /// step, closed form and measured acceleration, first order and biquad: the filter's
    /// part to (½ + α) LSB (first order: h from the state truncated to Q16.16) or 1 LSB
    /// (biquad: the residual), the inner value rounded (½ LSB), the product with the gain
    /// rounded (½ LSB).
    #[test]
    fn the_linear_step_is_the_fixed_point_step() {
        const LSB: f64 = 1.0 / 65536.0;
        let filters = [
            (
                LowPass::FirstOrder {
                    alpha: Coef::from_num(0.145),
                },
                0.5 + 0.145,
            ),
            (
                LowPass::SecondOrder {
                    b0: Coef::from_num(0.0048),
                    a1: Coef::from_num(-1.79),
                    a2: Coef::from_num(0.809),
                },
                1.0,
            ),
        ];
        let mut x = 0x2545_F491_4F6C_DD1Du64;
        let mut uniform = |span: f64| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            Pu::from_num(((x >> 11) as f64 / 2f64.powi(53) * 2.0 - 1.0) * span)
        };
        for (filter, filter_lsb) in filters {
            let a = AccelerationFeedback {
                mode: AfbMode::Error,
                ka: Gain::from_num(0.73),
                filter,
                limit: Pu::from_num(1000),
                ka_closed: Gain::from_num(0.41),
            };
            let lin = a.linear();
            let (mut closed, mut measured) = (LowPassState::default(), LowPassState::default());
            // The filter state as the linear form's ([`LowPassLinear`]).
            let as_linear = |s: &LowPassState| match filter {
                LowPass::FirstOrder { .. } => [s.y_q32 as f64 / 2f64.powi(32), 0.0, 0.0, 0.0],
                _ => [s.x[0], s.x[1], s.y[0], s.y[1]].map(|v| f64::from(v) * LSB),
            };
            let predict = |t: Pu| t * 2;
            for _ in 0..20_000 {
                let (p, a_cmd, a_meas) = (uniform(2.0), uniform(5.0), uniform(5.0));
                let f = |v: Pu| v.to_num::<f64>();
                // Closed form: ka_closed·(h + b0·x(P)).
                let (h, b0) = lin.filter.begin(&as_linear(&closed));
                let want = lin.ka_closed * (h + b0 * (f(a_cmd) - 2.0 * f(p)));
                let got = f(a.update_closed(&mut closed, p, a_cmd, predict));
                let tol = lin.ka_closed * (filter_lsb + 0.5) * LSB + 0.5 * LSB + 1e-12;
                assert!(
                    (got - want).abs() <= tol,
                    "closed {filter:?}: {got} vs {want}"
                );
                // Measured acceleration: ka·F(a_cmd − a_meas).
                let mut s = as_linear(&measured);
                let want = lin.ka * lin.filter.process(&mut s, f(a_cmd) - f(a_meas));
                let got = f(a.update(&mut measured, a_meas, a_cmd));
                let tol = lin.ka * filter_lsb * LSB + 0.5 * LSB + 1e-12;
                assert!(
                    (got - want).abs() <= tol,
                    "measured {filter:?}: {got} vs {want}"
                );
            }
        }
    }
}
