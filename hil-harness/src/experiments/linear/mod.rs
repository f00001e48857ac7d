//! The linear model of the whole discrete loop: the controller's ticks in f64 with its
//! quantized coefficients ([`mirror`]) around the exactly sampled plant ([`model`]), for
//! poles, damping, margins and stiffness.

pub mod analyze;
pub mod check;
pub mod hessenberg;
pub mod margins;
pub mod mirror;
pub mod model;
mod reduce;

pub use margins::{margins_of, Margins};
pub use mirror::{Break, Coefficients};
pub use model::LoopModel;

use crate::config::RunConfig;
use crate::error::Result;
use controller_core::Gains;
use plant_host::analysis::Gears;

/// Refuses a drive the model does not cover: the notch on the torque reference
/// (`[drive.notch]`) is not in the controller mirror yet, and a model without it would
/// predict another loop than the one that runs.
pub fn check_covered(cfg: &RunConfig) -> Result<()> {
    match cfg.drive.notch {
        None => Ok(()),
        Some(_) => Err(crate::error::HarnessError::config(
            "drive.notch",
            "the linear model does not model the notch filter yet: remove [drive.notch] to \
             analyze or tune this drive",
        )),
    }
}

/// The model of a run: its controller's coefficients (the gains it runs with, see
/// [`crate::engine::runner::regulator_gains`]) and its plant, with the gears `gears`.
pub fn for_run(cfg: &RunConfig, gears: Gears) -> Result<LoopModel> {
    check_covered(cfg)?;
    let gains = crate::engine::runner::regulator_gains(cfg)?;
    Ok(for_gains(cfg, &gains, gears))
}

/// The model of a run whose controller runs with `gains` (designed once by the caller,
/// [`crate::engine::runner::regulator_gains`] of `cfg`), with the gears `gears`.
#[must_use]
pub fn for_gains(cfg: &RunConfig, gains: &Gains, gears: Gears) -> LoopModel {
    LoopModel::new(
        Coefficients::new(&cfg.drive, gains),
        &cfg.plant,
        f64::from(cfg.drive.current_rate_hz),
        gears,
    )
}
