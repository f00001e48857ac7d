//! The closed loop with the real timing.
//!
//! Every current tick (Ts_c = 1/current_rate_hz, 250 µs for Table 1) the encoder and the
//! current are sampled at the tick instant; on every `current_rate/velocity_rate`-th tick
//! (500 µs) the velocity tick runs first, on the same samples, then the current tick. The
//! new voltage reaches the winding after the computational delay (`electrics.
//! computational_delay_s`, 180 µs) and is held until the next one arrives (zero-order
//! hold). A delay longer than a tick delays by whole ticks plus the remainder
//! ([`DelayLine`]). The plant is integrated exactly between those events: [t, t+r) with
//! the voltage applied before, [t+r, t+Ts_c) with the one that arrives at t+r. The load torque is evaluated at
//! the middle of each segment. Nothing depends on wall-clock time or threads, so a run is
//! bit-for-bit repeatable.

use crate::config::RunConfig;
use crate::engine::metrics::oscillation::CONFIRM_INTERPOLATION;
use crate::engine::metrics::{compute, Metrics, OscillationKind};
use crate::engine::plant::PlantView;
use crate::engine::protection::{FaultRecord, ProtectionSummary, ProtectionWatch};
use crate::engine::schedule::{LoadCursor, TickSteps};
use crate::engine::trace::{Trace, TraceRow};
use crate::error::{HarnessError, Result};
use controller_core::words::fault_code;
use controller_core::{
    Controller, CurrentInputs, CurrentOutputs, Gains, PmsmInputs, PmsmOutputs, Setpoint,
    VelocityInputs, VelocityOutputs,
};
use plant_host::TwoInertiaPlant;
use std::time::Instant;

/// A controller the harness can run: the fixed-point core on the host, or the firmware
/// in QEMU through the PIL link.
pub trait ControlBackend {
    /// One current-loop tick (every 250 µs for Table 1).
    fn current_tick(&mut self, inputs: CurrentInputs) -> CurrentOutputs;
    /// One velocity-loop tick (every 500 µs for Table 1), run before the current tick of
    /// the same instant.
    fn velocity_tick(&mut self, inputs: VelocityInputs) -> VelocityOutputs;
    /// One current tick of a PMSM drive (`[drive.pmsm]`), in place of
    /// [`Self::current_tick`]. The default is a backend that drives a DC motor only (the
    /// PIL link has no PMSM encoding): an error, and the run stops.
    fn pmsm_tick(&mut self, inputs: PmsmInputs) -> Result<PmsmOutputs> {
        let _ = inputs;
        Err(HarnessError::Backend(
            "this controller backend drives a DC motor only (electrics.motor = \"dc\"); \
             a PMSM drive runs on the host controller (`stiffdrive run`)"
                .into(),
        ))
    }
    /// Whether the backend can no longer control the plant (a PIL link fault): the run
    /// stops before the next tick, with the trace up to that point.
    fn halted(&self) -> bool {
        false
    }
    /// The excitation sample the last tick added \[pu\] (0 without one).
    fn excitation_pu(&self) -> f64 {
        0.0
    }
    /// The run's last tick is done: a backend whose other end waits in lock step (the PIL
    /// link, whose firmware watchdog would expire) ends its session here, before the
    /// end-of-run figures are computed.
    fn finished(&mut self) {}
}

/// The signals of one current tick as the drive records them, for a
/// [`run_recorded`] recorder (identification): what a drive can log, no plant state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TickRecord {
    /// Tick instant \[s\].
    pub t_s: f64,
    /// Motor encoder count at the tick, unwrapped (noise and quantization included).
    pub encoder_count: i64,
    /// Load encoder count, where one is fitted.
    pub load_encoder_count: Option<i64>,
    /// Measured current (= torque) sample \[pu\] (ADC, noise); for a PMSM the measured
    /// q current.
    pub current_pu: f64,
    /// Torque reference the tick formed \[pu\].
    pub current_ref_pu: f64,
    /// Excitation sample the tick added \[pu\].
    pub excitation_pu: f64,
}

impl ControlBackend for Controller {
    fn current_tick(&mut self, inputs: CurrentInputs) -> CurrentOutputs {
        Controller::current_tick(self, inputs)
    }

    fn velocity_tick(&mut self, inputs: VelocityInputs) -> VelocityOutputs {
        Controller::velocity_tick(self, inputs)
    }

    fn pmsm_tick(&mut self, inputs: PmsmInputs) -> Result<PmsmOutputs> {
        Ok(Controller::pmsm_tick(self, inputs))
    }

    fn excitation_pu(&self) -> f64 {
        crate::engine::plant::f(Controller::excitation_pu(self))
    }
}

/// The result of one run.
#[derive(Clone, Debug)]
pub struct RunOutput {
    /// Recorded signals, one row per velocity tick.
    pub trace: Trace,
    /// Metrics of the trace.
    pub metrics: Metrics,
    /// Simulated time (s).
    pub sim_time_s: f64,
    /// Wall-clock time of the closed loop alone (s).
    pub wall_time_s: f64,
    /// Current ticks executed.
    pub ticks: u64,
    /// The fault the drive latched first, if it did.
    pub fault: Option<FaultRecord>,
    /// The protections' figures of the run.
    pub protection: ProtectionSummary,
}

pub use super::summary::Summary;

/// The computational delay D = n·Tc + r (0 <= r < Tc) between a current tick and its
/// voltage reaching the winding: the command of tick k arrives r into the interval of tick
/// k + n. [`DelayLine::push`] takes tick k's command and returns the one that arrives
/// during this interval.
#[derive(Clone, Debug)]
pub struct DelayLine {
    whole_ticks: usize,
    remainder_s: f64,
    in_flight: std::collections::VecDeque<f64>,
}

impl DelayLine {
    /// A delay of `delay_s` (negative counts as 0) at tick period `tick_s`.
    pub fn new(delay_s: f64, tick_s: f64) -> Self {
        let delay_s = delay_s.max(0.0);
        let whole = (delay_s / tick_s).floor();
        let whole_ticks = whole as usize;
        Self {
            whole_ticks,
            remainder_s: delay_s - whole * tick_s,
            in_flight: std::collections::VecDeque::with_capacity(whole_ticks + 1),
        }
    }

    /// r, the part of the delay within one tick (s).
    pub fn remainder_s(&self) -> f64 {
        self.remainder_s
    }

    /// n, the whole ticks of the delay.
    pub fn whole_ticks(&self) -> usize {
        self.whole_ticks
    }

    /// Takes this tick's command; returns the command that arrives r into this interval
    /// (`held`, the one applied so far, while the line is still filling).
    pub fn push(&mut self, command: f64, held: f64) -> f64 {
        if self.whole_ticks == 0 {
            // Shorter than a tick: this tick's command, as the queue would return it.
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

/// A drive setting's error as the harness's, naming `drive.KEY`.
pub fn drive_error(e: controller_core::ConfigError) -> HarnessError {
    HarnessError::config(format!("drive.{}", e.param()), e.to_string())
}

/// The gains the controller of `cfg` runs with: its own `design()`, or, for a comparison
/// run without AFB ([`RunConfig::gains_of`]), the AFB run's `design()` without its AFB
/// (`Gains::without_afb`: Ka = 0, every regulator gain bit-identical to the AFB run's).
pub fn regulator_gains(cfg: &RunConfig) -> Result<Gains> {
    match &cfg.gains_of {
        None => controller_core::design(&cfg.drive).map_err(drive_error),
        Some(of) => {
            // The AFB run's gains without AFB, carrying this run's own (validated) drive for
            // its limits, modes and rates.
            cfg.drive.validate().map_err(drive_error)?;
            let mut g = controller_core::design(&of.drive)
                .map_err(drive_error)?
                .without_afb();
            g.cfg = cfg.drive;
            Ok(g)
        }
    }
}

/// Whether `a` and `b` are the same regulator gains, bit for bit: every field of [`Gains`]
/// except those of the acceleration-feedback path itself (Ka, its filter and its rate) and
/// the acceleration feed-forward, which `Gains::without_afb` sets to the inertia the
/// commanded acceleration meets without AFB (unchanged in the error form), compared
/// through their exact (shortest round-trip) decimal form.
pub fn same_regulator_gains(a: &Gains, b: &Gains) -> bool {
    let mut b = *b;
    b.cfg = a.cfg;
    b.ka = a.ka;
    b.k_accel_ff = a.k_accel_ff;
    b.afb_filter = a.afb_filter;
    b.afb_rate_hz = a.afb_rate_hz;
    format!("{a:?}") == format!("{b:?}")
}

/// The host controller of `cfg`: `Controller::from_gains(&regulator_gains(cfg))`.
pub fn controller(cfg: &RunConfig) -> Result<Controller> {
    Controller::from_gains(&regulator_gains(cfg)?).map_err(drive_error)
}

/// Runs `cfg` with the host controller (`controller_core::Controller`).
pub fn run_scenario(cfg: &RunConfig) -> Result<RunOutput> {
    let mut controller = controller(cfg)?;
    let mut out = run_with_backend(cfg, &mut controller)?;
    confirm_limit_cycle(cfg, &mut out);
    Ok(out)
}

/// The `oscillation` rule's step 5 on a finished run of `cfg`: a `limit_cycle` verdict is
/// checked by the same run on the host controller with the encoder interpolated
/// [`CONFIRM_INTERPOLATION`] times more ([`Metrics::confirm`](crate::engine::metrics::Metrics::confirm)).
/// A drive that cannot take the finer counts (its counter width, say) keeps the verdict
/// unconfirmed (`interpolated_amplitude_pu` stays `null`).
pub fn confirm_limit_cycle(cfg: &RunConfig, out: &mut RunOutput) {
    if out.metrics.oscillation.kind != OscillationKind::LimitCycle {
        return;
    }
    let again = finer_encoder(cfg)
        .and_then(|fine| Some((self::controller(&fine).ok()?, fine)))
        .and_then(|(mut c, fine)| run_with_backend(&fine, &mut c).ok());
    if let Some(again) = again {
        out.metrics.confirm(&again.metrics);
    }
}

/// `cfg` with its encoder interpolated [`CONFIRM_INTERPOLATION`] times more (the drive
/// counting the finer counts, and so the AFB drive a comparison run borrows its gains
/// from); `None` if the counts would not fit the drive's range.
pub fn finer_encoder(cfg: &RunConfig) -> Option<RunConfig> {
    let mut fine = cfg.clone();
    let s = &mut fine.plant.sensors;
    s.encoder_interpolation = s.encoder_interpolation.checked_mul(CONFIRM_INTERPOLATION)?;
    let cpr = fine.plant.counts_per_rev();
    (cpr < (1 << 30)
        && u64::from(cpr)
            == u64::from(fine.plant.mechanics.encoder_cpr)
                * u64::from(fine.plant.sensors.encoder_interpolation))
    .then(|| {
        // The fault limits are in revolutions and overspeed multiples: they keep their
        // angle. A comparison run's gains are designed from its AFB run's drive: that drive
        // counts the finer counts too, or the gains would scale the finer counts as the
        // coarse ones.
        for d in
            std::iter::once(&mut fine.drive).chain(fine.gains_of.as_mut().map(|g| &mut g.drive))
        {
            d.encoder_cpr = cpr;
        }
        fine
    })
}

/// The fixed quantities of a run: tick lengths and the count scales.
pub(super) struct Timing {
    /// Current tick \[s\].
    pub(super) tc_s: f64,
    /// The part of the computational delay within one tick \[s\].
    pub(super) delay_s: f64,
    /// Current ticks per velocity tick.
    pub(super) ratio: u64,
    /// Position command: counts = pu·s · (base rpm / 60) · cpr, in the counts the drive
    /// reads (after sin/cos interpolation).
    counts_per_pu_s: f64,
    /// Counts per radian of the motor shaft.
    counts_per_rad: f64,
    /// The hardware counter's range: the plant's unwrapped count modulo 2^counter_bits.
    pub(super) mask: u64,
    /// The controller takes its first reading as the position origin; commands are
    /// unwrapped counts relative to the same origin.
    initial_count: i64,
}

impl Timing {
    /// For a plant whose encoder reads `initial_count` at the start.
    pub(super) fn new(cfg: &RunConfig, initial_count: i64, delay_s: f64) -> Self {
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
pub(super) fn velocity_step<B: ControlBackend + ?Sized, P: PlantView>(
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

/// The plant over one current tick from `t_s`: the held voltage until the delayed command
/// arrives, then the new one. Returns the voltage applied at the end of the tick.
#[inline]
fn plant_step(
    plant: &mut TwoInertiaPlant,
    delay_line: &mut DelayLine,
    (tm, steps, load): (&Timing, &TickSteps, &mut LoadCursor),
    (t_s, voltage_pu, command_pu): (f64, f64, f64),
) -> Result<f64> {
    let delay_s = tm.delay_s;
    if let Some(step) = &steps.delay {
        plant
            .advance_fixed(step, voltage_pu, load.torque_pu(t_s + 0.5 * delay_s))
            .map_err(crate::engine::plant::plant_error)?;
    }
    let voltage_pu = delay_line.push(command_pu, voltage_pu);
    if let Some(step) = &steps.rest {
        let rest_s = step.dt_s();
        plant
            .advance_fixed(
                step,
                voltage_pu,
                load.torque_pu(t_s + delay_s + 0.5 * rest_s),
            )
            .map_err(crate::engine::plant::plant_error)?;
    }
    Ok(voltage_pu)
}

/// The scenario's plant: voltage driven, its load locked if the scenario says so.
fn plant_of(cfg: &RunConfig) -> TwoInertiaPlant {
    let plant = TwoInertiaPlant::voltage_driven(&cfg.plant);
    if cfg.scenario.load_locked {
        plant.with_locked_load()
    } else {
        plant
    }
}

/// Runs `cfg` with any [`ControlBackend`].
pub fn run_with_backend<B: ControlBackend + ?Sized>(
    cfg: &RunConfig,
    backend: &mut B,
) -> Result<RunOutput> {
    run_recorded(cfg, backend, |_| {})
}

/// [`run_with_backend`], handing every current tick's [`TickRecord`] to `record`.
pub fn run_recorded<B: ControlBackend + ?Sized>(
    cfg: &RunConfig,
    backend: &mut B,
    record: impl FnMut(&TickRecord),
) -> Result<RunOutput> {
    let run = run_ticks(cfg, backend, record)?;
    let mut metrics = compute(&run.trace, &cfg.metric_windows());
    if let Some(f) = &run.fault {
        metrics.tripped(f.kind);
    }
    Ok(RunOutput {
        fault: run.fault,
        protection: run.protection,
        trace: run.trace,
        metrics,
        sim_time_s: run.sim_time_s,
        wall_time_s: run.wall_time_s,
        ticks: run.ticks,
    })
}

/// A run before its metrics: what [`run_ticks`] returns.
#[derive(Debug, Clone)]
pub struct TickRun {
    /// Recorded signals, one row per velocity tick.
    pub trace: Trace,
    /// Simulated time (s).
    pub sim_time_s: f64,
    /// Wall-clock time of the closed loop (s).
    pub wall_time_s: f64,
    /// Current ticks executed.
    pub ticks: u64,
    /// The fault the drive latched first, if it did.
    pub fault: Option<FaultRecord>,
    /// The protections' figures of the run.
    pub protection: ProtectionSummary,
}

/// The closed loop of [`run_recorded`] without the metrics (their spectra cost as much as
/// the loop): for a caller that reads only the records, such as identification.
pub fn run_ticks<B: ControlBackend + ?Sized>(
    cfg: &RunConfig,
    backend: &mut B,
    mut record: impl FnMut(&TickRecord),
) -> Result<TickRun> {
    use crate::engine::plant::{f, pu};
    if super::pmsm::is_pmsm(cfg)? {
        return super::pmsm::run_ticks(cfg, backend, record);
    }
    let mut plant = plant_of(cfg);
    let current_rate_hz = f64::from(cfg.drive.current_rate_hz);
    let mut delay_line = DelayLine::new(
        cfg.plant.electrics.computational_delay_s,
        1.0 / current_rate_hz,
    );
    let tm = Timing::new(cfg, plant.encoder_count(), delay_line.remainder_s());
    let ticks = (cfg.scenario.duration_s * current_rate_hz).round() as u64;
    let mut rows = Vec::with_capacity((ticks / tm.ratio + 1) as usize);
    let steps = TickSteps::new(&mut plant, tm.delay_s, tm.tc_s - tm.delay_s)?;
    let mut load = LoadCursor::new(&cfg.scenario);
    let mut watch = ProtectionWatch::new(&cfg.drive);
    let mut voltage_pu = 0.0;
    let start = Instant::now();
    let mut ticks_run = 0;
    // Current ticks until the next velocity tick (k % ratio == 0).
    let mut to_velocity_tick: u64 = 0;
    for k in 0..ticks {
        if backend.halted() {
            break;
        }
        ticks_run = k + 1;
        let t_s = k as f64 * tm.tc_s;
        let encoder_count = ((plant.encoder_count() as u64) & tm.mask) as u32;
        let current_pu = plant.current_sample();
        let velocity_tick = to_velocity_tick == 0;
        to_velocity_tick = to_velocity_tick.checked_sub(1).unwrap_or(tm.ratio - 1);
        if velocity_tick {
            let inputs = (t_s, encoder_count, voltage_pu);
            let row = velocity_step(backend, &plant, cfg, (&tm, &mut load), inputs);
            rows.push(row);
        }
        let out = backend.current_tick(CurrentInputs {
            encoder_count,
            current_pu: pu(current_pu),
        });
        watch.tick(k, t_s, f(pu(current_pu)), out.fault);
        record(&TickRecord {
            t_s,
            encoder_count: plant.encoder_count(),
            load_encoder_count: plant.load_encoder_count(),
            current_pu: f(pu(current_pu)),
            current_ref_pu: f(out.current_ref_pu),
            excitation_pu: backend.excitation_pu(),
        });
        let step = (t_s, voltage_pu, f(out.voltage_cmd_pu));
        voltage_pu = plant_step(&mut plant, &mut delay_line, (&tm, &steps, &mut load), step)?;
        if let Some(row) = rows.last_mut().filter(|_| velocity_tick) {
            // Torque reference and AFB term as the current tick of this instant formed
            // them (the velocity tick's output plus the AFB path at the current rate).
            row.torque_cmd_pu = f(out.current_ref_pu);
            row.accel_fb_pu = f(out.accel_fb_pu);
            // A fault latched in the velocity tick is reported by this one too.
            row.fault = f64::from(fault_code(out.fault));
        }
    }
    backend.finished();
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

#[cfg(test)]
mod delay_tests {
    use super::DelayLine;

    #[test]
    fn a_delay_shorter_than_a_tick_applies_this_ticks_command_after_the_remainder() {
        let mut d = DelayLine::new(180e-6, 250e-6);
        assert_eq!((d.whole_ticks(), d.remainder_s()), (0, 180e-6));
        assert_eq!(d.push(1.0, 0.0), 1.0);
        assert_eq!(d.push(2.0, 1.0), 2.0);
    }

    #[test]
    fn a_longer_delay_is_whole_ticks_plus_the_remainder() {
        // 5 ms at 4 kHz: 20 whole ticks, no remainder; 0.5 ms + 30 µs: 2 ticks + 30 µs.
        let d = DelayLine::new(5e-3, 250e-6);
        assert_eq!(d.whole_ticks(), 20);
        assert!(d.remainder_s().abs() < 1e-12);
        let mut d = DelayLine::new(530e-6, 250e-6);
        assert_eq!(d.whole_ticks(), 2);
        assert!((d.remainder_s() - 30e-6).abs() < 1e-12);
        // Commands 1, 2, 3, ... : tick k's command arrives in the interval of tick k + 2.
        let mut held = 0.0;
        let arrived: Vec<f64> = (1..=6)
            .map(|k| {
                held = d.push(f64::from(k), held);
                held
            })
            .collect();
        assert_eq!(arrived, vec![0.0, 0.0, 1.0, 2.0, 3.0, 4.0]);
    }

    #[test]
    fn a_delay_of_exactly_one_tick_holds_the_previous_command_for_the_whole_tick() {
        let mut d = DelayLine::new(250e-6, 250e-6);
        assert_eq!((d.whole_ticks(), d.remainder_s()), (1, 0.0));
        assert_eq!(d.push(1.0, 0.0), 0.0);
        assert_eq!(d.push(2.0, 0.0), 1.0);
    }
}
