//! The linear model of stiffdrive's whole discrete loop: controller-core's ticks in f64 with
//! their quantized coefficients ([`mirror`]: the blocks' own linear forms) around
//! plant-host's exactly sampled two-inertia plant ([`model`]), for poles, damping, margins
//! ([`margins`]) and stiffness.
//!
//! It is the one closed-loop model for design and analysis: `tune` and `linear` in the
//! harness judge designs with it, and controller-core's design tests use it as a
//! dev-dependency. It depends on controller-core and plant-host only, so a change to
//! controller-core rebuilds this crate and not the harness.

pub mod hessenberg;
pub mod margins;
pub mod mirror;
pub mod model;
mod reduce;

pub use margins::{Margins, margin_grid, margins_of, refined};
pub use mirror::{Break, Coefficients};
pub use model::LoopModel;
