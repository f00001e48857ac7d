//! The full closed loop (current PI at 4 kHz, velocity loop at 2 kHz, winding, exact
//! two-inertia plant with lost motion, delay and ZOH) on one core. Throughput is in
//! simulated milliseconds, so criterion's "elem/s" divided by 1000 is the real-time
//! factor (simulated seconds per wall-clock second).
#![allow(missing_docs, clippy::unwrap_used, clippy::expect_used)]

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use sim_engine::{resolve, run_scenario};

fn closed_loop(c: &mut Criterion) {
    let mut group = c.benchmark_group("closed_loop");
    for scenario in ["fig6", "fig6-no-afb", "shock"] {
        let cfg = resolve(scenario, None, &[]).expect("scenario resolves");
        let sim_ms = (cfg.scenario.duration_s * 1000.0).round() as u64;
        group.throughput(Throughput::Elements(sim_ms));
        group.bench_function(scenario, |b| b.iter(|| run_scenario(&cfg).expect("runs")));
    }
    group.finish();
}

criterion_group!(benches, closed_loop);
criterion_main!(benches);
