//! The acceleration-feedback step of a tick: measured (differentiation) or closed form
//! through the observer's model ([`crate::accel_feedback`]).

use super::Controller;
use super::coefficients::AfbStep;
use crate::per_unit::{Pu, PuPerS};

impl Controller {
    /// Acceleration-feedback step with a measured acceleration (differentiation).
    #[inline]
    pub(super) fn afb_step(&mut self, a_meas: PuPerS) {
        if self.state.fault.is_none() {
            let a_cmd = self.state.accel_cmd;
            self.state.afb = self
                .coef
                .afb
                .update(&mut self.state.afb_filter, a_meas, a_cmd);
        }
    }

    /// Acceleration-feedback step with the observer's acceleration, the loop through its
    /// model solved in closed form for the torque reference `i_vel` + afb; `c` is the
    /// command part of the filter input (0 in the plain form, a_cmd in the error form).
    /// Returns the clamped torque the step completed its filter with (`None` when faulted:
    /// the step did not run).
    #[inline(always)]
    pub(super) fn afb_closed_step<const HOLD: bool>(&mut self, c: PuPerS) -> Option<Pu> {
        if self.state.fault.is_none() {
            let obs = &self.coef.observer;
            let os = &self.state.observer;
            let base = self.state.i_vel.saturating_add(self.torque_excitation());
            let (afb, t) = self.coef.afb.update_closed_torque::<HOLD>(
                &mut self.state.afb_filter,
                base,
                c,
                |t| obs.predicted_acceleration_pu_s(os, t),
                self.coef.afb_limit_abs,
            );
            self.state.afb = afb;
            Some(t)
        } else {
            None
        }
    }

    /// The AFB step `step` of a tick; `a_meas` is that tick's differentiated acceleration
    /// (used by [`AfbStep::Measured`] only).
    /// The closed form (the default) is inlined into the tick once, for both forms; the
    /// measured step runs out of line. Returns the closed-form step's clamped torque (`None`
    /// for the other steps, or when faulted).
    #[inline(always)]
    pub(super) fn run_afb(
        &mut self,
        step: AfbStep,
        a_meas: impl FnOnce(&mut Self) -> PuPerS,
    ) -> Option<Pu> {
        match step {
            AfbStep::None => None,
            AfbStep::Measured => {
                self.afb_measured_step(a_meas);
                None
            }
            AfbStep::ClosedPlain | AfbStep::ClosedError => {
                self.afb_closed_step::<false>(self.filter_command(step == AfbStep::ClosedError))
            }
            AfbStep::ClosedPlainHold | AfbStep::ClosedErrorHold => self.afb_hold_step(step),
        }
    }

    /// [`AfbStep::ClosedPlainHold`] and [`AfbStep::ClosedErrorHold`]: the closed form with
    /// the filter held while the torque is at the limit. Out of line and marked cold so that the
    /// tracking form (the default, the baked drive's) keeps its place in the tick: inlined,
    /// a run-time hold flag cost the baked drive's period 12 instructions (`cargo fw-bench`),
    /// out of line 4 to 8.
    #[cold]
    #[inline(never)]
    pub(super) fn afb_hold_step(&mut self, step: AfbStep) -> Option<Pu> {
        self.afb_closed_step::<true>(self.filter_command(step == AfbStep::ClosedErrorHold))
    }

    /// The command part c of the closed-form filter input x = c − â: a_cmd in the error
    /// form, 0 in the plain form.
    #[inline(always)]
    fn filter_command(&self, error_form: bool) -> PuPerS {
        if error_form {
            self.state.accel_cmd
        } else {
            PuPerS::ZERO
        }
    }

    /// [`AfbStep::Measured`]: differentiate (`a_meas`), then the plain AFB update.
    #[inline(never)]
    pub(super) fn afb_measured_step(&mut self, a_meas: impl FnOnce(&mut Self) -> PuPerS) {
        let a = a_meas(self);
        self.afb_step(a);
    }
}
