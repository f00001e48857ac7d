//! The closed loop: the runner (controller backends at 4 kHz / 2 kHz against the plant),
//! the plant with its sensors, the trace and the metrics computed from it, and the record
//! of the drive's protections (when and why it tripped).

mod dc;
mod delay;
mod frame;
pub mod metrics;
pub mod plant;
mod pmsm;
pub mod protection;
pub mod runner;
mod schedule;
pub mod summary;
pub mod trace;
