//! The PMSM drive in the closed loop (`configs/machines/table1-pmsm.toml`: Table 1's
//! mechanics on a field-oriented PMSM), through the same runner, trace and metrics as the
//! DC drive. The criteria were fixed before the runs:
//! - `fig6` is stable by the DC `fig6`'s metric (`metrics.stable`), without a fault;
//! - a drive whose encoder offset is 40°, 90° or 180° electrical off the plant's truth, or
//!   whose pole-pair count is one too few or one too many, latches a named fault within
//!   0.5 s of the motion starting, and the motor speed never passes `faults.overspeed_pu`:
//!   `commutation` (or `overcurrent` / `overspeed`, whichever comes first) wherever the
//!   motor turns; at 90° off the motor makes no torque and stays at rest, where no
//!   back-EMF shows the angle (a wrong angle at rest looks like a locked rotor), and the
//!   position loop's `following_error` latches;
//!
//! - an encoder counting against the electrical angle runs fig6 once the drive knows it,
//!   with the shaft ripple within 15 % of the forward machine's, and latches a fault when
//!   the drive does not;
//!
//! The fig6 pair's AFB / no-AFB shaft-ripple ratio against the DC model's (within 15 %)
//! is judged in REPORT.md's "The paper on a PMSM" (paper-repro `report::pmsm`).
//! - a backend that drives DC only refuses a PMSM run with an error, never a panic.
//!
//! `-- --nocapture` prints the measured figures.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use controller_core::{Controller, CurrentInputs, CurrentOutputs, VelocityInputs, VelocityOutputs};
use sim_engine::{
    resolve, run_scenario, run_with_backend, ControlBackend, HarnessError, RunOutput,
};

/// The machine file.
const PMSM: &str = "table1-pmsm";
/// The plant's true encoder offset in `table1-pmsm.toml` \[deg electrical\].
const TRUE_OFFSET_DEG: f64 = 23.0;
/// Its pole pairs.
const POLE_PAIRS: u32 = 4;

fn run(scenario: &str, config: Option<&str>, sets: &[String]) -> RunOutput {
    let cfg = resolve(scenario, config, sets).expect("scenario resolves");
    run_scenario(&cfg).expect("scenario runs")
}

#[test]
fn fig6_on_the_pmsm_is_stable_without_a_fault() {
    let out = run("fig6", Some(PMSM), &[]);
    eprintln!("fig6 on {PMSM}: {:?}", out.metrics.oscillation);
    assert_eq!(out.fault, None, "{:?}", out.fault);
    assert!(out.metrics.stable, "{:?}", out.metrics);
    // The trace is the DC run's shape: one row per velocity tick over 2.5 s.
    assert_eq!(out.trace.rows.len(), 5000);
    // At 1 pu after the ramp the motor follows (the speed loop closes through the FOC).
    let last = out.trace.rows.last().unwrap();
    assert!((last.motor_vel_pu - 1.0).abs() < 0.05, "{last:?}");
}

/// fig6 on table1-pmsm with `set`: the fault it latches (name, time after the motion
/// starts) and the largest motor speed.
fn wrong(set: String) -> (Option<&'static str>, f64, f64, f64) {
    let cfg = resolve("fig6", Some(PMSM), std::slice::from_ref(&set)).unwrap();
    let overspeed = f64::from(cfg.drive.faults.overspeed_pu);
    let out = run_scenario(&cfg).unwrap_or_else(|e| panic!("{set}: {e}"));
    let start = out
        .trace
        .rows
        .iter()
        .find(|r| r.vel_cmd_pu != 0.0)
        .map_or(0.0, |r| r.t_s);
    let fastest = out
        .trace
        .rows
        .iter()
        .map(|r| r.motor_vel_pu.abs())
        .fold(0.0, f64::max);
    let kind = out.fault.as_ref().map(|f| f.kind);
    let after = out.fault.as_ref().map_or(f64::INFINITY, |f| f.t_s - start);
    eprintln!("{set}: {kind:?} {after:.4} s after the motion starts; fastest {fastest:.3} pu");
    (kind, after, fastest, overspeed)
}

fn assert_caught(set: String) {
    let (kind, after, fastest, overspeed) = wrong(set.clone());
    assert!(
        matches!(kind, Some("commutation" | "overcurrent" | "overspeed")),
        "{set}: latched {kind:?}"
    );
    assert!(after <= 0.5, "{set}: {after} s");
    assert!(fastest <= overspeed, "{set}: {fastest} pu");
}

/// An encoder that counts against the electrical angle (the plant's
/// `electrics.encoder_reversed`: two motor leads swapped), measured as such
/// (`drive.pmsm.encoder_reversed`), runs fig6 as the forward machine does: stable, no
/// fault, the motor at 1 pu after the ramp, the shaft ripple within 15 % of the forward
/// run's. The same machine with a drive that takes the encoder as forward latches a named
/// fault within 0.5 s, the speed below the overspeed limit.
#[test]
fn a_reversed_encoder_runs_fig6_once_measured_and_trips_when_not() {
    let sets = [
        "electrics.encoder_reversed=true".to_string(),
        "drive.pmsm.encoder_reversed=true".to_string(),
    ];
    let out = run("fig6", Some(PMSM), &sets);
    let forward = run("fig6", Some(PMSM), &[]);
    let (r, f) = (
        out.metrics.shaft_torque_ripple_rms_pu,
        forward.metrics.shaft_torque_ripple_rms_pu,
    );
    eprintln!("reversed: ripple {r} pu, forward {f} pu");
    assert_eq!(out.fault, None, "{:?}", out.fault);
    assert!(out.metrics.stable, "{:?}", out.metrics);
    let last = out.trace.rows.last().unwrap();
    assert!((last.motor_vel_pu - 1.0).abs() < 0.05, "{last:?}");
    assert!((r / f - 1.0).abs() < 0.15, "ripple {r} against {f}");
    assert_caught("electrics.encoder_reversed=true".to_string());
}

fn offset(delta_deg: f64) -> String {
    format!(
        "drive.pmsm.encoder_offset_elec_deg={}",
        TRUE_OFFSET_DEG + delta_deg
    )
}

#[test]
fn an_offset_40_degrees_off_latches_commutation() {
    assert_caught(offset(40.0));
    assert_caught(offset(-40.0));
}

/// At 90° off the drive's q axis is the magnet's: the motor makes no torque and stays at
/// rest, so the commutation check (which judges the back-EMF, above
/// `pmsm.commutation_min_speed_pu`) has nothing to see, and the following-error limit
/// latches. Until then the motor stays below 0.01 pu; after it, with the inverter off, only
/// the load step (0.5 pu at 1.5 s) turns the machine, below the overspeed limit.
#[test]
fn an_offset_90_degrees_off_latches_following_error_at_rest() {
    for delta in [90.0, -90.0] {
        let set = offset(delta);
        let (kind, after, fastest, overspeed) = wrong(set.clone());
        assert_eq!(kind, Some("following_error"), "{set}");
        assert!(after <= 0.5, "{set}: {after} s");
        assert!(fastest <= overspeed, "{set}: {fastest} pu");
        let cfg = resolve("fig6", Some(PMSM), std::slice::from_ref(&set)).unwrap();
        let out = run_scenario(&cfg).unwrap();
        let tripped_at = out.fault.as_ref().map_or(f64::INFINITY, |f| f.t_s);
        let before = out
            .trace
            .rows
            .iter()
            .filter(|r| r.t_s < tripped_at)
            .map(|r| r.motor_vel_pu.abs())
            .fold(0.0, f64::max);
        assert!(before < 0.01, "{set}: {before} pu before the fault");
    }
}

#[test]
fn an_offset_180_degrees_off_latches_commutation() {
    assert_caught(offset(180.0));
}

#[test]
fn one_pole_pair_too_few_or_too_many_latches_commutation() {
    assert_caught(format!("drive.pmsm.pole_pairs={}", POLE_PAIRS - 1));
    assert_caught(format!("drive.pmsm.pole_pairs={}", POLE_PAIRS + 1));
}

/// A backend with only the DC ticks (as the PIL link is).
struct DcOnly(Controller);

impl ControlBackend for DcOnly {
    fn current_tick(&mut self, inputs: CurrentInputs) -> CurrentOutputs {
        self.0.current_tick(inputs)
    }
    fn velocity_tick(&mut self, inputs: VelocityInputs) -> VelocityOutputs {
        self.0.velocity_tick(inputs)
    }
}

#[test]
fn a_backend_that_drives_dc_only_refuses_a_pmsm_run_with_an_error() {
    let cfg = resolve("fig6", Some(PMSM), &[]).unwrap();
    let mut backend = DcOnly(sim_engine::engine::runner::controller(&cfg).unwrap());
    match run_with_backend(&cfg, &mut backend) {
        Err(HarnessError::Backend(m)) => assert!(m.contains("DC motor only"), "{m}"),
        other => panic!("{:?}", other.map(|o| o.fault)),
    }
}
