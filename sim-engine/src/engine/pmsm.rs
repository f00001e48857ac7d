//! The PMSM drive in the closed loop (`[drive.pmsm]`, `electrics.motor = "pmsm"`): the
//! frame's loop ([`super::frame`], the DC drive's timing step for step) with the
//! field-oriented current tick (`controller_core::Controller::pmsm_tick`) and
//! `plant_host::PmsmPlant` in place of the DC winding.
//!
//! Each current tick samples the two phase currents (a, b) at the tick instant; the tick's
//! three duties reach the inverter after the computational delay ([`DelayLine`]) and are
//! held until the next arrive. A tick whose drive reports `enabled = false` (a latched
//! fault: all six switches off) opens the inverter with the same delay
//! (`PmsmPlant::set_enabled`); the plant's model of the open inverter holds while the line back-EMF stays below the bus,
//! √3·λ·|ωm| < `electrics.dc_bus_pu`, and a run that goes beyond stops with an error naming
//! both (the diodes would conduct and brake the motor, which is not modelled).
//!
//! The trace has the DC run's columns, so every metric and report reads a PMSM run as it
//! reads a DC one. For a PMSM:
//! - `current_pu` is the measured q current i_q in the drive's frame, signed by the counts'
//!   direction (negated with `encoder_reversed`; with λ = 1 pu it is the magnets' torque);
//! - `voltage_pu` is the q component v_q of the voltage the inverter applies at the
//!   instant, in the rotor's true frame (0 while the inverter is off);
//! - `torque_cmd_pu` and `accel_fb_pu` are the tick's torque reference and AFB term, as
//!   for the DC drive.
//!
//! The protections' figures ([`super::protection::ProtectionWatch`]) see the measured current vector's
//! magnitude √(i_d² + i_q²), the quantity the drive's overcurrent and I²t protections use.

use super::delay::DelayLine;
use super::frame::{CurrentTick, Motor, Segment};
use super::plant::{f, plant_error, pu};
use super::runner::{controller, ControlBackend};
use crate::config::RunConfig;
use crate::error::{HarnessError, Result};
use controller_core::PmsmInputs;
use plant_host::{MotorKind, PmsmPlant};

/// The PWM timer's clock \[Hz\]: `[drive.pmsm] pwm_period_counts` counts of a timer counting
/// up and down at this clock make one PWM period (the default 4200 is 20 kHz, as
/// `controller-core/src/foc/config.rs` states). Only the plant's dead time depends on it.
pub const PWM_TIMER_CLOCK_HZ: f64 = 168e6;

/// Whether `cfg` is a PMSM run: `[drive.pmsm]` is set. An error when the drive and the
/// plant disagree on the motor (a PMSM drive on a DC winding, or the reverse).
pub(super) fn is_pmsm(cfg: &RunConfig) -> Result<bool> {
    let plant = cfg.plant.electrics.motor == MotorKind::Pmsm;
    match (cfg.drive.pmsm.is_some(), plant) {
        (true, false) => Err(HarnessError::config(
            "electrics.motor",
            "the drive has a [drive.pmsm] table but the plant's motor is \"dc\"; \
             set electrics.motor = \"pmsm\" or remove [drive.pmsm]",
        )),
        (false, true) => Err(HarnessError::config(
            "drive.pmsm",
            "the plant's motor is \"pmsm\" (electrics.motor) but the drive has no \
             [drive.pmsm] table",
        )),
        (drive, _) => Ok(drive),
    }
}

/// The drive's FOC coefficients: its PWM period (the duties' full scale) and its motor
/// model.
fn foc_of(cfg: &RunConfig) -> Result<controller_core::foc::FocCoefficients> {
    controller(cfg)?
        .foc()
        .copied()
        .ok_or_else(|| HarnessError::config("drive.pmsm", "a PMSM run needs [drive.pmsm]"))
}

/// The scenario's PMSM, its load locked if the scenario says so.
fn plant_of(cfg: &RunConfig, period: u16) -> Result<PmsmPlant> {
    let pwm_hz = PWM_TIMER_CLOCK_HZ / (2.0 * f64::from(period.max(1)));
    let plant = PmsmPlant::new(&cfg.plant, pwm_hz).map_err(plant_error)?;
    Ok(if cfg.scenario.load_locked {
        plant.with_locked_load()
    } else {
        plant
    })
}

/// What a tick tells the inverter: three duties in [0, 1], or `None` (switches off).
type Command = Option<[f64; 3]>;

/// Advances `plant` by `dt_s` under `command`; an error once the open inverter's model no
/// longer holds.
fn advance(plant: &mut PmsmPlant, dt_s: f64, command: Command, load_pu: f64) -> Result<()> {
    if dt_s <= 0.0 {
        return Ok(());
    }
    let on = command.is_some();
    if plant.enabled() != on {
        plant.set_enabled(on);
    }
    let duties = command.unwrap_or([0.5; 3]);
    plant
        .try_advance(dt_s, duties, load_pu)
        .map_err(plant_error)?;
    match plant.diode_limit_exceeded_s() {
        None => Ok(()),
        Some(t) => Err(HarnessError::Backend(format!(
            "plant: at {t:.4} s the drive's inverter is off and the motor turns at {:.3} pu: \
             the line back-EMF √3·λ·|ωm| is {:.3} × electrics.dc_bus_pu, so the diodes \
             conduct and brake the motor, which the plant does not model; the run stops here",
            plant.motor_vel_pu(),
            plant.back_emf_over_bus(),
        ))),
    }
}

/// v_q of the voltage the inverter applies now, in the rotor's true frame \[pu\].
fn applied_v_q(plant: &PmsmPlant) -> f64 {
    let v_ab = plant_host::clarke(plant.phase_voltages_pu());
    plant_host::park(v_ab, plant.electrical_angle_rad())[1]
}

/// The PMSM behind its inverter, and the drive's PWM full scale.
pub(super) struct PmsmMotor {
    plant: PmsmPlant,
    /// The duties' full scale: the drive's PWM period \[timer counts\].
    full_scale: f64,
    /// The drive's `encoder_reversed`: its q axis turns against the counts.
    reversed: bool,
    /// The drive's motor model: the torque of its measured currents.
    mtpa: controller_core::foc::mtpa::Mtpa,
}

impl PmsmMotor {
    /// The scenario's PMSM (its load locked if the scenario says so) and its computational
    /// delay.
    pub(super) fn new(cfg: &RunConfig) -> Result<(Self, DelayLine<Command>)> {
        let foc = foc_of(cfg)?;
        let period = foc.svpwm.period();
        let plant = plant_of(cfg, period)?;
        let tc_s = 1.0 / f64::from(cfg.drive.current_rate_hz);
        let line = DelayLine::new(cfg.plant.electrics.computational_delay_s, tc_s);
        let full_scale = f64::from(period);
        let reversed = cfg.drive.pmsm.is_some_and(|p| p.encoder_reversed);
        Ok((
            Self {
                plant,
                full_scale,
                reversed,
                mtpa: foc.mtpa,
            },
            line,
        ))
    }
}

impl Motor for PmsmMotor {
    type Plant = PmsmPlant;
    /// Phase currents a and b as the ADC reports them \[pu\].
    type Sample = [f64; 2];
    type Command = Command;

    fn plant(&self) -> &PmsmPlant {
        &self.plant
    }

    fn encoder_count(&self) -> i64 {
        self.plant.encoder_count()
    }

    fn load_encoder_count(&self) -> Option<i64> {
        self.plant.load_encoder_count()
    }

    fn sample(&self) -> [f64; 2] {
        self.plant.phase_current_samples()
    }

    fn initial_command(&self) -> Command {
        Some(self.plant.applied_duties())
    }

    /// v_q of the voltage the inverter applies now, in the rotor's true frame.
    fn voltage_pu(&self, _: Command) -> f64 {
        applied_v_q(&self.plant)
    }

    fn current_tick<B: ControlBackend + ?Sized>(
        &self,
        backend: &mut B,
        encoder_count: u32,
        [a, b]: [f64; 2],
    ) -> Result<CurrentTick<Command>> {
        let out = backend.pmsm_tick(PmsmInputs {
            encoder_count,
            phase_current_pu: [pu(a), pu(b)],
        })?;
        let (i_d, i_q) = (f(out.current.d), f(out.current.q));
        let full_scale = self.full_scale;
        Ok(CurrentTick {
            command: out
                .enabled
                .then(|| out.duties.map(|d| f64::from(d) / full_scale)),
            // The drive's torque of its measured currents, as `Controller::pmsm_measured_torque`
            // forms it (here from the outputs, so that every backend gives the same).
            current_pu: {
                let t = f(self.mtpa.torque(out.current));
                if self.reversed {
                    -t
                } else {
                    t
                }
            },
            watched_pu: i_d.hypot(i_q),
            current_ref_pu: f(out.torque_ref_pu),
            accel_fb_pu: f(out.accel_fb_pu),
            fault: out.fault,
        })
    }

    fn advance(&mut self, _: Segment, dt_s: f64, command: Command, load_pu: f64) -> Result<()> {
        advance(&mut self.plant, dt_s, command, load_pu)
    }
}
