//! The velocity loop of the paper's Fig. 5: the feedback filter and the velocity PI with the
//! acceleration feed-forward, their quantized coefficients, their state and their step.
//!
//! ```text
//! ω_fb  = F(ω_raw)                                   (velocity-feedback low-pass)
//! i_vel = PI(ω_cmd − ω_fb) + k_aff·a_sp              (±torque_limit, anti-windup judged
//!                                                     on i_vel + the AFB term held now)
//! ```

use crate::config::{AfbMode, DriveConfig};
use crate::design::Gains;
use crate::error::ConfigError;
use crate::filter::{LowPass, LowPassState};
use crate::per_unit::{Gain, Pu, PuPerS, mul_gain};
use crate::pi::{PiCoefficients, PiState};
use crate::ranges as r;
use crate::validate::{Scales, fit};

/// The velocity loop's quantized coefficients.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct VelocityLoop {
    /// The velocity PI (limit: the torque limit).
    pub(super) regulator: PiCoefficients,
    /// The velocity-feedback filter.
    pub(super) filter: LowPass,
    /// The acceleration feed-forward \[pu torque per pu/s\].
    pub(super) k_accel_ff: Gain,
    /// |limit| of the regulator (raw, saturating), resolved once.
    limit_abs: i32,
    /// The regulator's headroom beyond the limit while saturated (raw Q16.16;
    /// `accel_feedback.limit_headroom_fraction` × the torque limit, 0 without AFB).
    headroom: i32,
}

/// The velocity loop's state.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct VelocityState {
    /// The PI's integrator.
    pub(super) regulator: PiState,
    /// The feedback filter's state.
    pub(super) filter: LowPassState,
}

impl VelocityLoop {
    /// k_aff = `accel_ff_gain` × the inertia the commanded acceleration meets, in Q16.16.
    pub(super) fn accel_ff(g: &Gains) -> Result<Gain, ConfigError> {
        let cfg = &g.cfg;
        fit(
            g.k_accel_ff,
            Scales {
                cap: f32::INFINITY,
                range: &r::ACCEL_FF_GAIN,
                setting: cfg.accel_ff_gain,
                power: 1.0,
                given: "motor_inertia_s + load_inertia_s (plus Ka in the plain form): \
                        accel_ff_gain × inertia must fit Q16.16 within 1 %; 0 turns it off",
            },
            |a| {
                a * match cfg.accel_feedback.mode {
                    AfbMode::Plain => g.j_total_s + g.ka,
                    AfbMode::Off | AfbMode::Error => g.j_total_s,
                }
            },
        )
    }

    /// The regulator's headroom beyond the torque limit (raw Q16.16): the fraction of the
    /// limit `accel_feedback.limit_headroom_fraction`, with AFB on; 0 with it off, where no
    /// term follows the regulator.
    pub(super) fn headroom(cfg: &DriveConfig) -> Result<i32, ConfigError> {
        if cfg.accel_feedback.mode == AfbMode::Off {
            return Ok(0);
        }
        let f = cfg.accel_feedback.limit_headroom_fraction;
        Ok(fit::<Pu>(
            f * cfg.torque_limit_pu,
            Scales {
                cap: f32::INFINITY,
                range: &r::AFB_LIMIT_HEADROOM_FRACTION,
                setting: f,
                power: 1.0,
                given: "torque_limit_pu: the headroom (fraction × torque_limit_pu) must fit \
                        Q16.16 within 1 %; 0 for none",
            },
            |f| f * cfg.torque_limit_pu,
        )?
        .to_bits())
    }

    /// The loop from its quantized parts.
    pub(super) fn new(
        regulator: PiCoefficients,
        filter: LowPass,
        k_accel_ff: Gain,
        headroom: i32,
    ) -> Self {
        Self {
            regulator,
            filter,
            k_accel_ff,
            limit_abs: regulator.abs_limit(),
            headroom,
        }
    }

    /// The filtered velocity feedback of this tick.
    #[inline(always)]
    pub(super) fn feedback(&self, st: &mut VelocityState, raw: Pu) -> Pu {
        self.filter.process(&mut st.filter, raw)
    }

    /// The torque reference of this tick: the PI on the speed error `e` plus the
    /// acceleration feed-forward of `accel_sp`, its anti-windup judged on the sum with the
    /// AFB term `afb` held now.
    #[inline(always)]
    pub(super) fn regulate(&self, st: &mut VelocityState, e: Pu, accel_sp: PuPerS, afb: Pu) -> Pu {
        let ff = mul_gain(accel_sp, self.k_accel_ff);
        self.regulator.update_with_offset_within(
            &mut st.regulator,
            e,
            ff,
            afb,
            [self.limit_abs, self.headroom],
        )
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use crate::controller::{Controller, Setpoint, VelocityInputs};
    use crate::{DriveConfig, PuPerS};

    /// At rest with no speed error, the first velocity tick's torque reference is the
    /// acceleration feed-forward alone: accel_ff_gain × J_total × a_sp.
    #[test]
    fn the_acceleration_feed_forward_is_the_inertia_times_the_commanded_acceleration() {
        let mut cfg: DriveConfig = toml::from_str(include_str!(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/doc/example-drive.toml"
        )))
        .unwrap();
        for (gain, a) in [(1.0_f32, 0.5_f64), (0.5, -0.8)] {
            cfg.accel_ff_gain = gain;
            let mut c = Controller::new(&cfg).unwrap();
            let out = c.velocity_tick(VelocityInputs {
                encoder_count: 0,
                setpoint: Setpoint {
                    acceleration_pu_s: PuPerS::from_num(a),
                    ..Setpoint::default()
                },
                fault_input: false,
            });
            let want = f64::from(gain * cfg.total_inertia_s()) * a;
            let got = out.current_ref_pu.to_num::<f64>();
            assert!(
                (got - want).abs() < 1e-3,
                "{gain} {a}: {got} against {want}"
            );
        }
    }
}
