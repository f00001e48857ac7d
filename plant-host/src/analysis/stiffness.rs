//! The stiffness of a PI-regulated inertia, the paper's Eq. 1: τL/θ = Jp·s² + Kp·s + Ki
//! (θ in pu·s of position, i.e. rad/ω_b), evaluated at s = jω (Fig. 2).

use nalgebra::Complex;

/// Eq. 1's coefficients.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PiStiffness {
    /// Plant inertia Jp, s.
    pub jp: f64,
    /// Proportional gain Kp, pu torque per pu speed.
    pub kp: f64,
    /// Integral gain Ki, pu torque per pu speed per s.
    pub ki: f64,
}

/// Stiffness at one frequency.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StiffnessPoint {
    /// Frequency, rad/s.
    pub omega_rad_s: f64,
    /// |τL/θ|, pu torque per pu·s.
    pub magnitude: f64,
    /// |τL/θ| in dB.
    pub magnitude_db: f64,
    /// arg(τL/θ), degrees in [0, 180].
    pub phase_deg: f64,
}

impl PiStiffness {
    /// Gains that put the two zeros of Eq. 1 at `w1` and `w2` rad/s:
    /// Jp·(s + w1)(s + w2) → Kp = Jp·(w1 + w2), Ki = Jp·w1·w2 (Fig. 2: 1 and 10 rad/s).
    pub fn from_zeros(jp: f64, w1_rad_s: f64, w2_rad_s: f64) -> Self {
        Self {
            jp,
            kp: jp * (w1_rad_s + w2_rad_s),
            ki: jp * w1_rad_s * w2_rad_s,
        }
    }

    /// τL/θ at s = jω.
    pub fn at(&self, omega_rad_s: f64) -> Complex<f64> {
        let s = Complex::new(0.0, omega_rad_s);
        s * s * self.jp + s * self.kp + self.ki
    }

    /// Magnitude and phase at `omega_rad_s`.
    pub fn point(&self, omega_rad_s: f64) -> StiffnessPoint {
        let z = self.at(omega_rad_s);
        StiffnessPoint {
            omega_rad_s,
            magnitude: z.norm(),
            magnitude_db: 20.0 * z.norm().log10(),
            phase_deg: z.arg().to_degrees(),
        }
    }

    /// The curve over `omegas` (Fig. 2).
    pub fn curve(&self, omegas: &[f64]) -> Vec<StiffnessPoint> {
        omegas.iter().map(|w| self.point(*w)).collect()
    }

    /// The roots of Jp·s² + Kp·s + Ki as corner frequencies (rad/s) when real:
    /// the stiffness breaks at these frequencies.
    pub fn corner_frequencies_rad_s(&self) -> Option<(f64, f64)> {
        let disc = self.kp * self.kp - 4.0 * self.jp * self.ki;
        if disc < 0.0 || self.jp <= 0.0 {
            return None;
        }
        let r = disc.sqrt();
        Some((
            (self.kp - r) / (2.0 * self.jp),
            (self.kp + r) / (2.0 * self.jp),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fig2_breaks_at_1_and_10_rad_s() {
        let st = PiStiffness::from_zeros(1.0, 1.0, 10.0);
        assert_eq!((st.kp, st.ki), (11.0, 10.0));
        let (a, b) = st.corner_frequencies_rad_s().unwrap_or((0.0, 0.0));
        assert!((a - 1.0).abs() < 1e-12 && (b - 10.0).abs() < 1e-12);
        // Low frequency: Ki, phase 0; high: Jp·ω², phase → 180°.
        let lo = st.point(1e-3);
        assert!((lo.magnitude - 10.0).abs() < 1e-3 && lo.phase_deg.abs() < 0.1);
        let hi = st.point(1e4);
        assert!((hi.magnitude / 1e8 - 1.0).abs() < 1e-3 && hi.phase_deg > 179.9);
        // At each zero the magnitude is √2 above the product of the asymptotes meeting there
        // only approximately (the zeros are a decade apart): check the exact values.
        assert!((st.point(1.0).magnitude - (9.0_f64 * 9.0 + 11.0 * 11.0).sqrt()).abs() < 1e-12);
        // Phase 90° exactly where the real part vanishes: ω = √(Ki/Jp) = √10.
        assert!((st.point(10.0_f64.sqrt()).phase_deg - 90.0).abs() < 1e-9);
    }
}
