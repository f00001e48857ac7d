//! The linear model of the whole discrete loop: the controller's ticks in f64 with its
//! quantized coefficients ([`mirror`], with the torque-reference notch: [`notch`]) around
//! the exactly sampled plant ([`model`]), for poles, damping, margins and stiffness.

pub mod analyze;
pub mod check;
pub mod hessenberg;
pub mod margins;
pub mod mirror;
pub mod model;
pub mod notch;
mod reduce;

pub use margins::{margins_of, Margins};
pub use mirror::{Break, Coefficients};
pub use model::LoopModel;

use crate::config::RunConfig;
use crate::error::Result;
use controller_core::Gains;
use plant_host::analysis::Gears;

/// The model of a run: its controller's coefficients (the gains it runs with, see
/// [`crate::engine::runner::regulator_gains`]) and its plant, with the gears `gears`.
pub fn for_run(cfg: &RunConfig, gears: Gears) -> Result<LoopModel> {
    let gains = crate::engine::runner::regulator_gains(cfg)?;
    for_gains(cfg, &gains, gears)
}

/// The model of a run whose controller runs with `gains` (designed once by the caller,
/// [`crate::engine::runner::regulator_gains`] of `cfg`), with the gears `gears`. Fails
/// only where the controller would refuse the gains (a notch that does not quantize).
pub fn for_gains(cfg: &RunConfig, gains: &Gains, gears: Gears) -> Result<LoopModel> {
    let coef = Coefficients::new(&cfg.drive, gains).map_err(crate::engine::runner::drive_error)?;
    Ok(LoopModel::new(
        coef,
        &cfg.plant,
        f64::from(cfg.drive.current_rate_hz),
        gears,
    ))
}
