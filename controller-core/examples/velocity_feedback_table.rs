//! The paper's setting (velocity and acceleration by differentiation at 4096 CPR) against
//! the observer, with and without acceleration feedback, on the test plant of
//! `tests/it/sim.rs` (Table 1 mechanics, 0.5° lost motion, 0.18 ms delay).
//! `cargo run -p controller-core --release --example velocity_feedback_table`
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing,
    missing_docs
)]

#[path = "../tests/common/mod.rs"]
mod common;
#[path = "../tests/it/sim.rs"]
mod sim;

use controller_core::{AfbMode, Controller, Estimator, FilterConfig};
use sim::{run_fig6, run_scenario, PlantParams, Scenario};

fn main() {
    let plant = PlantParams::table1();
    println!("| velocity feedback | AFB | Fig. 6 stable | speed err RMS [pu] | torque ripple RMS [pu] | Fig. 4 stable | torque ripple RMS [pu] |");
    println!("|---|---|---|---|---|---|---|");
    for (vel, vf) in [
        (Estimator::Differentiation, 0.0f32),
        (Estimator::Differentiation, 25.0),
        (Estimator::Differentiation, 50.0),
        (Estimator::Observer, 0.0),
    ] {
        for (mode, src, fc) in [
            (AfbMode::Off, Estimator::Observer, 100.0f32),
            (AfbMode::Error, Estimator::Differentiation, 25.0),
            (AfbMode::Error, Estimator::Observer, 100.0),
        ] {
            let mut cfg = common::table1();
            cfg.velocity_estimator = vel;
            cfg.velocity_filter = if vf == 0.0 {
                FilterConfig::None
            } else {
                FilterConfig::FirstOrder { corner_hz: vf }
            };
            cfg.accel_feedback.mode = mode;
            cfg.accel_feedback.source = src;
            cfg.accel_feedback.filter = FilterConfig::FirstOrder { corner_hz: fc };
            let r6 = run_fig6(&cfg, &plant, 2.0);
            let mut ctl = Controller::new(&cfg).unwrap();
            let r4 = run_scenario(&mut ctl, &cfg, &plant, &Scenario::fig4());
            let v = match (vel, vf) {
                (Estimator::Observer, _) => "observer 75 Hz".to_string(),
                (_, 0.0) => "differentiation, raw".to_string(),
                (_, f) => format!("differentiation, 1st-order {f} Hz"),
            };
            let a = match mode {
                AfbMode::Off => "off".to_string(),
                _ => format!("error form, Ka 0.5·J, {src:?} + 1st-order {fc} Hz"),
            };
            println!(
                "| {v} | {a} | {} | {:.4} | {:.3} | {} | {:.3} |",
                r6.stable(),
                r6.speed_err_rms_pu,
                r6.torque_ripple_rms_pu,
                r4.stable(),
                r4.torque_ripple_rms_pu
            );
        }
    }
}
