//! sim-engine: wires controller-core to plant-host with the real timing (current tick
//! every 250 µs, velocity tick every 500 µs, computational delay, zero-order hold) and
//! writes what a run gives: its trace, metrics, summary and plots.
//!
//! * [`config`]: a run's configuration, composed from the machine, scenario and grids files;
//! * [`engine`]: the closed loop, its trace, metrics, summary and protections;
//! * [`output`]: run directories written through a staging directory, never over foreign files;
//! * [`plot`], [`progress`]: figures (PNG and SVG) and progress bars;
//! * [`run`]: one scenario into its run directory (`run`);
//! * [`replay`]: plant-host's open-loop replay of a torque CSV (`replay`);
//! * [`error`]: the one error type, with the process exit code of each.
//!
//! Entry points: [`engine::runner::run_scenario`] (host controller) and
//! [`engine::runner::run_with_backend`] with any [`engine::runner::ControlBackend`] (e.g. the
//! firmware through the PIL link), on a [`config::RunConfig`] from [`config::resolve()`].

pub mod config;
pub mod engine;
pub mod error;
pub mod output;
pub mod plot;
pub mod progress;
pub mod replay;
pub mod run;

pub use config::{resolve, RunConfig};
pub use engine::runner::{run_scenario, run_with_backend, ControlBackend, RunOutput};
pub use error::{HarnessError, Result};
