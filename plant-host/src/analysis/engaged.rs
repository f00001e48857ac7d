//! The engaged two-inertia plant as a state-space model, x = [θm, θl (rad), ωm, ωl (pu)],
//! u = [Tm, TL (pu)]:
//!   θ̇m = ω_b·ωm, θ̇l = ω_b·ωl,
//!   Jm·ω̇m = Tm − K·(θm − θl) − D·(ωm − ωl) − Bm·ωm,
//!   Jl·ω̇l = K·(θm − θl) + D·(ωm − ωl) − TL − Bl·ωl.

use crate::config::MechanicsConfig;
use nalgebra::{Complex, Matrix2, Matrix4, Matrix4x2, SMatrix, Vector4};
use std::f64::consts::PI;

/// A, B of the engaged plant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EngagedPlant {
    /// State matrix.
    pub a: Matrix4<f64>,
    /// Input matrix (columns: motor torque, load torque).
    pub b: Matrix4x2<f64>,
    /// ω_b, rad/s per pu.
    pub base_speed_rad_s: f64,
}

/// The plant's oscillatory modes from its eigenvalues and transmission zeros.
#[derive(Debug, Clone, PartialEq)]
pub struct Modes {
    /// Resonance: natural frequency |λ|/2π of the complex pole pair, Hz.
    pub resonance_hz: f64,
    /// Damping ratio of that pair.
    pub resonance_damping: f64,
    /// Anti-resonance: natural frequency of the complex zeros of ωm/Tm, Hz.
    pub anti_resonance_hz: f64,
    /// Damping ratio of the zeros.
    pub anti_resonance_damping: f64,
    /// All eigenvalues of A, 1/s.
    pub poles: Vec<Complex<f64>>,
    /// The zeros of ωm/Tm, 1/s.
    pub zeros: Vec<Complex<f64>>,
}

/// Transfer functions of the engaged plant at one frequency.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlantResponse {
    /// ωm/Tm, pu speed per pu torque.
    pub motor_speed_per_motor_torque: Complex<f64>,
    /// ωm/TL.
    pub motor_speed_per_load_torque: Complex<f64>,
    /// ωl/Tm.
    pub load_speed_per_motor_torque: Complex<f64>,
    /// ωl/TL.
    pub load_speed_per_load_torque: Complex<f64>,
}

impl EngagedPlant {
    /// From the `[plant]` parameters (K, D from the formulas in `plant-host/README.md`).
    pub fn new(m: &MechanicsConfig) -> Self {
        let d = m.derived();
        let (wb, k, c) = (d.base_speed_rad_s, d.stiffness_pu_per_rad, d.damping_pu);
        let (jm, jl) = (m.motor_inertia_s, m.load_inertia_s);
        #[rustfmt::skip]
        let a = Matrix4::new(
            0.0,      0.0,     wb,                             0.0,
            0.0,      0.0,     0.0,                            wb,
            -k / jm,  k / jm,  (-c - m.motor_viscous_pu) / jm, c / jm,
            k / jl,   -k / jl, c / jl,                         (-c - m.load_viscous_pu) / jl,
        );
        #[rustfmt::skip]
        let b = Matrix4x2::new(
            0.0,      0.0,
            0.0,      0.0,
            1.0 / jm, 0.0,
            0.0,      -1.0 / jl,
        );
        Self {
            a,
            b,
            base_speed_rad_s: wb,
        }
    }

    /// The plant with the gears apart (inside the lost motion): no shaft, the motor alone
    /// (Jm) and the load coasting. What a velocity loop sees while the gap is crossed.
    pub fn disengaged(m: &MechanicsConfig) -> Self {
        let mut free = *m;
        free.shaft_damping_ratio = 0.0;
        let mut p = Self::new(&free);
        // Remove the spring: zero the coupling terms of the speed rows.
        for (r, c) in [(2, 0), (2, 1), (3, 0), (3, 1)] {
            if let Some(v) = p.a.get_mut((r, c)) {
                *v = 0.0;
            }
        }
        p
    }

    /// Poles, resonance and anti-resonance. The zeros of ωm/Tm (relative degree one, c·b ≠ 0)
    /// are the eigenvalues of (I − b·c/(c·b))·A restricted to ker c, i.e. with the ωm row
    /// and column removed.
    pub fn modes(&self) -> Modes {
        let poles: Vec<Complex<f64>> = self.a.complex_eigenvalues().iter().copied().collect();
        let b = self.b.column(0).into_owned();
        let c = Vector4::new(0.0, 0.0, 1.0, 0.0);
        let cb = c.dot(&b);
        let n = (Matrix4::identity() - b * c.transpose() / cb) * self.a;
        // Remove row and column 2 (ωm).
        let keep = [0_usize, 1, 3];
        let z = SMatrix::<f64, 3, 3>::from_fn(|i, j| {
            let (r, s) = (
                keep.get(i).copied().unwrap_or(0),
                keep.get(j).copied().unwrap_or(0),
            );
            n.get((r, s)).copied().unwrap_or(0.0)
        });
        let zeros: Vec<Complex<f64>> = z.complex_eigenvalues().iter().copied().collect();
        let (rf, rz) = oscillatory(&poles);
        let (af, az) = oscillatory(&zeros);
        Modes {
            resonance_hz: rf / (2.0 * PI),
            resonance_damping: rz,
            anti_resonance_hz: af / (2.0 * PI),
            anti_resonance_damping: az,
            poles,
            zeros,
        }
    }

    /// (jωI − A)⁻¹·B at ω rad/s. Returns None only if jω is an eigenvalue of A.
    pub fn response(&self, omega_rad_s: f64) -> Option<PlantResponse> {
        let s = Complex::new(0.0, omega_rad_s);
        let m = Matrix4::<Complex<f64>>::identity() * s - self.a.map(Complex::from);
        let x = m.lu().solve(&self.b.map(Complex::from))?;
        // Rows 2, 3 of (sI − A)⁻¹B are the speeds; columns the two inputs.
        let t: Matrix2<Complex<f64>> = x.fixed_view::<2, 2>(2, 0).into_owned();
        Some(PlantResponse {
            motor_speed_per_motor_torque: t.m11,
            motor_speed_per_load_torque: t.m12,
            load_speed_per_motor_torque: t.m21,
            load_speed_per_load_torque: t.m22,
        })
    }
}

/// (natural frequency rad/s, damping) of the complex pair with positive imaginary part;
/// (0, 1) if there is none.
fn oscillatory(roots: &[Complex<f64>]) -> (f64, f64) {
    roots
        .iter()
        .filter(|r| r.im > 1e-9)
        .map(|r| (r.norm(), -r.re / r.norm()))
        .fold((0.0, 1.0), |best, x| if x.0 > best.0 { x } else { best })
}
