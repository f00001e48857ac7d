//! The electrical angle from the motor encoder: `θe = offset ± pole_pairs·2π·count/cpr`,
//! as a 32-bit phase (2^32 per electrical turn, wrapping), and its advance by the
//! computational delay, `θe + ω_e·t_delay`, so that the inverse Park transform uses the
//! angle at which the voltage acts.

use crate::error::ConfigError;
use crate::per_unit::Pu;

/// The angle's coefficients, fixed at configuration.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AngleCoefficients {
    /// Encoder counts per mechanical revolution (after quadrature), ≥ 1.
    cpr: u32,
    /// One count in phase units, Q32.32 taken modulo 2^64: round(2^64·pole_pairs/cpr).
    /// Only the phase modulo one turn matters, so the wrapped product is exact there.
    phase_per_count: u64,
    /// The phase at count 0.
    offset: u32,
    /// Counts that rise while the electrical angle falls.
    reversed: bool,
    /// Phase units per Q16.16 bit of speed, Q32.32: round(2^32·pole_pairs·(rpm/60)·t_delay·2^16/2^16).
    advance_per_speed_bit: i64,
}

/// The angle's state: the count within one mechanical revolution, in `[0, cpr)`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct AngleState {
    /// Counts since the last whole revolution from count 0.
    pub count_in_rev: u32,
}

/// A phase in units of 2^-32 turn from an angle in degrees (wrapping).
#[must_use]
pub fn phase_of_deg(deg: f32) -> u32 {
    let turns = f64::from(deg) / 360.0;
    let frac = turns - floor(turns);
    // frac in [0, 1]; 2^32·frac rounds to at most 2^32, which wraps to 0 (the same angle).
    ((frac * 4_294_967_296.0 + 0.5) as u64) as u32
}

/// `x.floor()` without std.
fn floor(x: f64) -> f64 {
    let t = x as i64 as f64;
    if t > x { t - 1.0 } else { t }
}

impl AngleCoefficients {
    /// The angle of a motor with `pole_pairs` on an encoder of `cpr` counts per revolution,
    /// whose electrical angle at count 0 is `offset_elec_deg`, counting against the
    /// electrical angle when `reversed`. `t_delay_s` is the time from the current sample to
    /// the middle of the voltage it sets; `base_speed_rpm` is 1 pu of speed.
    ///
    /// ```
    /// use controller_core::foc::AngleCoefficients;
    /// let a = AngleCoefficients::new(4, 4096, 90.0, false, 1000.0, 0.0).unwrap();
    /// // A quarter electrical turn past count 0 at 1/16 of a mechanical turn (4 pole pairs).
    /// assert_eq!(a.phase_at(256), 1u32 << 31);
    /// ```
    pub fn new(
        pole_pairs: u32,
        cpr: u32,
        offset_elec_deg: f32,
        reversed: bool,
        base_speed_rpm: f32,
        t_delay_s: f32,
    ) -> Result<Self, ConfigError> {
        if cpr == 0 {
            return Err(ConfigError::OutOfRange {
                param: "encoder_cpr",
                value: 0.0,
                min: 1.0,
                max: 1_073_741_824.0,
                min_exclusive: false,
            });
        }
        if pole_pairs == 0 || pole_pairs >= cpr {
            return Err(ConfigError::OutOfRange {
                param: "pmsm.pole_pairs",
                value: pole_pairs as f32,
                min: 1.0,
                max: (cpr - 1) as f32,
                min_exclusive: false,
            });
        }
        if !offset_elec_deg.is_finite() {
            return Err(ConfigError::NotFinite {
                param: "pmsm.encoder_offset_elec_deg",
            });
        }
        let num = u128::from(pole_pairs) << 64;
        let den = u128::from(cpr);
        let phase_per_count = ((num + den / 2) / den) as u64;
        let adv = f64::from(pole_pairs) * f64::from(base_speed_rpm) / 60.0
            * f64::from(t_delay_s)
            * 4_294_967_296.0
            / 65_536.0
            * 4_294_967_296.0;
        if !adv.is_finite() || adv.abs() >= 9.0e18 {
            return Err(ConfigError::NotFinite {
                param: "angle advance (pole_pairs, base_speed_rpm, current_rate_hz)",
            });
        }
        Ok(Self {
            cpr,
            phase_per_count,
            offset: phase_of_deg(offset_elec_deg),
            reversed,
            advance_per_speed_bit: adv as i64,
        })
    }

    /// The state at encoder count `count` (any integer, reduced modulo one revolution).
    #[must_use]
    pub fn state_at(&self, count: i64) -> AngleState {
        AngleState {
            count_in_rev: count.rem_euclid(i64::from(self.cpr)) as u32,
        }
    }

    /// Moves the count by `delta` counts and returns the electrical phase there.
    #[inline]
    pub fn update(&self, state: &mut AngleState, delta: i32) -> u32 {
        let cpr = i64::from(self.cpr);
        let c = i64::from(state.count_in_rev) + i64::from(delta);
        // One revolution at most per tick in the usual case: an add or a subtract.
        let c = if c < 0 {
            c + cpr
        } else if c >= cpr {
            c - cpr
        } else {
            c
        };
        let c = if (0..cpr).contains(&c) {
            c
        } else {
            c.rem_euclid(cpr)
        };
        state.count_in_rev = c as u32;
        self.phase_at(c as u32)
    }

    /// Whether the counts rise while the electrical angle falls: the drive's positive
    /// direction (the counts') is then the rotor's negative electrical one.
    #[inline]
    #[must_use]
    pub fn reversed(&self) -> bool {
        self.reversed
    }

    /// The electrical phase at `count_in_rev` counts from count 0 (within one revolution).
    #[inline]
    #[must_use]
    pub fn phase_at(&self, count_in_rev: u32) -> u32 {
        let mech = (u64::from(count_in_rev).wrapping_mul(self.phase_per_count) >> 32) as u32;
        if self.reversed {
            self.offset.wrapping_sub(mech)
        } else {
            self.offset.wrapping_add(mech)
        }
    }

    /// `phase` advanced by ω_e·t_delay at speed `speed` (pu of base speed).
    #[inline]
    #[must_use]
    pub fn advanced(&self, phase: u32, speed: Pu) -> u32 {
        // Only the phase modulo one turn matters: the wrapped product's bits 32..63 are the
        // advance modulo 2^32 phase units.
        let adv =
            (i64::from(speed.to_bits()).wrapping_mul(self.advance_per_speed_bit) >> 32) as u32;
        phase.wrapping_add(adv)
    }
}
