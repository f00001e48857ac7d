//! Cost of the plant per simulated second (`cargo bench -p host-bench --bench plant`).
//! - mechanics: 4000 steps of 250 µs under a torque profile that crosses the gap ~40 times.
//! - drive: winding + mechanics in the harness's pattern, a new voltage the computational
//!   delay after each 250 µs tick (8000 `advance` calls per simulated second), plus the
//!   encoder and ADC reads. The plant is `configs/machines/table1.toml`.
#![allow(missing_docs, clippy::unwrap_used)]

use criterion::{Criterion, black_box, criterion_group, criterion_main};
use plant_host::{PlantConfig, TwoInertiaPlant};
use std::f64::consts::PI;
use std::time::Duration;

fn profile(t: f64) -> (f64, f64) {
    let tm = 1.2 * (2.0 * PI * 4.0 * t).sin() + 0.4 * (2.0 * PI * 31.0 * t + 1.0).sin();
    let tl = 0.2 * (2.0 * PI * 1.3 * t).sin() + if t >= 0.5 { 0.3 } else { 0.0 };
    (tm, tl)
}

fn bench(c: &mut Criterion) {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../configs/machines/table1.toml"
    );
    let cfg = PlantConfig::from_machine_file(path.as_ref()).unwrap();
    let delay = cfg.electrics.computational_delay_s;
    let rest = 250e-6 - delay;
    let torques: Vec<(f64, f64)> = (0..4000).map(|k| profile(k as f64 * 250e-6)).collect();
    let mut g = c.benchmark_group("plant per simulated second");
    g.sample_size(20).measurement_time(Duration::from_secs(4));
    // Warm plants (their per-step-length matrix exponentials cached), cloned per iteration:
    // the figure is the steady cost of a long run.
    let mut warm_mech = TwoInertiaPlant::torque_driven(&cfg);
    for (tm, tl) in &torques {
        warm_mech.advance(250e-6, *tm, *tl);
    }
    let mut warm_drive = TwoInertiaPlant::voltage_driven(&cfg);
    for (tm, tl) in &torques {
        warm_drive.advance(delay, 0.05 * tm, *tl);
        warm_drive.advance(rest, 0.05 * tm, *tl);
    }
    eprintln!(
        "mechanics: {} contact changes, {} crossing searches per simulated second",
        warm_mech.mode_changes(),
        warm_mech.crossing_searches()
    );
    g.bench_function("mechanics 4 kHz, gap-crossing profile", |b| {
        b.iter(|| {
            let mut p = warm_mech.clone();
            p.set_state(0.0, 0.0, 0.0, 0.0, 0.0);
            for (tm, tl) in &torques {
                p.advance(250e-6, *tm, *tl);
            }
            black_box(p.motor_pos_rad())
        })
    });
    g.bench_function("drive 4 kHz, delay + rest events, sensors read", |b| {
        b.iter(|| {
            let mut d = warm_drive.clone();
            d.set_state(0.0, 0.0, 0.0, 0.0, 0.0);
            let mut v_prev = 0.0;
            let mut acc = 0_i64;
            for (tm, tl) in &torques {
                acc = acc.wrapping_add(d.encoder_count());
                let i = d.current_sample();
                let v = 0.05 * tm + d.motor_vel_pu() + 0.01 * i;
                d.advance(delay, v_prev, *tl);
                d.advance(rest, v, *tl);
                v_prev = v;
            }
            black_box((acc, d.mode_changes()))
        })
    });
    g.bench_function("mechanics 4 kHz, engaged, no crossing", |b| {
        let mut p = warm_mech.clone();
        b.iter(|| {
            for _ in 0..4000 {
                p.advance(250e-6, 0.5, 0.3);
            }
            black_box(p.motor_pos_rad())
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
