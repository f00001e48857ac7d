//! `hil-harness identify --config CFG --out DIR`: measure the machine in the closed loop
//! and fit its model, reading only the signals a drive records.
//!
//! 0. On a PMSM machine (`electrics.motor = "pmsm"`), first the motor calibration
//!    ([`motor`]): phase resistance, d and q inductances, pole pairs, encoder direction and
//!    offset, each with its standard error; the steps below then run with the drive using
//!    them (so a `[drive.pmsm]` without `encoder_offset_elec_deg` is identified too). A DC
//!    machine has no step 0;
//! 1. The frequency response θm/Tm from a PRBS on the torque reference, H1 with Welch
//!    averaging and the excitation as the instrument, with its coherence
//!    ([`measure`]);
//! 2. the two-inertia fit: Jm, Jl, anti-resonance (and the resonance it implies), shaft
//!    damping, viscous friction (Bm + Bl), each with its standard error;
//! 3. the lost motion from the reversal test, fitted by simulating the test on the
//!    identified model ([`lost_motion`]);
//! 4. the same measurement and fits on a simulated twin with the identified mechanics, whose
//!    bias is taken out of the estimates and whose spread enters their standard errors
//!    ([`twin`]);
//! 5. `DIR/plant.toml` (the `[plant]` table), `DIR/identify.json`, `DIR/identify.md` with
//!    the measured and fitted Bode plot (`DIR/bode.png|svg`), all staged: on an error
//!    nothing is written ([`mod@write`]).
//!
//! The machine file is read as `run` reads it (one value tree, `--set` applied to it, one
//! typed deserialization each for the plant and the drive), and its optional
//! `[identify]` table holds the measurement settings ([`spec::IdentifySpec`]). During the
//! measurement the drive runs in speed mode at zero speed with acceleration feedback off
//! and a soft velocity loop (`identify.velocity_bandwidth_rad_s`); its other settings
//! (rates, current loop, observer, limits) are the file's.
//!
//! `identify --board --qemu | --port PATH` ([`board`]) takes the two records from the
//! board instead: the board runs each measurement in its own loops (the console's
//! `Identify`, `pil_link::board::identify`) with controller-core's PRBS, the one
//! [`measure`] adds on the host, and streams every current tick; [`identify_records`] then
//! does steps 1 to 5 on them, as on the simulated records. With `--qemu` the board is the
//! `board` image built with the machine file, whose virtual machine is the file's `[plant]`
//! (two inertias, shaft, dead-zone lost motion, viscous friction; `firmware/build.rs`).
//! The twin of step 4 is still simulated on the host. On a PMSM machine the board runs step
//! 0 too ([`crate::calibrate::board`]: the sequence in its current loop, the estimate
//! here), and the calibration is set and saved on the board before the two measurements.

pub mod board;
pub mod lost_motion;
pub mod measure;
pub mod motor;
pub mod spec;
pub mod twin;
pub mod write;

use controller_core::AfbMode;
use lost_motion::{fit_lost_motion, LostMotionFit};
use plant_host::analysis::{closed_loop_response, fit_two_inertia, FitResult, MeasuredResponse};
use sim_engine::config::{config_path, machine, overrides, read_table, RunConfig};
use sim_engine::error::{HarnessError, Result};
use sim_engine::output::Staging;
use spec::IdentifySpec;
use std::path::Path;

/// Everything `identify` measured and fitted.
#[derive(Clone, Debug)]
pub struct Identification {
    /// The measured θm/Tm \[rad per pu torque\] and its coherence.
    pub response: MeasuredResponse,
    /// The two-inertia fit, the twin's bias taken out ([`twin::corrected`]).
    pub fit: FitResult,
    /// The lost motion, the twin's bias taken out.
    pub lost_motion: LostMotionFit,
    /// The fit and the lost motion as measured, before the twin's correction.
    pub raw: (FitResult, LostMotionFit),
    /// What the twin showed (`None` when no twin run gave a fit: the estimates are then the
    /// raw ones).
    pub twin: Option<twin::Twin>,
    /// Length of the frequency-response record used \[s\].
    pub record_s: f64,
    /// Where the two records were taken (the simulated machine, or the board).
    pub measured_on: String,
    /// A PMSM's motor calibration ([`motor`]), which the drive ran the measurement with;
    /// `None` for a DC machine.
    pub motor: Option<crate::calibrate::MotorEstimates>,
}

/// The machine of `config` (a path or a name under `configs/`) with `sets` applied, as
/// a run on the test rig, and the `[identify]` settings.
pub fn load(config: &str, sets: &[String]) -> Result<(RunConfig, IdentifySpec)> {
    let path = config_path(config)?;
    let mut doc = read_table(&path)?;
    overrides::apply_all(&mut doc, sets)?;
    let spec = IdentifySpec::take(&mut doc)?;
    let (plant, mut drive) = machine(doc)?;
    // The measurement's loop: speed mode, AFB off, the soft velocity loop.
    drive.position_bandwidth_rad_s = 0.0;
    drive.accel_feedback.mode = AfbMode::Off;
    drive.velocity_bandwidth_rad_s = spec.velocity_bandwidth_rad_s as f32;
    drive.validate().map_err(|e| {
        HarnessError::config(
            "identify.velocity_bandwidth_rad_s",
            format!("drive.{}: {e}", e.param()),
        )
    })?;
    let base = RunConfig {
        name: "identify".into(),
        scenario: measure::rig_run_spec(&path),
        plant,
        drive,
        config_path: path,
        gains_of: None,
    };
    Ok((base, spec))
}

/// What [`identify_machine`] names its source.
pub const SIMULATED: &str = "the simulated machine (sim-engine's closed loop)";

/// Measures and fits (module docs): a PMSM's motor calibration first, then the mechanics
/// with the drive [`motor::calibrated`] by it.
pub fn identify_machine(base: &RunConfig, spec: &IdentifySpec) -> Result<Identification> {
    let motor = motor::calibrate(base)?;
    let base = &motor::with_calibration(base, motor.as_ref())?;
    let rec = measure::frequency_response_run(base, spec)?;
    let reversal = measure::reversal_run(base, spec)?;
    let ident = identify_records(base, spec, &rec, &reversal, SIMULATED)?;
    Ok(Identification { motor, ..ident })
}

/// The estimation from the two records, whichever backend recorded them: `rec` the
/// frequency-response record after its settling (as [`measure::frequency_response_run`]
/// returns it), `reversal` the whole lost-motion test ([`measure::reversal_run`]);
/// `measured_on` says where they were taken.
pub fn identify_records(
    base: &RunConfig,
    spec: &IdentifySpec,
    rec: &measure::Record,
    reversal: &measure::Record,
    measured_on: &str,
) -> Result<Identification> {
    let rate = f64::from(base.drive.current_rate_hz);
    let (response, fit) = fit_response(base, spec, rec)?;
    let lost_motion = fit_lost_motion(base, spec, &fit.fit, reversal)?;
    let twin = twin::check(base, spec, &fit.fit, &lost_motion);
    let (corrected, corrected_lm) = match &twin {
        Some(t) => twin::corrected(&fit, &lost_motion, t, base.drive.encoder_cpr),
        None => (fit, lost_motion),
    };
    Ok(Identification {
        response,
        fit: corrected,
        lost_motion: corrected_lm,
        raw: (fit, lost_motion),
        twin,
        record_s: rec.counts.len() as f64 / rate,
        measured_on: measured_on.to_string(),
        motor: None,
    })
}

/// The frequency response of a frequency-response record (after its settling, as
/// [`measure::frequency_response_run`] returns it) and the two-inertia fit to it, whichever
/// backend recorded it.
pub fn fit_response(
    base: &RunConfig,
    spec: &IdentifySpec,
    rec: &measure::Record,
) -> Result<(MeasuredResponse, FitResult)> {
    let rate = f64::from(base.drive.current_rate_hz);
    let counts_per_rad = f64::from(base.drive.encoder_cpr) / std::f64::consts::TAU;
    let position: Vec<f64> = rec.counts.iter().map(|c| c / counts_per_rad).collect();
    let response = closed_loop_response(
        &rec.excitation,
        &rec.current,
        &position,
        rate,
        spec.segment_len,
    )
    .map_err(|e| HarnessError::config("identify.segment_len", e.to_string()))?;
    let wb = f64::from(base.drive.base_speed_rpm) * std::f64::consts::TAU / 60.0;
    let fit = fit_two_inertia(&response, wb, spec.min_coherence, spec.max_freq_hz)
        .map_err(|e| HarnessError::Backend(format!("identify: {e}")))?;
    Ok((response, fit))
}

/// `hil-harness identify`.
pub fn identify(config: &str, sets: &[String], out: &Path) -> Result<String> {
    let (base, spec) = load(config, sets)?;
    // The output directory is checked before the measurement.
    let staging = Staging::new(out)?;
    let ident = identify_machine(&base, &spec)?;
    write::write_all(staging.dir(), &base, &spec, &ident)?;
    staging.commit()?;
    Ok(summary(&base, &ident, out))
}

/// The line `identify` prints.
fn summary(base: &RunConfig, ident: &Identification, out: &Path) -> String {
    let f = &ident.fit.fit;
    let motor = ident
        .motor
        .as_ref()
        .map_or_else(String::new, |m| format!("{}, ", m.describe()));
    format!(
        "identify {}: {motor}Jm = {:.4} s, Jl = {:.4} s, anti-resonance {:.2} Hz, resonance {:.2} Hz, \
         damping {:.3}, viscous {:.4} pu, lost motion {:.4} deg (measured on {}){} -> {}",
        base.config_path.display(),
        f.motor_inertia_s,
        f.load_inertia_s,
        f.anti_resonance_hz,
        f.resonance_hz(),
        f.shaft_damping_ratio,
        f.viscous_pu,
        ident.lost_motion.backlash_deg,
        ident.measured_on,
        if ident.twin.is_some() {
            ""
        } else {
            "; the simulated twin gave no fit, so these are the raw fit's, the method's own \
             bias not taken out and not in the standard errors (identify.md)"
        },
        out.display()
    )
}
