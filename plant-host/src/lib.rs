//! plant-host: the simulated machine of the paper's Fig. 3, a two-inertia plant with lost
//! motion reflected to the motor side, in per unit; the motor winding, computational delay
//! and sensor quantization around it; and the linear analysis (nalgebra) that explains it.
//! It knows nothing of the controller.
//!
//! - [`TwoInertiaPlant`]: the mechanics and sensors, torque in, or with the winding in
//!   front, voltage in.
//! - [`PmsmPlant`]: the same mechanics driven by a permanent-magnet synchronous motor
//!   (`electrics.motor = "pmsm"`) behind an averaged [`Inverter`], duties in.
//! - [`LoadTorque`]: load disturbances.
//! - [`PlantConfig`]: the `[plant]`, `[electrics]`, `[sensors]`, `[lost_motion]` TOML
//!   tables, their range table [`RANGES`] and [`PlantConfig::validate`].
//! - [`replay()`]: a torque profile through the mechanics, CSV in and out.
//! - [`analysis`]: modes, stiffness (Eq. 1), closed velocity loop response and margins.
//!
//! Modules: `config` (plain data) ← `model` (matrices) ← `discrete` + `events` (the exact
//! maps and the event search) ← `piecewise` (the integrator) ← `two_inertia` (the plant);
//! `validate` and `parse` check and read a config.

pub mod analysis;
mod config;
mod discrete;
mod error;
mod events;
mod expm;
mod load;
mod model;
mod parse;
mod piecewise;
mod pmsm;
mod replay;
pub mod rounding;
pub mod sensors;
mod two_inertia;
mod validate;

pub use config::{
    Allowed, BacklashModel, ElectricsConfig, KeyRange, LostMotionConfig, MechanicsConfig,
    MechanicsDerived, MotorKind, PlantConfig, RANGES, Reading, SensorsConfig, range_of,
};
pub use error::{ConfigError, PlantError};
pub use load::{LoadTorque, SMOOTH_LOAD_STEP_S, TimeSeries, for_each_load_piece};
pub use model::{Contact, Winding};
pub use pmsm::{
    Inverter, MAX_DEAD_TIME_FRACTION, PmsmParams, PmsmPlant, clarke, inverse_clarke, inverse_park,
    park,
};
pub use replay::{
    COLUMN_RANGES, MAX_SPAN_S, REPLAY_INPUT_HEADER, REPLAY_OUTPUT_HEADER, ReplaySummary, StateRow,
    TorqueRow, parse_torque_csv, replay, simulate, write_atomically,
};
pub use two_inertia::{FixedStep, TwoInertiaPlant};
pub use validate::MAX_RATE_PER_S;
