//! controller-core's integration tests, built as one test binary: each module is one
//! concern, on the Table 1 drive and plant of `common`. Design questions go to the linear model
//! of the loop that `tune` uses (`afb_loop`). What it cannot answer stays elsewhere, each
//! module saying what: `accel_loop` and `afb_design` (the fixed-point controller around
//! plant-host's plant through lost motion, `plant_loop`; one test on the hand-written plant of
//! `sim`) and `afb_skeleton` (a tick skeleton that builds a structure the controller does not
//! run).
//! `cargo test -p controller-core --test it <module>::` runs one module.

mod common;
mod plant_loop;
mod sim;

mod accel_loop;
mod afb_design;
mod afb_loop;
mod afb_skeleton;
mod blocks;
mod controller;
mod estimator;
mod foc;
mod gains;
mod given_ranges;
mod notch;
mod pinned;
mod properties;
mod ranges;
mod serde_config;
mod setting_paths;
mod validation;
