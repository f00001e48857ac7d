//! The one tick driver of the closed loop, for either motor ([`Motor`]): the cadence of
//! the current and velocity ticks, the trace rows, the computational delay and the
//! plant's two segments per tick, the protections' watch and the [`TickRun`].
//!
//! Every current tick (Ts_c = 1/current_rate_hz) the encoder and the motor's current
//! sensors are sampled at the tick instant; on every `current_rate/velocity_rate`-th tick
//! the velocity tick runs first, on the same samples, then the current tick. The tick's
//! command reaches the plant after the computational delay ([`DelayLine`]: whole ticks
//! plus the remainder r) and is held until the next one arrives. The plant is advanced
//! over [t, t+r) with the command applied before and over [t+r, t+Ts_c) with the one that
//! arrives at t+r, the load torque at each segment's middle.
//!
//! What differs between the motors is the current tick's inputs and outputs and the
//! plant's step: the DC winding (`super::dc`) and the PMSM behind its inverter
//! (`super::pmsm`) implement [`Motor`].

use super::delay::DelayLine;
use super::plant::PlantView;
use super::protection::ProtectionWatch;
use super::runner::{ControlBackend, TickRecord, TickRun};
use super::schedule::LoadCursor;
use super::trace::{Trace, TraceRow};
use crate::config::RunConfig;
use crate::error::Result;
use controller_core::words::fault_code;
use controller_core::{Fault, Setpoint, VelocityInputs};
use std::time::Instant;

/// The fixed quantities of a run: tick lengths and the count scales.
struct Timing {
    /// Current tick \[s\].
    tc_s: f64,
    /// The part of the computational delay within one tick \[s\].
    delay_s: f64,
    /// Current ticks per velocity tick.
    ratio: u64,
    /// Position command: counts = pu·s · (base rpm / 60) · cpr, in the counts the drive
    /// reads (after sin/cos interpolation).
    counts_per_pu_s: f64,
    /// Counts per radian of the motor shaft.
    counts_per_rad: f64,
    /// The hardware counter's range: the plant's unwrapped count modulo 2^counter_bits.
    mask: u64,
    /// The controller takes its first reading as the position origin; commands are
    /// unwrapped counts relative to the same origin.
    initial_count: i64,
}

impl Timing {
    /// For a plant whose encoder reads `initial_count` at the start.
    fn new(cfg: &RunConfig, initial_count: i64, delay_s: f64) -> Self {
        let drive = &cfg.drive;
        let cpr = f64::from(cfg.plant.counts_per_rev());
        Self {
            tc_s: 1.0 / f64::from(drive.current_rate_hz),
            delay_s,
            ratio: u64::from((drive.current_rate_hz / drive.velocity_rate_hz.max(1)).max(1)),
            counts_per_pu_s: cfg.plant.mechanics.base_speed_rpm / 60.0 * cpr,
            counts_per_rad: cpr / std::f64::consts::TAU,
            mask: if drive.counter_bits >= 32 {
                u64::from(u32::MAX)
            } else {
                (1u64 << drive.counter_bits) - 1
            },
            initial_count,
        }
    }
}

/// The velocity tick at `t_s`, and the trace row of this instant.
fn velocity_step<B: ControlBackend + ?Sized, P: PlantView>(
    backend: &mut B,
    plant: &P,
    cfg: &RunConfig,
    (tm, load): (&Timing, &mut LoadCursor),
    (t_s, encoder_count, voltage_pu): (f64, u32, f64),
) -> TraceRow {
    use crate::engine::plant::{counts, f, pu, pu_s};
    let scenario = &cfg.scenario;
    let cmd = scenario.profile.command(t_s);
    let pos_counts = cmd.position_pu_s * tm.counts_per_pu_s;
    let setpoint = Setpoint {
        position_counts: counts(tm.initial_count as f64 + pos_counts),
        velocity_pu: pu(cmd.velocity_pu),
        acceleration_pu_s: pu_s(cmd.acceleration_pu_s),
    };
    let last_vel = backend.velocity_tick(VelocityInputs {
        encoder_count,
        setpoint,
        fault_input: false,
    });
    TraceRow {
        t_s,
        pos_cmd_counts: pos_counts,
        motor_pos_counts: plant.motor_pos_rad() * tm.counts_per_rad,
        load_pos_counts: plant.load_pos_rad() * tm.counts_per_rad,
        vel_cmd_pu: cmd.velocity_pu,
        motor_vel_pu: plant.motor_vel_pu(),
        load_vel_pu: plant.load_vel_pu(),
        vel_est_pu: f(last_vel.velocity_est_pu),
        torque_cmd_pu: f(last_vel.current_ref_pu),
        current_pu: plant.current_pu(),
        accel_fb_pu: f(last_vel.accel_fb_pu),
        shaft_torque_pu: plant.shaft_torque_pu(),
        load_torque_pu: load.torque_pu(t_s),
        voltage_pu,
        accel_est_pu_s: f(last_vel.acceleration_est_pu_s),
        fault: f64::from(fault_code(last_vel.fault)),
    }
}

/// Which of a tick's two plant segments: before the delayed command arrives (the
/// computational delay's remainder r), or after it (the rest of the tick).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Segment {
    /// [t, t+r): the command applied before.
    Delay,
    /// [t+r, t+Ts_c): the command that arrived at t+r.
    Rest,
}

/// What a motor's current tick hands the frame.
#[derive(Clone, Copy, Debug)]
pub(super) struct CurrentTick<C> {
    /// The command for the plant, before the computational delay.
    pub(super) command: C,
    /// The measured torque-producing current the [`TickRecord`] carries \[pu\].
    pub(super) current_pu: f64,
    /// The measured current the protections' figures see \[pu\].
    pub(super) watched_pu: f64,
    /// The torque reference the tick formed \[pu\].
    pub(super) current_ref_pu: f64,
    /// The tick's AFB term \[pu\].
    pub(super) accel_fb_pu: f64,
    /// The fault the tick reports.
    pub(super) fault: Option<Fault>,
}

/// A motor kind in the closed loop: its plant, what its current tick reads and commands,
/// and how its plant is advanced under a held command.
pub(super) trait Motor {
    /// The plant, as a trace row reads it.
    type Plant: PlantView;
    /// What the current sensors give at a tick instant.
    type Sample: Copy;
    /// What reaches the plant through the computational delay.
    type Command: Copy;

    /// The plant.
    fn plant(&self) -> &Self::Plant;
    /// The motor encoder's count, unwrapped.
    fn encoder_count(&self) -> i64;
    /// The load encoder's count, where one is fitted.
    fn load_encoder_count(&self) -> Option<i64>;
    /// The current sensors at this instant.
    fn sample(&self) -> Self::Sample;
    /// The command the plant holds at the start (before the first tick's arrives).
    fn initial_command(&self) -> Self::Command;
    /// The trace's `voltage_pu` while `applied` is applied.
    fn voltage_pu(&self, applied: Self::Command) -> f64;
    /// One current tick of `backend` on this instant's samples.
    fn current_tick<B: ControlBackend + ?Sized>(
        &self,
        backend: &mut B,
        encoder_count: u32,
        sample: Self::Sample,
    ) -> Result<CurrentTick<Self::Command>>;
    /// Advances the plant over `segment` (`dt_s` long) with `command` and the load torque
    /// held.
    fn advance(
        &mut self,
        segment: Segment,
        dt_s: f64,
        command: Self::Command,
        load_pu: f64,
    ) -> Result<()>;
}

/// The plant over one current tick from `t_s`: `held` until the delayed command arrives,
/// then that one. Returns the command applied at the end of the tick.
#[inline]
fn plant_step<M: Motor>(
    motor: &mut M,
    delay_line: &mut DelayLine<M::Command>,
    (tm, load): (&Timing, &mut LoadCursor),
    (t_s, held, command): (f64, M::Command, M::Command),
) -> Result<M::Command> {
    let delay_s = tm.delay_s;
    let load_pu = load.torque_pu(t_s + 0.5 * delay_s);
    motor.advance(Segment::Delay, delay_s, held, load_pu)?;
    let now = delay_line.push(command, held);
    let rest_s = tm.tc_s - delay_s;
    let load_pu = load.torque_pu(t_s + delay_s + 0.5 * rest_s);
    motor.advance(Segment::Rest, rest_s, now, load_pu)?;
    Ok(now)
}

/// The closed loop of `cfg` with `backend` on `motor`, whose plant is at its start and
/// whose tick is delayed by `delay_line`; every current tick's [`TickRecord`] goes to
/// `record`. The backend's session ends ([`ControlBackend::finished`]) on an error too.
pub(super) fn run<M: Motor, B: ControlBackend + ?Sized>(
    cfg: &RunConfig,
    backend: &mut B,
    (mut motor, mut delay_line): (M, DelayLine<M::Command>),
    mut record: impl FnMut(&TickRecord),
) -> Result<TickRun> {
    let current_rate_hz = f64::from(cfg.drive.current_rate_hz);
    let tm = Timing::new(cfg, motor.encoder_count(), delay_line.remainder_s());
    let ticks = (cfg.scenario.duration_s * current_rate_hz).round() as u64;
    let mut rows = Vec::with_capacity((ticks / tm.ratio + 1) as usize);
    let mut load = LoadCursor::new(&cfg.scenario);
    let mut watch = ProtectionWatch::new(&cfg.drive);
    let mut applied = motor.initial_command();
    let start = Instant::now();
    let mut ticks_run = 0;
    // Current ticks until the next velocity tick (k % ratio == 0).
    let mut to_velocity_tick: u64 = 0;
    // The loop, as a closure so that the backend's session ends on an error too.
    let mut ticks_loop = || -> Result<()> {
        for k in 0..ticks {
            if backend.halted() {
                break;
            }
            ticks_run = k + 1;
            let t_s = k as f64 * tm.tc_s;
            let encoder_count = ((motor.encoder_count() as u64) & tm.mask) as u32;
            let sample = motor.sample();
            let velocity_tick = to_velocity_tick == 0;
            to_velocity_tick = to_velocity_tick.checked_sub(1).unwrap_or(tm.ratio - 1);
            if velocity_tick {
                let inputs = (t_s, encoder_count, motor.voltage_pu(applied));
                let plant = motor.plant();
                rows.push(velocity_step(backend, plant, cfg, (&tm, &mut load), inputs));
            }
            let out = motor.current_tick(backend, encoder_count, sample)?;
            watch.tick(k, t_s, out.watched_pu, out.fault);
            record(&TickRecord {
                t_s,
                encoder_count: motor.encoder_count(),
                load_encoder_count: motor.load_encoder_count(),
                current_pu: out.current_pu,
                current_ref_pu: out.current_ref_pu,
                excitation_pu: backend.excitation_pu(),
            });
            let step = (t_s, applied, out.command);
            applied = plant_step(&mut motor, &mut delay_line, (&tm, &mut load), step)?;
            if let Some(row) = rows.last_mut().filter(|_| velocity_tick) {
                // Torque reference and AFB term as the current tick of this instant formed
                // them (the velocity tick's output plus the AFB path at the current rate).
                row.torque_cmd_pu = out.current_ref_pu;
                row.accel_fb_pu = out.accel_fb_pu;
                // A fault latched in the velocity tick is reported by this one too.
                row.fault = f64::from(fault_code(out.fault));
            }
        }
        Ok(())
    };
    let ran = ticks_loop();
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
