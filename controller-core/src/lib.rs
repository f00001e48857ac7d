//! controller-core: the regulators of the paper's Fig. 5 as a `no_std`, no-alloc,
//! fixed-point crate. Cascaded position P, velocity PI and current PI regulators, the
//! acceleration-feedback path with its filters and a state observer, an optional notch on
//! the torque reference, profiles and faults.
//! The same code runs, bit for bit, in the firmware's interrupts and in the host harness.
//!
//! Configuration ([`DriveConfig`] → [`design()`] → [`Gains`]) uses `f32` once; the ticks
//! ([`Controller::current_tick`], [`Controller::velocity_tick`], [`Profile::next`]) use
//! only fixed-point integer arithmetic, saturate instead of wrapping, and cannot panic.
//!
//! Features: `serde` derives `Serialize`/`Deserialize` on [`DriveConfig`] and its nested
//! settings (the `[drive]` TOML contract; still `no_std`, no alloc); `schema` adds
//! `schemars::JsonSchema` (std). [`RANGES`] is the one range table [`DriveConfig::validate`]
//! checks. [`words`] holds the raw-word layout of the tick outputs and the fault codes.
#![cfg_attr(not(test), no_std)]

pub mod accel_feedback;
mod cfgmath;
pub mod config;
pub mod controller;
pub mod design;
pub mod differentiator;
pub mod error;
pub mod excitation;
pub mod fault;
pub mod filter;
pub mod foc;
pub mod notch;
pub mod observer;
pub mod per_unit;
pub mod pi;
pub mod profile;
pub mod protection;
pub mod ranges;
mod validate;
pub mod words;

pub use config::{
    AccelFeedbackConfig, AfbFilterAtLimit, AfbMode, AfbRate, DriveConfig, Estimator, FaultLimits,
    FilterConfig, NotchConfig, ObserverConfig, ObserverInertia, ObserverTorque, PiInertia,
};
pub use controller::{
    Controller, CurrentInputs, CurrentOutputs, PmsmInputs, PmsmOutputs, Setpoint, VelocityInputs,
    VelocityOutputs,
};
pub use design::{Gains, design};
pub use error::{ConfigError, QFormat};
pub use fault::Fault;
pub use per_unit::{Counts, CountsErr, Pu, PuPerS};
pub use profile::{Profile, ProfileConfig, ProfileKind};
pub use ranges::{RANGES, Range};
