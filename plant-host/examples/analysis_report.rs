//! Prints the plant's linear facts: each shipped machine's shaft constants, resonance and
//! anti-resonance, and Eq. 1's PI stiffness (Fig. 2):
//! `cargo run --release -p plant-host --example analysis_report`.
//! The closed loop's linear model (poles, margins, stability) is the harness's `linear`
//! command, the one model of the loop that `tune` designs on.
#![allow(missing_docs)]

use plant_host::PlantConfig;
use plant_host::analysis::{EngagedPlant, PiStiffness};
use std::f64::consts::PI;
use std::path::PathBuf;

fn config(name: &str) -> Result<PlantConfig, plant_host::PlantError> {
    PlantConfig::from_machine_file(
        &PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("../configs/machines")
            .join(name),
    )
}

/// The modes and constants of each shipped machine.
fn machines() -> Result<(), plant_host::PlantError> {
    for name in ["table1.toml", "printing-press.toml"] {
        let cfg = config(name)?;
        let d = cfg.mechanics.derived();
        let m = EngagedPlant::new(&cfg.mechanics).modes();
        println!("== {name}");
        println!(
            "  K = {:.2} pu/rad, D = {:.3} pu/pu, half gap g = {:.4e} rad ({:.2} counts)",
            d.stiffness_pu_per_rad,
            d.damping_pu,
            d.half_gap_rad,
            2.0 * d.half_gap_rad * f64::from(cfg.mechanics.encoder_cpr) / (2.0 * PI)
        );
        println!(
            "  resonance {:.2} Hz (damping {:.3}), anti-resonance {:.2} Hz (damping {:.3})",
            m.resonance_hz, m.resonance_damping, m.anti_resonance_hz, m.anti_resonance_damping
        );
    }
    Ok(())
}

/// Eq. 1 / Fig. 2.
fn eq1() {
    println!("== Eq. 1 / Fig. 2 (Jp = 1 s, zeros at 1 and 10 rad/s)");
    let st = PiStiffness::from_zeros(1.0, 1.0, 10.0);
    for p in st.curve(&[0.1, 1.0, 3.162, 10.0, 100.0]) {
        println!(
            "  {:7.3} rad/s: |τL/θ| = {:9.3} ({:6.1} dB), phase {:6.1} deg",
            p.omega_rad_s, p.magnitude, p.magnitude_db, p.phase_deg
        );
    }
}

fn main() -> Result<(), plant_host::PlantError> {
    machines()?;
    eq1();
    Ok(())
}
