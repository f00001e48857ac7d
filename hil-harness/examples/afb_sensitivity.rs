//! The report's two linear AFB pairs (`shock-50`, `fig6-65k` against their no-AFB runs at the same
//! gains) over a grid of observer bandwidth × AFB filter corner: how much the shaft-torque
//! ripple result moves with the estimator, and at what frequency the ripple is.
//!
//! `cargo run --release -p hil-harness --example afb_sensitivity`
use sim_engine::{resolve, run_scenario};

fn main() {
    println!("pair, observer Hz, AFB corner Hz: ripple with / without AFB (pu), change, ripple frequency with / without (Hz)");
    for pair in ["shock-50", "fig6-65k"] {
        for observer in [50.0, 75.0, 100.0, 150.0] {
            for corner in [100.0, 200.0, 400.0, 1000.0] {
                let sets = vec![
                    format!("drive.observer.bandwidth_hz={observer}"),
                    format!("drive.accel_feedback.filter_corner_hz={corner}"),
                ];
                let run = |name: String| {
                    resolve(&name, None, &sets)
                        .and_then(|cfg| run_scenario(&cfg))
                        .map(|out| out.metrics)
                };
                match (run(pair.to_string()), run(format!("{pair}-no-afb"))) {
                    (Ok(a), Ok(b)) => println!(
                        "{pair}, {observer}, {corner}: {:.5} / {:.5}, {:+.1} %{}, {:.0} / {:.0}",
                        a.shaft_torque_ripple_rms_pu,
                        b.shaft_torque_ripple_rms_pu,
                        100.0 * (a.shaft_torque_ripple_rms_pu / b.shaft_torque_ripple_rms_pu - 1.0),
                        if a.stable { "" } else { " (AFB run unstable)" },
                        a.shaft_ripple_freq_hz,
                        b.shaft_ripple_freq_hz
                    ),
                    (Err(e), _) | (_, Err(e)) => println!("{pair}, {observer}, {corner}: {e}"),
                }
            }
        }
    }
}
