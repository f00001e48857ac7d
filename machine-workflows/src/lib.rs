//! machine-workflows: what a drive engineer runs on a machine, each on `sim-engine`'s
//! closed loop: the bandwidth sweep, the dynamic stiffness, the linear model of the loop,
//! `tune`, which designs on that model and proves the design in the loop, `identify`, which
//! measures the machine and fits its model, `commission`, which does both and verifies the
//! design on the machine, and `flash`, which puts a drive on the board.

pub mod calibrate;
pub mod commission;
pub mod flash;
pub mod identify;
pub mod linear;
pub mod stiffness;
pub mod sweep;
pub mod tune;
