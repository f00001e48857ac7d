//! controller-core: the regulators of the paper's Fig. 5 as a `no_std`, no-alloc,
//! fixed-point crate. Cascaded position P, velocity PI and current PI regulators, the
//! acceleration-feedback path with its filters and a state observer, profiles and faults.
//! The same code runs, bit for bit, in the firmware's interrupts and in the host harness.
#![cfg_attr(not(test), no_std)]
