//! The computational delay is modelled for every value the config accepts: longer delays
//! change the run (a delay clamped to one current period would give 0.5, 5 and 10 ms the
//! trace of 250 µs).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use sim_engine::{resolve, run_scenario};

fn voltages(delay_s: f64) -> Vec<f64> {
    let sets = vec![
        format!("electrics.computational_delay_s={delay_s}"),
        "scenario.duration_s=1.5".to_string(),
    ];
    let cfg = resolve("fig6", None, &sets).unwrap();
    let out = run_scenario(&cfg).unwrap();
    out.trace.rows.iter().map(|r| r.voltage_pu).collect()
}

#[test]
fn delays_past_one_current_period_change_the_run() {
    let base = voltages(250e-6);
    for d in [0.5e-3, 5e-3, 10e-3] {
        assert_ne!(
            voltages(d),
            base,
            "a delay of {d} s gave the trace of 250 µs"
        );
    }
    // Two different long delays differ from each other too.
    assert_ne!(voltages(5e-3), voltages(10e-3));
}
