//! Drive settings: plain `Copy` data, all in SI or per-unit as the field names say.
//! [`crate::design()`] validates them ([`DriveConfig::validate`], one range table:
//! [`crate::ranges::RANGES`]) and turns them into gains once. With the `serde` feature the
//! same types are the `[drive]` TOML contract; with `schema`, its JSON Schema.

/// Source of a velocity or acceleration estimate.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
pub enum Estimator {
    /// Backward differences of the encoder counts at the consuming loop's rate
    /// (velocity = Δcounts/Ts, acceleration = Δ²counts/Ts²), with their quantization.
    Differentiation,
    /// The Luenberger state observer (position and torque command in), run every current tick.
    Observer,
}

/// A low-pass filter on an estimate.
#[derive(Clone, Copy, Debug, PartialEq)]
// Deserialize is written out (`filter_de`): serde's derive of an internally tagged enum
// buffers the map, which needs `alloc`.
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
#[cfg_attr(
    feature = "serde",
    serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)
)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
pub enum FilterConfig {
    /// No filter.
    None,
    /// First-order low-pass, corner in Hz (matched pole: α = 1 − e^(−2π·f_c·Ts)).
    FirstOrder {
        /// Corner frequency \[Hz\], 0 < f_c < rate/2.
        corner_hz: f32,
    },
    /// Second-order (biquad) low-pass, bilinear with pre-warped corner.
    SecondOrder {
        /// Corner frequency \[Hz\], 0 < f_c < rate/2.
        corner_hz: f32,
        /// Quality factor, 0.1..=10; 1/√2 (Butterworth) when absent.
        #[cfg_attr(feature = "serde", serde(default = "defaults::butterworth_q"))]
        q: f32,
    },
}

/// How the acceleration feedback term is formed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
pub enum AfbMode {
    /// No acceleration feedback.
    Off,
    /// Plain form: torque reference −= Ka·LPF(measured acceleration).
    Plain,
    /// Acceleration-error form (Rockwell US 7,141,946):
    /// torque reference += Ka·LPF(commanded − measured acceleration).
    Error,
}

/// Which tick runs the acceleration feedback path.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
pub enum AfbRate {
    /// Every current tick (`current_rate_hz`).
    Current,
    /// Every velocity tick (`velocity_rate_hz`).
    Velocity,
}

/// Acceleration feedback ("inertia stabilization") settings.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields, default))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
pub struct AccelFeedbackConfig {
    /// Form of the feedback.
    pub mode: AfbMode,
    /// Ka as a fraction of the total inertia (Ka = fraction·J_total, in s), 0..=20.
    pub gain_fraction: f32,
    /// Low-pass filter on the acceleration (or acceleration error).
    pub filter: FilterConfig,
    /// Tick that runs the path.
    pub rate: AfbRate,
    /// Source of the measured acceleration.
    pub source: Estimator,
    /// How far beyond the torque limit the velocity regulator may ask while it is
    /// saturated, as a fraction of `torque_limit_pu`, 0..=1. The regulator's output is
    /// clamped so that it plus the AFB term reaches the limit; the AFB term is recomputed
    /// every current tick after that, so without headroom each tick-to-tick change of the
    /// estimate (count noise) takes the torque off the limit while the drive is saturated.
    /// With it, the torque stays at the limit until the regulator itself asks for less.
    /// 0 is the plain clamp and the default: in loops that oscillate through the limit the
    /// headroom also holds the torque there longer, which turned one design `tune` had
    /// verified into one it refuses (`docs/design.md`). 0.15 is the middle of the range
    /// (0.1 to 0.2) in which the dyno's saturated acceleration has less shaft ripple with
    /// AFB than without; `configs/machines/dyno.toml` sets it.
    pub limit_headroom_fraction: f32,
    /// What the AFB filter does on a current tick whose torque reference is at its limit
    /// (observer source only).
    pub filter_at_limit: AfbFilterAtLimit,
}

/// The AFB filter on a tick whose torque reference is at its limit. The AFB term is
/// solved in closed form through the observer's model, and the filter step is completed
/// with the acceleration the applied torque predicts. At the limit the torque no longer
/// follows the AFB term, and a tracking filter keeps running on an input the torque cannot
/// act on (`docs/design.md`, "The AFB filter at the limit").
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
pub enum AfbFilterAtLimit {
    /// Complete the filter step with the clamped torque, as on any tick (the default).
    Track,
    /// Hold the filter's state while the torque is at the limit: the AFB term still follows
    /// the estimate through the filter's feed-through, and the filter resumes from where it
    /// was when the torque leaves the limit. With `source = "differentiation"` the filter's
    /// input holds no torque, and the two are the same.
    Hold,
}

/// Inertia the observer's model uses to turn the torque command into acceleration.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
pub enum ObserverInertia {
    /// Motor plus load (`motor_inertia_s + load_inertia_s`): right while the gears are engaged.
    Total,
    /// Motor alone (`motor_inertia_s`): right inside the lost motion.
    Motor,
}

/// Inertia the velocity PI is sized for (Kp = ω_v·J, Ki = Kp·ω_v/(4ζ²)).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
pub enum PiInertia {
    /// J = J_total: the regulator is tuned for the machine and acceleration feedback adds
    /// inertia electrically on top of it (the paper's reading, Fig. 2). With AFB off or on,
    /// the velocity gains are the same.
    Total,
    /// J = J_total + Ka: the velocity loop keeps its bandwidth with AFB on, at the price of
    /// most of the disturbance benefit (the regulator gains grow with Ka).
    TotalPlusAfb,
}

/// Torque the observer's model is driven with.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
pub enum ObserverTorque {
    /// The torque (current) reference of the last current tick.
    Command,
    /// The measured current: the mean of this and the last current tick's sample.
    MeasuredCurrent,
}

/// Luenberger observer settings.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields, default))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
pub struct ObserverConfig {
    /// Observer bandwidth \[Hz\]: the three observer poles sit at z = e^(−2π·f·Ts_current).
    /// 0 < f < current_rate_hz/2.
    pub bandwidth_hz: f32,
    /// Model inertia.
    pub model_inertia: ObserverInertia,
    /// Torque input of the model (see `docs/design.md` for the measurement
    /// behind the default, `Command`).
    pub torque_input: ObserverTorque,
    /// The encoder's quantization in the innovation \[counts\], 0..=0.5: a count n says
    /// only that the position lies in \[n, n + 1). With h > 0 the observer corrects by how
    /// far its predicted position lies outside the interval of half-width h around the
    /// middle of that count (no correction inside it), so the count's own steps stop
    /// reaching the velocity and acceleration estimates; 0.5 is the whole count. 0 is the
    /// plain innovation (n − p̂) and the default (`docs/design.md`, "The count interval in
    /// the observer").
    pub count_interval_counts: f32,
}

/// A notch filter on the torque reference (`[drive.notch]`), designed at the current rate
/// ([`crate::notch`]). All three keys are required when the table is present.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
pub struct NotchConfig {
    /// Centre frequency f0 \[Hz\], > 0 and below current_rate_hz/2.
    pub centre_hz: f32,
    /// −3 dB width of the notch \[Hz\], > 0 and at most `centre_hz`.
    pub width_hz: f32,
    /// Attenuation at the centre \[dB\], 0..=80 (0 is a pass-through).
    pub depth_db: f32,
}

/// Fault thresholds.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields, default))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
pub struct FaultLimits {
    /// Overspeed trip on the velocity estimate \[pu\], > 0.
    pub overspeed_pu: f32,
    /// Following-error trip on |commanded − measured position| \[motor revolutions\], > 0;
    /// only while the position loop is on. The drive compares it in counts
    /// (× `encoder_cpr`, the counts the drive reads per revolution, after any
    /// interpolation), held in Q24.8: the limit in counts must stay below 2^23, so the
    /// range is (0, 2^23 / encoder_cpr] (at most 1000).
    pub following_error_rev: f32,
    /// Encoder jump trip: a change of counts between two current ticks larger than
    /// `margin × overspeed_pu × counts per current tick at 1 pu + 2` counts, ≥ 1: a multiple
    /// of the motion the overspeed limit allows, so the same on any encoder.
    pub encoder_jump_margin: f32,
    /// Overcurrent trip level as a multiple of `torque_limit_pu` (so always above the
    /// torque limit), 1 < ratio ≤ 100: |measured current| above
    /// `overcurrent_ratio × torque_limit_pu` for `overcurrent_ticks` current ticks in a row.
    pub overcurrent_ratio: f32,
    /// Consecutive current ticks over the overcurrent level that trip, 1..=1000.
    #[cfg_attr(feature = "serde", serde(deserialize_with = "whole::u32"))]
    #[cfg_attr(feature = "schema", schemars(with = "u32"))]
    pub overcurrent_ticks: u32,
    /// Winding current the motor carries without limit (I²t model's i_cont) \[pu\], > 0.
    pub continuous_current_pu: f32,
    /// The overload class's current \[pu\], above `continuous_current_pu`: the I²t model
    /// trips after `overload_time_s` at this current from cold (150 % for 60 s by default).
    pub overload_current_pu: f32,
    /// The overload class's time \[s\], 0 < t ≤ 3600.
    pub overload_time_s: f32,
    /// The I²t model warns ([`crate::Controller::thermal_warning`]) from this fraction of
    /// its trip level on, 0 < f ≤ 1.
    pub thermal_warning_fraction: f32,
    /// Stall: |velocity estimate| below this \[pu\] (0..=1) with |torque reference| at or
    /// above `stall_torque_fraction × torque_limit_pu` for `stall_time_s` trips.
    pub stall_speed_pu: f32,
    /// The torque of a stall as a fraction of `torque_limit_pu`, 0 < f ≤ 1 (1: the
    /// velocity tick's torque reference at its limit, i.e. the speed regulator saturated).
    pub stall_torque_fraction: f32,
    /// Stall time \[s\], 0..=600; 0 turns the stall trip off.
    pub stall_time_s: f32,
}

/// The drive's settings. Every field is plain data; the units are in the names.
///
/// With the `serde` feature this is the `[drive]` table of a configuration file: the machine
/// keys (`base_speed_rpm`, `encoder_cpr`, `motor_inertia_s`, `load_inertia_s`,
/// `winding_resistance_pu`, `winding_inductance_pu_s`) and the loop keys (`current_rate_hz`,
/// `velocity_rate_hz`, `position_bandwidth_rad_s`, `velocity_bandwidth_rad_s`,
/// `current_bandwidth_rad_s`) are required; every other key defaults to stiffdrive's design
/// default (see [`defaults`]); without a `[drive.notch]` table there is no notch. Ranges:
/// [`crate::ranges::RANGES`], checked by [`DriveConfig::validate`].
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
pub struct DriveConfig {
    /// Base (rated) speed \[rpm\], defines 1 pu of speed. > 0.
    pub base_speed_rpm: f32,
    /// Encoder counts per motor revolution (after quadrature), ≥ 4.
    #[cfg_attr(feature = "serde", serde(deserialize_with = "whole::u32"))]
    #[cfg_attr(feature = "schema", schemars(with = "u32"))]
    pub encoder_cpr: u32,
    /// Width of the hardware counter that delivers `encoder_count` \[bits\], 16..=32.
    #[cfg_attr(
        feature = "serde",
        serde(default = "defaults::counter_bits", deserialize_with = "whole::u8")
    )]
    #[cfg_attr(feature = "schema", schemars(with = "u8"))]
    pub counter_bits: u8,
    /// Current-loop tick rate \[Hz\], 100..=100,000.
    #[cfg_attr(feature = "serde", serde(deserialize_with = "whole::u32"))]
    #[cfg_attr(feature = "schema", schemars(with = "u32"))]
    pub current_rate_hz: u32,
    /// Velocity-loop tick rate \[Hz\]; must divide `current_rate_hz`.
    #[cfg_attr(feature = "serde", serde(deserialize_with = "whole::u32"))]
    #[cfg_attr(feature = "schema", schemars(with = "u32"))]
    pub velocity_rate_hz: u32,
    /// Motor inertia \[s\], > 0.
    pub motor_inertia_s: f32,
    /// Load inertia reflected to the motor \[s\], ≥ 0.
    pub load_inertia_s: f32,
    /// Position-loop bandwidth \[rad/s\] (Kpp = ω_pos); 0 = position loop off (velocity mode).
    pub position_bandwidth_rad_s: f32,
    /// Velocity-loop bandwidth \[rad/s\]: Kp = ω·J, Ki = Kp·ω/(4ζ²). > 0, below π·velocity_rate_hz.
    pub velocity_bandwidth_rad_s: f32,
    /// Velocity-loop damping ζ, 0.1..=10 (1 = Ki = Kp·ω/4).
    #[cfg_attr(feature = "serde", serde(default = "defaults::velocity_damping"))]
    pub velocity_damping: f32,
    /// Inertia the velocity PI is sized for (`[drive] velocity_pi_inertia`).
    #[cfg_attr(feature = "serde", serde(default = "defaults::velocity_pi_inertia"))]
    pub velocity_pi_inertia: PiInertia,
    /// Current-loop bandwidth \[rad/s\]: Kp = L·ω_c, Ki = R·ω_c. > 0, below π·current_rate_hz.
    pub current_bandwidth_rad_s: f32,
    /// Winding resistance \[pu voltage per pu current\], > 0.
    pub winding_resistance_pu: f32,
    /// Winding inductance \[pu voltage per pu current per second, i.e. pu·s\], > 0.
    pub winding_inductance_pu_s: f32,
    /// Torque (= current) reference limit \[pu\], > 0.
    #[cfg_attr(feature = "serde", serde(default = "defaults::torque_limit_pu"))]
    pub torque_limit_pu: f32,
    /// Voltage command limit \[pu\], > 0.
    #[cfg_attr(feature = "serde", serde(default = "defaults::voltage_limit_pu"))]
    pub voltage_limit_pu: f32,
    /// Fraction of the commanded velocity fed forward into the velocity reference, 0..=1
    /// (position mode; in velocity mode the setpoint velocity is the reference).
    #[cfg_attr(feature = "serde", serde(default = "defaults::velocity_ff_gain"))]
    pub velocity_ff_gain: f32,
    /// Fraction of the commanded acceleration times inertia fed forward as torque, 0..=1.
    #[cfg_attr(feature = "serde", serde(default = "defaults::accel_ff_gain"))]
    pub accel_ff_gain: f32,
    /// Low-pass filter on the velocity feedback.
    #[cfg_attr(feature = "serde", serde(default = "defaults::velocity_filter"))]
    pub velocity_filter: FilterConfig,
    /// Source of the velocity feedback.
    #[cfg_attr(feature = "serde", serde(default = "defaults::velocity_estimator"))]
    pub velocity_estimator: Estimator,
    /// Acceleration feedback.
    #[cfg_attr(feature = "serde", serde(default))]
    pub accel_feedback: AccelFeedbackConfig,
    /// State observer.
    #[cfg_attr(feature = "serde", serde(default))]
    pub observer: ObserverConfig,
    /// Fault thresholds.
    #[cfg_attr(feature = "serde", serde(default))]
    pub faults: FaultLimits,
    /// Notch filter on the torque reference; `None` (no `[drive.notch]` table): no notch.
    #[cfg_attr(
        feature = "serde",
        serde(default, skip_serializing_if = "Option::is_none")
    )]
    pub notch: Option<NotchConfig>,
    /// The motor kind's current loop: `None` (no `[drive.pmsm]` table) drives one DC
    /// winding with the current PI; a `[drive.pmsm]` table drives a three-phase
    /// permanent-magnet motor by field-oriented control ([`crate::foc`]).
    #[cfg_attr(
        feature = "serde",
        serde(default, skip_serializing_if = "Option::is_none")
    )]
    pub pmsm: Option<crate::foc::PmsmConfig>,
}

impl DriveConfig {
    /// Total inertia J_total = motor + load \[s\].
    #[must_use]
    pub fn total_inertia_s(&self) -> f32 {
        self.motor_inertia_s + self.load_inertia_s
    }
}

impl Default for AccelFeedbackConfig {
    fn default() -> Self {
        defaults::ACCEL_FEEDBACK
    }
}

impl Default for ObserverConfig {
    fn default() -> Self {
        defaults::OBSERVER
    }
}

impl Default for FaultLimits {
    fn default() -> Self {
        defaults::FAULTS
    }
}

pub mod defaults {
    //! stiffdrive's design defaults of the settings a configuration may omit (the ones
    //! `docs/design.md` explains: acceleration feedback in the error form at
    //! Ka = 0.5·J_total from the observer, first-order filter at 100 Hz, every current tick;
    //! observer at 75 Hz with the motor-inertia model). They are design choices, not machine
    //! data: the machine and loop-rate keys have no default.
    use super::{
        AccelFeedbackConfig, AfbFilterAtLimit, AfbMode, AfbRate, Estimator, FaultLimits,
        FilterConfig, ObserverConfig, ObserverInertia, ObserverTorque, PiInertia,
    };

    /// Acceleration feedback: error form, Ka = 0.5·J_total, first order at 100 Hz, every
    /// current tick, acceleration from the observer, no headroom beyond the torque limit.
    pub const ACCEL_FEEDBACK: AccelFeedbackConfig = AccelFeedbackConfig {
        mode: AfbMode::Error,
        gain_fraction: 0.5,
        filter: FilterConfig::FirstOrder { corner_hz: 100.0 },
        rate: AfbRate::Current,
        source: Estimator::Observer,
        limit_headroom_fraction: 0.0,
        filter_at_limit: AfbFilterAtLimit::Track,
    };
    /// Observer: 75 Hz, motor-inertia model, driven by the torque command, the plain
    /// innovation.
    pub const OBSERVER: ObserverConfig = ObserverConfig {
        bandwidth_hz: 75.0,
        model_inertia: ObserverInertia::Motor,
        torque_input: ObserverTorque::Command,
        count_interval_counts: 0.0,
    };
    /// Fault limits: overspeed 1.5 pu, following error a quarter of a motor revolution,
    /// encoder-jump margin 2;
    /// overcurrent at 1.5 × the torque limit for 3 current ticks; I²t with 1 pu continuous
    /// and the 150 % for 60 s overload class, warning at 80 %; stall below 0.02 pu at the
    /// torque limit for 3 s.
    pub const FAULTS: FaultLimits = FaultLimits {
        overspeed_pu: 1.5,
        following_error_rev: 0.25,
        encoder_jump_margin: 2.0,
        overcurrent_ratio: 1.5,
        overcurrent_ticks: 3,
        continuous_current_pu: 1.0,
        overload_current_pu: 1.5,
        overload_time_s: 60.0,
        thermal_warning_fraction: 0.8,
        stall_speed_pu: 0.02,
        stall_torque_fraction: 1.0,
        stall_time_s: 3.0,
    };

    /// Butterworth Q = 1/√2 of a second-order filter that names no `q`.
    #[must_use]
    pub const fn butterworth_q() -> f32 {
        core::f32::consts::FRAC_1_SQRT_2
    }
    /// 16-bit hardware counter.
    #[must_use]
    pub const fn counter_bits() -> u8 {
        16
    }
    /// ζ = 1 (Ki = Kp·ω/4).
    #[must_use]
    pub const fn velocity_damping() -> f32 {
        1.0
    }
    /// PI sized for J_total.
    #[must_use]
    pub const fn velocity_pi_inertia() -> PiInertia {
        PiInertia::Total
    }
    /// 2 pu torque.
    #[must_use]
    pub const fn torque_limit_pu() -> f32 {
        2.0
    }
    /// 1.2 pu voltage.
    #[must_use]
    pub const fn voltage_limit_pu() -> f32 {
        1.2
    }
    /// Full velocity feed-forward.
    #[must_use]
    pub const fn velocity_ff_gain() -> f32 {
        1.0
    }
    /// Full acceleration feed-forward.
    #[must_use]
    pub const fn accel_ff_gain() -> f32 {
        1.0
    }
    /// No velocity filter.
    #[must_use]
    pub const fn velocity_filter() -> FilterConfig {
        FilterConfig::None
    }
    /// Velocity from the observer.
    #[must_use]
    pub const fn velocity_estimator() -> Estimator {
        Estimator::Observer
    }
}

#[cfg(feature = "serde")]
mod whole {
    //! Whole-number fields accept an integer or an integral float (`24` or `24.0`) and
    //! reject a fractional one: a count, a bit width or a rate is never truncated.
    use core::fmt;
    use serde::de::{self, Deserializer, Visitor};

    struct Whole(u64);

    impl<'de> serde::Deserialize<'de> for Whole {
        fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
            d.deserialize_any(WholeVisitor)
        }
    }

    struct WholeVisitor;

    impl Visitor<'_> for WholeVisitor {
        type Value = Whole;
        fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
            f.write_str("a non-negative whole number")
        }
        fn visit_u64<E: de::Error>(self, v: u64) -> Result<Whole, E> {
            Ok(Whole(v))
        }
        fn visit_i64<E: de::Error>(self, v: i64) -> Result<Whole, E> {
            u64::try_from(v)
                .map(Whole)
                .map_err(|_| E::custom(format_args!("{v}: must be a non-negative whole number")))
        }
        fn visit_f64<E: de::Error>(self, v: f64) -> Result<Whole, E> {
            // 2^64 is exact in f64; below it an integral value converts without loss.
            if (0.0..18_446_744_073_709_551_616.0).contains(&v) && v == (v as u64) as f64 {
                Ok(Whole(v as u64))
            } else {
                Err(E::custom(format_args!("{v}: must be a whole number")))
            }
        }
    }

    fn narrow<'de, D: Deserializer<'de>, T: TryFrom<u64>>(d: D) -> Result<T, D::Error> {
        let Whole(v) = serde::Deserialize::deserialize(d)?;
        T::try_from(v).map_err(|_| {
            de::Error::custom(format_args!(
                "{v}: too large for a {}",
                core::any::type_name::<T>()
            ))
        })
    }

    pub(super) fn u32<'de, D: Deserializer<'de>>(d: D) -> Result<u32, D::Error> {
        narrow(d)
    }

    pub(super) fn u8<'de, D: Deserializer<'de>>(d: D) -> Result<u8, D::Error> {
        narrow(d)
    }
}

#[cfg(feature = "serde")]
mod filter_de;
