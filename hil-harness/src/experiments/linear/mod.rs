//! The linear model of the whole discrete loop: the controller's ticks in f64 with its
//! quantized coefficients ([`mirror`]) around the exactly sampled plant ([`model`]), for
//! poles, damping, margins and stiffness.

pub mod analyze;
pub mod check;
pub mod margins;
pub mod mirror;
pub mod model;
mod reduce;

pub use margins::{margins_of, Margins};
pub use mirror::{Break, Coefficients};
pub use model::LoopModel;

use crate::config::RunConfig;
use crate::error::Result;
use plant_host::analysis::Gears;

/// The model of a run: its controller's coefficients (the gains it runs with, see
/// [`crate::engine::runner::regulator_gains`]) and its plant, with the gears `gears`.
pub fn for_run(cfg: &RunConfig, gears: Gears) -> Result<LoopModel> {
    let gains = crate::engine::runner::regulator_gains(cfg)?;
    let coef = Coefficients::new(&cfg.drive, &gains);
    Ok(LoopModel::new(
        coef,
        &cfg.plant,
        f64::from(cfg.drive.current_rate_hz),
        gears,
    ))
}
