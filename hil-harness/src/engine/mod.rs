//! The closed loop: the runner (controller backends at 4 kHz / 2 kHz against the plant),
//! the plant with its sensors, the trace and the metrics computed from it.

pub mod metrics;
pub mod plant;
pub mod runner;
mod schedule;
pub mod trace;
