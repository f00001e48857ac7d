//! The position loop, the outer P of the paper's Fig. 5: its quantized coefficients (no
//! state: the position is the encoder's) and its step. Its linear form is its gains'
//! stored bits ([`super::Blocks`]: `k_pos`, `velocity_ff`).
//!
//! ```text
//! err   = θ_sp − θ                      (Q24.8 counts, saturating; trips above the limit)
//! ω_cmd = vff·ω_sp + k_pos·err          (position mode)
//! ω_cmd = ω_sp                          (velocity mode: position_bandwidth_rad_s = 0)
//! ```

use super::Setpoint;
use super::coefficients::MagnitudeLimit;
use crate::config::DriveConfig;
use crate::design::Gains;
use crate::error::ConfigError;
use crate::per_unit::{CountsErr, Gain, PosGain, Pu, mul_bits, mul_gain, sat_i32};
use crate::ranges as r;
use crate::validate::{Scales, fit, fit_setting};

/// The position loop's quantized coefficients.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct PositionLoop {
    /// The loop is on (`position_bandwidth_rad_s` > 0).
    pub(super) enabled: bool,
    /// k_pos \[pu per count\] (Q1.31; 0 with the loop off).
    pub(super) k_pos: PosGain,
    /// The velocity feed-forward gain vff (Q16.16).
    pub(super) velocity_ff: Gain,
    /// `velocity_ff` is exactly 1 (the default): ω_sp·1 rounded is ω_sp itself, so the tick
    /// skips the product.
    velocity_ff_unity: bool,
    /// |following error limit| as raw Q24.8 bits.
    following_error_abs: MagnitudeLimit,
}

impl PositionLoop {
    /// k_pos of `g`, quantized to Q1.31 (zero with the loop off); a gain that does not fit
    /// is reported as `position_bandwidth_rad_s` with its range given the encoder.
    pub(super) fn gain(g: &Gains) -> Result<PosGain, ConfigError> {
        let cfg = &g.cfg;
        if g.kpp <= 0.0 {
            return Ok(PosGain::ZERO);
        }
        fit(
            g.k_pos_pu_per_count,
            Scales {
                cap: (core::f32::consts::PI * cfg.velocity_rate_hz as f32).next_down(),
                range: &r::POSITION_BANDWIDTH_RAD_S,
                setting: cfg.position_bandwidth_rad_s,
                power: 1.0,
                given: "encoder_cpr and base_speed_rpm: k_pos = position_bandwidth_rad_s \
                        / counts per pu·s must fit Q1.31 within 1 %; 0 turns the position \
                        loop off",
            },
            |w| w / crate::per_unit::counts_per_pu_s(cfg.encoder_cpr, cfg.base_speed_rpm),
        )
    }

    /// vff (`velocity_ff_gain`) in Q16.16.
    pub(super) fn feed_forward(cfg: &DriveConfig) -> Result<Gain, ConfigError> {
        fit_setting(
            &r::VELOCITY_FF_GAIN,
            cfg.velocity_ff_gain,
            "its format Q16.16 (0, or within 1 %)",
        )
    }

    /// The loop of `g` from its quantized parts.
    pub(super) fn new(
        g: &Gains,
        k_pos: PosGain,
        velocity_ff: Gain,
        following_error_abs: MagnitudeLimit,
    ) -> Self {
        Self {
            enabled: g.kpp > 0.0,
            k_pos,
            velocity_ff,
            velocity_ff_unity: velocity_ff == Gain::ONE,
            following_error_abs,
        }
    }

    /// One velocity tick at the unwrapped `position`: the position error (Q24.8 counts,
    /// saturating), the velocity command, and whether the error is past the following
    /// error limit (the caller latches the fault).
    #[inline(always)]
    pub(super) fn command(&self, position: i64, sp: &Setpoint) -> (CountsErr, Pu, bool) {
        if !self.enabled {
            return (CountsErr::ZERO, sp.velocity_pu, false);
        }
        // Q48.16 ≫ 8 is below 2^55 in magnitude; while |position| < 2^54 counts (the bits
        // from 2^54 up all the sign: one high-word compare) position·256 is below 2^62 and
        // the difference below 2^63, so plain arithmetic gives the exact value the
        // saturating form gives.
        let sp_q8 = sp.position_counts.to_bits() >> 8;
        let err_bits = if position >> 54 == position >> 63 {
            sp_q8 - (position << 8)
        } else {
            sp_q8.saturating_sub(position.saturating_mul(256))
        };
        let err = CountsErr::from_bits(sat_i32(err_bits));
        let tripped = self.following_error_abs.exceeded_by(err.to_bits());
        // Q24.8 · Q1.31 = Q.39 → Q16.16.
        let p_term = Pu::from_bits(mul_bits::<23>(err.to_bits(), self.k_pos.to_bits()));
        let ff = if self.velocity_ff_unity {
            sp.velocity_pu
        } else {
            mul_gain(sp.velocity_pu, self.velocity_ff)
        };
        (err, ff.saturating_add(p_term), tripped)
    }
}
