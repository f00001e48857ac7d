//! The full closed loop of the PMSM drive (`configs/machines/table1-pmsm.toml`: the
//! field-oriented current tick at 4 kHz, the velocity loop at 2 kHz, the PMSM behind its
//! averaged inverter on the exact two-inertia plant with lost motion, delay and ZOH), `fig6`,
//! on one core. Throughput is in simulated milliseconds, so criterion's "elem/s" divided by
//! 1000 is the real-time factor (simulated seconds per wall-clock second).
//!
//! Its parts, each on the same 2.5 s of `fig6` and with the same throughput unit:
//! - `controller`: the controller's ticks alone (every velocity and PMSM current tick of
//!   the run, replayed on the inputs the run gave them: the same work, bit for bit);
//! - `plant`: `PmsmPlant` alone, advanced over the run's two segments per tick with the
//!   duties the run applied and its load torque (the same trajectory);
//! - `metrics`: the metrics of the run's trace.
#![allow(missing_docs, clippy::unwrap_used, clippy::expect_used)]

use std::hint::black_box;

use controller_core::{
    Controller, CurrentInputs, CurrentOutputs, PmsmInputs, PmsmOutputs, VelocityInputs,
    VelocityOutputs,
};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use plant_host::PmsmPlant;
use sim_engine::engine::metrics::compute;
use sim_engine::engine::runner::{ControlBackend, run_recorded};
use sim_engine::{RunConfig, resolve, run_scenario};

/// A controller tick of the run, with its inputs.
#[derive(Clone, Copy)]
enum Call {
    Velocity(VelocityInputs),
    Pmsm(PmsmInputs),
}

/// The host controller, recording every tick's inputs and the duties it commands.
struct Recorder {
    ctl: Controller,
    calls: Vec<Call>,
    /// Each current tick's command: duties in [0, 1], or `None` (switches off).
    commands: Vec<Option<[f64; 3]>>,
    full_scale: f64,
}

impl ControlBackend for Recorder {
    fn current_tick(&mut self, inputs: CurrentInputs) -> CurrentOutputs {
        self.ctl.current_tick(inputs)
    }
    fn velocity_tick(&mut self, inputs: VelocityInputs) -> VelocityOutputs {
        self.calls.push(Call::Velocity(inputs));
        self.ctl.velocity_tick(inputs)
    }
    fn pmsm_tick(&mut self, inputs: PmsmInputs) -> sim_engine::Result<PmsmOutputs> {
        self.calls.push(Call::Pmsm(inputs));
        let out = self.ctl.pmsm_tick(inputs);
        let fs = self.full_scale;
        let duties = out.duties.map(|d| f64::from(d) / fs);
        self.commands.push(out.enabled.then_some(duties));
        Ok(out)
    }
}

/// The run of `cfg` on the host controller, recorded.
fn record(cfg: &RunConfig) -> (Controller, Recorder, sim_engine::RunOutput) {
    let ctl = sim_engine::engine::runner::controller(cfg).unwrap();
    let full_scale = f64::from(ctl.foc().unwrap().svpwm.period());
    let mut rec = Recorder {
        ctl,
        calls: Vec::new(),
        commands: Vec::new(),
        full_scale,
    };
    let out = run_recorded(cfg, &mut rec, |_| {}).unwrap();
    (ctl, rec, out)
}

/// The run's plant trajectory: `commands` (one per current tick) arriving after the
/// computational delay, the load torque at each segment's middle; `at_tick` sees the plant
/// at each tick instant.
fn replay_plant(
    cfg: &RunConfig,
    commands: &[Option<[f64; 3]>],
    mut at_tick: impl FnMut(usize, &PmsmPlant),
) -> PmsmPlant {
    // The table's drive has no dead time, so the PWM frequency plays no part.
    let mut plant = PmsmPlant::new(&cfg.plant, 20e3).unwrap();
    let tc = 1.0 / f64::from(cfg.drive.current_rate_hz);
    let delay = cfg.plant.electrics.computational_delay_s;
    let rest = tc - delay;
    let mut held = Some([0.5; 3]);
    for (k, &command) in commands.iter().enumerate() {
        let t = k as f64 * tc;
        at_tick(k, &plant);
        for (dt, c, load_t) in [
            (delay, held, t + 0.5 * delay),
            (rest, command, t + delay + 0.5 * rest),
        ] {
            if plant.enabled() != c.is_some() {
                plant.set_enabled(c.is_some());
            }
            let load = cfg.scenario.load_torque_pu(load_t);
            plant.try_advance(dt, c.unwrap_or([0.5; 3]), load).unwrap();
        }
        held = command;
    }
    plant
}

fn closed_loop_pmsm(c: &mut Criterion) {
    let mut group = c.benchmark_group("closed_loop_pmsm");
    let cfg = resolve("fig6", Some("table1-pmsm"), &[]).expect("scenario resolves");
    let sim_ms = (cfg.scenario.duration_s * 1000.0).round() as u64;
    group.throughput(Throughput::Elements(sim_ms));
    group.bench_function("fig6", |b| b.iter(|| run_scenario(&cfg).expect("runs")));

    let (fresh, rec, out) = record(&cfg);
    // The replayed plant is the run's: the trace's motor speed at every velocity tick,
    // bit for bit.
    let mut speeds = Vec::new();
    let ratio = (cfg.drive.current_rate_hz / cfg.drive.velocity_rate_hz) as usize;
    replay_plant(&cfg, &rec.commands, |k, p| {
        if k % ratio == 0 {
            speeds.push(p.motor_vel_pu());
        }
    });
    let traced: Vec<f64> = out.trace.rows.iter().map(|r| r.motor_vel_pu).collect();
    assert!(
        speeds.len() > 1000 && speeds == traced,
        "the replay is the run"
    );
    group.bench_function("controller", |b| {
        b.iter(|| {
            let mut ctl = fresh;
            for call in &rec.calls {
                match *call {
                    Call::Velocity(i) => {
                        black_box(ctl.velocity_tick(black_box(i)));
                    }
                    Call::Pmsm(i) => {
                        black_box(ctl.pmsm_tick(black_box(i)));
                    }
                }
            }
            ctl
        })
    });
    group.bench_function("plant", |b| {
        b.iter(|| replay_plant(&cfg, black_box(&rec.commands), |_, _| {}))
    });
    let windows = cfg.metric_windows();
    group.bench_function("metrics", |b| b.iter(|| compute(&out.trace, &windows)));
    group.finish();
}

criterion_group!(benches, closed_loop_pmsm);
criterion_main!(benches);
