//! `hil-harness stiffness --config FILE [--set …]`: the dynamic stiffness of the user's
//! machine, with its own plant and drive, with acceleration feedback on and off.
//!
//! The run is `configs/scenarios/stiffness.toml`'s sine load on FILE as the file describes
//! it (the scenario's `set` table, which turns the dyno into Fig. 2's rigid machine, is
//! not applied; `--set` is, after the file). "AFB on" is the file's drive; a file with
//! acceleration feedback off gets the drive's default design
//! (`controller_core::config::defaults::ACCEL_FEEDBACK`). "AFB off" is the same drive at
//! the AFB design's regulator gains ([`sim_engine::config::borrow_gains`]).

use super::{measure_on, StiffnessPoint, FREQS_RAD_S};
use controller_core::{AfbMode, Estimator};
use rayon::prelude::*;
use sim_engine::config::{resolve_on_machine, RunConfig};
use sim_engine::error::{HarnessError, Result};
use std::fmt::Write as _;
use std::path::Path;

/// The stiffness run on `config` with `sets`, AFB on, and its acceleration source.
pub fn machine_base(config: &str, sets: &[String]) -> Result<(RunConfig, Estimator)> {
    let mut cfg = resolve_on_machine("stiffness", config, sets)?;
    if cfg.drive.accel_feedback.mode == AfbMode::Off {
        cfg.drive.accel_feedback = controller_core::config::defaults::ACCEL_FEEDBACK;
    }
    let source = cfg.drive.accel_feedback.source;
    Ok((cfg, source))
}

/// Every frequency of [`FREQS_RAD_S`] with AFB off and on, on the machine.
pub fn measure_machine(config: &str, sets: &[String]) -> Result<Vec<StiffnessPoint>> {
    let (base, source) = machine_base(config, sets)?;
    let jobs: Vec<(Option<Estimator>, f64)> = [None, Some(source)]
        .iter()
        .flat_map(|a| FREQS_RAD_S.iter().map(move |w| (*a, *w)))
        .collect();
    jobs.par_iter()
        .map(|(a, w)| measure_on(&base, *a, *w))
        .collect()
}

/// Writes `stiffness.csv` for the machine into `dir`; returns the per-frequency summary.
pub fn machine_into(dir: &Path, config: &str, sets: &[String]) -> Result<String> {
    let points = measure_machine(config, sets)?;
    let path = dir.join("stiffness.csv");
    let io = |e: csv::Error| HarnessError::io(&path, e);
    let mut w = csv::Writer::from_path(&path).map_err(io)?;
    for p in &points {
        w.serialize(p).map_err(io)?;
    }
    w.flush().map_err(|e| HarnessError::io(&path, e))?;
    let mut text = format!("stiffness of {config}, AFB off and on (its own plant and drive)\n");
    for f in FREQS_RAD_S {
        let at = |afb: bool| points.iter().find(|p| p.afb == afb && p.freq_rad_s == f);
        if let (Some(off), Some(on)) = (at(false), at(true)) {
            let _ = writeln!(
                text,
                "{f:>7} rad/s: no AFB {:.4}, AFB {:.4} ({}); ratio {:.2}{}",
                off.measured,
                on.measured,
                on.source,
                on.measured / off.measured.max(1e-12),
                if on.stable && off.stable {
                    ""
                } else {
                    " (a run not stable)"
                }
            );
        }
    }
    Ok(text)
}

/// `hil-harness stiffness --config FILE`.
pub fn stiffness_machine(out: &Path, config: &str, sets: &[String]) -> Result<String> {
    sim_engine::output::staged(out, |dir| machine_into(dir, config, sets))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    /// A machine no shipped config describes: a soft coupling (12 Hz anti-resonance), a
    /// heavy motor (J_M = J_L) and a 65 536-count encoder, velocity loop at 40 rad/s.
    const MACHINE: &str = r#"
[plant]
base_speed_rpm = 1500.0
motor_inertia_s = 0.6
load_inertia_s = 0.6
anti_resonance_hz = 12.0
shaft_damping_ratio = 0.04
backlash_deg = 0.0
motor_viscous_pu = 0.0
load_viscous_pu = 0.0
encoder_cpr = 65536

[electrics]
computational_delay_s = 100e-6

[sensors]
load_encoder_cpr = 0
gear_ratio = 1.0
encoder_noise_counts = 0.0
current_noise_pu = 0.0
noise_seed = 1

[lost_motion]
model = "dead_zone"

[drive]
current_rate_hz = 4000
velocity_rate_hz = 2000
position_bandwidth_rad_s = 0.0
velocity_bandwidth_rad_s = 40.0
current_bandwidth_rad_s = 2000.0
"#;

    #[test]
    fn stiffness_runs_on_a_machine_file_with_its_own_plant_and_drive() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("soft.toml");
        std::fs::write(&file, MACHINE).unwrap();
        let file = file.to_str().unwrap();
        let (cfg, _) = machine_base(file, &[]).unwrap();
        assert_eq!(cfg.plant.mechanics.anti_resonance_hz, 12.0);
        assert_eq!(cfg.plant.mechanics.encoder_cpr, 65536);
        assert_eq!(cfg.drive.velocity_bandwidth_rad_s, 40.0);
        assert_ne!(cfg.drive.accel_feedback.mode, AfbMode::Off);
        let out = dir.path().join("out");
        let text = stiffness_machine(&out, file, &[]).unwrap();
        let csv = std::fs::read_to_string(out.join("stiffness.csv")).unwrap();
        // A header and one row per frequency, AFB off and on.
        assert_eq!(csv.lines().count(), 1 + 2 * FREQS_RAD_S.len(), "{csv}");
        assert!(text.contains("100 rad/s"), "{text}");
        assert!(csv.lines().skip(1).all(|l| !l.contains("NaN")), "{csv}");
    }

    /// The forced response to the sine is not an oscillation (the `oscillation` rule leaves
    /// the injected frequency out): at 40 rad/s, which table1's loop follows just above the
    /// verdict's 5 Hz floor, and at 100 rad/s, the runs with AFB from the observer and
    /// without are stable on table1 and on the dyno, where nothing else oscillates.
    #[test]
    fn a_forced_sine_alone_is_stable_on_table1_and_the_dyno() {
        for config in ["table1", "dyno"] {
            let (base, source) = machine_base(config, &[]).unwrap();
            for w in [40.0, 100.0] {
                for afb in [None, Some(source)] {
                    let p = measure_on(&base, afb, w).unwrap();
                    assert!(p.stable, "{config} {w} rad/s {afb:?}: {p:?}");
                }
            }
        }
    }
}
