//! The experiments built on the loop: the bandwidth sweep, the dynamic stiffness, the
//! paper's Sec. II map, the linear model of the loop, and `tune`, which designs on that
//! model and proves the design in the loop.

pub mod commission;
pub mod identify;
pub mod linear;
pub mod sec2;
pub mod stiffness;
pub mod sweep;
pub mod tune;
