//! The PMSM's constants in per unit, and the frame changes between the phases (a, b, c),
//! the stator frame (α, β) and the rotor frame (d, q).
//!
//! Per unit: speed in pu of base speed ω_b (rad/s of the shaft), time in seconds, current
//! in pu of the rated peak phase current, voltage in pu of the peak phase voltage that the
//! magnets induce at base speed when λ = 1. Clarke and Park are amplitude-invariant (a
//! phase current of peak 1 is a current vector of length 1), and the pu power base is
//! (3/2)·V_base·I_base, so the power is v_d·i_d + v_q·i_q pu. The electrical speed in
//! rad/s is p·ω_b·ωm; with the inductances in pu·s the reactances at base electrical speed
//! are x = p·ω_b·L (pu), and
//!
//! ```text
//! Ld·di_d/dt = v_d − R·i_d + p·ω_b·ωm·Lq·i_q
//! Lq·di_q/dt = v_q − R·i_q − p·ω_b·ωm·Ld·i_d − λ·ωm        (back-EMF λ·ωm: 1 pu at base speed)
//! Tm = λ·i_q + (x_d − x_q)·i_d·i_q,   x_d − x_q = p·ω_b·(Ld − Lq)
//! θe = p·θm + offset
//! ```
//!
//! The torque is what the power balance asks: v_d·i_d + v_q·i_q = R·|i|² +
//! d/dt(½·Ld·i_d² + ½·Lq·i_q²) + Tm·ωm.

use crate::config::{MotorKind, PlantConfig};
use crate::error::ConfigError;

/// √3/2.
const SQRT3_2: f64 = 0.866_025_403_784_438_6;

/// The PMSM of a `motor = "pmsm"` `[electrics]` table, with the base speed it needs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PmsmParams {
    /// Pole pairs p.
    pub pole_pairs: u32,
    /// Phase resistance R, pu.
    pub r_pu: f64,
    /// Ld, pu·s.
    pub ld_pu_s: f64,
    /// Lq, pu·s.
    pub lq_pu_s: f64,
    /// λ, pu (back-EMF at base speed, torque per pu q current).
    pub flux_linkage_pu: f64,
    /// The true electrical angle at encoder count 0 (θm = 0) in the motor's own phase
    /// order, rad: `electrics.encoder_offset_elec_deg`, negated with `encoder_reversed`
    /// (two leads swapped mirror the angle the drive sees).
    pub encoder_offset_rad: f64,
    /// p·ω_b: electrical rad/s per pu of shaft speed.
    pub electrical_rad_s_per_pu: f64,
}

impl PmsmParams {
    /// The motor of `config`, whose `electrics.motor` must be `"pmsm"` with its keys set
    /// (a validated config has them).
    pub fn from_config(config: &PlantConfig) -> Result<Self, ConfigError> {
        let e = &config.electrics;
        let missing = |key: &str| ConfigError::Missing {
            key: key.into(),
            allowed: "a value; required with electrics.motor = \"pmsm\"".into(),
        };
        if e.motor != MotorKind::Pmsm {
            return Err(ConfigError::OutOfRange {
                key: "electrics.motor".into(),
                value: format!("\"{}\"", e.motor.as_str()),
                allowed: "\"pmsm\" for a PMSM plant".into(),
            });
        }
        let pole_pairs = e
            .pole_pairs
            .ok_or_else(|| missing("electrics.pole_pairs"))?;
        let ld = e
            .d_inductance_pu_s
            .ok_or_else(|| missing("electrics.d_inductance_pu_s"))?;
        let lq = e
            .q_inductance_pu_s
            .ok_or_else(|| missing("electrics.q_inductance_pu_s"))?;
        let offset = e
            .encoder_offset_elec_deg
            .ok_or_else(|| missing("electrics.encoder_offset_elec_deg"))?;
        Ok(Self {
            pole_pairs,
            r_pu: e.winding_resistance_pu,
            ld_pu_s: ld,
            lq_pu_s: lq,
            flux_linkage_pu: e.flux_linkage_pu.unwrap_or(1.0),
            encoder_offset_rad: if e.encoder_reversed == Some(true) {
                -offset.to_radians()
            } else {
                offset.to_radians()
            },
            electrical_rad_s_per_pu: f64::from(pole_pairs)
                * config.mechanics.derived().base_speed_rad_s,
        })
    }

    /// Tm = λ·i_q + p·ω_b·(Ld − Lq)·i_d·i_q, pu.
    ///
    /// ```
    /// # use plant_host::PmsmParams;
    /// let m = PmsmParams { pole_pairs: 4, r_pu: 0.05, ld_pu_s: 4e-4, lq_pu_s: 6e-4,
    ///     flux_linkage_pu: 1.0, encoder_offset_rad: 0.0, electrical_rad_s_per_pu: 400.0 };
    /// assert_eq!(m.torque_pu(0.0, 1.0), 1.0);
    /// // Ld < Lq: a negative d current adds reluctance torque (x_d − x_q = −0.08 pu).
    /// assert!((m.torque_pu(-0.5, 1.0) - 1.04).abs() < 1e-12);
    /// ```
    pub fn torque_pu(&self, i_d_pu: f64, i_q_pu: f64) -> f64 {
        self.flux_linkage_pu * i_q_pu + self.saliency_pu() * i_d_pu * i_q_pu
    }

    /// x_d − x_q = p·ω_b·(Ld − Lq), pu: the reluctance torque per pu of i_d·i_q.
    pub fn saliency_pu(&self) -> f64 {
        self.electrical_rad_s_per_pu * (self.ld_pu_s - self.lq_pu_s)
    }

    /// The electrical angle θe = p·θm + offset, rad (not wrapped).
    pub fn electrical_angle_rad(&self, motor_pos_rad: f64) -> f64 {
        f64::from(self.pole_pairs) * motor_pos_rad + self.encoder_offset_rad
    }

    /// The magnetic energy ½·Ld·i_d² + ½·Lq·i_q², pu·s (pu power × s).
    pub fn magnetic_energy_pu_s(&self, i_d_pu: f64, i_q_pu: f64) -> f64 {
        0.5 * (self.ld_pu_s * i_d_pu * i_d_pu + self.lq_pu_s * i_q_pu * i_q_pu)
    }
}

/// Clarke, amplitude-invariant: (a, b, c) → (α, β), the zero sequence dropped.
pub fn clarke([a, b, c]: [f64; 3]) -> [f64; 2] {
    [(2.0 * a - b - c) / 3.0, (b - c) / 3.0_f64.sqrt()]
}

/// Inverse Clarke: (α, β) → (a, b, c), without zero sequence.
pub fn inverse_clarke([alpha, beta]: [f64; 2]) -> [f64; 3] {
    [
        alpha,
        -0.5 * alpha + SQRT3_2 * beta,
        -0.5 * alpha - SQRT3_2 * beta,
    ]
}

/// Park: (α, β) → (d, q) at the electrical angle θe (d on the magnet's axis).
pub fn park([alpha, beta]: [f64; 2], theta_e_rad: f64) -> [f64; 2] {
    let (s, c) = theta_e_rad.sin_cos();
    [c * alpha + s * beta, -s * alpha + c * beta]
}

/// Inverse Park: (d, q) → (α, β) at θe.
pub fn inverse_park([d, q]: [f64; 2], theta_e_rad: f64) -> [f64; 2] {
    let (s, c) = theta_e_rad.sin_cos();
    [c * d - s * q, s * d + c * q]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clarke_and_park_invert_and_keep_the_amplitude() {
        let th = 0.7_f64;
        // A balanced set of peak 1 at angle th is the vector (cos th, sin th).
        let abc = [
            th.cos(),
            (th - 2.0 * std::f64::consts::PI / 3.0).cos(),
            (th + 2.0 * std::f64::consts::PI / 3.0).cos(),
        ];
        let [al, be] = clarke(abc);
        assert!((al - th.cos()).abs() < 1e-15 && (be - th.sin()).abs() < 1e-15);
        let back = inverse_clarke([al, be]);
        for (x, y) in back.iter().zip(abc) {
            assert!((x - y).abs() < 1e-15);
        }
        // Park at th puts it on the d axis.
        let [d, q] = park([al, be], th);
        assert!((d - 1.0).abs() < 1e-15 && q.abs() < 1e-15);
        let [a2, b2] = inverse_park([d, q], th);
        assert!((a2 - al).abs() < 1e-15 && (b2 - be).abs() < 1e-15);
    }
}
