//! The identification excitation's entry into the ticks ([`crate::excitation`]).

use super::{Controller, ExcitationState};
use crate::error::ConfigError;
use crate::excitation::{Excitation, ExcitationConfig, ExcitationParams, Injection};
use crate::per_unit::Pu;

impl Controller {
    /// The same controller with an excitation for measuring the machine (a chirp or a
    /// PRBS, [`crate::excitation`]): on the torque reference it is designed at the current
    /// rate and added to the torque reference every current tick before the clamp; on the
    /// velocity reference it is designed at the velocity rate and added to ω_cmd every
    /// velocity tick. It starts with the next tick, ends after its length (zero from then
    /// on), restarts with [`Controller::reset`] and is zero while a fault is latched.
    /// `names` are the settings' paths for the errors.
    ///
    /// ```
    /// use controller_core::excitation::*;
    /// # let cfg: controller_core::DriveConfig = toml::from_str(include_str!(concat!(
    /// #     env!("CARGO_MANIFEST_DIR"), "/doc/example-drive.toml"))).unwrap();
    /// let e = ExcitationConfig {
    ///     waveform: Waveform::Prbs { bits: 7, hold_ticks: 1, periods: 1 },
    ///     amplitude_pu: 0.1,
    ///     injection: Injection::TorqueReference,
    /// };
    /// let names = ExcitationParams {
    ///     amplitude_pu: "a", start_or_bits: "b", end_or_hold: "h", duration_or_periods: "p",
    /// };
    /// let mut c = controller_core::Controller::new(&cfg).unwrap().with_excitation(&e, names)?;
    /// let out = c.current_tick(controller_core::CurrentInputs::default());
    /// // The first PRBS bit is +amplitude; it reaches the torque reference at once.
    /// assert_eq!(c.excitation_pu(), controller_core::Pu::from_num(0.1));
    /// assert!(out.current_ref_pu > controller_core::Pu::ZERO);
    /// # Ok::<(), controller_core::ConfigError>(())
    /// ```
    pub fn with_excitation(
        mut self,
        cfg: &ExcitationConfig,
        names: ExcitationParams,
    ) -> Result<Self, ConfigError> {
        let c = &self.gains.cfg;
        let rate_hz = match cfg.injection {
            Injection::TorqueReference => c.current_rate_hz,
            Injection::VelocityReference => c.velocity_rate_hz,
        };
        self.excitation = Some(Excitation::new(cfg, rate_hz as f32, names)?);
        self.torque_excited = cfg.injection == Injection::TorqueReference;
        self.velocity_excited = cfg.injection == Injection::VelocityReference;
        self.closed_total = Self::closed_total_exact(&self.coef, self.torque_excited);
        self.state.excitation = ExcitationState::default();
        self.state.excitation_pu = Pu::ZERO;
        Ok(self)
    }

    /// The excitation's latest sample \[pu of torque or speed\]: what the last tick at its
    /// injection point added (zero without an excitation, after it ended, or when faulted).
    #[must_use]
    pub fn excitation_pu(&self) -> Pu {
        self.state.excitation_pu
    }

    /// The next excitation sample if the excitation enters at `at` (and no fault is
    /// latched), recorded as the latest; zero otherwise.
    #[inline(always)]
    pub(super) fn excite(&mut self, at: Injection) -> Pu {
        let here = match at {
            Injection::TorqueReference => self.torque_excited,
            Injection::VelocityReference => self.velocity_excited,
        };
        if !here {
            return Pu::ZERO;
        }
        match self.excitation {
            Some(e) => {
                let v = if self.state.fault.is_none() {
                    e.next(&mut self.state.excitation)
                } else {
                    Pu::ZERO
                };
                self.state.excitation_pu = v;
                v
            }
            None => Pu::ZERO,
        }
    }

    /// The torque-reference excitation of this current tick (zero unless it enters there).
    #[inline(always)]
    pub(super) fn torque_excitation(&self) -> Pu {
        if self.torque_excited {
            self.state.excitation_pu
        } else {
            Pu::ZERO
        }
    }
}
