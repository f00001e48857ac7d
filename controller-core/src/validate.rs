//! [`DriveConfig::validate`]: every setting against its entry of [`crate::ranges::RANGES`],
//! then the ranges that depend on other settings.

use crate::config::{AfbRate, DriveConfig, FilterConfig, NotchConfig};
use crate::error::ConfigError;
use crate::per_unit::{Gain, TickGain, checked_q, counts_per_pu_s, quantize};
use crate::ranges::{self, Range};

mod scales;
pub(crate) use scales::{Scales, fit, fit_setting, smallest_fitting, velocity_pi_gains};
use scales::{largest_fitting, largest_whole, smallest_whole, velocity_loop_inertia};

/// `v` if below the (exclusive) Nyquist limit `nyquist` of its loop.
pub(crate) fn below_nyquist(v: f32, param: &'static str, nyquist: f32) -> Result<f32, ConfigError> {
    if v < nyquist {
        Ok(v)
    } else {
        Err(ConfigError::AboveNyquist {
            param,
            value: v,
            nyquist,
        })
    }
}

/// `v` against `r` and below the (exclusive) limit `nyquist`. A value that is not a finite
/// number is refused with its whole range, up to the largest value below the limit.
pub(crate) fn check_below_nyquist(r: &Range, v: f32, nyquist: f32) -> Result<f32, ConfigError> {
    if !v.is_finite() {
        return Err(ConfigError::OutOfRange {
            param: r.key,
            value: v,
            min: r.min,
            max: nyquist.next_down().min(r.max),
            min_exclusive: r.min_exclusive,
        });
    }
    below_nyquist(r.check(v)?, r.key, nyquist)
}

/// A filter's corner against its range and below `rate_hz / 2`, its `q` against its range.
pub(crate) fn check_filter(
    f: &FilterConfig,
    rate_hz: f32,
    corner: &Range,
    q: &Range,
) -> Result<(), ConfigError> {
    let corner_hz = match *f {
        FilterConfig::None => return Ok(()),
        FilterConfig::FirstOrder { corner_hz } => corner_hz,
        FilterConfig::SecondOrder { corner_hz, q: qv } => {
            q.check(qv)?;
            corner_hz
        }
    };
    check_below_nyquist(corner, corner_hz, rate_hz / 2.0)?;
    Ok(())
}

/// A notch at the current rate `rate_hz`: each key against its range, the centre below
/// `rate_hz / 2` and the width at most the centre (the error's range then ends there).
pub(crate) fn check_notch(n: &NotchConfig, rate_hz: f32) -> Result<(), ConfigError> {
    let (c, w) = (&ranges::NOTCH_CENTRE_HZ, &ranges::NOTCH_WIDTH_HZ);
    let centre = check_below_nyquist(c, n.centre_hz, rate_hz / 2.0)?;
    let width = w.check(n.width_hz)?;
    if width > centre {
        return Err(ConfigError::OutOfRange {
            param: w.key,
            value: width,
            min: w.min,
            max: centre,
            min_exclusive: w.min_exclusive,
        });
    }
    ranges::NOTCH_DEPTH_DB.check(n.depth_db)?;
    Ok(())
}

/// Largest plausible change of counts between two current ticks: the encoder-jump limit
/// `margin × overspeed × counts per current tick at 1 pu + 2`.
pub(crate) fn max_count_step(cfg: &DriveConfig) -> f32 {
    let cpps = counts_per_pu_s(cfg.encoder_cpr, cfg.base_speed_rpm);
    let ts_cur = 1.0 / cfg.current_rate_hz as f32;
    cfg.faults.encoder_jump_margin * cfg.faults.overspeed_pu * cpps * ts_cur + 2.0
}

impl DriveConfig {
    /// Check every setting: its [`crate::ranges::RANGES`] entry, then the ranges that depend
    /// on other settings (tick-rate ratio, Nyquist limits, the current bandwidth against the
    /// velocity bandwidth, the encoder counts the counter and the count scales hold, the
    /// following-error limit in counts). The error names the setting by its dotted key
    /// ([`ConfigError::param`]) and its range (given the others where they bound it).
    ///
    /// ```
    /// # let cfg: controller_core::DriveConfig = toml::from_str(include_str!(concat!(
    /// #     env!("CARGO_MANIFEST_DIR"), "/doc/example-drive.toml"))).unwrap();
    /// assert!(cfg.validate().is_ok());
    /// let mut bad = cfg;
    /// bad.accel_feedback.gain_fraction = 25.0;
    /// assert_eq!(bad.validate().unwrap_err().param(), "accel_feedback.gain_fraction");
    /// ```
    pub fn validate(&self) -> Result<(), ConfigError> {
        let (f_cur, f_vel) = self.validate_rates()?;
        self.validate_scalars()?;
        let pi = core::f32::consts::PI;
        check_below_nyquist(
            &ranges::POSITION_BANDWIDTH_RAD_S,
            self.position_bandwidth_rad_s,
            pi * f_vel,
        )?;
        let w_vel = check_below_nyquist(
            &ranges::VELOCITY_BANDWIDTH_RAD_S,
            self.velocity_bandwidth_rad_s,
            pi * f_vel,
        )?;
        let w_cur = check_below_nyquist(
            &ranges::CURRENT_BANDWIDTH_RAD_S,
            self.current_bandwidth_rad_s,
            pi * f_cur,
        )?;
        self.check_velocity_bandwidth(w_vel, w_cur, pi * f_vel)?;
        let afb = &self.accel_feedback;
        let afb_rate_hz = match afb.rate {
            AfbRate::Current => f_cur,
            AfbRate::Velocity => f_vel,
        };
        check_filter(
            &afb.filter,
            afb_rate_hz,
            &ranges::AFB_FILTER_CORNER_HZ,
            &ranges::AFB_FILTER_Q,
        )?;
        check_filter(
            &self.velocity_filter,
            f_vel,
            &ranges::VELOCITY_FILTER_CORNER_HZ,
            &ranges::VELOCITY_FILTER_Q,
        )?;
        check_below_nyquist(
            &ranges::OBSERVER_BANDWIDTH_HZ,
            self.observer.bandwidth_hz,
            f_cur / 2.0,
        )?;
        if let Some(p) = &self.pmsm {
            crate::foc::config::check(self, p)?;
        }
        if let Some(n) = &self.notch {
            check_notch(n, f_cur)?;
        }
        self.validate_encoder_cpr()?;
        self.validate_following_error()
    }

    /// The settings whose range depends on nothing else.
    fn validate_scalars(&self) -> Result<(), ConfigError> {
        use ranges as r;
        let f = &self.faults;
        for (range, v) in [
            (&r::BASE_SPEED_RPM, self.base_speed_rpm),
            (&r::MOTOR_INERTIA_S, self.motor_inertia_s),
            (&r::LOAD_INERTIA_S, self.load_inertia_s),
            (&r::VELOCITY_DAMPING, self.velocity_damping),
            (&r::WINDING_RESISTANCE_PU, self.winding_resistance_pu),
            (&r::WINDING_INDUCTANCE_PU_S, self.winding_inductance_pu_s),
            (&r::TORQUE_LIMIT_PU, self.torque_limit_pu),
            (&r::VOLTAGE_LIMIT_PU, self.voltage_limit_pu),
            (&r::VELOCITY_FF_GAIN, self.velocity_ff_gain),
            (&r::ACCEL_FF_GAIN, self.accel_ff_gain),
            (&r::AFB_GAIN_FRACTION, self.accel_feedback.gain_fraction),
            (
                &r::AFB_LIMIT_HEADROOM_FRACTION,
                self.accel_feedback.limit_headroom_fraction,
            ),
            (
                &r::OBSERVER_COUNT_INTERVAL_COUNTS,
                self.observer.count_interval_counts,
            ),
            (&r::OVERSPEED_PU, f.overspeed_pu),
            (&r::FOLLOWING_ERROR_REV, f.following_error_rev),
            (&r::ENCODER_JUMP_MARGIN, f.encoder_jump_margin),
            (&r::OVERCURRENT_RATIO, f.overcurrent_ratio),
            (&r::CONTINUOUS_CURRENT_PU, f.continuous_current_pu),
            (&r::OVERLOAD_CURRENT_PU, f.overload_current_pu),
            (&r::OVERLOAD_TIME_S, f.overload_time_s),
            (&r::THERMAL_WARNING_FRACTION, f.thermal_warning_fraction),
            (&r::STALL_SPEED_PU, f.stall_speed_pu),
            (&r::STALL_TORQUE_FRACTION, f.stall_torque_fraction),
            (&r::STALL_TIME_S, f.stall_time_s),
        ] {
            range.check(v)?;
        }
        r::ENCODER_CPR.check_whole(self.encoder_cpr)?;
        r::COUNTER_BITS.check_whole(u32::from(self.counter_bits))?;
        r::OVERCURRENT_TICKS.check_whole(f.overcurrent_ticks)?;
        // The overload class lies above the continuous current (else nothing could trip).
        let ol = &r::OVERLOAD_CURRENT_PU;
        if f.overload_current_pu <= f.continuous_current_pu {
            return Err(ConfigError::OutOfRange {
                param: ol.key,
                value: f.overload_current_pu,
                min: f.continuous_current_pu,
                max: ol.max,
                min_exclusive: true,
            });
        }
        Ok(())
    }

    /// The tick rates: each in range, and `current_rate_hz = n·velocity_rate_hz`, n = 1..=16.
    fn validate_rates(&self) -> Result<(f32, f32), ConfigError> {
        let f_cur = ranges::CURRENT_RATE_HZ.check_whole(self.current_rate_hz)?;
        let f_vel = ranges::VELOCITY_RATE_HZ.check_whole(self.velocity_rate_hz)?;
        if f_cur % f_vel != 0 || f_cur / f_vel > 16 {
            return Err(ConfigError::RateRatio {
                current_rate_hz: f_cur,
                velocity_rate_hz: f_vel,
            });
        }
        Ok((f_cur as f32, f_vel as f32))
    }

    /// `encoder_cpr` against the range the other settings leave it
    /// ([`encoder_cpr_range`]).
    fn validate_encoder_cpr(&self) -> Result<(), ConfigError> {
        let (min, max, _) = encoder_cpr_range(self);
        if (min..=max).contains(&self.encoder_cpr) {
            return Ok(());
        }
        Err(encoder_cpr_error(self))
    }

    /// The following-error limit in counts (`following_error_rev × encoder_cpr`) must fit
    /// the position error's format, Q24.8: below 2^23 counts.
    fn validate_following_error(&self) -> Result<(), ConfigError> {
        let cpr = self.encoder_cpr as f32;
        let rev = self.faults.following_error_rev;
        if rev * cpr < COUNTS_ERR_LIMIT {
            return Ok(());
        }
        let r = &ranges::FOLLOWING_ERROR_REV;
        let mut max = (COUNTS_ERR_LIMIT / cpr).min(r.max);
        while max * cpr >= COUNTS_ERR_LIMIT {
            max = max.next_down();
        }
        Err(ConfigError::OutOfRangeGiven {
            param: r.key,
            value: rev,
            min: r.min,
            max,
            min_exclusive: r.min_exclusive,
            given: "encoder_cpr: the limit in counts (following_error_rev × encoder_cpr) must \
                    stay below 2^23 counts, the range of the position error (Q24.8)",
        })
    }
}

/// 2^23: the position error (Q24.8) holds magnitudes below it \[counts\].
const COUNTS_ERR_LIMIT: f32 = 8_388_608.0;

/// What bounds the velocity bandwidth when the current loop does.
const RATIO_GIVEN: &str = "current_bandwidth_rad_s: the current loop must be at least 1.5 \
    times as fast (current_bandwidth_rad_s ≥ 1.5 × velocity_bandwidth_rad_s)";

/// What bounds the velocity bandwidth when the PI's gains do.
pub(crate) const VELOCITY_GIVEN: &str = "motor_inertia_s + load_inertia_s (plus Ka with \
    velocity_pi_inertia = \"total_plus_afb\"), velocity_damping and velocity_rate_hz: \
    Kp = ω·J (Q16.16) and Ki·Ts = ω²·J/(4ζ²·velocity_rate_hz) (Q8.24) must fit within 1 %; \
    and current_bandwidth_rad_s ≥ 1.5 × velocity_bandwidth_rad_s";

impl DriveConfig {
    /// The velocity bandwidth ω against the range the other settings leave it: below the
    /// Nyquist limit `nyquist`, at most the current bandwidth over
    /// [`ranges::MIN_CURRENT_TO_VELOCITY_BANDWIDTH`], and with the velocity PI's gains
    /// Kp = ω·J (Q16.16) and Ki·Ts = ω²·J/(4ζ²·f_vel) (Q8.24) at most their format's
    /// maximum and at least 50 of its steps (within 1 %). The error names the key that
    /// bounds it: `current_bandwidth_rad_s` where the current loop does.
    fn check_velocity_bandwidth(
        &self,
        w: f32,
        w_cur: f32,
        nyquist: f32,
    ) -> Result<(), ConfigError> {
        let r = &ranges::VELOCITY_BANDWIDTH_RAD_S;
        let j_total = f64::from(self.total_inertia_s());
        let afb_on = self.accel_feedback.mode != crate::config::AfbMode::Off;
        let j = match self.velocity_pi_inertia {
            crate::config::PiInertia::TotalPlusAfb if afb_on => {
                j_total * (1.0 + f64::from(self.accel_feedback.gain_fraction))
            }
            _ => j_total,
        };
        let zeta = f64::from(self.velocity_damping);
        let ki_scale = 4.0 * zeta * zeta * f64::from(self.velocity_rate_hz) / j;
        let sqrt = crate::cfgmath::sqrt;
        // The bottom keeps 50 steps of each format; `quantize` keeps down to about 49.5
        // (within 1 %), far below any rounding of it. The top is where Kp or Ki·Ts, in the
        // design's own f32 arithmetic, would round onto the format's bound: found exactly.
        let lo = (GAIN_MIN / j).max(sqrt(TICK_MIN * ki_scale)) as f32;
        let j_loop = velocity_loop_inertia(self);
        let fits = |w: f32| {
            let (kp, ki_ts) = velocity_pi_gains(
                w,
                j_loop,
                self.velocity_damping,
                self.velocity_rate_hz as f32,
            );
            checked_q::<Gain>(kp).is_some() && checked_q::<TickGain>(ki_ts).is_some()
        };
        let ratio = w_cur / ranges::MIN_CURRENT_TO_VELOCITY_BANDWIDTH;
        let cap = nyquist.next_down();
        if w >= lo && w <= ratio.min(cap) && fits(w) {
            return Ok(());
        }
        let hi_gains = largest_fitting(f32::INFINITY, fits);
        let hi = hi_gains.min(ratio).min(cap);
        Err(ConfigError::OutOfRangeGiven {
            param: r.key,
            value: w,
            min: lo.max(r.min),
            max: hi,
            min_exclusive: lo <= r.min,
            given: if w > ratio && ratio <= hi_gains {
                RATIO_GIVEN
            } else {
                VELOCITY_GIVEN
            },
        })
    }
}

/// Q16.16 (`Gain`): its largest value and 50 of its steps (the 1 % rule of `quantize`).
pub(crate) const GAIN_MAX: f64 = 32_768.0 - 1.0 / 65_536.0;
pub(crate) const GAIN_MIN: f64 = 50.0 / 65_536.0;
/// Q8.24 (`TickGain`): likewise.
const TICK_MAX: f64 = 128.0 - 1.0 / 16_777_216.0;
const TICK_MIN: f64 = 50.0 / 16_777_216.0;

/// The text of [`encoder_cpr_range`]'s bounds.
const ENCODER_CPR_GIVEN: &str = "base_speed_rpm, current_rate_hz, velocity_rate_hz, \
    motor_inertia_s, counter_bits, faults.overspeed_pu and faults.encoder_jump_margin: the \
    counter must not wrap by half between two current ticks at the encoder-jump limit (a \
    wider counter_bits, up to 32, allows more counts), the observer's velocity holds at most \
    32768 counts per current tick up to overspeed, and the count scales of the estimators \
    (Q8.24 and Q16.16, within 1 %) and the observer's torque scale (Q8.24) must fit";

/// The encoder counts per revolution the drive's fixed-point scales and its counter hold,
/// given the other settings: `(min, max, what bounds them)`. With c = counts per pu·s per
/// count per revolution (`base_speed_rpm / 60`) and Ts the tick length:
/// * counter: the encoder-jump limit (margin × overspeed × cpr·c·Ts_cur + 2 counts) below
///   half the counter's range, and below 2^23 (its Q24.8 limit);
/// * observer velocity (Q16.16 counts per current tick, when the observer estimates the
///   velocity or the AFB's acceleration): cpr·c·Ts_cur × overspeed below 2^15;
/// * observer torque scale k_u = Ts_cur²·cpr·c / J_model below 128 and at least 50 of its
///   steps (Q8.24);
/// * count scales 1/(cpr·c·Ts) (Q8.24) and 1/(cpr·c·Ts²) (Q16.16) at both rates: below
///   their format's maximum and at least 50 of its steps (within 1 %).
pub(crate) fn encoder_cpr_range(cfg: &DriveConfig) -> (u32, u32, &'static str) {
    let c = f64::from(cfg.base_speed_rpm) / 60.0;
    let ts_cur = 1.0 / f64::from(cfg.current_rate_hz);
    let ts_vel = 1.0 / f64::from(cfg.velocity_rate_hz);
    let (tick_max, tick_min, gain_max, gain_min) = (TICK_MAX, TICK_MIN, GAIN_MAX, GAIN_MIN);
    // Lower bounds: 1/(cpr·c·Ts) ≤ tick_max and 1/(cpr·c·Ts²) ≤ gain_max at both rates
    // (the current rate's are the larger).
    let lo = (1.0 / (tick_max * c * ts_cur)).max(1.0 / (gain_max * c * ts_cur * ts_cur));
    // Upper bounds: the scales at the velocity rate (the smaller) at least their minimum.
    let mut hi = (1.0 / (tick_min * c * ts_vel)).min(1.0 / (gain_min * c * ts_vel * ts_vel));
    let f = &cfg.faults;
    let jump = f64::from(f.encoder_jump_margin) * f64::from(f.overspeed_pu) * c * ts_cur;
    let half_counter = (1u64 << (u32::from(cfg.counter_bits.clamp(16, 32)) - 1)) as f64;
    hi = hi.min((half_counter.min(8_388_608.0) - 2.0) / jump);
    let j_obs = f64::from(match cfg.observer.model_inertia {
        crate::config::ObserverInertia::Total => cfg.total_inertia_s(),
        crate::config::ObserverInertia::Motor => cfg.motor_inertia_s,
    });
    hi = hi.min(tick_max * j_obs / (ts_cur * ts_cur * c));
    let lo = lo.max(tick_min * j_obs / (ts_cur * ts_cur * c));
    let observer_used = cfg.velocity_estimator == crate::config::Estimator::Observer
        || (cfg.accel_feedback.mode != crate::config::AfbMode::Off
            && cfg.accel_feedback.source == crate::config::Estimator::Observer);
    if observer_used {
        hi = hi.min(32_768.0 / (f64::from(f.overspeed_pu) * c * ts_cur));
    }
    let r = &ranges::ENCODER_CPR;
    // Strict bounds as whole counts: the largest count below `hi`, the smallest above `lo`.
    // (`as` truncates a non-negative value: its floor, saturated to u32.)
    let max = hi.next_down().min(f64::from(r.max)).max(0.0) as u32;
    let min = ((lo.max(0.0) as u32).saturating_add(1)).max(r.min as u32);
    // Narrowed to the counts whose coefficients, in the design's f32 arithmetic, stay below
    // their formats' tops (those in f64 above could round onto a bound).
    let max = largest_whole(max, |cpr| count_coefficients_fit(cfg, cpr).1);
    let min = smallest_whole(min, |cpr| count_coefficients_fit(cfg, cpr).0);
    (min, max, ENCODER_CPR_GIVEN)
}

/// Whether the coefficients derived from `cpr` stay below their formats' tops, as `design`
/// computes them (f32): `(those that fall with cpr, those that grow with it)`. Falling: the
/// count scales 1/(cpps·Ts) (Q8.24) and 1/(cpps·Ts²) (Q16.16) at both rates (cpps the
/// counts per pu·s); growing: the observer's torque scale Ts_cur²·cpps/J_model (Q8.24) and
/// the encoder-jump limit in counts ([`max_count_step`], Q24.8). Their floors keep the
/// 1 % slack of `quantize` and need no such check.
fn count_coefficients_fit(cfg: &DriveConfig, cpr: u32) -> (bool, bool) {
    let cpps = counts_per_pu_s(cpr, cfg.base_speed_rpm);
    let falling = [cfg.current_rate_hz, cfg.velocity_rate_hz]
        .iter()
        .all(|&f| {
            let ts = 1.0 / f as f32;
            checked_q::<TickGain>(1.0 / (cpps * ts)).is_some()
                && checked_q::<Gain>(1.0 / (cpps * ts * ts)).is_some()
        });
    let ts_cur = 1.0 / cfg.current_rate_hz as f32;
    let j_obs = match cfg.observer.model_inertia {
        crate::config::ObserverInertia::Total => cfg.total_inertia_s(),
        crate::config::ObserverInertia::Motor => cfg.motor_inertia_s,
    };
    let with_cpr = DriveConfig {
        encoder_cpr: cpr,
        ..*cfg
    };
    let growing = checked_q::<TickGain>(ts_cur * ts_cur * cpps / j_obs).is_some()
        && checked_q::<crate::per_unit::CountsErr>(max_count_step(&with_cpr)).is_some();
    (falling, growing)
}

/// The error naming `encoder_cpr` with the range [`encoder_cpr_range`] gives: where a count
/// scale or limit derived from the encoder does not fit its format.
/// Its bounds are whole counts stated as f32, rounded inwards: above 2^24 counts not every
/// whole count is an f32, and the nearest one could lie outside the range.
pub(crate) fn encoder_cpr_error(cfg: &DriveConfig) -> ConfigError {
    let (min, max, given) = encoder_cpr_range(cfg);
    let (mut lo, mut hi) = (min as f32, max as f32);
    if f64::from(lo) < f64::from(min) {
        lo = lo.next_up();
    }
    if f64::from(hi) > f64::from(max) {
        hi = hi.next_down();
    }
    ConfigError::OutOfRangeGiven {
        param: ranges::ENCODER_CPR.key,
        value: cfg.encoder_cpr as f32,
        min: lo,
        max: hi,
        min_exclusive: false,
        given,
    }
}
