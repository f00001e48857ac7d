//! The closed loop with the real timing.
//!
//! Every current tick (Ts_c = 1/current_rate_hz, 250 µs for Table 1) the encoder and the
//! current are sampled at the tick instant; on every `current_rate/velocity_rate`-th tick
//! (500 µs) the velocity tick runs first, on the same samples, then the current tick. The
//! new voltage reaches the winding after the computational delay (`electrics.
//! computational_delay_s`, 180 µs) and is held until the next one arrives (zero-order
//! hold). A delay longer than a tick delays by whole ticks plus the remainder
//! ([`DelayLine`]). The plant is integrated exactly between those events: [t, t+r) with
//! the voltage applied before, [t+r, t+Ts_c) with the one that arrives at t+r. The load
//! torque is evaluated at the middle of each segment. Nothing depends on wall-clock time
//! or threads, so a run is bit-for-bit repeatable. The loop itself is `super::frame`'s,
//! one for both motors: the DC winding (`super::dc`) and the PMSM (`super::pmsm`).

use crate::config::RunConfig;
use crate::engine::frame;
use crate::engine::metrics::oscillation::CONFIRM_INTERPOLATION;
use crate::engine::metrics::{compute, Metrics, OscillationKind};
use crate::engine::protection::{FaultRecord, ProtectionSummary};
use crate::engine::trace::Trace;
use crate::error::{HarnessError, Result};
use controller_core::{
    Controller, CurrentInputs, CurrentOutputs, Gains, PmsmInputs, PmsmOutputs, VelocityInputs,
    VelocityOutputs,
};

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
    /// Measured current (= torque) sample \[pu\] (ADC, noise); for a PMSM the torque of
    /// the measured currents in the drive's motor model, `λ·i_q + k·i_d·i_q`
    /// (`Controller::pmsm_measured_torque`), in the counts' direction.
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

pub use super::delay::DelayLine;

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
    record: impl FnMut(&TickRecord),
) -> Result<TickRun> {
    if super::pmsm::is_pmsm(cfg)? {
        let motor = super::pmsm::PmsmMotor::new(cfg)?;
        frame::run(cfg, backend, motor, record)
    } else {
        frame::run(cfg, backend, super::dc::DcMotor::new(cfg)?, record)
    }
}
