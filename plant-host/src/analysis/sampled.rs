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
//! motion) it reproduces [`crate::TwoInertiaPlant::voltage_driven`] to rounding.

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
