//! The mechanical plant of Fig. 3 on its own: motor torque in, positions and speeds out.

use crate::config::{BacklashModel, MechanicsConfig, MechanicsDerived};
use crate::error::PlantError;
use crate::load::{for_each_load_piece, LoadTorque};
use crate::model::{Contact, Vec3, Vec5};
use crate::piecewise::Piecewise;

/// Two inertias coupled by a damped shaft through lost motion, reflected to the motor side,
/// in per unit (the paper's Fig. 3). Starts at rest with zero twist.
///
/// ```
/// use plant_host::{PlantConfig, TwoInertiaPlant};
/// let cfg = PlantConfig::table1();
/// let mut plant = TwoInertiaPlant::new(&cfg.mechanics, cfg.backlash);
/// // 1 pu torque for 10 ms: the motor crosses the 0.25° half-gap alone, then drags the load.
/// for _ in 0..40 {
///     plant.advance(250e-6, 1.0, 0.0);
/// }
/// assert!(plant.motor_pos_rad() > plant.load_pos_rad());
/// assert!(plant.shaft_torque_pu() > 0.0);
/// ```
#[derive(Debug, Clone)]
pub struct TwoInertiaPlant {
    core: Piecewise,
    derived: MechanicsDerived,
    time_s: f64,
}

impl TwoInertiaPlant {
    /// A plant at rest with zero twist.
    pub fn new(mechanics: &MechanicsConfig, backlash: BacklashModel) -> Self {
        Self {
            core: Piecewise::new(&mechanics.model(backlash, None)),
            derived: mechanics.derived(),
            time_s: 0.0,
        }
    }

    /// Advances `dt_s` seconds with both torques held (pu). Invalid input (negative or
    /// non-finite `dt_s`, non-finite torque) leaves the plant unchanged; use
    /// [`Self::try_advance`] to see the error.
    pub fn advance(&mut self, dt_s: f64, motor_torque_pu: f64, load_torque_pu: f64) {
        // The error is the caller's contract violation; the plant stays as it was.
        let _ = self.try_advance(dt_s, motor_torque_pu, load_torque_pu);
    }

    /// Advances `dt_s` with `motor_torque_pu` held and the load torque following `load` (time from
    /// [`Self::time_s`]): steps end at the load's discontinuities and a sinusoid is held at
    /// midpoints of ≤ 50 µs pieces.
    pub fn advance_with_load(
        &mut self,
        dt_s: f64,
        motor_torque_pu: f64,
        load: &LoadTorque,
    ) -> Result<(), PlantError> {
        check_step(dt_s, &[motor_torque_pu])?;
        let mut result = Ok(());
        for_each_load_piece(self.time_s, dt_s, load, |h, tl| {
            if result.is_ok() {
                result = self.try_advance(h, motor_torque_pu, tl);
            }
        });
        result
    }

    /// As [`Self::advance`], reporting invalid input.
    pub fn try_advance(
        &mut self,
        dt_s: f64,
        motor_torque_pu: f64,
        load_torque_pu: f64,
    ) -> Result<(), PlantError> {
        check_step(dt_s, &[motor_torque_pu, load_torque_pu])?;
        self.core
            .advance(dt_s, &Vec3::new(motor_torque_pu, load_torque_pu, 1.0));
        self.time_s += dt_s;
        Ok(())
    }

    /// Simulated time since construction, s.
    pub fn time_s(&self) -> f64 {
        self.time_s
    }
    /// Motor angle θm, rad.
    pub fn motor_pos_rad(&self) -> f64 {
        self.core.motor_pos_rad()
    }
    /// Load angle θl reflected to the motor side, rad.
    pub fn load_pos_rad(&self) -> f64 {
        self.core.load_pos_rad()
    }
    /// Motor speed ωm, pu.
    pub fn motor_vel_pu(&self) -> f64 {
        self.core.motor_vel_pu()
    }
    /// Load speed ωl (motor side), pu.
    pub fn load_vel_pu(&self) -> f64 {
        self.core.load_vel_pu()
    }
    /// Twist δ = θm − θl, rad.
    pub fn twist_rad(&self) -> f64 {
        self.core.twist_rad()
    }
    /// Shaft torque Ts, pu.
    pub fn shaft_torque_pu(&self) -> f64 {
        self.core.shaft_torque_pu()
    }
    /// Which side of the lost motion the gears are on.
    pub fn contact(&self) -> Contact {
        self.core.contact()
    }
    /// Number of contact changes located so far (edge crossings).
    pub fn mode_changes(&self) -> u64 {
        self.core.mode_changes()
    }
    /// Steps redone to search for a crossing (suspected or real): a cost diagnostic.
    pub fn crossing_searches(&self) -> u64 {
        self.core.crossing_searches()
    }
    /// K, D, g, ω_b... of this plant.
    pub fn derived(&self) -> &MechanicsDerived {
        &self.derived
    }
    /// The longest internal sub-step, s (steps are split so that ‖A‖·h ≤ 0.5 and h ≤ 250 µs).
    pub fn max_substep_s(&self) -> f64 {
        self.core.max_step_s()
    }

    /// Puts the plant in a given state (positions rad, speeds pu); the contact follows.
    pub fn set_state(
        &mut self,
        motor_pos_rad: f64,
        load_pos_rad: f64,
        motor_vel_pu: f64,
        load_vel_pu: f64,
    ) {
        self.core.set_state(Vec5::new(
            motor_pos_rad - load_pos_rad,
            load_pos_rad,
            motor_vel_pu,
            load_vel_pu,
            0.0,
        ));
    }
}

/// A step must be finite and ≥ 0 and its inputs finite.
#[inline]
pub(crate) fn check_step(dt_s: f64, inputs: &[f64]) -> Result<(), PlantError> {
    if !(dt_s.is_finite() && dt_s >= 0.0) {
        return Err(PlantError::BadStep { dt_s });
    }
    if let Some(bad) = inputs.iter().find(|v| !v.is_finite()) {
        return Err(PlantError::BadInput { value: *bad });
    }
    Ok(())
}
