//! Quick cost probe: simulates N seconds of the engaged plant and of the gap-crossing profile
//! and prints wall time per simulated second (`cargo run --release -p plant-host --example plant_cost`).
#![allow(missing_docs)]

use plant_host::{PlantConfig, TwoInertiaPlant};
use std::f64::consts::PI;
use std::time::Instant;

fn main() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../configs/machines/table1.toml"
    );
    let cfg = match PlantConfig::from_machine_file(path.as_ref()) {
        Ok(cfg) => cfg,
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(1);
        }
    };
    let mut p = TwoInertiaPlant::torque_driven(&cfg);
    let seconds: u32 = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(50);
    let start = Instant::now();
    for _ in 0..seconds * 4000 {
        p.advance(250e-6, 0.5, 0.3);
    }
    let engaged = start.elapsed().as_secs_f64() / f64::from(seconds);
    let mut q = TwoInertiaPlant::torque_driven(&cfg);
    let torques: Vec<f64> = (0..seconds * 4000)
        .map(|k| {
            let t = f64::from(k) * 250e-6;
            1.2 * (2.0 * PI * 4.0 * t).sin() + 0.4 * (2.0 * PI * 31.0 * t + 1.0).sin()
        })
        .collect();
    let start = Instant::now();
    for tm in &torques {
        q.advance(250e-6, *tm, 0.2);
    }
    let crossing = start.elapsed().as_secs_f64() / f64::from(seconds);
    println!(
        "engaged: {:.1} us per simulated second; gap-crossing: {:.1} us per simulated second ({} crossings, {} searches); {}",
        engaged * 1e6,
        crossing * 1e6,
        q.mode_changes(),
        q.crossing_searches(),
        p.motor_pos_rad() + q.motor_pos_rad()
    );
}
