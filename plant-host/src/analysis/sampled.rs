//! The drive plant as the controller's sampler sees it, discretized exactly over one tick.
//!
//! The continuous plant is the winding in front of the two-inertia mechanics, with
//! x = [i, θm, θl (rad), ωm, ωl (pu)] and u = [v, TL] (pu):
//!
//! - L·di/dt = v − R·i − ωm (back-EMF = speed in pu), Tm = i;
//! - the mechanics of [`super::EngagedPlant`]: gears engaged, or apart inside the lost
//!   motion ([`Gears::Apart`]: the motor alone and the load coasting).
//!
//! Over a tick of length T, the voltage computed at the tick's sampling instant is applied
//! `delay_s` (d, 0 ≤ d ≤ T) after it. Until then the previous command holds (PWM
//! zero-order hold). The load torque is constant over the tick. With
//! exp([[A, B], [0, 0]]·h) = [[Φ(h), Γ(h)], [0, I]]:
//!
//!   x[k+1] = Φ·x[k] + Γ_new·v[k] + Γ_old·v[k−1] + Γ_load·TL[k]
//!   Φ = Φ(T−d)·Φ(d), Γ_old = Φ(T−d)·Γv(d), Γ_new = Γv(T−d)
//!   Γ_load = Φ(T−d)·ΓL(d) + ΓL(T−d)
//!
//! This is exact for piecewise-constant inputs, so with the gears engaged (or no lost
//! motion) it reproduces [`crate::DrivePlant`] to rounding.

use super::EngagedPlant;
use crate::{ElectricsConfig, MechanicsConfig};
use nalgebra::{DMatrix, DVector};

/// Which mechanics the sampled model holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Gears {
    /// Gears in contact: the shaft couples motor and load.
    Engaged,
    /// Gears apart inside the lost motion: the motor alone.
    Apart,
}

/// Index of each state in [`SampledPlant`]'s state vector.
pub mod state {
    /// Winding current \[pu\].
    pub const CURRENT: usize = 0;
    /// Motor angle \[rad\].
    pub const MOTOR_ANGLE: usize = 1;
    /// Load angle \[rad\].
    pub const LOAD_ANGLE: usize = 2;
    /// Motor speed \[pu\].
    pub const MOTOR_SPEED: usize = 3;
    /// Load speed \[pu\].
    pub const LOAD_SPEED: usize = 4;
    /// Number of states.
    pub const COUNT: usize = 5;
}

/// The one-tick map of the drive plant.
#[derive(Debug, Clone, PartialEq)]
pub struct SampledPlant {
    /// Φ (5×5).
    pub phi: DMatrix<f64>,
    /// Γ_new: this tick's voltage command (5).
    pub gamma_new: DVector<f64>,
    /// Γ_old: the previous tick's voltage command, still applied for `delay_s` (5).
    pub gamma_old: DVector<f64>,
    /// Γ_load: the load torque (5).
    pub gamma_load: DVector<f64>,
    /// Tick period T \[s\].
    pub period_s: f64,
    /// Computational delay d \[s\].
    pub delay_s: f64,
}

/// The continuous A (5×5) and B (5×2) of the winding plus mechanics.
#[must_use]
pub fn continuous(
    m: &MechanicsConfig,
    e: &ElectricsConfig,
    gears: Gears,
) -> (DMatrix<f64>, DMatrix<f64>) {
    let mech = match gears {
        Gears::Engaged => EngagedPlant::new(m),
        Gears::Apart => EngagedPlant::disengaged(m),
    };
    let n = state::COUNT;
    let (r, l) = (e.winding_resistance_pu, e.winding_inductance_pu_s);
    let mut a = DMatrix::zeros(n, n);
    let mut b = DMatrix::zeros(n, 2);
    // Mechanics in rows/columns 1..5; the motor torque column of B becomes the coupling
    // from the current (Tm = i).
    a.view_mut((1, 1), (4, 4)).copy_from(&mech.a);
    a.view_mut((1, 0), (4, 1)).copy_from(&mech.b.column(0));
    b.view_mut((1, 1), (4, 1)).copy_from(&mech.b.column(1));
    if let Some(v) = a.get_mut((0, 0)) {
        *v = -r / l;
    }
    if let Some(v) = a.get_mut((0, state::MOTOR_SPEED)) {
        *v = -1.0 / l;
    }
    if let Some(v) = b.get_mut((0, 0)) {
        *v = 1.0 / l;
    }
    (a, b)
}

/// (Φ(h), Γ(h)) for a held input over `h` seconds, from the augmented exponential.
fn hold(a: &DMatrix<f64>, b: &DMatrix<f64>, h: f64) -> (DMatrix<f64>, DMatrix<f64>) {
    let (n, m) = (a.nrows(), b.ncols());
    let mut aug = DMatrix::zeros(n + m, n + m);
    aug.view_mut((0, 0), (n, n)).copy_from(&(a * h));
    aug.view_mut((0, n), (n, m)).copy_from(&(b * h));
    let e = aug.exp();
    (
        e.view((0, 0), (n, n)).into_owned(),
        e.view((0, n), (n, m)).into_owned(),
    )
}

impl SampledPlant {
    /// The one-tick map for a tick of `period_s` and a delay of `delay_s`, clamped to
    /// [0, period_s]. A delay of one or more whole ticks is the caller's shift register.
    #[must_use]
    pub fn new(
        m: &MechanicsConfig,
        e: &ElectricsConfig,
        gears: Gears,
        period_s: f64,
        delay_s: f64,
    ) -> Self {
        let d = delay_s.clamp(0.0, period_s);
        let (a, b) = continuous(m, e, gears);
        let (phi1, g1) = hold(&a, &b, d);
        let (phi2, g2) = hold(&a, &b, period_s - d);
        let g1_v = g1.column(0).into_owned();
        let g1_l = g1.column(1).into_owned();
        Self {
            phi: &phi2 * &phi1,
            gamma_new: g2.column(0).into_owned(),
            gamma_old: &phi2 * g1_v,
            gamma_load: &phi2 * g1_l + g2.column(1),
            period_s,
            delay_s: d,
        }
    }

    /// One tick: x ← Φ·x + Γ_new·v_new + Γ_old·v_old + Γ_load·TL.
    #[must_use]
    pub fn step(&self, x: &DVector<f64>, v_new: f64, v_old: f64, load_pu: f64) -> DVector<f64> {
        &self.phi * x
            + &self.gamma_new * v_new
            + &self.gamma_old * v_old
            + &self.gamma_load * load_pu
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::indexing_slicing)]
    use super::*;
    use crate::{DrivePlant, PlantConfig};

    /// With no lost motion the sampled map is the simulated drive, tick for tick.
    #[test]
    fn the_sampled_map_reproduces_the_drive_plant() {
        let mut cfg = PlantConfig::table1();
        cfg.mechanics.backlash_deg = 0.0;
        cfg.mechanics.motor_viscous_pu = 0.01;
        cfg.mechanics.load_viscous_pu = 0.02;
        let (t, d) = (250e-6, 180e-6);
        let sp = SampledPlant::new(&cfg.mechanics, &cfg.electrics, Gears::Engaged, t, d);
        let mut drive = DrivePlant::new(&cfg);
        let mut x = DVector::zeros(state::COUNT);
        let mut v_old = 0.0;
        let mut seed = 5u64;
        for k in 0..400 {
            seed = seed
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            let v = ((seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 0.2;
            let tl = if k > 200 { 0.3 } else { 0.0 };
            x = sp.step(&x, v, v_old, tl);
            drive.advance(d, v_old, tl);
            drive.advance(t - d, v, tl);
            v_old = v;
            let want = [
                drive.current_pu(),
                drive.motor_pos_rad(),
                drive.load_pos_rad(),
                drive.motor_vel_pu(),
                drive.load_vel_pu(),
            ];
            for (i, w) in want.iter().enumerate() {
                let got = x.get(i).copied().unwrap_or(f64::NAN);
                assert!(
                    (got - w).abs() <= 1e-9 * (1.0 + w.abs()),
                    "tick {k}, state {i}: {got} vs {w}"
                );
            }
        }
    }

    /// Apart, the motor sees only its own inertia: a held current accelerates it by i/Jm.
    #[test]
    fn apart_the_motor_is_alone() {
        let cfg = PlantConfig::table1();
        let sp = SampledPlant::new(&cfg.mechanics, &cfg.electrics, Gears::Apart, 250e-6, 0.0);
        let mut x = DVector::zeros(state::COUNT);
        x[state::CURRENT] = 1.0;
        let (a, _) = continuous(&cfg.mechanics, &cfg.electrics, Gears::Apart);
        let accel = (&a * &x)[state::MOTOR_SPEED];
        assert!((accel - 1.0 / cfg.mechanics.motor_inertia_s).abs() < 1e-12);
        let y = sp.step(&x, 0.0, 0.0, 0.0);
        assert_eq!(y[state::LOAD_SPEED], 0.0);
    }
}
