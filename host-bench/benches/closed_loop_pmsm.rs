//! The full closed loop of the PMSM drive (`configs/machines/table1-pmsm.toml`: the
//! field-oriented current tick at 4 kHz, the velocity loop at 2 kHz, the PMSM behind its
//! averaged inverter on the exact two-inertia plant with lost motion, delay and ZOH), `fig6`,
//! on one core. Throughput is in simulated milliseconds, so criterion's "elem/s" divided by
//! 1000 is the real-time factor (simulated seconds per wall-clock second).
#![allow(missing_docs, clippy::unwrap_used, clippy::expect_used)]

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use sim_engine::{resolve, run_scenario};

fn closed_loop_pmsm(c: &mut Criterion) {
    let mut group = c.benchmark_group("closed_loop_pmsm");
    let cfg = resolve("fig6", Some("table1-pmsm"), &[]).expect("scenario resolves");
    let sim_ms = (cfg.scenario.duration_s * 1000.0).round() as u64;
    group.throughput(Throughput::Elements(sim_ms));
    group.bench_function("fig6", |b| b.iter(|| run_scenario(&cfg).expect("runs")));
    group.finish();
}

criterion_group!(benches, closed_loop_pmsm);
criterion_main!(benches);
