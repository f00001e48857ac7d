//! Space-vector modulation by min-max (zero-sequence) injection: the three phase voltages of
//! (α, β), shifted together by −(max + min)/2 so that they use the whole DC bus, become
//! three duties of the PWM period.
//!
//! ```text
//! v_a = α,  v_b = −α/2 + (√3/2)·β,  v_c = −α/2 − (√3/2)·β
//! v_0 = −(max(v) + min(v))/2
//! duty_x = period·(1/2 + (v_x + v_0)/V_dc), clamped to [0, period]
//! ```
//! The linear range is the circle |(α, β)| ≤ V_dc/√3; [`super::VoltageCircle`] keeps the
//! vector inside it, and the clamp holds the duties in `[0, period]` whatever the input.

use super::transforms::AlphaBeta;
use crate::error::ConfigError;

/// √3/2 in Q1.31.
const SQRT3_2_Q31: i64 = 1_859_775_393;
/// The largest |α| and |β| the modulator takes (raw Q16.16, 4,096 pu).
const IN_LIMIT: i32 = 1 << 28;

/// The modulator's coefficients.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Svpwm {
    /// Timer counts of a whole PWM period (the largest duty).
    period: u16,
    /// V_dc/2, Q16.16 raw (at most 500 pu, < 2^25): the largest phase voltage about the
    /// bus midpoint.
    half_bus: i32,
    /// period/V_dc as Q32.32 counts per pu (raw i64).
    counts_per_pu: i64,
}

impl Svpwm {
    /// A modulator for a bus of `dc_bus_pu` and a period of `period` timer counts.
    ///
    /// ```
    /// use controller_core::foc::{Svpwm, transforms::AlphaBeta};
    /// use controller_core::per_unit::Pu;
    /// let m = Svpwm::new(1.8, 1000).unwrap();
    /// assert_eq!(m.duties(AlphaBeta::default()), [500, 500, 500]);
    /// ```
    pub fn new(dc_bus_pu: f32, period: u16) -> Result<Self, ConfigError> {
        crate::ranges::Range::real("pmsm.dc_bus_pu", 0.01, 1000.0, false).check(dc_bus_pu)?;
        if period < 2 {
            return Err(ConfigError::OutOfRange {
                param: "pmsm.pwm_period_counts",
                value: f32::from(period),
                min: 2.0,
                max: 65535.0,
                min_exclusive: false,
            });
        }
        let bus = f64::from(dc_bus_pu);
        Ok(Self {
            period,
            half_bus: (bus / 2.0 * 65_536.0) as i32,
            // Positive: + 0.5 then truncation rounds to nearest.
            counts_per_pu: (f64::from(period) / bus * 65_536.0 + 0.5) as i64,
        })
    }

    /// The timer counts of a whole period.
    #[must_use]
    pub fn period(&self) -> u16 {
        self.period
    }

    /// The three duties (timer counts, each in `[0, period]`) of the voltage vector `v`.
    #[inline]
    #[must_use]
    pub fn duties(&self, v: AlphaBeta) -> [u16; 3] {
        // In 32-bit words: α and β held within ±2^28 (4,096 pu, eight times the largest
        // bus) keep every sum below 2^30; the duties of a vector that far out are clamped
        // to the bus all the same.
        let a = v.alpha.to_bits().clamp(-IN_LIMIT, IN_LIMIT);
        let b = v.beta.to_bits().clamp(-IN_LIMIT, IN_LIMIT);
        let half_a = a >> 1;
        // |b·√3/2| < 2^59: rounded to nearest, within ±2^28.
        let sb = ((i64::from(b) * SQRT3_2_Q31 + (1 << 30)) >> 31) as i32;
        let va = a;
        let vb = sb - half_a;
        let vc = -sb - half_a;
        let max = va.max(vb).max(vc);
        let min = va.min(vb).min(vc);
        let zero = -((max + min) >> 1);
        [va, vb, vc].map(|x| self.duty(x + zero))
    }

    /// One phase's duty for a voltage `v` (Q16.16 raw) about the bus midpoint.
    #[inline(always)]
    fn duty(&self, v: i32) -> u16 {
        // Within ±V_dc/2 the product is at most period/2·2^32 < 2^47, and the duty's
        // high word at most the period.
        let v = v.clamp(-self.half_bus, self.half_bus);
        let half = (i64::from(self.period) << 31) + (1 << 31);
        let d = ((half + i64::from(v) * self.counts_per_pu) >> 32) as i32;
        d.clamp(0, i32::from(self.period)) as u16
    }
}
