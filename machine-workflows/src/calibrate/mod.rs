//! Motor calibration of a PMSM: phase resistance, d and q inductances, encoder direction and
//! offset, and pole pairs, measured as a drive's commissioning measures them before it
//! closes the current loop.
//!
//! The excitation is controller-core's ([`controller_core::foc::calibration`]): a voltage
//! sequence in the stationary frame, the same on the board as here. [`record`] runs it on
//! the simulated machine of a machine file and keeps, each tick, what a board would report:
//! the stage, the voltage set, the commanded angle, the two phase currents as the ADC reads
//! them and the encoder count. [`estimate()`] reads only such a record, wherever it came from:
//! [`board`] takes it from the board, which runs the same sequence in its own loops
//! ([`Record::from_board`]), and sets and saves the calibration there.

pub mod board;
pub mod estimate;
pub mod record;

pub use estimate::{estimate, Estimate, MotorEstimates};
pub use record::{record_on_plant, Record, Row};

#[cfg(test)]
mod tests;
