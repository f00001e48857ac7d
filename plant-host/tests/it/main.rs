//! plant-host's integration tests, built as one test binary: each module is one concern,
//! on the shipped machine files and the independent reference integrator of `common`.
//! `cargo test -p plant-host --test it <module>::` runs one module.

mod common;

mod accuracy;
mod analysis;
mod arbitrary_steps;
mod config;
mod drive_input;
mod drive_sensors;
mod fit;
mod fixed_step;
mod identify;
mod long_random;
mod lost_motion_width;
mod pmsm;
mod pmsm_reference;
mod replay_bounds;
mod sampled;
