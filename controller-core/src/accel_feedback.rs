//! Acceleration feedback ("inertia stabilization", paper Fig. 5 and 7).
//!
//! ```text
//! Plain:  afb = −Ka·LPF(a_meas)
//! Error:  afb = +Ka·LPF(a_cmd − a_meas)      (Rockwell US 7,141,946)
//! ```
//! `afb` \[pu torque\] is added to the torque reference and clamped to ±torque limit.
//! Ka \[s\] is Q16.16, the filter Q2.30 (see [`crate::filter`]).

use crate::config::AfbMode;
use crate::filter::{LowPass, LowPassState};
use crate::per_unit::{mul_gain, Gain, Pu, PuPerS};

/// Acceleration feedback coefficients.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AccelerationFeedback {
    /// Form of the feedback.
    pub mode: AfbMode,
    /// Ka \[pu torque per pu/s\].
    pub ka: Gain,
    /// Low-pass filter on the acceleration or acceleration error.
    pub filter: LowPass,
    /// Output limit \[pu torque\].
    pub limit: Pu,
}

impl AccelerationFeedback {
    /// One step: returns the torque term \[pu\] to add to the torque reference.
    ///
    /// ```
    /// use controller_core::accel_feedback::AccelerationFeedback;
    /// use controller_core::filter::{LowPass, LowPassState};
    /// use controller_core::per_unit::{Gain, Pu};
    /// use controller_core::AfbMode;
    /// let afb = AccelerationFeedback { mode: AfbMode::Plain, ka: Gain::from_num(0.5),
    ///     filter: LowPass::None, limit: Pu::from_num(2) };
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
        let lim = self.limit.saturating_abs();
        mul_gain(filtered, self.ka).max(-lim).min(lim)
    }
}
