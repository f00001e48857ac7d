//! The quantized coefficients of a [`super::Controller`], built once from [`Gains`] (and the
//! validated settings they carry). Each coefficient is quantized with
//! [`crate::validate::fit`]: a value that does not fit its format is reported as the user's
//! setting it scales with, and the range of that setting that fits given the others
//! ([`ConfigError::OutOfRangeGiven`]). The count scales and limits derived from the encoder
//! are bounded by [`DriveConfig::validate`] already (`encoder_cpr`'s range).

use super::current::DcCurrentLoop;
use super::position::PositionLoop;
use super::velocity::VelocityLoop;
use crate::accel_feedback::AccelerationFeedback;
use crate::config::{AfbFilterAtLimit, AfbMode, AfbRate, DriveConfig, Estimator, ObserverTorque};
use crate::design::Gains;
use crate::differentiator::Differentiator;
use crate::error::ConfigError;
use crate::filter::LowPass;
use crate::notch::Notch;
use crate::observer::{CountInterval, Observer};
use crate::per_unit::{Coef, CountsErr, Gain, Pu, TickGain, counter_shift, quantize};
use crate::pi::PiCoefficients;
use crate::protection::Protection;
use crate::ranges as r;
use crate::validate::{
    Scales, VELOCITY_GIVEN, encoder_cpr_error, fit, fit_setting, smallest_fitting,
};

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
    /// The position loop ([`super::position`]).
    pub(super) position: PositionLoop,
    /// The velocity loop ([`super::velocity`]).
    pub(super) velocity: VelocityLoop,
    /// The DC current loop ([`super::current`]).
    pub(super) current: DcCurrentLoop,
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
    /// |limit| of the AFB (raw, saturating), resolved here so the ticks do not take it
    /// again.
    pub(super) afb_limit_abs: Pu,
    /// |overspeed| as raw Q16.16 bits (the tick compares magnitudes).
    pub(super) overspeed_abs: MagnitudeLimit,
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
    let key = r::AFB_GAIN_FRACTION.key;
    let filter = LowPass::quantize(&g.afb_filter, r::AFB_FILTER_CORNER_HZ.key)?;
    // Closed form of the loop through the observer's model (accel_feedback module docs):
    // g·Ka with g = 1/(1 + b0·Ka/J_model); b0 from the quantized filter, so that the
    // solved loop is the one the tick runs. Both Ka and the closed form's gain come from the
    // gain fraction, so either not fitting states the range that fits both.
    let b0 = (cfg.accel_feedback.source == Estimator::Observer)
        .then(|| filter.feedthrough().to_num::<f32>());
    let ka = quantize::<Gain>(g.ka, key).map_err(|_| gain_fraction_error(g, b0))?;
    let ka_closed = match b0 {
        Some(b0) => {
            let gain = 1.0 / (1.0 + b0 * g.ka / g.observer_inertia_s);
            quantize::<Gain>(g.ka * gain, key).map_err(|_| gain_fraction_error(g, Some(b0)))?
        }
        None => Gain::ZERO,
    };
    Ok(AccelerationFeedback {
        mode: cfg.accel_feedback.mode,
        ka,
        filter,
        limit: lim,
        ka_closed,
    })
}

/// The largest f32 at or below Q16.16's largest (2^15 − 2^−16 is no f32; 2^15 − 2^−9 is):
/// Ka = gain_fraction × J_total rounded to f32 stays at or below it whenever the exact
/// product does, so a top stated against it holds in the build's own arithmetic.
const KA_TOP: f32 = 32_768.0 - 1.0 / 512.0;

/// The range of `accel_feedback.gain_fraction` that fits given the other settings, when Ka
/// = gain_fraction × J_total or the closed form's Ka/(1 + b·Ka) (b = b0/J_model; `b0` the
/// AFB filter's feed-through, given with the observer as the source) does not fit Q16.16.
///
/// Both must keep 50 steps of Q16.16 (m). The closed form grows with Ka towards 1/b and
/// stays below Ka, so it fits from Ka = m/(1 − b·m) on, above Ka's own floor m: with the
/// closed form, that is the range's bottom whichever of the two was refused (Ka's floor
/// alone would state values the closed form refuses). If 1/b itself is below m, no Ka fits
/// and the model inertia is too small: from b0·m on, and from m (the observer's own floor
/// for it). The top is Ka's: [`KA_TOP`] / J_total, rounded down
/// to f32. The bottom needs no such care: `quantize` keeps a value down to about 49.5 steps
/// (within 1 %), far below any f32 rounding of 50.
pub(super) fn gain_fraction_error(g: &Gains, b0: Option<f32>) -> ConfigError {
    use crate::validate::GAIN_MIN;
    let cfg = &g.cfg;
    let j = f64::from(g.j_total_s);
    let r = &r::AFB_GAIN_FRACTION;
    let b = b0.map_or(0.0, |b0| f64::from(b0) / f64::from(g.observer_inertia_s));
    if let Some(b0) = b0.filter(|_| b * GAIN_MIN >= 1.0) {
        let m = &r::MOTOR_INERTIA_S;
        // J_model itself must keep 50 steps too (the observer's k_load names this key).
        return ConfigError::OutOfRangeGiven {
            param: m.key,
            value: cfg.motor_inertia_s,
            min: (f64::from(b0).max(1.0) * GAIN_MIN * 1.001) as f32,
            max: m.max,
            min_exclusive: false,
            given: "accel_feedback and observer.model_inertia: the closed form's \
                    Ka/(1 + b0·Ka/J_model), below J_model/b0 (b0 the AFB filter's \
                    feed-through), must fit Q16.16 within 1 %",
        };
    }
    let top = f64::from(KA_TOP) / j;
    let mut max = top as f32;
    if f64::from(max) > top {
        max = max.next_down();
    }
    ConfigError::OutOfRangeGiven {
        param: r.key,
        value: cfg.accel_feedback.gain_fraction,
        min: (GAIN_MIN / ((1.0 - b * GAIN_MIN) * j)) as f32,
        max: max.min(r.max),
        min_exclusive: false,
        given: GAIN_FRACTION_GIVEN,
    }
}

/// The state observer.
fn observer(g: &Gains) -> Result<Observer, ConfigError> {
    let [l1, l2, l3] = g.observer_l;
    let cfg = &g.cfg;
    // Below the Nyquist limit every gain lies in (0, 1.5): none can overflow Q2.30, and
    // the smallest, l3 = (1 − θ)³, grows with the bandwidth (with its cube at the low end).
    // So a gain that does not fit is too small: the bandwidth's range starts at the smallest
    // f32 at which l3, as the design computes it, keeps 50 steps of Q2.30 (1 %).
    let bw = &r::OBSERVER_BANDWIDTH_HZ;
    let f_cur = cfg.current_rate_hz as f32;
    let cap = (f_cur / 2.0).next_down();
    let l = |v: f32| {
        quantize::<Coef>(v, bw.key).map_err(|_| {
            let floor = 50.0 * Coef::DELTA.to_num::<f32>();
            let l3_of = |f| crate::design::observer_poles(f, f_cur).1[2];
            ConfigError::OutOfRangeGiven {
                param: bw.key,
                value: cfg.observer.bandwidth_hz,
                min: smallest_fitting(cap, |f| l3_of(f) >= floor).max(bw.min),
                max: cap,
                min_exclusive: false,
                given: "current_rate_hz: the observer's correction gains (Q2.30) must keep 1 %",
            }
        })
    };
    let cpr = |_| encoder_cpr_error(cfg);
    Ok(Observer {
        l1: l(l1)?,
        l2: l(l2)?,
        l3: l(l3)?,
        k_u: quantize(g.observer_k_u, r::ENCODER_CPR.key).map_err(cpr)?,
        k_vel: quantize(g.cur_tick_pu_per_count, r::ENCODER_CPR.key).map_err(cpr)?,
        k_acc: quantize(g.cur_tick_pu_s_per_count, r::ENCODER_CPR.key).map_err(cpr)?,
        k_load: fit(
            -g.observer_inertia_s,
            Scales {
                cap: f32::INFINITY,
                range: &r::MOTOR_INERTIA_S,
                setting: cfg.motor_inertia_s,
                power: 1.0,
                given: "observer.model_inertia: the observer's model inertia (Q16.16) must \
                        keep 1 %",
            },
            |jm| match cfg.observer.model_inertia {
                crate::config::ObserverInertia::Total => -(jm + cfg.load_inertia_s),
                crate::config::ObserverInertia::Motor => -jm,
            },
        )?,
        count_interval: CountInterval::of(fit_setting(
            &r::OBSERVER_COUNT_INTERVAL_COUNTS,
            cfg.observer.count_interval_counts,
            "its format Q16.16 (0, or within 1 %)",
        )?),
    })
}

/// What the range of `accel_feedback.gain_fraction` ([`gain_fraction_error`]) depends on.
const GAIN_FRACTION_GIVEN: &str = "motor_inertia_s + load_inertia_s: Ka = gain_fraction × \
    J_total (and the closed form's Ka/(1 + b0·Ka/J_model)) must fit Q16.16 within 1 %; 0 or \
    mode = \"off\" turns the feedback off";

/// A differentiator with velocity scale `v` and acceleration scale `a` (counts to pu: both
/// bounded by `encoder_cpr`'s range).
fn differentiator(cfg: &DriveConfig, v: f32, a: f32) -> Result<Differentiator, ConfigError> {
    let cpr = |_| encoder_cpr_error(cfg);
    Ok(Differentiator {
        k_vel: quantize(v, r::ENCODER_CPR.key).map_err(cpr)?,
        k_acc: quantize(a, r::ENCODER_CPR.key).map_err(cpr)?,
    })
}

/// What the current PI's gains depend on besides the bandwidth.
const CURRENT_GIVEN: &str = "winding_inductance_pu_s, winding_resistance_pu and \
    current_rate_hz: Kp = L·ω (Q16.16) and Ki·Ts = R·ω/current_rate_hz (Q8.24) must fit \
    within 1 %";

/// A PI's gains `kp` (∝ ω) and `ki_ts` (∝ ω^`ki_power`) from the bandwidth `range`, each
/// as `(value, how the design computes it from a bandwidth)`; if either does not fit, the
/// error gives the bandwidth's range that fits both ([`Scales::bounds`]).
pub(super) fn pi_gains(
    range: &'static crate::ranges::Range,
    w: f32,
    (kp, kp_of): (f32, impl Fn(f32) -> f32),
    (ki_ts, ki_ts_of): (f32, impl Fn(f32) -> f32),
    ki_power: f64,
    given: &'static str,
    cap: f32,
) -> Result<(Gain, TickGain), ConfigError> {
    let p = Scales {
        cap,
        range,
        setting: w,
        power: 1.0,
        given,
    };
    let i = Scales {
        power: ki_power,
        ..p
    };
    match (
        quantize::<Gain>(kp, range.key),
        quantize::<TickGain>(ki_ts, range.key),
    ) {
        (Ok(kp), Ok(ki)) => Ok((kp, ki)),
        _ => {
            let (lo_p, hi_p) = p.bounds::<Gain>(kp, kp_of);
            let (lo_i, hi_i) = i.bounds::<TickGain>(ki_ts, ki_ts_of);
            let min = lo_p.max(lo_i);
            Err(ConfigError::OutOfRangeGiven {
                param: range.key,
                value: w,
                min,
                max: hi_p.min(hi_i),
                min_exclusive: range.min_exclusive && min <= range.min,
                given,
            })
        }
    }
}

/// The velocity and current PI regulators (torque limit `lim`, voltage limit `vlim`).
pub(super) fn regulators(
    g: &Gains,
    lim: Pu,
    vlim: Pu,
) -> Result<(PiCoefficients, PiCoefficients), ConfigError> {
    let cfg = &g.cfg;
    let f_vel = cfg.velocity_rate_hz as f32;
    let vel = |w| crate::validate::velocity_pi_gains(w, g.j_loop_s, cfg.velocity_damping, f_vel);
    let (kp, ki_ts) = pi_gains(
        &r::VELOCITY_BANDWIDTH_RAD_S,
        cfg.velocity_bandwidth_rad_s,
        (g.kp_vel, |w| vel(w).0),
        (g.ki_vel / f_vel, |w| vel(w).1),
        2.0,
        VELOCITY_GIVEN,
        (core::f32::consts::PI * cfg.velocity_rate_hz as f32).next_down(),
    )?;
    let velocity = PiCoefficients {
        kp,
        ki_ts,
        limit: lim,
    };
    let f_cur = cfg.current_rate_hz as f32;
    let (kp, ki_ts) = pi_gains(
        &r::CURRENT_BANDWIDTH_RAD_S,
        cfg.current_bandwidth_rad_s,
        (g.kp_cur, |w| cfg.winding_inductance_pu_s * w),
        (g.ki_cur / f_cur, |w| cfg.winding_resistance_pu * w / f_cur),
        1.0,
        CURRENT_GIVEN,
        (core::f32::consts::PI * cfg.current_rate_hz as f32).next_down(),
    )?;
    let current = PiCoefficients {
        kp,
        ki_ts,
        limit: vlim,
    };
    Ok((velocity, current))
}

/// The differentiators at the velocity and at the current rate.
fn differentiators(g: &Gains) -> Result<[Differentiator; 2], ConfigError> {
    Ok([
        differentiator(&g.cfg, g.vel_tick_pu_per_count, g.vel_tick_pu_s_per_count)?,
        differentiator(&g.cfg, g.cur_tick_pu_per_count, g.cur_tick_pu_s_per_count)?,
    ])
}

/// The fault limits as raw magnitudes: overspeed, following error, encoder jump. The
/// following error is set in motor revolutions and compared in counts: × `encoder_cpr`,
/// the counts the drive reads per revolution (after any interpolation).
fn fault_limits(g: &Gains) -> Result<[MagnitudeLimit; 3], ConfigError> {
    let cfg = &g.cfg;
    let rev = cfg.faults.following_error_rev;
    let cpr = cfg.encoder_cpr as f32;
    let following = fit::<CountsErr>(
        rev * cpr,
        Scales {
            cap: f32::INFINITY,
            range: &r::FOLLOWING_ERROR_REV,
            setting: rev,
            power: 1.0,
            given: "encoder_cpr: the limit in counts (following_error_rev × encoder_cpr) \
                    must fit the position error's format Q24.8 (below 2^23 counts, at least \
                    0.2 count)",
        },
        |rev| rev * cpr,
    )?;
    Ok([
        MagnitudeLimit::new(
            fit_setting::<Pu>(
                &r::OVERSPEED_PU,
                cfg.faults.overspeed_pu,
                "its format Q16.16 (within 1 %)",
            )?
            .to_bits()
            .unsigned_abs(),
        ),
        MagnitudeLimit::new(following.to_bits().unsigned_abs()),
        MagnitudeLimit::new(
            quantize::<CountsErr>(g.max_count_step, r::ENCODER_CPR.key)
                .map_err(|_| encoder_cpr_error(cfg))?
                .to_num::<i32>()
                .unsigned_abs(),
        ),
    ])
}

impl Coefficients {
    /// Quantize `g` (designed from, and carrying, validated settings).
    pub(super) fn from_gains(g: &Gains) -> Result<Self, ConfigError> {
        let cfg = &g.cfg;
        let q16 = "its format Q16.16 (within 1 %)";
        let lim: Pu = fit_setting(&r::TORQUE_LIMIT_PU, cfg.torque_limit_pu, q16)?;
        let vlim: Pu = fit_setting(&r::VOLTAGE_LIMIT_PU, cfg.voltage_limit_pu, q16)?;
        // Quantized in the order of the error precedence: AFB, observer, position, regulators,
        // notch.
        let afb = accel_feedback(g, lim)?;
        let observer = observer(g)?;
        let k_pos = PositionLoop::gain(g)?;
        let velocity_ff = PositionLoop::feed_forward(cfg)?;
        let k_accel_ff = VelocityLoop::accel_ff(g)?;
        let (velocity_regulator, current_regulator) = regulators(g, lim, vlim)?;
        let notch = match &g.notch {
            Some(d) => Some(Notch::quantize(d, r::NOTCH_CENTRE_HZ.key)?),
            None => None,
        };
        // Then the velocity filter, the differentiators and the fault limits.
        let velocity_filter =
            LowPass::quantize(&g.velocity_filter, r::VELOCITY_FILTER_CORNER_HZ.key)?;
        let [diff_velocity_rate, diff_current_rate] = differentiators(g)?;
        let [overspeed_abs, following_error_abs, max_count_step_abs] = fault_limits(g)?;
        let protection = Protection::new(cfg)?;
        let headroom = VelocityLoop::headroom(cfg)?;
        Ok(Self {
            counter_bits: cfg.counter_bits,
            counter_shift: counter_shift(cfg.counter_bits),
            position: PositionLoop::new(g, k_pos, velocity_ff, following_error_abs),
            velocity: VelocityLoop::new(velocity_regulator, velocity_filter, k_accel_ff, headroom),
            current: DcCurrentLoop::new(current_regulator),
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
            overspeed_abs,
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
