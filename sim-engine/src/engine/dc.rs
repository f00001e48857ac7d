//! The DC drive in the closed loop ([`super::frame`]): the winding's current sampled
//! through the ADC, the current tick's voltage command, and `plant_host::TwoInertiaPlant`
//! voltage driven, each of a tick's two segments by its exact map, computed once.

use super::delay::DelayLine;
use super::frame::{CurrentTick, Motor, Segment};
use super::plant::{f, plant_error, pu};
use super::runner::ControlBackend;
use super::schedule::TickSteps;
use crate::config::RunConfig;
use crate::error::Result;
use controller_core::CurrentInputs;
use plant_host::TwoInertiaPlant;

/// The DC winding on the two-inertia plant, with its two segments' maps.
pub(super) struct DcMotor {
    plant: TwoInertiaPlant,
    steps: TickSteps,
}

impl DcMotor {
    /// The scenario's plant (voltage driven, its load locked if the scenario says so) and
    /// its computational delay.
    pub(super) fn new(cfg: &RunConfig) -> Result<(Self, DelayLine<f64>)> {
        let plant = TwoInertiaPlant::voltage_driven(&cfg.plant);
        let mut plant = if cfg.scenario.load_locked {
            plant.with_locked_load()
        } else {
            plant
        };
        let tc_s = 1.0 / f64::from(cfg.drive.current_rate_hz);
        let line = DelayLine::new(cfg.plant.electrics.computational_delay_s, tc_s);
        let delay_s = line.remainder_s();
        let steps = TickSteps::new(&mut plant, delay_s, tc_s - delay_s)?;
        Ok((Self { plant, steps }, line))
    }
}

impl Motor for DcMotor {
    type Plant = TwoInertiaPlant;
    /// The winding current as the ADC reports it \[pu\].
    type Sample = f64;
    /// The winding voltage \[pu\].
    type Command = f64;

    #[inline]
    fn plant(&self) -> &TwoInertiaPlant {
        &self.plant
    }

    #[inline]
    fn encoder_count(&self) -> i64 {
        self.plant.encoder_count()
    }

    #[inline]
    fn load_encoder_count(&self) -> Option<i64> {
        self.plant.load_encoder_count()
    }

    #[inline]
    fn sample(&self) -> f64 {
        self.plant.current_sample()
    }

    fn initial_command(&self) -> f64 {
        0.0
    }

    #[inline]
    fn voltage_pu(&self, applied: f64) -> f64 {
        applied
    }

    #[inline]
    fn current_tick<B: ControlBackend + ?Sized>(
        &self,
        backend: &mut B,
        encoder_count: u32,
        sample: f64,
    ) -> Result<CurrentTick<f64>> {
        let current = pu(sample);
        let out = backend.current_tick(CurrentInputs {
            encoder_count,
            current_pu: current,
        });
        Ok(CurrentTick {
            command: f(out.voltage_cmd_pu),
            current_pu: f(current),
            watched_pu: f(current),
            current_ref_pu: f(out.current_ref_pu),
            accel_fb_pu: f(out.accel_fb_pu),
            fault: out.fault,
        })
    }

    #[inline]
    fn advance(&mut self, segment: Segment, _: f64, voltage_pu: f64, load_pu: f64) -> Result<()> {
        let step = match segment {
            Segment::Delay => &self.steps.delay,
            Segment::Rest => &self.steps.rest,
        };
        match step {
            Some(step) => self
                .plant
                .advance_fixed(step, voltage_pu, load_pu)
                .map_err(plant_error),
            None => Ok(()),
        }
    }
}
