//! The ranges of the settings that derived numbers scale with ([`Scales`]), and the
//! searches that state their tops exactly: a derived number is computed in f32 (the
//! design's own arithmetic), and near its format's top (no f32: 2^15 − 2^−16 for Q16.16)
//! a top worked out in f64 could round onto the format's bound and be refused.

use super::{ConfigError, DriveConfig, Range, checked_q, quantize};

/// The inertia the velocity PI is designed for, in `design`'s own f32 arithmetic: J_total,
/// plus Ka = gain_fraction × J_total with `velocity_pi_inertia = "total_plus_afb"` and the
/// feedback on.
pub(crate) fn velocity_loop_inertia(cfg: &DriveConfig) -> f32 {
    let j_total = cfg.total_inertia_s();
    let ka = if cfg.accel_feedback.mode == crate::config::AfbMode::Off {
        0.0
    } else {
        cfg.accel_feedback.gain_fraction * j_total
    };
    match cfg.velocity_pi_inertia {
        crate::config::PiInertia::Total => j_total,
        crate::config::PiInertia::TotalPlusAfb => j_total + ka,
    }
}

/// The velocity PI's `(Kp, Ki·Ts)` at bandwidth `w` for the loop inertia `j_loop`, damping
/// `zeta` and velocity rate `f_vel`, in the f32 arithmetic (and order) of `design` and the
/// regulators' quantization: Kp = ω·J, Ki·Ts = Kp·ω/(4ζ²)/f_vel.
pub(crate) fn velocity_pi_gains(w: f32, j_loop: f32, zeta: f32, f_vel: f32) -> (f32, f32) {
    let kp = w * j_loop;
    (kp, kp * w / (4.0 * zeta * zeta) / f_vel)
}

/// The largest f32 in [0, `limit`] at which `fits` holds, for a `fits` that holds from 0 up
/// to some value and not above it (a derived number that grows with the setting, against
/// its format's top): `limit` if it fits, else by bisection on the bits of the
/// non-negative f32s, which order as their values (at most 32 steps). 0 if `fits(0)` fails.
pub(crate) fn largest_fitting(limit: f32, fits: impl Fn(f32) -> bool) -> f32 {
    let limit = limit.max(0.0);
    if fits(limit) {
        return limit;
    }
    if !fits(0.0) {
        return 0.0;
    }
    f32::from_bits(last_true(0, limit.to_bits(), |b| fits(f32::from_bits(b))))
}

/// The smallest f32 in [0, `limit`] at which `fits` holds, for a `fits` that holds from some
/// value on (a derived number that grows with the setting, against its format's floor): by
/// bisection on the bits, as [`largest_fitting`]. ∞ if `fits(limit)` fails.
pub(crate) fn smallest_fitting(limit: f32, fits: impl Fn(f32) -> bool) -> f32 {
    let limit = limit.max(0.0);
    if fits(0.0) {
        return 0.0;
    }
    if !fits(limit) {
        return f32::INFINITY;
    }
    f32::from_bits(last_true(0, limit.to_bits(), |b| !fits(f32::from_bits(b))) + 1)
}

/// The largest whole count in [0, `limit`] at which `fits` holds (holding from 0 up to some
/// count): `limit` if it fits, else by bisection. 0 if `fits(0)` fails.
pub(crate) fn largest_whole(limit: u32, fits: impl Fn(u32) -> bool) -> u32 {
    if fits(limit) {
        return limit;
    }
    if !fits(0) {
        return 0;
    }
    last_true(0, limit, fits)
}

/// The smallest whole count at or above `start` at which `fits` holds (holding from some
/// count on): `start` if it fits, else by bisection. `u32::MAX` if none does.
pub(crate) fn smallest_whole(start: u32, fits: impl Fn(u32) -> bool) -> u32 {
    if fits(start) {
        return start;
    }
    if !fits(u32::MAX) {
        return u32::MAX;
    }
    last_true(start, u32::MAX, |x| !fits(x)) + 1
}

/// The last `x` in [`lo`, `hi`) with `p(x)`, given `p(lo)` and not `p(hi)` (`p` true up to
/// some point, false after it): by bisection, at most 32 steps.
fn last_true(mut lo: u32, mut hi: u32, p: impl Fn(u32) -> bool) -> u32 {
    while hi - lo > 1 {
        let mid = lo + (hi - lo) / 2;
        if p(mid) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

/// The user's setting a derived number scales with: `value = c · setting^power`, the other
/// settings fixed. A quantization that fails ([`fit`]) is reported as this setting, with
/// the range of it that fits ([`Scales::bounds`]).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Scales {
    /// The setting's range (its key and its own bounds).
    pub(crate) range: &'static Range,
    /// The setting's value.
    pub(crate) setting: f32,
    /// How the derived number grows with it (1: in proportion, 2: with its square; > 0).
    pub(crate) power: f64,
    /// The other settings the range depends on, and the format.
    pub(crate) given: &'static str,
    /// A bound of the setting's own above the format's (the largest value below its loop's
    /// Nyquist limit), or ∞.
    pub(crate) cap: f32,
}

impl Scales {
    /// The range of the setting that keeps `value` inside `T`: |value| at most `T`'s
    /// maximum, and (non-zero) at least 50 of its steps, so that the rounding stays within
    /// 1 % ([`quantize`]'s rule). Intersected with the setting's own range.
    ///
    /// `derive` is the derived number as the design computes it from a value of the
    /// setting (the others fixed), in the same f32 arithmetic: the top is the largest f32
    /// setting whose number `T` holds ([`largest_fitting`]), since the format's largest
    /// value is no f32 and a top worked out in f64 could round onto the format's bound.
    pub(crate) fn bounds<T: fixed::traits::Fixed>(
        &self,
        value: f32,
        derive: impl Fn(f32) -> f32,
    ) -> (f32, f32) {
        let top = largest_fitting(self.range.max.min(self.cap), |x| {
            checked_q::<T>(derive(x)).is_some()
        });
        (self.floor::<T>(value), top)
    }

    /// The bottom of [`Scales::bounds`]: where `value` (at this setting) falls to 50 steps of
    /// `T`, or the setting's own minimum. It needs no f32 care: `quantize` keeps a value
    /// down to about 49.5 steps (within 1 %), far below any rounding of 50.
    fn floor<T: fixed::traits::Fixed>(&self, value: f32) -> f32 {
        let r = self.range;
        let (v, x) = (f64::from(value).abs(), f64::from(self.setting));
        if v == 0.0 || x <= 0.0 || !v.is_finite() || self.power <= 0.0 {
            return r.min;
        }
        let step: f64 = T::DELTA.to_num();
        let ratio = crate::cfgmath::ln(50.0 * step / v) / self.power;
        ((x * crate::cfgmath::exp(ratio)) as f32).max(r.min)
    }

    /// The error for `value` (`derive` of this setting) not fitting `T`: this setting, its
    /// value and its range ([`Scales::bounds`]).
    pub(crate) fn error<T: fixed::traits::Fixed>(
        &self,
        value: f32,
        derive: impl Fn(f32) -> f32,
    ) -> ConfigError {
        let (min, max) = self.bounds::<T>(value, derive);
        ConfigError::OutOfRangeGiven {
            param: self.range.key,
            value: self.setting,
            min,
            max,
            min_exclusive: self.range.min_exclusive && min <= self.range.min,
            given: self.given,
        }
    }
}

/// `value` quantized to `T`; if it does not fit, the error names the user's setting `s`
/// and the range of it that fits. `derive`: `value` as the design computes it from the
/// setting ([`Scales::bounds`]).
pub(crate) fn fit<T: fixed::traits::Fixed>(
    value: f32,
    s: Scales,
    derive: impl Fn(f32) -> f32,
) -> Result<T, ConfigError> {
    quantize::<T>(value, s.range.key).map_err(|_| s.error::<T>(value, derive))
}

/// A setting quantized as itself (`power` 1) to `T`, whose format bounds it.
pub(crate) fn fit_setting<T: fixed::traits::Fixed>(
    range: &'static Range,
    value: f32,
    given: &'static str,
) -> Result<T, ConfigError> {
    fit(
        value,
        Scales {
            range,
            setting: value,
            power: 1.0,
            given,
            cap: f32::INFINITY,
        },
        |x| x,
    )
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::{largest_fitting, largest_whole, smallest_fitting, smallest_whole};
    use crate::config::{AfbMode, PiInertia};

    /// The velocity PI's gains as the range checks compute them are `design`'s, bit for
    /// bit, across the inertia choices and AFB modes.
    #[test]
    fn the_velocity_pi_formula_is_the_design_s() {
        let base: crate::DriveConfig = toml::from_str(include_str!(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/doc/example-drive.toml"
        )))
        .unwrap();
        for (k, pi) in [PiInertia::Total, PiInertia::TotalPlusAfb]
            .into_iter()
            .enumerate()
        {
            for (m, mode) in [AfbMode::Off, AfbMode::Plain, AfbMode::Error]
                .into_iter()
                .enumerate()
            {
                let mut c = base;
                c.velocity_pi_inertia = pi;
                c.accel_feedback.mode = mode;
                c.accel_feedback.gain_fraction = 0.37 + 0.91 * m as f32;
                c.load_inertia_s = 0.6 + 0.173 * k as f32;
                c.velocity_damping = 0.71 + 0.3 * m as f32;
                let g = crate::design(&c).unwrap();
                let j = super::velocity_loop_inertia(&c);
                assert_eq!(j.to_bits(), g.j_loop_s.to_bits());
                let f = c.velocity_rate_hz as f32;
                let (kp, ki) =
                    super::velocity_pi_gains(c.velocity_bandwidth_rad_s, j, c.velocity_damping, f);
                assert_eq!(kp.to_bits(), g.kp_vel.to_bits());
                assert_eq!(ki.to_bits(), (g.ki_vel / f).to_bits());
            }
        }
    }

    /// The searches find the edge of a threshold exactly, and their ends.
    #[test]
    fn the_searches_find_the_edge() {
        let t = 1.2345f32;
        assert_eq!(largest_fitting(10.0, |x| x <= t), t);
        assert_eq!(largest_fitting(1.0, |x| x <= t), 1.0);
        assert_eq!(
            largest_fitting(f32::INFINITY, |x| x * 3.0 < 32_768.0),
            10_922.666
        );
        assert_eq!(largest_fitting(10.0, |x| x < 0.0), 0.0);
        assert_eq!(smallest_fitting(10.0, |x| x >= t), t);
        assert_eq!(smallest_fitting(10.0, |x| x >= 20.0), f32::INFINITY);
        assert_eq!(smallest_fitting(10.0, |_| true), 0.0);
        assert_eq!(largest_whole(1000, |n| n <= 617), 617);
        assert_eq!(largest_whole(500, |n| n <= 617), 500);
        assert_eq!(largest_whole(u32::MAX, |n| n < 3), 2);
        assert_eq!(smallest_whole(4, |n| n >= 617), 617);
        assert_eq!(smallest_whole(700, |n| n >= 617), 700);
        assert_eq!(smallest_whole(0, |n| n == u32::MAX), u32::MAX);
        assert_eq!(smallest_whole(0, |_| false), u32::MAX);
    }
}
