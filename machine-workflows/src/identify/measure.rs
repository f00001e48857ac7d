//! The two runs of the measurement against the plant in the closed loop, and what the
//! estimators take from them:
//!
//! - **Frequency response.** The drive as configured holds zero speed against the rig's
//!   preload torque (gears in contact) while a PRBS from controller-core's excitation
//!   generator is added to its torque reference
//!   ([`controller_core::Controller::with_excitation`]). Recorded every current tick: the
//!   excitation r, the motor torque u as the drive measures it (a DC winding's current,
//!   k_t = 1; a PMSM's `λ·i_q + k·i_d·i_q` of its measured currents, not i_q alone) and the
//!   encoder count y. The response θm/Tm is H1(r → y)/H1(r → u) with Welch averaging
//!   (`plant_host::analysis::closed_loop_response`), and the two-inertia model is fitted to
//!   it (`plant_host::analysis::fit_two_inertia`).
//! - **Lost-motion test.** The drive holds zero speed while the rig reverses its load
//!   torque, ±`reversal_torque_pu`, every `reversal_hold_s`: at each reversal the gears
//!   part, the load crosses the lost motion and strikes the other flank, and the drive's
//!   torque reference shows the flight and the impact ([`super::lost_motion`]).

use super::spec::IdentifySpec;
use controller_core::excitation::{ExcitationConfig, ExcitationParams, Injection, Waveform};
use sim_engine::config::scenario::{LoadStep, MetricSpec, ProfileSpec, ScenarioSpec};
use sim_engine::config::RunConfig;
use sim_engine::engine::runner::{controller, run_ticks, ControlBackend, TickRecord};
use sim_engine::error::{HarnessError, Result};
use std::collections::BTreeMap;

/// The paths an excitation error names.
const NAMES: ExcitationParams = ExcitationParams {
    amplitude_pu: "identify.amplitude_pu",
    start_or_bits: "identify.prbs_bits",
    end_or_hold: "identify.prbs_hold_ticks",
    duration_or_periods: "identify.prbs_periods",
};

/// The signals recorded every current tick.
#[derive(Clone, Debug, Default)]
pub struct Record {
    /// Excitation \[pu\].
    pub excitation: Vec<f64>,
    /// Measured motor torque \[pu\] (the DC current; a PMSM's torque of its measured currents).
    pub current: Vec<f64>,
    /// Torque reference \[pu\].
    pub torque_ref: Vec<f64>,
    /// Motor encoder \[counts\].
    pub counts: Vec<f64>,
}

impl Record {
    fn push(&mut self, t: &TickRecord) {
        self.excitation.push(t.excitation_pu);
        self.current.push(t.current_pu);
        self.torque_ref.push(t.current_ref_pu);
        self.counts.push(t.encoder_count as f64);
    }

    /// The record from sample `from` on.
    pub fn tail(&self, from: usize) -> Self {
        let cut = |v: &Vec<f64>| v.get(from..).unwrap_or(&[]).to_vec();
        Self {
            excitation: cut(&self.excitation),
            current: cut(&self.current),
            torque_ref: cut(&self.torque_ref),
            counts: cut(&self.counts),
        }
    }
}

/// The rig's scenario for the machine file `config`: the drive holds zero speed, no
/// load (a run sets its length and load torque, [`rig_run`]).
pub fn rig_run_spec(config: &std::path::Path) -> ScenarioSpec {
    ScenarioSpec {
        description: "identify: the drive holds zero speed on the test rig".into(),
        paper: String::new(),
        config: config.display().to_string(),
        duration_s: 1.0,
        profile: ProfileSpec {
            speed_pu: 0.0,
            accel_s: 0.0,
            start_s: 0.0,
            hold_s: None,
            decel_s: None,
        },
        load: Vec::new(),
        sine_load: None,
        load_locked: false,
        metrics: MetricSpec::default(),
        comparison: None,
        set: BTreeMap::new(),
    }
}

/// A run of `base`'s machine holding zero speed for `duration_s` under the rig's load
/// torque `load` (steps in time order).
pub fn rig_run(base: &RunConfig, duration_s: f64, load: Vec<LoadStep>) -> RunConfig {
    let mut cfg = base.clone();
    cfg.scenario.duration_s = duration_s;
    cfg.scenario.load = load;
    cfg
}

/// Runs `cfg` with `backend`, recording every current tick; a fault of the drive is an
/// error (the measurement would not be of the machine in the loop).
pub fn record<B: ControlBackend>(cfg: &RunConfig, backend: &mut B, what: &str) -> Result<Record> {
    let n = (cfg.scenario.duration_s * f64::from(cfg.drive.current_rate_hz)) as usize;
    let mut rec = Record {
        excitation: Vec::with_capacity(n),
        current: Vec::with_capacity(n),
        torque_ref: Vec::with_capacity(n),
        counts: Vec::with_capacity(n),
    };
    let run = run_ticks(cfg, backend, |t| rec.push(t))?;
    if run.trace.faulted() {
        return Err(HarnessError::Backend(format!(
            "identify: the drive faulted during the {what}; lower identify.amplitude_pu or \
             identify.reversal_torque_pu"
        )));
    }
    Ok(rec)
}

/// The frequency-response run: the PRBS on the torque reference under the preload. Returns
/// the record after `settle_s`.
pub fn frequency_response_run(base: &RunConfig, spec: &IdentifySpec) -> Result<Record> {
    let (cfg, excitation) = frequency_response_setup(base, spec)?;
    let mut ctl = excited_controller(&cfg, &excitation)?;
    let rec = record(&cfg, &mut ctl, FREQUENCY_RESPONSE)?;
    Ok(frequency_response_tail(&cfg, spec, &rec))
}

/// The host controller of `cfg` with `excitation` added; its errors name the
/// `identify.*` keys.
pub fn excited_controller(
    cfg: &RunConfig,
    excitation: &ExcitationConfig,
) -> Result<controller_core::Controller> {
    controller(cfg)?
        .with_excitation(excitation, NAMES)
        .map_err(|e| HarnessError::config(e.param(), e.to_string()))
}

/// What [`record`] calls the frequency-response run in its errors.
pub const FREQUENCY_RESPONSE: &str = "frequency-response measurement";

/// The frequency-response run's configuration (the rig holding zero speed under the preload
/// for the PRBS's length) and its excitation: what [`frequency_response_run`] records with
/// the host controller, and what a run through the firmware sends it
/// (`pil_host::with_firmware`).
pub fn frequency_response_setup(
    base: &RunConfig,
    spec: &IdentifySpec,
) -> Result<(RunConfig, ExcitationConfig)> {
    let rate = f64::from(base.drive.current_rate_hz);
    let duration_s = spec.prbs_ticks() as f64 / rate;
    if duration_s <= spec.settle_s + 2.0 * spec.segment_len as f64 / rate {
        return Err(HarnessError::config(
            "identify.prbs_periods",
            format!(
                "the PRBS lasts {duration_s:.3} s: it must cover identify.settle_s and two \
                 Welch segments (identify.segment_len)"
            ),
        ));
    }
    let cfg = rig_run(
        base,
        duration_s,
        vec![LoadStep {
            t_s: 0.0,
            torque_pu: spec.preload_pu,
        }],
    );
    let excitation = ExcitationConfig {
        waveform: Waveform::Prbs {
            bits: spec.prbs_bits,
            hold_ticks: spec.prbs_hold_ticks,
            periods: spec.prbs_periods,
        },
        amplitude_pu: spec.amplitude_pu as f32,
        injection: Injection::TorqueReference,
    };
    Ok((cfg, excitation))
}

/// The frequency-response record after `settle_s` (what the estimators take).
pub fn frequency_response_tail(cfg: &RunConfig, spec: &IdentifySpec, rec: &Record) -> Record {
    let rate = f64::from(cfg.drive.current_rate_hz);
    rec.tail((spec.settle_s * rate) as usize)
}

/// The lost-motion test's rig load: +T from the start, then reversed every `hold` seconds,
/// twice (one crossing each way). Returns the steps and the run length.
pub fn reversal_load(spec: &IdentifySpec) -> (Vec<LoadStep>, f64) {
    let (t, hold) = (spec.reversal_torque_pu, spec.reversal_hold_s);
    let steps = [t, -t, t]
        .iter()
        .enumerate()
        .map(|(i, &torque_pu)| LoadStep {
            t_s: i as f64 * hold,
            torque_pu,
        })
        .collect();
    (steps, 3.0 * hold)
}

/// The lost-motion test on `cfg`'s plant with the drive's own controller.
pub fn reversal_run(base: &RunConfig, spec: &IdentifySpec) -> Result<Record> {
    let (load, duration_s) = reversal_load(spec);
    let cfg = rig_run(base, duration_s, load);
    let mut ctl = controller(&cfg)?;
    record(&cfg, &mut ctl, "lost-motion test")
}
