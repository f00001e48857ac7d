//! The linear model of a run's loop: the `loop-model` crate (the controller's ticks in f64
//! with its quantized coefficients around the exactly sampled plant) built for a
//! [`RunConfig`], the `linear` command ([`analyze`]) and its check against the nonlinear
//! loop ([`check`]).

pub mod analyze;
pub mod check;

pub use loop_model::{hessenberg, margins, mirror, model};
pub use loop_model::{margins_of, Break, Coefficients, LoopModel, Margins};

use controller_core::Gains;
use plant_host::analysis::Gears;
use sim_engine::config::RunConfig;
use sim_engine::error::Result;

/// The model of a run: its controller's coefficients (the gains it runs with, see
/// [`sim_engine::engine::runner::regulator_gains`]) and its plant, with the gears `gears`.
pub fn for_run(cfg: &RunConfig, gears: Gears) -> Result<LoopModel> {
    let gains = sim_engine::engine::runner::regulator_gains(cfg)?;
    for_gains(cfg, &gains, gears)
}

/// The model of a run whose controller runs with `gains` (designed once by the caller,
/// [`sim_engine::engine::runner::regulator_gains`] of `cfg`), with the gears `gears`. Fails
/// where the controller refuses the gains (`controller_core::Controller::from_gains`).
pub fn for_gains(cfg: &RunConfig, gains: &Gains, gears: Gears) -> Result<LoopModel> {
    let coef =
        Coefficients::new(&cfg.drive, gains).map_err(sim_engine::engine::runner::drive_error)?;
    Ok(LoopModel::new(
        coef,
        &cfg.plant,
        f64::from(cfg.drive.current_rate_hz),
        gears,
    ))
}
