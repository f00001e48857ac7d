//! The model of Fig. 3 as linear systems: the shaft law, the winding, and the state-space
//! matrices of each contact mode. The model is built from the configuration (plain data,
//! which knows nothing of it), and the integrator steps it.
//!
//! State x = [δ (rad), θl (rad), ωm (pu), ωl (pu), i (pu)], input u = [u_motor, TL (pu), 1].
//! u_motor is the winding voltage (pu) when the winding is modelled, else the motor torque.

use crate::config::{BacklashModel, ElectricsConfig, MechanicsConfig};
use nalgebra::{SMatrix, SVector};

pub(crate) type Vec5 = SVector<f64, 5>;
pub(crate) type Vec3 = SVector<f64, 3>;
pub(crate) type Mat5 = SMatrix<f64, 5, 5>;
pub(crate) type Mat53 = SMatrix<f64, 5, 3>;

/// Which side of the lost motion the gears are on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Contact {
    /// Inside the gap (or, for the clamped law, released): no shaft torque.
    Free,
    /// Motor ahead of the load beyond +g: the shaft law with the dead zone's +g edge.
    Driving,
    /// Motor behind the load beyond −g: the shaft law with the −g edge.
    Braking,
}

impl Contact {
    /// The three modes, in the order of [`Contact::index`].
    pub(crate) const ALL: [Contact; 3] = [Contact::Free, Contact::Driving, Contact::Braking];

    /// 0, 1, 2 for free, driving, braking: the slot of this mode in per-mode tables.
    pub(crate) fn index(self) -> usize {
        self as usize
    }
}

/// The motor winding, when the electrics are modelled: the plant's input is then its
/// voltage (L·di/dt = v − R·i − ωm, torque = current), else the motor torque.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Winding {
    /// R, pu.
    pub r_pu: f64,
    /// L, pu·s.
    pub l_pu_s: f64,
}

/// Shaft law constants: Ts = K·(δ ∓ g) + D·(ωm − ωl) in contact.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Shaft {
    /// K, pu torque per rad.
    pub k: f64,
    /// D, pu torque per pu speed.
    pub d: f64,
    /// g, half the lost motion, rad.
    pub g: f64,
}

/// Everything the matrices of the three modes are made of.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Model {
    /// Jm, s.
    pub motor_inertia_s: f64,
    /// Jl, s.
    pub load_inertia_s: f64,
    /// Bm, pu.
    pub motor_viscous_pu: f64,
    /// Bl, pu.
    pub load_viscous_pu: f64,
    /// ω_b, rad/s per pu speed.
    pub base_speed_rad_s: f64,
    /// The shaft law.
    pub shaft: Shaft,
    /// The lost-motion law.
    pub law: BacklashModel,
    /// The winding, when the electrics are modelled (voltage in), else torque in.
    pub winding: Option<Winding>,
    /// The load held still (a locked-rotor test's brake): its speed stays at zero whatever
    /// the shaft and the load torque do.
    pub load_locked: bool,
}

impl From<&ElectricsConfig> for Winding {
    fn from(e: &ElectricsConfig) -> Self {
        Self {
            r_pu: e.winding_resistance_pu,
            l_pu_s: e.winding_inductance_pu_s,
        }
    }
}

impl Model {
    /// The linear model of each contact mode for `mechanics` under `law`, with the winding
    /// when the electrics are modelled.
    pub(crate) fn new(
        mechanics: &MechanicsConfig,
        law: BacklashModel,
        winding: Option<Winding>,
    ) -> Self {
        let dv = mechanics.derived();
        Self {
            motor_inertia_s: mechanics.motor_inertia_s,
            load_inertia_s: mechanics.load_inertia_s,
            motor_viscous_pu: mechanics.motor_viscous_pu,
            load_viscous_pu: mechanics.load_viscous_pu,
            base_speed_rad_s: dv.base_speed_rad_s,
            shaft: Shaft {
                k: dv.stiffness_pu_per_rad,
                d: dv.damping_pu,
                g: dv.half_gap_rad,
            },
            law,
            winding,
            load_locked: false,
        }
    }

    /// A and B of the mode `contact`.
    pub(crate) fn matrices(&self, contact: Contact) -> (Mat5, Mat53) {
        let (on, sigma) = match contact {
            Contact::Free => (0.0, 0.0),
            Contact::Driving => (1.0, 1.0),
            Contact::Braking => (1.0, -1.0),
        };
        self.system_matrices(on, sigma)
    }

    /// Fastest rate of the plant, ‖A‖∞ of the engaged mode (1/s): sets the internal
    /// sub-step (‖A‖·h ≤ 0.5).
    pub(crate) fn fastest_rate_per_s(&self) -> f64 {
        row_sum_norm(&self.matrices(Contact::Driving).0)
    }

    /// A and B of one mode. `on` = 1 when the shaft transmits, `sigma` = ±1 selects the edge.
    fn system_matrices(&self, on: f64, sigma: f64) -> (Mat5, Mat53) {
        let (jm, jl) = (self.motor_inertia_s, self.load_inertia_s);
        let wb = self.base_speed_rad_s;
        let s = &self.shaft;
        let (k, d) = (on * s.k, on * s.d);
        let offset = sigma * s.k * s.g; // Ts = K·δ − σ·K·g + D·(ωm − ωl)
        let (i_to_wm, u_to_wm, i_row, u_to_i) = match self.winding {
            // L·di/dt = v − R·i − ωm ; Tm = i.
            Some(w) => (
                1.0 / jm,
                0.0,
                [0.0, 0.0, -1.0 / w.l_pu_s, 0.0, -w.r_pu / w.l_pu_s],
                1.0 / w.l_pu_s,
            ),
            // Tm = u directly; the current state stays at zero.
            None => (0.0, 1.0 / jm, [0.0; 5], 0.0),
        };
        let [i0, i1, i2, i3, i4] = i_row;
        let (bm, bl) = (self.motor_viscous_pu, self.load_viscous_pu);
        #[rustfmt::skip]
        let mut a = Mat5::new(
            0.0,      0.0, wb,              -wb,             0.0,
            0.0,      0.0, 0.0,             wb,              0.0,
            -k / jm,  0.0, (-d - bm) / jm,  d / jm,          i_to_wm,
            k / jl,   0.0, d / jl,          (-d - bl) / jl,  0.0,
            i0,       i1,  i2,              i3,              i4,
        );
        #[rustfmt::skip]
        let mut b = Mat53::new(
            0.0,     0.0,       0.0,
            0.0,     0.0,       0.0,
            u_to_wm, 0.0,       offset / jm,
            0.0,     -1.0 / jl, -offset / jl,
            u_to_i,  0.0,       0.0,
        );
        if self.load_locked {
            // ω̇l = 0: the load speed keeps its value, zero from rest.
            a.set_row(3, &nalgebra::RowSVector::<f64, 5>::zeros());
            b.set_row(3, &nalgebra::RowSVector::<f64, 3>::zeros());
        }
        (a, b)
    }
}

/// ‖A‖∞, the largest absolute row sum.
pub(crate) fn row_sum_norm(a: &Mat5) -> f64 {
    a.row_iter()
        .map(|r| r.iter().map(|v| v.abs()).sum::<f64>())
        .fold(0.0, f64::max)
}

/// The unit tests' machine, with the winding (so the current is a state), under `law`.
#[cfg(test)]
pub(crate) fn test_model(law: crate::config::BacklashModel) -> Model {
    Model {
        motor_inertia_s: 0.2,
        load_inertia_s: 0.5,
        motor_viscous_pu: 0.01,
        load_viscous_pu: 0.02,
        base_speed_rad_s: 300.0,
        shaft: Shaft {
            k: 40.0,
            d: 0.3,
            g: 0.004,
        },
        law,
        winding: Some(Winding {
            r_pu: 0.05,
            l_pu_s: 0.002,
        }),
        load_locked: false,
    }
}
