//! Prints the linear-analysis figures quoted in docs/design.md:
//! `cargo run --release -p plant-host --example analysis_report`.
//! Acceleration here comes from differencing the encoder (no observer): the figures bound
//! what the differentiation path allows; the controller's observer is analysed elsewhere.
#![allow(missing_docs)]

use plant_host::analysis::{log_space, EngagedPlant, PiStiffness, VelocityLoop};
use plant_host::PlantConfig;
use std::f64::consts::PI;
use std::path::PathBuf;

fn config(name: &str) -> Result<PlantConfig, plant_host::PlantError> {
    PlantConfig::from_machine_file(
        &PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("../configs")
            .join(name),
    )
}

/// Kp = ω_bw·J_total, Ki = Kp·ω_bw/4 (ζ = 1), current loop 318 Hz, the config's delay.
fn design(
    cfg: &PlantConfig,
    bw: f64,
    ka_frac: f64,
    fc_hz: f64,
    periods_s: (f64, f64),
) -> VelocityLoop {
    let (period_s, accel_period_s) = periods_s;
    let j = cfg.mechanics.motor_inertia_s + cfg.mechanics.load_inertia_s;
    VelocityLoop {
        plant: EngagedPlant::new(&cfg.mechanics),
        kp: bw * j,
        ki: bw * j * bw / 4.0,
        ka: ka_frac * j,
        accel_filter_hz: fc_hz,
        velocity_period_s: period_s,
        accel_period_s,
        delay_s: cfg.electrics.computational_delay_s,
        current_bandwidth_hz: Some(318.0),
    }
}

/// Largest bandwidth on a log grid below which every grid point is stable.
fn max_stable_bw(cfg: &PlantConfig, ka_frac: f64, fc_hz: f64, periods_s: (f64, f64)) -> f64 {
    let mut last = 0.0;
    for bw in log_space(1.0, 3000.0, 400) {
        if !design(cfg, bw, ka_frac, fc_hz, periods_s).is_stable() {
            break;
        }
        last = bw;
    }
    last
}

/// The modes and constants of each shipped machine, and the stable bandwidths.
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
        let (slow, fast, mixed) = ((500e-6, 500e-6), (250e-6, 250e-6), (500e-6, 250e-6));
        for (label, ka, fc, t) in [
            ("no AFB, 2 kHz", 0.0, 100.0, slow),
            ("no AFB, 4 kHz", 0.0, 100.0, fast),
            (
                "AFB Ka=0.5 J, 100 Hz filter, all at 2 kHz",
                0.5,
                100.0,
                slow,
            ),
            (
                "AFB Ka=0.5 J, 100 Hz filter, PI 2 kHz + AFB 4 kHz",
                0.5,
                100.0,
                mixed,
            ),
            (
                "AFB Ka=0.5 J, 100 Hz filter, all at 4 kHz",
                0.5,
                100.0,
                fast,
            ),
            (
                "AFB Ka=1.0 J, 100 Hz filter, all at 2 kHz",
                1.0,
                100.0,
                slow,
            ),
            ("AFB Ka=1.0 J, 20 Hz filter, all at 2 kHz", 1.0, 20.0, slow),
            (
                "AFB Ka=1.0 J, 20 Hz filter, PI 2 kHz + AFB 4 kHz",
                1.0,
                20.0,
                mixed,
            ),
            ("AFB Ka=1.0 J, 20 Hz filter, all at 4 kHz", 1.0, 20.0, fast),
        ] {
            println!(
                "  largest linearly stable velocity bandwidth, {label}: {:.0} rad/s",
                max_stable_bw(&cfg, ka, fc, t)
            );
        }
    }

    Ok(())
}

/// Table 1 at the paper's velocity bandwidth, with and without AFB.
fn table1_loops(cfg: &PlantConfig) {
    println!(
        "== Table 1, velocity bandwidth 15 Hz (94.2 rad/s), 2 kHz, {:.2} ms delay, 318 Hz current loop",
        cfg.electrics.computational_delay_s * 1e3
    );
    for (label, ka, fc) in [
        ("no AFB", 0.0, 100.0),
        ("Ka=0.5 J, 100 Hz", 0.5, 100.0),
        ("Ka=1.0 J, 20 Hz", 1.0, 20.0),
    ] {
        let lp = design(cfg, 2.0 * PI * 15.0, ka, fc, (500e-6, 500e-6));
        let mg = lp.margins();
        let am = lp.accel_margins();
        println!(
            "  {label}: PM {:.1} deg at {:.1} rad/s, GM {:.1} dB at {:.0} rad/s, spectral radius {:.5}; accel loop alone GM {:.1} dB",
            mg.phase_margin_deg,
            mg.gain_crossover_rad_s,
            mg.gain_margin_db,
            mg.phase_crossover_rad_s,
            lp.sampled_spectral_radius(),
            am.gain_margin_db
        );
        for w in [1.0, 10.0, 100.0, 409.0] {
            if let Some(p) = lp.point(w) {
                println!(
                    "    {w:6.0} rad/s: |load stiffness| {:.3e}, |motor stiffness| {:.3e} pu/pu·s",
                    p.load_stiffness.norm(),
                    p.motor_stiffness.norm()
                );
            }
        }
    }
}

/// Table 1 gains with the gears apart, and the multi-rate loops.
fn apart_and_rates(cfg: &PlantConfig) {
    println!("== Table 1 gains (designed for J_total) with the gears APART (Jm alone), 2 kHz");
    for (bw_label, bw) in [("15 Hz", 2.0 * PI * 15.0), ("2 rad/s", 2.0)] {
        for (label, ka, fc) in [("no AFB", 0.0, 100.0), ("Ka=1.0 J, 20 Hz", 1.0, 20.0)] {
            let mut lp = design(cfg, bw, ka, fc, (500e-6, 500e-6));
            lp.plant = EngagedPlant::disengaged(&cfg.mechanics);
            let mg = lp.margins();
            println!(
                "  bandwidth {bw_label}, {label}: PM {:.1} deg at {:.0} rad/s, GM {:.1} dB, spectral radius {:.5} ({})",
                mg.phase_margin_deg,
                mg.gain_crossover_rad_s,
                mg.gain_margin_db,
                lp.sampled_spectral_radius(),
                if lp.is_stable() { "stable" } else { "UNSTABLE" }
            );
        }
    }

    // Describing-function view of the lost motion: a dead zone of half-width g driven by a
    // twist of amplitude A > g acts, to first harmonic, like the spring and damper scaled by
    // N(A) = 1 − (2/π)·(asin(g/A) + (g/A)·√(1 − (g/A)²)), N from 0 (inside the gap) to 1.
    // The equivalent plant has K·N and D·N, i.e. f_ar·√N and ζ·√N.
    println!(
        "== Table 1, equivalent-stiffness sweep (dead-zone describing function N), 15 Hz, PI 2 kHz"
    );
    for (label, ka, fc, periods) in [
        ("no AFB", 0.0, 100.0, (500e-6, 500e-6)),
        ("Ka=1.0 J, 20 Hz, AFB 4 kHz", 1.0, 20.0, (500e-6, 250e-6)),
        ("Ka=0.5 J, 100 Hz, AFB 4 kHz", 0.5, 100.0, (500e-6, 250e-6)),
    ] {
        let mut unstable = Vec::new();
        for k in 1..=100 {
            let n = f64::from(k) / 100.0;
            let mut eq = *cfg;
            eq.mechanics.anti_resonance_hz *= n.sqrt();
            eq.mechanics.shaft_damping_ratio *= n.sqrt();
            let lp = design(&eq, 2.0 * PI * 15.0, ka, fc, periods);
            if !lp.is_stable() {
                unstable.push(n);
            }
        }
        let span = match (unstable.first(), unstable.last()) {
            (Some(a), Some(b)) => format!(
                "unstable for N in [{a:.2}, {b:.2}] ({} of 100 points)",
                unstable.len()
            ),
            _ => "stable for every N in (0, 1]".to_string(),
        };
        println!("  {label}: {span}");
    }
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
    let cfg = config("table1.toml")?;
    table1_loops(&cfg);
    apart_and_rates(&cfg);
    eq1();
    Ok(())
}
