//! [`DriveConfig::validate`]: every setting against its entry of [`crate::ranges::RANGES`],
//! then the ranges that depend on other settings.

use crate::config::{AfbRate, DriveConfig, FilterConfig, NotchConfig};
use crate::error::ConfigError;
use crate::per_unit::counts_per_pu_s;
use crate::ranges::{self, Range};

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
    below_nyquist(corner.check(corner_hz)?, corner.key, rate_hz / 2.0)?;
    Ok(())
}

/// A notch at the current rate `rate_hz`: each key against its range, the centre below
/// `rate_hz / 2` and the width at most the centre (the error's range then ends there).
pub(crate) fn check_notch(n: &NotchConfig, rate_hz: f32) -> Result<(), ConfigError> {
    let (c, w) = (&ranges::NOTCH_CENTRE_HZ, &ranges::NOTCH_WIDTH_HZ);
    let centre = below_nyquist(c.check(n.centre_hz)?, c.key, rate_hz / 2.0)?;
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
    /// on other settings (tick-rate ratio, Nyquist limits, counter width). The error names
    /// the setting by its dotted key ([`ConfigError::param`]).
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
        self.validate_scalars()?;
        let (f_cur, f_vel) = self.validate_rates()?;
        let pi = core::f32::consts::PI;
        let nyq = |v: f32, r: &Range, limit: f32| below_nyquist(v, r.key, limit).map(|_| ());
        nyq(
            self.position_bandwidth_rad_s,
            &ranges::POSITION_BANDWIDTH_RAD_S,
            pi * f_vel,
        )?;
        nyq(
            self.velocity_bandwidth_rad_s,
            &ranges::VELOCITY_BANDWIDTH_RAD_S,
            pi * f_vel,
        )?;
        nyq(
            self.current_bandwidth_rad_s,
            &ranges::CURRENT_BANDWIDTH_RAD_S,
            pi * f_cur,
        )?;
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
        let obs = ranges::OBSERVER_BANDWIDTH_HZ.check(self.observer.bandwidth_hz)?;
        nyq(obs, &ranges::OBSERVER_BANDWIDTH_HZ, f_cur / 2.0)?;
        if let Some(n) = &self.notch {
            check_notch(n, f_cur)?;
        }
        self.validate_counter_bits()
    }

    /// The settings whose range depends on nothing else.
    fn validate_scalars(&self) -> Result<(), ConfigError> {
        use ranges as r;
        let f = &self.faults;
        for (range, v) in [
            (&r::BASE_SPEED_RPM, self.base_speed_rpm),
            (&r::MOTOR_INERTIA_S, self.motor_inertia_s),
            (&r::LOAD_INERTIA_S, self.load_inertia_s),
            (&r::POSITION_BANDWIDTH_RAD_S, self.position_bandwidth_rad_s),
            (&r::VELOCITY_BANDWIDTH_RAD_S, self.velocity_bandwidth_rad_s),
            (&r::VELOCITY_DAMPING, self.velocity_damping),
            (&r::CURRENT_BANDWIDTH_RAD_S, self.current_bandwidth_rad_s),
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
            (&r::FOLLOWING_ERROR_COUNTS, f.following_error_counts),
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

    /// The counter must not wrap by half its range between two current ticks at the jump
    /// limit, or a legal motion would read as a jump backwards.
    fn validate_counter_bits(&self) -> Result<(), ConfigError> {
        let step = max_count_step(self);
        let mut bits_needed = 16u32;
        while bits_needed < 32 && step >= (1u64 << (bits_needed - 1)) as f32 {
            bits_needed += 1;
        }
        if u32::from(self.counter_bits) < bits_needed || step >= (1u64 << 31) as f32 {
            return Err(ConfigError::OutOfRange {
                param: ranges::COUNTER_BITS.key,
                value: f32::from(self.counter_bits),
                min: bits_needed as f32,
                max: 32.0,
                min_exclusive: false,
            });
        }
        Ok(())
    }
}
