//! Typed configuration errors. Each names the offending parameter (its `DriveConfig` or
//! `ProfileConfig` field path) and the allowed range.

use core::fmt;

/// A fixed-point format Qm.n, read off the type itself ([`QFormat::of`]), so an error can
/// never name another format than the one the value was quantized to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct QFormat {
    /// Integer bits m (including the sign bit).
    pub int_bits: u32,
    /// Fractional bits n.
    pub frac_bits: u32,
}

impl QFormat {
    /// The format of the `fixed` type `T`, e.g. `Q16.16` for `I16F16`.
    ///
    /// ```
    /// use controller_core::error::QFormat;
    /// use controller_core::per_unit::Coef;
    /// assert_eq!(QFormat::of::<Coef>().to_string(), "Q2.30");
    /// ```
    #[must_use]
    pub const fn of<T: fixed::traits::Fixed>() -> Self {
        Self {
            int_bits: T::INT_NBITS,
            frac_bits: T::FRAC_NBITS,
        }
    }
}

impl fmt::Display for QFormat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Q{}.{}", self.int_bits, self.frac_bits)
    }
}

/// A bad setting found by [`crate::design()`], [`crate::Controller::new`] or
/// [`crate::Profile::new`]. Never a panic and never a silent clamp.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ConfigError {
    /// The value is NaN or infinite.
    NotFinite {
        /// Field path, e.g. `"motor_inertia_s"`.
        param: &'static str,
    },
    /// The value lies outside its allowed range `[min, max]` (`min_exclusive`: `(min, max]`).
    OutOfRange {
        /// Field path.
        param: &'static str,
        /// The value given.
        value: f32,
        /// Smallest allowed value.
        min: f32,
        /// Largest allowed value.
        max: f32,
        /// Whether `min` itself is excluded (e.g. strictly positive quantities).
        min_exclusive: bool,
    },
    /// The value lies outside the range the other settings leave it: a quantity derived from
    /// it (a gain, a limit in counts) must fit its fixed-point format or the encoder
    /// counter. `given` names the other settings and what bounds the range.
    OutOfRangeGiven {
        /// Field path of the setting.
        param: &'static str,
        /// The value given.
        value: f32,
        /// Smallest allowed value, given the others.
        min: f32,
        /// Largest allowed value, given the others.
        max: f32,
        /// Whether `min` itself is excluded.
        min_exclusive: bool,
        /// The other settings the range depends on, and why.
        given: &'static str,
    },
    /// A frequency at or above its loop's Nyquist limit.
    AboveNyquist {
        /// Field path.
        param: &'static str,
        /// The value given, in the field's unit (rad/s or Hz).
        value: f32,
        /// The (exclusive) limit in the same unit.
        nyquist: f32,
    },
    /// A derived gain or coefficient does not fit its fixed-point format.
    CoefficientOverflow {
        /// Name of the derived coefficient (see `Gains`) and the settings it comes from.
        param: &'static str,
        /// The computed value.
        value: f32,
        /// The Q-format it must fit.
        q_format: QFormat,
    },
    /// A non-zero derived gain or coefficient is too small for its fixed-point format
    /// (it would be quantized with more than 1 % error).
    CoefficientUnderflow {
        /// Name of the derived coefficient and the settings it comes from.
        param: &'static str,
        /// The computed value.
        value: f32,
        /// The Q-format it must fit.
        q_format: QFormat,
    },
    /// A setting the drive needs before it may enable, which only a measurement gives
    /// (the PMSM's encoder offset): `measure` says what to run.
    Missing {
        /// Field path.
        param: &'static str,
        /// The command that measures it.
        measure: &'static str,
    },
    /// `current_rate_hz` is not an integer multiple of `velocity_rate_hz`.
    RateRatio {
        /// Current tick rate \[Hz\].
        current_rate_hz: u32,
        /// Velocity tick rate \[Hz\].
        velocity_rate_hz: u32,
    },
}

impl ConfigError {
    /// `value` of `param` does not fit the format of `T`.
    #[must_use]
    pub const fn overflow<T: fixed::traits::Fixed>(param: &'static str, value: f32) -> Self {
        Self::CoefficientOverflow {
            param,
            value,
            q_format: QFormat::of::<T>(),
        }
    }

    /// `value` of `param` is too small for the format of `T`.
    #[must_use]
    pub const fn underflow<T: fixed::traits::Fixed>(param: &'static str, value: f32) -> Self {
        Self::CoefficientUnderflow {
            param,
            value,
            q_format: QFormat::of::<T>(),
        }
    }

    /// The name of the offending parameter.
    #[must_use]
    pub fn param(&self) -> &'static str {
        match self {
            Self::NotFinite { param }
            | Self::OutOfRange { param, .. }
            | Self::OutOfRangeGiven { param, .. }
            | Self::AboveNyquist { param, .. }
            | Self::CoefficientOverflow { param, .. }
            | Self::CoefficientUnderflow { param, .. }
            | Self::Missing { param, .. } => param,
            Self::RateRatio { .. } => "velocity_rate_hz",
        }
    }
}

/// `[min, max]`, `(min, max]`, or with an unbounded `max` `[min, ∞)`.
fn write_range(f: &mut fmt::Formatter<'_>, min: f32, max: f32, min_exclusive: bool) -> fmt::Result {
    let open = if min_exclusive { '(' } else { '[' };
    write!(f, "{open}{}, ", Num(min))?;
    if max == f32::INFINITY {
        f.write_str("∞)")
    } else {
        write!(f, "{}]", Num(max))
    }
}

/// A number as a user wrote it: a whole number of 10^7 or more (counts, an encoder's
/// 2^30) in all its digits, where `f32`'s shortest form would round it (1073741800).
struct Num(f32);

impl fmt::Display for Num {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let v = self.0;
        if v.is_finite() && v.abs() >= 1e7 && v.abs() < 1e15 && v == (v as i64) as f32 {
            write!(f, "{}", v as i64)
        } else {
            write!(f, "{v}")
        }
    }
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::NotFinite { param } => write!(f, "{param}: must be a finite number"),
            Self::Missing { param, measure } => write!(
                f,
                "{param} is not set: the drive refuses to enable without it; measure it with `{measure}`"
            ),
            Self::OutOfRange {
                param,
                value,
                min,
                max,
                min_exclusive,
            } => {
                write!(f, "{param} = {}: allowed range is ", Num(value))?;
                write_range(f, min, max, min_exclusive)
            }
            Self::OutOfRangeGiven {
                param,
                value,
                min,
                max,
                min_exclusive,
                given,
            } => {
                write!(f, "{param} = {}: allowed range is ", Num(value))?;
                write_range(f, min, max, min_exclusive)?;
                write!(f, " given {given}")
            }
            Self::AboveNyquist {
                param,
                value,
                nyquist,
            } => write!(
                f,
                "{param} = {value}: must be below the loop's Nyquist limit {nyquist}"
            ),
            Self::CoefficientOverflow {
                param,
                value,
                q_format,
            } => write!(
                f,
                "{param} = {value}: does not fit its fixed-point format {q_format}"
            ),
            Self::CoefficientUnderflow {
                param,
                value,
                q_format,
            } => write!(
                f,
                "{param} = {value}: too small for its fixed-point format {q_format} (more than 1 % quantization error)"
            ),
            Self::RateRatio {
                current_rate_hz,
                velocity_rate_hz,
            } => write!(
                f,
                "velocity_rate_hz = {velocity_rate_hz}: must divide current_rate_hz = {current_rate_hz} \
                 (allowed: current_rate_hz / n, n = 1..=16)"
            ),
        }
    }
}
