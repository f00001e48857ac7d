//! One 4 kHz period on the host: a current tick plus half a velocity tick, measured as a
//! pair of periods (two current ticks and one velocity tick); divide by two for one period.
//! The motor turns at 2 counts per current tick and the setpoint follows it, so
//! every regulator, the observer and the AFB path run (no fault short-cut).
//! `cargo bench -p host-bench --bench period`
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, missing_docs)]

use std::hint::black_box;

use controller_core::{
    Controller, Counts, CurrentInputs, Profile, ProfileConfig, Pu, Setpoint, VelocityInputs,
};
use criterion::{Criterion, criterion_group, criterion_main};

struct Rig {
    ctl: Controller,
    pos: i64,
    /// The speed of 2 counts per current tick \[pu\].
    speed: Pu,
}

impl Rig {
    fn raw(&self) -> u32 {
        (self.pos as u64 & 0xFFFF) as u32
    }
    fn setpoint(&self) -> Setpoint {
        Setpoint {
            position_counts: Counts::from_num(self.pos + 3),
            velocity_pu: self.speed,
            acceleration_pu_s: Pu::from_num(0.5),
        }
    }
    fn current(&mut self) -> controller_core::CurrentOutputs {
        self.pos += 2;
        let raw = self.raw();
        self.ctl.current_tick(black_box(CurrentInputs {
            encoder_count: raw,
            current_pu: Pu::from_num(0.3),
        }))
    }
    fn velocity(&mut self) -> controller_core::VelocityOutputs {
        let inp = VelocityInputs {
            encoder_count: self.raw(),
            setpoint: self.setpoint(),
            fault_input: false,
        };
        self.ctl.velocity_tick(black_box(inp))
    }
}

fn periods(c: &mut Criterion) {
    let cfg = table1_drive();
    let counts_per_s = 2.0 * f64::from(cfg.current_rate_hz);
    let base_counts_per_s = f64::from(cfg.encoder_cpr) * f64::from(cfg.base_speed_rpm) / 60.0;
    let mut rig = Rig {
        ctl: Controller::new(&cfg).unwrap(),
        pos: 0,
        speed: Pu::from_num(counts_per_s / base_counts_per_s),
    };
    c.bench_function(
        "two 4 kHz periods (velocity tick + 2 current ticks), Table 1 default",
        |b| {
            b.iter(|| {
                let v = rig.velocity();
                let a = rig.current();
                let b2 = rig.current();
                black_box((v, a, b2))
            });
        },
    );
    assert_eq!(
        rig.ctl.fault(),
        None,
        "the benchmark must not run the faulted path"
    );
    c.bench_function("current tick alone", |b| {
        b.iter(|| black_box(rig.current()))
    });
    c.bench_function("velocity tick alone", |b| {
        b.iter(|| black_box(rig.velocity()))
    });
    assert_eq!(
        rig.ctl.fault(),
        None,
        "the benchmark must not run the faulted path"
    );
    let mut profile = Profile::new(&ProfileConfig::fig6(), &cfg).unwrap();
    c.bench_function("profile next", |b| b.iter(|| black_box(profile.next())));
}

criterion_group!(benches, periods);
criterion_main!(benches);

/// The paper's Table 1 drive, composed from `configs/machines/table1.toml` by the one composer.
fn table1_drive() -> controller_core::DriveConfig {
    machine_file::table1()
        .expect("configs/machines/table1.toml composes")
        .drive
}
