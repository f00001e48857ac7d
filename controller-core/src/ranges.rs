//! The one range table of the drive settings. [`crate::DriveConfig::validate`] checks every
//! entry; the harness reads [`RANGES`] to put `minimum`/`maximum` into the JSON Schema of
//! `[drive]`. A key is the dotted path of the setting below `[drive]`.
//!
//! Ranges that depend on other settings (a frequency below its loop's Nyquist limit, the
//! ratio of the tick rates, the counter width the encoder-jump limit needs) are explicit
//! checks in `validate`, naming the key they concern.

use crate::error::ConfigError;

/// The allowed range of one setting: `[min, max]`, or `(min, max]` when `min_exclusive`.
/// `max = ∞` means no upper bound (besides being finite).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Range {
    /// Dotted path below `[drive]`, e.g. `"accel_feedback.gain_fraction"`.
    pub key: &'static str,
    /// Smallest allowed value.
    pub min: f32,
    /// Largest allowed value (`f32::INFINITY`: unbounded).
    pub max: f32,
    /// Whether `min` itself is excluded.
    pub min_exclusive: bool,
    /// Whether the setting is a whole number (counts, bits, rates).
    pub whole: bool,
}

impl Range {
    pub(crate) const fn real(key: &'static str, min: f32, max: f32, min_exclusive: bool) -> Self {
        Self {
            key,
            min,
            max,
            min_exclusive,
            whole: false,
        }
    }

    const fn whole(key: &'static str, min: f32, max: f32) -> Self {
        Self {
            key,
            min,
            max,
            min_exclusive: false,
            whole: true,
        }
    }

    /// `v` if it is finite and inside the range, else the error naming [`Range::key`].
    pub fn check(&self, v: f32) -> Result<f32, ConfigError> {
        // NaN fails both comparisons below and ±∞ is outside every range: a value that is
        // not a finite number is refused with the range, like any other bad number.
        if !v.is_finite() {
            return Err(self.out_of_range(v));
        }
        let low_ok = if self.min_exclusive {
            v > self.min
        } else {
            v >= self.min
        };
        if low_ok && v <= self.max {
            Ok(v)
        } else {
            Err(self.out_of_range(v))
        }
    }

    /// A whole-number setting: `v` if inside the range.
    pub fn check_whole(&self, v: u32) -> Result<u32, ConfigError> {
        // Every bound of the table is exact in f32 (powers of two or below 2^24).
        self.check(v as f32).map(|_| v)
    }

    /// The out-of-range error of `v`.
    #[must_use]
    pub fn out_of_range(&self, v: f32) -> ConfigError {
        ConfigError::OutOfRange {
            param: self.key,
            value: v,
            min: self.min,
            max: self.max,
            min_exclusive: self.min_exclusive,
        }
    }
}

const INF: f32 = f32::INFINITY;

/// Base speed \[rpm\].
pub const BASE_SPEED_RPM: Range = Range::real("base_speed_rpm", 0.0, 100_000.0, true);
/// Encoder counts per revolution.
pub const ENCODER_CPR: Range = Range::whole("encoder_cpr", 4.0, 1_073_741_824.0);
/// Counter width \[bits\] (and at least what the encoder-jump limit needs).
pub const COUNTER_BITS: Range = Range::whole("counter_bits", 16.0, 32.0);
/// Current tick rate \[Hz\].
pub const CURRENT_RATE_HZ: Range = Range::whole("current_rate_hz", 100.0, 100_000.0);
/// Velocity tick rate \[Hz\] (and `current_rate_hz / n`, n = 1..=16).
pub const VELOCITY_RATE_HZ: Range = Range::whole("velocity_rate_hz", 10.0, 100_000.0);
/// Motor inertia \[s\].
pub const MOTOR_INERTIA_S: Range = Range::real("motor_inertia_s", 0.0, 1000.0, true);
/// Load inertia \[s\].
pub const LOAD_INERTIA_S: Range = Range::real("load_inertia_s", 0.0, 1000.0, false);
/// Position bandwidth \[rad/s\] (and below π·velocity_rate_hz); 0 = velocity mode.
pub const POSITION_BANDWIDTH_RAD_S: Range =
    Range::real("position_bandwidth_rad_s", 0.0, INF, false);
/// Velocity bandwidth \[rad/s\] (and below π·velocity_rate_hz).
pub const VELOCITY_BANDWIDTH_RAD_S: Range = Range::real("velocity_bandwidth_rad_s", 0.0, INF, true);
/// The current loop is at least this many times as fast as the velocity loop:
/// `current_bandwidth_rad_s ≥ 1.5 × velocity_bandwidth_rad_s`. 1.5 keeps every shipped
/// drive and every point of the search grids (`configs/grids.toml`: the sweep reaches
/// 1000 rad/s on a 1998 rad/s current loop, a ratio of 2) and refuses a velocity loop
/// faster than its current loop.
pub const MIN_CURRENT_TO_VELOCITY_BANDWIDTH: f32 = 1.5;
/// Velocity damping ζ.
pub const VELOCITY_DAMPING: Range = Range::real("velocity_damping", 0.1, 10.0, false);
/// Current bandwidth \[rad/s\] (and below π·current_rate_hz).
pub const CURRENT_BANDWIDTH_RAD_S: Range = Range::real("current_bandwidth_rad_s", 0.0, INF, true);
/// Winding resistance \[pu\].
pub const WINDING_RESISTANCE_PU: Range = Range::real("winding_resistance_pu", 0.0, 100.0, true);
/// Winding inductance \[pu·s\].
pub const WINDING_INDUCTANCE_PU_S: Range = Range::real("winding_inductance_pu_s", 0.0, 100.0, true);
/// Torque limit \[pu\].
pub const TORQUE_LIMIT_PU: Range = Range::real("torque_limit_pu", 0.0, 1000.0, true);
/// Voltage limit \[pu\].
pub const VOLTAGE_LIMIT_PU: Range = Range::real("voltage_limit_pu", 0.0, 1000.0, true);
/// Velocity feed-forward fraction.
pub const VELOCITY_FF_GAIN: Range = Range::real("velocity_ff_gain", 0.0, 1.0, false);
/// Acceleration feed-forward fraction.
pub const ACCEL_FF_GAIN: Range = Range::real("accel_ff_gain", 0.0, 1.0, false);
/// Velocity filter corner \[Hz\] (and below velocity_rate_hz/2).
pub const VELOCITY_FILTER_CORNER_HZ: Range =
    Range::real("velocity_filter.corner_hz", 0.0, INF, true);
/// Velocity filter Q.
pub const VELOCITY_FILTER_Q: Range = Range::real("velocity_filter.q", 0.1, 10.0, false);
/// Ka as a fraction of J_total.
pub const AFB_GAIN_FRACTION: Range = Range::real("accel_feedback.gain_fraction", 0.0, 20.0, false);
/// The velocity regulator's headroom beyond the torque limit, as a fraction of the limit.
pub const AFB_LIMIT_HEADROOM_FRACTION: Range =
    Range::real("accel_feedback.limit_headroom_fraction", 0.0, 1.0, false);
/// AFB filter corner \[Hz\] (and below the AFB rate / 2).
pub const AFB_FILTER_CORNER_HZ: Range =
    Range::real("accel_feedback.filter.corner_hz", 0.0, INF, true);
/// AFB filter Q.
pub const AFB_FILTER_Q: Range = Range::real("accel_feedback.filter.q", 0.1, 10.0, false);
/// Observer bandwidth \[Hz\] (and below current_rate_hz/2).
pub const OBSERVER_BANDWIDTH_HZ: Range = Range::real("observer.bandwidth_hz", 0.0, INF, true);
/// Half-width of the count interval in the observer's innovation \[counts\].
pub const OBSERVER_COUNT_INTERVAL_COUNTS: Range =
    Range::real("observer.count_interval_counts", 0.0, 0.5, false);
/// Overspeed trip \[pu\].
pub const OVERSPEED_PU: Range = Range::real("faults.overspeed_pu", 0.0, 100.0, true);
/// Following-error trip \[motor revolutions\] (and below 2^23 counts: at most
/// 2^23 / `encoder_cpr`, the Q24.8 limit of the position error).
pub const FOLLOWING_ERROR_REV: Range = Range::real("faults.following_error_rev", 0.0, 1000.0, true);
/// Encoder-jump margin.
pub const ENCODER_JUMP_MARGIN: Range =
    Range::real("faults.encoder_jump_margin", 1.0, 1000.0, false);
/// Overcurrent level as a multiple of the torque limit.
pub const OVERCURRENT_RATIO: Range = Range::real("faults.overcurrent_ratio", 1.0, 100.0, true);
/// Consecutive current ticks over the overcurrent level.
pub const OVERCURRENT_TICKS: Range = Range::whole("faults.overcurrent_ticks", 1.0, 1000.0);
/// Continuous current of the I²t model \[pu\].
pub const CONTINUOUS_CURRENT_PU: Range =
    Range::real("faults.continuous_current_pu", 0.0, 100.0, true);
/// Overload-class current of the I²t model \[pu\] (and above the continuous current).
pub const OVERLOAD_CURRENT_PU: Range = Range::real("faults.overload_current_pu", 0.0, 100.0, true);
/// Overload-class time of the I²t model \[s\].
pub const OVERLOAD_TIME_S: Range = Range::real("faults.overload_time_s", 0.0, 3600.0, true);
/// I²t warning level as a fraction of the trip level.
pub const THERMAL_WARNING_FRACTION: Range =
    Range::real("faults.thermal_warning_fraction", 0.0, 1.0, true);
/// Stall speed \[pu\].
pub const STALL_SPEED_PU: Range = Range::real("faults.stall_speed_pu", 0.0, 1.0, false);
/// Stall torque as a fraction of the torque limit.
pub const STALL_TORQUE_FRACTION: Range =
    Range::real("faults.stall_torque_fraction", 0.0, 1.0, true);
/// Stall time \[s\] (0 = off).
pub const STALL_TIME_S: Range = Range::real("faults.stall_time_s", 0.0, 600.0, false);
/// Notch centre \[Hz\] (and below current_rate_hz/2).
pub const NOTCH_CENTRE_HZ: Range = Range::real("notch.centre_hz", 0.0, INF, true);
/// Notch −3 dB width \[Hz\] (and at most `notch.centre_hz`).
pub const NOTCH_WIDTH_HZ: Range = Range::real("notch.width_hz", 0.0, INF, true);
/// Notch depth at the centre \[dB\].
pub const NOTCH_DEPTH_DB: Range =
    Range::real("notch.depth_db", 0.0, crate::notch::MAX_DEPTH_DB, false);

/// Every numeric setting of [`crate::DriveConfig`] with its range, in declaration order.
pub const RANGES: &[Range] = &[
    BASE_SPEED_RPM,
    ENCODER_CPR,
    COUNTER_BITS,
    CURRENT_RATE_HZ,
    VELOCITY_RATE_HZ,
    MOTOR_INERTIA_S,
    LOAD_INERTIA_S,
    POSITION_BANDWIDTH_RAD_S,
    VELOCITY_BANDWIDTH_RAD_S,
    VELOCITY_DAMPING,
    CURRENT_BANDWIDTH_RAD_S,
    WINDING_RESISTANCE_PU,
    WINDING_INDUCTANCE_PU_S,
    TORQUE_LIMIT_PU,
    VOLTAGE_LIMIT_PU,
    VELOCITY_FF_GAIN,
    ACCEL_FF_GAIN,
    VELOCITY_FILTER_CORNER_HZ,
    VELOCITY_FILTER_Q,
    AFB_GAIN_FRACTION,
    AFB_LIMIT_HEADROOM_FRACTION,
    AFB_FILTER_CORNER_HZ,
    AFB_FILTER_Q,
    OBSERVER_BANDWIDTH_HZ,
    OBSERVER_COUNT_INTERVAL_COUNTS,
    OVERSPEED_PU,
    FOLLOWING_ERROR_REV,
    ENCODER_JUMP_MARGIN,
    OVERCURRENT_RATIO,
    OVERCURRENT_TICKS,
    CONTINUOUS_CURRENT_PU,
    OVERLOAD_CURRENT_PU,
    OVERLOAD_TIME_S,
    THERMAL_WARNING_FRACTION,
    STALL_SPEED_PU,
    STALL_TORQUE_FRACTION,
    STALL_TIME_S,
    NOTCH_CENTRE_HZ,
    NOTCH_WIDTH_HZ,
    NOTCH_DEPTH_DB,
];

/// The range of `key` (a dotted path below `[drive]`), if it has one.
#[must_use]
pub fn range_of(key: &str) -> Option<&'static Range> {
    RANGES.iter().find(|r| r.key == key)
}
