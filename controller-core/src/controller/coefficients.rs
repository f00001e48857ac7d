//! The quantized coefficients of a [`super::Controller`], built once from [`Gains`] (and the
//! validated settings they carry). Each coefficient is quantized with
//! [`quantize`], whose error names the Q-format of the coefficient's own type.

use crate::accel_feedback::AccelerationFeedback;
use crate::config::{AfbFilterAtLimit, AfbMode, AfbRate, DriveConfig, Estimator, ObserverTorque};
use crate::design::Gains;
use crate::differentiator::Differentiator;
use crate::error::ConfigError;
use crate::filter::LowPass;
use crate::notch::Notch;
use crate::observer::{CountInterval, Observer};
use crate::per_unit::{Coef, CountsErr, Gain, PosGain, Pu, TickGain, counter_shift, quantize};
use crate::pi::PiCoefficients;
use crate::protection::Protection;

/// A limit L on the magnitude of a raw 32-bit value, |x| > L tested with one add and one
/// unsigned compare: for L < 2^31, x + L (mod 2^32) is within [0, 2L] exactly when
/// −L ≤ x ≤ L (x > L gives 2L < x + L < 2^32 − 1, no wrap; x < −L wraps to
/// x + L + 2^32 ≥ 2^31 + L > 2L). The limits held here are the magnitudes of validated,
/// non-negative settings quantized to i32 bits (`ranges`: at most 2.048·10^9 < 2^31), so L
/// is below 2^31; a larger one is held as 2^31 − 1, which gives the same answer for every
/// x but i32::MIN.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct MagnitudeLimit(u32);

impl MagnitudeLimit {
    /// The limit |x| ≤ `abs` (`abs` < 2^31, see the type).
    pub(super) const fn new(abs: u32) -> Self {
        Self(if abs < 1 << 31 { abs } else { (1 << 31) - 1 })
    }

    /// `x.unsigned_abs() > abs`, bit for bit (for `abs` < 2^31).
    #[inline(always)]
    pub(super) const fn exceeded_by(self, x: i32) -> bool {
        x.cast_unsigned().wrapping_add(self.0) > self.0 << 1
    }
}

/// Quantized coefficients (fixed point), built once from [`Gains`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Coefficients {
    pub(super) counter_bits: u8,
    /// [`counter_shift`] of `counter_bits`, for the per-tick wrap-safe difference.
    pub(super) counter_shift: u32,
    pub(super) position_loop: bool,
    pub(super) k_pos: PosGain,
    pub(super) velocity_ff: Gain,
    /// `velocity_ff` is exactly 1 (the default): ω_sp·1 rounded is ω_sp itself, so the tick
    /// skips the product.
    pub(super) velocity_ff_unity: bool,
    pub(super) k_accel_ff: Gain,
    pub(super) velocity_regulator: PiCoefficients,
    pub(super) current_regulator: PiCoefficients,
    pub(super) velocity_filter: LowPass,
    pub(super) diff_velocity_rate: Differentiator,
    pub(super) diff_current_rate: Differentiator,
    pub(super) observer: Observer,
    pub(super) afb: AccelerationFeedback,
    pub(super) afb_source: Estimator,
    pub(super) velocity_source: Estimator,
    pub(super) observer_torque: ObserverTorque,
    /// The AFB step of the current tick (none unless the mode is on at rate Current).
    pub(super) afb_current: AfbStep,
    /// The AFB step of the velocity tick (none unless the mode is on at rate Velocity).
    pub(super) afb_velocity: AfbStep,
    /// The velocity-rate differentiator is used (velocity or acceleration source).
    pub(super) diff_in_velocity_tick: bool,
    pub(super) torque_limit: Pu,
    /// |limit| of the AFB, the current and the velocity regulator (raw, saturating),
    /// resolved here so the ticks do not take it again.
    pub(super) afb_limit_abs: Pu,
    pub(super) current_limit_abs: i32,
    pub(super) velocity_limit_abs: i32,
    /// The velocity regulator's headroom beyond the limit while saturated (raw Q16.16;
    /// `accel_feedback.limit_headroom_fraction` × the torque limit, 0 without AFB).
    pub(super) velocity_headroom: i32,
    /// |overspeed| as raw Q16.16 bits (the tick compares magnitudes).
    pub(super) overspeed_abs: MagnitudeLimit,
    /// |following error limit| as raw Q24.8 bits.
    pub(super) following_error_abs: MagnitudeLimit,
    /// |largest encoder step per tick| \[counts\].
    pub(super) max_count_step_abs: MagnitudeLimit,
    /// Overcurrent, I²t and stall ([`crate::protection`]).
    pub(super) protection: Protection,
    /// The torque-reference notch (Q2.30), `None` without one: the current tick then has
    /// no notch step at all.
    pub(super) notch: Option<Notch>,
}

/// Which acceleration-feedback step a tick runs: source and form resolved once, when the
/// coefficients are built, so the tick makes one branch instead of testing the mode, the
/// rate and the source every time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum AfbStep {
    /// No AFB in this tick.
    None,
    /// `AccelerationFeedback::update` on the differentiated acceleration.
    Measured,
    /// The closed form on the observer, plain form (filter input −â).
    ClosedPlain,
    /// The closed form on the observer, error form (filter input a_cmd − â).
    ClosedError,
    /// [`AfbStep::ClosedPlain`] with the filter held while the torque is at the limit
    /// (`accel_feedback.filter_at_limit = "hold"`).
    ClosedPlainHold,
    /// [`AfbStep::ClosedError`] with the filter held while the torque is at the limit.
    ClosedErrorHold,
}

impl AfbStep {
    fn select(cfg: &DriveConfig, rate: AfbRate) -> Self {
        let afb = &cfg.accel_feedback;
        if afb.rate != rate {
            return Self::None;
        }
        let hold = afb.filter_at_limit == AfbFilterAtLimit::Hold;
        match (afb.mode, afb.source, hold) {
            (AfbMode::Off, _, _) => Self::None,
            (_, Estimator::Differentiation, _) => Self::Measured,
            (AfbMode::Plain, Estimator::Observer, false) => Self::ClosedPlain,
            (AfbMode::Error, Estimator::Observer, false) => Self::ClosedError,
            (AfbMode::Plain, Estimator::Observer, true) => Self::ClosedPlainHold,
            (AfbMode::Error, Estimator::Observer, true) => Self::ClosedErrorHold,
        }
    }
}

/// The acceleration-feedback block with torque limit `lim`.
fn accel_feedback(g: &Gains, lim: Pu) -> Result<AccelerationFeedback, ConfigError> {
    let cfg = &g.cfg;
    let filter = LowPass::quantize(&g.afb_filter, "accel_feedback.filter coefficients")?;
    // Closed form of the loop through the observer's model (accel_feedback module docs):
    // g·Ka with g = 1/(1 + b0·Ka/J_model); b0 from the quantized filter, so that the
    // solved loop is the one the tick runs.
    let ka_closed = if cfg.accel_feedback.source == Estimator::Observer {
        let b0: f32 = filter.feedthrough().to_num();
        let gain = 1.0 / (1.0 + b0 * g.ka / g.observer_inertia_s);
        quantize::<Gain>(
            g.ka * gain,
            "ka/(1 + b0·Ka/J_model) (accel_feedback.gain_fraction, filter, observer inertia)",
        )?
    } else {
        Gain::ZERO
    };
    Ok(AccelerationFeedback {
        mode: cfg.accel_feedback.mode,
        ka: quantize(g.ka, "ka (accel_feedback.gain_fraction × total inertia)")?,
        filter,
        limit: lim,
        ka_closed,
    })
}

/// The state observer.
fn observer(g: &Gains) -> Result<Observer, ConfigError> {
    let [l1, l2, l3] = g.observer_l;
    Ok(Observer {
        l1: quantize::<Coef>(l1, "observer l1 (observer.bandwidth_hz)")?,
        l2: quantize::<Coef>(l2, "observer l2 (observer.bandwidth_hz)")?,
        l3: quantize::<Coef>(l3, "observer l3 (observer.bandwidth_hz)")?,
        k_u: quantize(
            g.observer_k_u,
            "observer k_u (inertia, encoder_cpr, current_rate_hz)",
        )?,
        k_vel: quantize(
            g.cur_tick_pu_per_count,
            "pu per count per current tick (encoder_cpr, base_speed_rpm, current_rate_hz)",
        )?,
        k_acc: quantize(
            g.cur_tick_pu_s_per_count,
            "pu/s per count per current tick² (encoder_cpr, base_speed_rpm, current_rate_hz)",
        )?,
        k_load: quantize(-g.observer_inertia_s, "observer model inertia")?,
        count_interval: CountInterval::of(quantize(
            g.cfg.observer.count_interval_counts,
            "observer.count_interval_counts",
        )?),
    })
}

/// A differentiator with velocity scale `v` and acceleration scale `a`.
fn differentiator(
    v: f32,
    a: f32,
    pv: &'static str,
    pa: &'static str,
) -> Result<Differentiator, ConfigError> {
    Ok(Differentiator {
        k_vel: quantize(v, pv)?,
        k_acc: quantize(a, pa)?,
    })
}

/// The velocity and current PI regulators (torque limit `lim`, voltage limit `vlim`).
fn regulators(
    g: &Gains,
    lim: Pu,
    vlim: Pu,
) -> Result<(PiCoefficients, PiCoefficients), ConfigError> {
    let cfg = &g.cfg;
    let velocity = PiCoefficients {
        kp: quantize(g.kp_vel, "kp_vel (velocity_bandwidth_rad_s × inertia)")?,
        ki_ts: quantize::<TickGain>(
            g.ki_vel / cfg.velocity_rate_hz as f32,
            "ki_vel·Ts (velocity_bandwidth_rad_s, velocity_damping)",
        )?,
        limit: lim,
    };
    let current = PiCoefficients {
        kp: quantize(
            g.kp_cur,
            "kp_cur (winding_inductance_pu_s × current_bandwidth_rad_s)",
        )?,
        ki_ts: quantize::<TickGain>(
            g.ki_cur / cfg.current_rate_hz as f32,
            "ki_cur·Ts (winding_resistance_pu × current_bandwidth_rad_s)",
        )?,
        limit: vlim,
    };
    Ok((velocity, current))
}

/// The differentiators at the velocity and at the current rate.
fn differentiators(g: &Gains) -> Result<[Differentiator; 2], ConfigError> {
    Ok([
        differentiator(
            g.vel_tick_pu_per_count,
            g.vel_tick_pu_s_per_count,
            "pu per count per velocity tick (encoder_cpr, base_speed_rpm, velocity_rate_hz)",
            "pu/s per count per velocity tick² (encoder_cpr, base_speed_rpm, velocity_rate_hz)",
        )?,
        differentiator(
            g.cur_tick_pu_per_count,
            g.cur_tick_pu_s_per_count,
            "pu per count per current tick (encoder_cpr, base_speed_rpm, current_rate_hz)",
            "pu/s per count per current tick² (encoder_cpr, base_speed_rpm, current_rate_hz)",
        )?,
    ])
}

/// The fault limits as raw magnitudes: overspeed, following error, encoder jump.
fn fault_limits(g: &Gains) -> Result<[MagnitudeLimit; 3], ConfigError> {
    let cfg = &g.cfg;
    Ok([
        MagnitudeLimit::new(
            quantize::<Pu>(cfg.faults.overspeed_pu, "faults.overspeed_pu")?
                .to_bits()
                .unsigned_abs(),
        ),
        MagnitudeLimit::new(
            quantize::<CountsErr>(
                cfg.faults.following_error_counts,
                "faults.following_error_counts",
            )?
            .to_bits()
            .unsigned_abs(),
        ),
        MagnitudeLimit::new(
            quantize::<CountsErr>(
                g.max_count_step,
                "max count step (faults.encoder_jump_margin × overspeed)",
            )?
            .to_num::<i32>()
            .unsigned_abs(),
        ),
    ])
}

/// The velocity regulator's headroom beyond the torque limit (raw Q16.16): the fraction of
/// the limit `accel_feedback.limit_headroom_fraction`, with AFB on; 0 with it off, where no
/// term follows the regulator.
fn velocity_headroom(cfg: &DriveConfig) -> Result<i32, ConfigError> {
    if cfg.accel_feedback.mode == AfbMode::Off {
        return Ok(0);
    }
    let h = cfg.accel_feedback.limit_headroom_fraction * cfg.torque_limit_pu;
    Ok(quantize::<Pu>(
        h,
        "accel_feedback.limit_headroom_fraction × torque_limit_pu",
    )?
    .to_bits())
}

impl Coefficients {
    /// Quantize `g` (designed from, and carrying, validated settings).
    pub(super) fn from_gains(g: &Gains) -> Result<Self, ConfigError> {
        let cfg = &g.cfg;
        let lim: Pu = quantize(cfg.torque_limit_pu, "torque_limit_pu")?;
        let vlim: Pu = quantize(cfg.voltage_limit_pu, "voltage_limit_pu")?;
        // Quantized in the order of the error precedence: AFB, observer, position, regulators,
        // notch.
        let afb = accel_feedback(g, lim)?;
        let observer = observer(g)?;
        let k_pos = if g.kpp > 0.0 {
            quantize(
                g.k_pos_pu_per_count,
                "k_pos (position_bandwidth_rad_s / counts per pu·s)",
            )?
        } else {
            PosGain::ZERO
        };
        let velocity_ff = quantize(cfg.velocity_ff_gain, "velocity_ff_gain")?;
        let k_accel_ff = quantize(g.k_accel_ff, "k_accel_ff (accel_ff_gain × inertia)")?;
        let (velocity_regulator, current_regulator) = regulators(g, lim, vlim)?;
        let notch = match &g.notch {
            Some(d) => Some(Notch::quantize(
                d,
                "notch coefficients (notch.centre_hz, notch.width_hz, notch.depth_db)",
            )?),
            None => None,
        };
        // Then the velocity filter, the differentiators and the fault limits.
        let velocity_filter =
            LowPass::quantize(&g.velocity_filter, "velocity_filter coefficients")?;
        let [diff_velocity_rate, diff_current_rate] = differentiators(g)?;
        let [overspeed_abs, following_error_abs, max_count_step_abs] = fault_limits(g)?;
        let protection = Protection::new(cfg)?;
        Ok(Self {
            counter_bits: cfg.counter_bits,
            counter_shift: counter_shift(cfg.counter_bits),
            position_loop: g.kpp > 0.0,
            k_pos,
            velocity_ff,
            velocity_ff_unity: velocity_ff == Gain::ONE,
            k_accel_ff,
            velocity_regulator,
            current_regulator,
            velocity_filter,
            diff_velocity_rate,
            diff_current_rate,
            observer,
            afb,
            afb_source: cfg.accel_feedback.source,
            velocity_source: cfg.velocity_estimator,
            observer_torque: cfg.observer.torque_input,
            afb_current: AfbStep::select(cfg, AfbRate::Current),
            afb_velocity: AfbStep::select(cfg, AfbRate::Velocity),
            diff_in_velocity_tick: cfg.velocity_estimator == Estimator::Differentiation
                || cfg.accel_feedback.source == Estimator::Differentiation,
            torque_limit: lim,
            afb_limit_abs: afb.abs_limit(),
            current_limit_abs: current_regulator.abs_limit(),
            velocity_limit_abs: velocity_regulator.abs_limit(),
            velocity_headroom: velocity_headroom(cfg)?,
            overspeed_abs,
            following_error_abs,
            max_count_step_abs,
            protection,
            notch,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::MagnitudeLimit;

    /// The one-compare magnitude test is `unsigned_abs() > abs` at and around every edge.
    #[test]
    fn magnitude_limit_is_the_abs_compare() {
        let edges = [
            0u32,
            1,
            2,
            3,
            1000,
            (1 << 30) - 1,
            1 << 30,
            (1 << 31) - 2,
            (1 << 31) - 1,
        ];
        for &abs in &edges {
            let lim = MagnitudeLimit::new(abs);
            let mut xs = vec![i32::MIN, i32::MIN + 1, i32::MAX, i32::MAX - 1, 0];
            for &e in &edges {
                for d in [-1i64, 0, 1] {
                    for sign in [-1i64, 1] {
                        let x = sign * (i64::from(e) + d);
                        if let Ok(x) = i32::try_from(x) {
                            xs.push(x);
                        }
                    }
                }
            }
            for d in -2i64..=2 {
                for sign in [-1i64, 1] {
                    if let Ok(x) = i32::try_from(sign * (i64::from(abs) + d)) {
                        xs.push(x);
                    }
                }
            }
            for x in xs {
                assert_eq!(lim.exceeded_by(x), x.unsigned_abs() > abs, "{abs} {x}");
            }
        }
        let mut seed = 1u32;
        for _ in 0..200_000 {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            let abs = seed >> (1 + seed % 31);
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            let x = seed.cast_signed() >> (seed % 32);
            assert_eq!(
                MagnitudeLimit::new(abs).exceeded_by(x),
                x.unsigned_abs() > abs,
                "{abs} {x}"
            );
        }
    }
}
