//! The harness's view of plant-host's `DrivePlant`, and the conversions between the
//! plant's f64 per-unit values and the controller's fixed-point signals.

use crate::error::{HarnessError, Result};
use controller_core::per_unit::{Pu, PuPerS};
use plant_host::{DrivePlant, PlantConfig};

/// The true plant state at one instant (what a perfect sensor would see).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Snapshot {
    /// Motor angle (rad).
    pub motor_pos_rad: f64,
    /// Load angle reflected to the motor side (rad).
    pub load_pos_rad: f64,
    /// Motor speed (pu).
    pub motor_vel_pu: f64,
    /// Load speed (pu).
    pub load_vel_pu: f64,
    /// Coupling torque (pu).
    pub shaft_torque_pu: f64,
    /// Exact winding current (pu).
    pub current_pu: f64,
}

/// plant-host's drive (winding + two inertias + sensors).
#[derive(Clone, Debug)]
pub struct Plant {
    inner: DrivePlant,
}

impl Plant {
    /// A plant at rest.
    pub fn new(config: &PlantConfig) -> Result<Self> {
        Ok(Self {
            inner: DrivePlant::new(config),
        })
    }

    /// Raw motor encoder count (unwrapped; the runner wraps it to the counter width).
    pub fn encoder_count(&self) -> i64 {
        self.inner.encoder_count()
    }

    /// Current as the ADC reports it (pu).
    pub fn current_sample(&self) -> f64 {
        self.inner.current_sample()
    }

    /// Advances `dt_s` with the voltage and load torque held.
    pub fn advance(&mut self, dt_s: f64, voltage_pu: f64, load_torque_pu: f64) -> Result<()> {
        self.inner
            .try_advance(dt_s, voltage_pu, load_torque_pu)
            .map_err(|e| HarnessError::Backend(format!("plant: {e}")))
    }

    /// The true state.
    pub fn snapshot(&self) -> Snapshot {
        Snapshot {
            motor_pos_rad: self.inner.motor_pos_rad(),
            load_pos_rad: self.inner.load_pos_rad(),
            motor_vel_pu: self.inner.motor_vel_pu(),
            load_vel_pu: self.inner.load_vel_pu(),
            shaft_torque_pu: self.inner.shaft_torque_pu(),
            current_pu: self.inner.current_pu(),
        }
    }
}

/// f64 pu → the controller's Q16.16 (saturating).
pub fn pu(x: f64) -> Pu {
    // Round to the nearest LSB (2^-16) and saturate; NaN maps to 0. A hand-written
    // conversion: the generic one was 4 % of a closed-loop run.
    let bits = (x * 65536.0)
        .round()
        .clamp(f64::from(i32::MIN), f64::from(i32::MAX));
    Pu::from_bits(bits as i32)
}

/// f64 pu/s → Q16.16 (saturating).
pub fn pu_s(x: f64) -> PuPerS {
    PuPerS::saturating_from_num(x)
}

/// Any fixed-point signal → f64.
pub fn f<T: fixed::traits::Fixed>(x: T) -> f64 {
    x.to_num::<f64>()
}
