//! controller-core's integration tests, built as one test binary: each module is one
//! concern, on the Table 1 drive of `common` and the closed-loop simulation of `sim`.
//! `cargo test -p controller-core --test it <module>::` runs one module.

mod common;
mod sim;

mod accel_loop;
mod afb_design;
mod afb_state_space;
mod blocks;
mod controller;
mod estimator;
mod gains;
mod notch;
mod pinned;
mod properties;
mod ranges;
mod serde_config;
mod setting_paths;
mod validation;
