//! The inverter's linear range as a circle on (v_d, v_q), d first:
//!
//! ```text
//! |v_d| ≤ V_max,   |v_q| ≤ √(V_max² − v_d²)
//! ```
//! The d axis keeps what it needs (it holds the current against the cross-coupling and, in
//! field weakening, the flux); q takes what is left. Each PI clamps its integrator to its own
//! bound ([`crate::pi`]), which is the anti-windup.

use crate::error::ConfigError;
use crate::per_unit::Pu;

/// The voltage circle's radius and its square.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct VoltageCircle {
    /// V_max, Q16.16 raw, ≥ 0.
    radius: i32,
    /// V_max², Q32.32 raw.
    radius_sq: u64,
}

impl VoltageCircle {
    /// The circle of radius `v_max_pu` (e.g. `dc_bus_pu/√3` for space-vector modulation).
    pub fn new(v_max_pu: f32) -> Result<Self, ConfigError> {
        let r: Pu = crate::per_unit::quantize(v_max_pu, "voltage circle (dc_bus_pu/√3)")?;
        let radius = r.to_bits().max(0);
        Ok(Self {
            radius,
            radius_sq: (radius as u64) * (radius as u64),
        })
    }

    /// The bound on |v_d|, raw Q16.16.
    #[inline]
    #[must_use]
    pub fn d_bound(&self) -> i32 {
        self.radius
    }

    /// The bound on |v_q| for a d voltage `v_d`: √(V_max² − v_d²), raw Q16.16.
    #[inline]
    #[must_use]
    pub fn q_bound(&self, v_d: Pu) -> i32 {
        let d = u64::from(v_d.to_bits().unsigned_abs());
        let rest = self.radius_sq.saturating_sub(d * d);
        // rest < 2^62, so its root is below 2^31.
        crate::per_unit::isqrt_u64(rest) as i32
    }
}
