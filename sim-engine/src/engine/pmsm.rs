//! The closed loop of a PMSM drive (`[drive.pmsm]`, `electrics.motor = "pmsm"`): the
//! runner's loop ([`super::runner::run_ticks`]) with the field-oriented current tick
//! (`controller_core::Controller::pmsm_tick`) and `plant_host::PmsmPlant` in place of the
//! DC winding.
//!
//! The timing is the DC loop's, step for step: each current tick samples the encoder and
//! the two phase currents (a, b) at the tick instant; on every velocity tick the velocity
//! tick runs first on the same samples; the tick's three duties reach the inverter after
//! the computational delay (whole ticks plus the remainder, as [`DelayLine`]) and are held
//! until the next arrive. The plant is integrated over [t, t+r) with the duties applied
//! before and over [t+r, t+Ts_c) with the new ones, the load torque at each segment's
//! middle. A tick whose drive reports `enabled = false` (a latched fault: all six switches
//! off) opens the inverter with the same delay (`PmsmPlant::set_enabled`); the plant's model
//! of the open inverter holds while the line back-EMF stays below the bus,
//! √3·λ·|ωm| < `electrics.dc_bus_pu`, and a run that goes beyond stops with an error naming
//! both (the diodes would conduct and brake the motor, which is not modelled).
//!
//! The trace has the DC run's columns, so every metric and report reads a PMSM run as it
//! reads a DC one. For a PMSM:
//! - `current_pu` is the true q current i_q (the rotor's own frame; with λ = 1 pu it is
//!   the magnets' torque);
//! - `voltage_pu` is the q component v_q of the voltage the inverter applies at the
//!   instant, in the rotor's true frame (0 while the inverter is off);
//! - `torque_cmd_pu` and `accel_fb_pu` are the tick's torque reference and AFB term, as
//!   for the DC drive.
//!
//! The protections' figures ([`ProtectionWatch`]) see the measured current vector's
//! magnitude √(i_d² + i_q²), the quantity the drive's overcurrent and I²t protections use.

use super::plant::{f, plant_error, pu};
use super::protection::ProtectionWatch;
use super::runner::{
    controller, velocity_step, ControlBackend, DelayLine, TickRecord, TickRun, Timing,
};
use super::schedule::LoadCursor;
use super::trace::Trace;
use crate::config::RunConfig;
use crate::error::{HarnessError, Result};
use controller_core::words::fault_code;
use controller_core::PmsmInputs;
use plant_host::{MotorKind, PmsmPlant};
use std::collections::VecDeque;
use std::time::Instant;

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

/// The duties' full scale: the drive's PWM period \[timer counts\].
fn pwm_period(cfg: &RunConfig) -> Result<u16> {
    controller(cfg)?
        .foc()
        .map(|foc| foc.svpwm.period())
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

/// [`DelayLine`] for the inverter's commands.
struct CommandDelay {
    whole_ticks: usize,
    in_flight: VecDeque<Command>,
}

impl CommandDelay {
    fn new(line: &DelayLine) -> Self {
        Self {
            whole_ticks: line.whole_ticks(),
            in_flight: VecDeque::with_capacity(line.whole_ticks() + 1),
        }
    }

    /// As [`DelayLine::push`].
    fn push(&mut self, command: Command, held: Command) -> Command {
        if self.whole_ticks == 0 {
            return command;
        }
        self.in_flight.push_back(command);
        if self.in_flight.len() > self.whole_ticks {
            self.in_flight.pop_front().unwrap_or(held)
        } else {
            held
        }
    }
}

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

/// The plant over one current tick from `t_s`: the held command until the delayed one
/// arrives, then that one. Returns the command applied at the end of the tick.
fn plant_step(
    plant: &mut PmsmPlant,
    delay: &mut CommandDelay,
    (tm, load): (&Timing, &mut LoadCursor),
    (t_s, held, command): (f64, Command, Command),
) -> Result<Command> {
    let delay_s = tm.delay_s;
    advance(plant, delay_s, held, load.torque_pu(t_s + 0.5 * delay_s))?;
    let now = delay.push(command, held);
    let rest_s = tm.tc_s - delay_s;
    let load_pu = load.torque_pu(t_s + delay_s + 0.5 * rest_s);
    advance(plant, rest_s, now, load_pu)?;
    Ok(now)
}

/// v_q of the voltage the inverter applies now, in the rotor's true frame \[pu\].
fn applied_v_q(plant: &PmsmPlant) -> f64 {
    let v_ab = plant_host::clarke(plant.phase_voltages_pu());
    plant_host::park(v_ab, plant.electrical_angle_rad())[1]
}

/// The PMSM loop of [`super::runner::run_ticks`].
pub(super) fn run_ticks<B: ControlBackend + ?Sized>(
    cfg: &RunConfig,
    backend: &mut B,
    mut record: impl FnMut(&TickRecord),
) -> Result<TickRun> {
    let period = pwm_period(cfg)?;
    let full_scale = f64::from(period);
    let mut plant = plant_of(cfg, period)?;
    let current_rate_hz = f64::from(cfg.drive.current_rate_hz);
    let line = DelayLine::new(
        cfg.plant.electrics.computational_delay_s,
        1.0 / current_rate_hz,
    );
    let mut delay = CommandDelay::new(&line);
    let tm = Timing::new(cfg, plant.encoder_count(), line.remainder_s());
    let ticks = (cfg.scenario.duration_s * current_rate_hz).round() as u64;
    let mut rows = Vec::with_capacity((ticks / tm.ratio + 1) as usize);
    let mut load = LoadCursor::new(&cfg.scenario);
    let mut watch = ProtectionWatch::new(&cfg.drive);
    let mut applied: Command = Some(plant.applied_duties());
    let start = Instant::now();
    let mut ticks_run = 0;
    let mut to_velocity_tick: u64 = 0;
    // The loop, as a closure so that the backend's session ends on an error too.
    let mut run = || -> Result<()> {
        for k in 0..ticks {
            if backend.halted() {
                break;
            }
            ticks_run = k + 1;
            let t_s = k as f64 * tm.tc_s;
            let encoder_count = ((plant.encoder_count() as u64) & tm.mask) as u32;
            let [a, b] = plant.phase_current_samples();
            let velocity_tick = to_velocity_tick == 0;
            to_velocity_tick = to_velocity_tick.checked_sub(1).unwrap_or(tm.ratio - 1);
            if velocity_tick {
                let inputs = (t_s, encoder_count, applied_v_q(&plant));
                let row = velocity_step(backend, &plant, cfg, (&tm, &mut load), inputs);
                rows.push(row);
            }
            let out = backend.pmsm_tick(PmsmInputs {
                encoder_count,
                phase_current_pu: [pu(a), pu(b)],
            })?;
            let (i_d, i_q) = (f(out.current.d), f(out.current.q));
            watch.tick(k, t_s, i_d.hypot(i_q), out.fault);
            record(&TickRecord {
                t_s,
                encoder_count: plant.encoder_count(),
                load_encoder_count: plant.load_encoder_count(),
                current_pu: i_q,
                current_ref_pu: f(out.torque_ref_pu),
                excitation_pu: backend.excitation_pu(),
            });
            let command = out
                .enabled
                .then(|| out.duties.map(|d| f64::from(d) / full_scale));
            let step = (t_s, applied, command);
            applied = plant_step(&mut plant, &mut delay, (&tm, &mut load), step)?;
            if let Some(row) = rows.last_mut().filter(|_| velocity_tick) {
                row.torque_cmd_pu = f(out.torque_ref_pu);
                row.accel_fb_pu = f(out.accel_fb_pu);
                row.fault = f64::from(fault_code(out.fault));
            }
        }
        Ok(())
    };
    let ran = run();
    backend.finished();
    ran?;
    let wall_time_s = start.elapsed().as_secs_f64();
    let (fault, protection) = watch.finish();
    Ok(TickRun {
        trace: Trace { rows },
        sim_time_s: ticks_run as f64 * tm.tc_s,
        wall_time_s,
        ticks: ticks_run,
        fault,
        protection,
    })
}
