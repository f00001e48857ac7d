//! Records the loop-in-the-loop input sequence `firmware/lil/inputs.csv` (host only):
//! `cargo run -p firmware --features record --bin lil-record > firmware/lil/inputs.csv`.
//!
//! The firmware's own App closes the loop around the virtual motor (RL winding + rigid
//! inertia, `virtual_motor.rs`) for 1.1 s at 4 kHz: the run's trapezoid profile, a 0.3 pu
//! load step at 0.4 s, the external fault input raised for the last 25 ms. What is
//! recorded is what a board would sample: the 16-bit encoder counter (started near its
//! wrap at 65,000 so the run crosses it) and the current quantized like a 12-bit ADC
//! (1/1024 pu per LSB) with ±3 LSB of deterministic pseudo-random noise. The replay is open
//! loop: the recording stays valid input whatever the core's gains become.
//!
//! With a PMSM drive baked (`STIFFDRIVE_DRIVE=configs/machines/table1-pmsm.toml cargo run -p
//! firmware --features record --bin lil-record > firmware/lil/inputs-pmsm.csv`) the App's PMSM
//! tick closes the loop around plant-host's PMSM of the same machine file (`PmsmPlant`: the
//! three duties after the file's computational delay, the two phase currents through its
//! ADC model), the same motion, load step and fault input. Recorded: the 16-bit encoder
//! counter (the motor starts at 65,000, −536 counts) and the phase currents a and b with
//! ±2 LSB of the same deterministic noise.
#![allow(clippy::print_stdout)]

#[path = "lil_record/pmsm.rs"]
mod pmsm;

use controller_core::Pu;
use firmware::app::{velocity_inputs, App, DEFAULT_TRACE};
use firmware::lil::words::{self, LilInput};
use firmware::lil::ReplayIo;
use firmware::virtual_motor::{VirtualMotor, VirtualMotorConfig};

pub(crate) const PERIODS: u32 = 4400;
pub(crate) const LOAD_STEP_PERIOD: u32 = 1600;
pub(crate) const LOAD_STEP_PU: f32 = 0.3;
pub(crate) const FAULT_FROM_PERIOD: u32 = 4300;
const START_COUNTS: u32 = 65_000;
/// ADC resolution [pu per LSB] and noise amplitude [LSB].
const ADC_PU_PER_LSB: f32 = 1.0 / 1024.0;
const NOISE_LSB: i32 = 3;

fn main() {
    let result = match firmware::drive::baked() {
        Ok(cfg) if cfg.pmsm.is_some() => pmsm::run(&cfg),
        _ => run().map_err(|e| format!("{e:?}")),
    };
    if let Err(e) = result {
        eprintln!("lil-record: {e}");
        std::process::exit(1);
    }
}

fn run() -> Result<(), firmware::app::AppError> {
    let cfg = firmware::drive::baked().map_err(firmware::app::AppError::Settings)?;
    let mut app = App::new(&cfg, cfg.counter_bits, DEFAULT_TRACE)?;
    app.set_enable_request(true);
    let mut profile = controller_core::Profile::new(&words::profile_config(), &cfg)
        .map_err(firmware::app::AppError::Config)?;
    let ratio = words::tick_ratio(&cfg);
    let mut motor =
        VirtualMotor::new(VirtualMotorConfig::for_drive(&cfg)).with_counts(START_COUNTS);
    let mut noise = noise(NOISE_LSB);
    println!("# stiffdrive loop-in-the-loop recording: written by `cargo run -p firmware --features record --bin lil-record`");
    println!("# one line per 4 kHz period; current_pu_bits = Q16.16 bits; see firmware/src/bin/lil_record.rs");
    println!("period,encoder_count,current_pu_bits,fault_input");
    let mut io = ReplayIo::default();
    for k in 0..PERIODS {
        if k == LOAD_STEP_PERIOD {
            motor.set_load_torque_pu(LOAD_STEP_PU);
        }
        let lsb = (motor.current_pu() / ADC_PU_PER_LSB).round() as i32 + noise();
        let rec = LilInput {
            encoder_count: motor.counts() & 0xFFFF,
            current_pu: Pu::from_num(lsb) * Pu::from_num(ADC_PU_PER_LSB),
            fault_input: k >= FAULT_FROM_PERIOD,
        };
        println!(
            "{k},{},{},{}",
            rec.encoder_count,
            rec.current_pu.to_bits(),
            u8::from(rec.fault_input)
        );
        io.record = rec;
        app.on_current_tick(&mut io);
        if words::velocity_after(k, ratio) {
            app.on_velocity_tick(velocity_inputs(&mut io, &mut profile));
        }
        let v: f32 = io.applied_voltage_pu.to_num();
        motor.step(v);
    }
    eprintln!(
        "lil-record: {PERIODS} periods, final speed {:.3} pu, fault {:?}",
        motor.speed_pu(),
        app.fault()
    );
    Ok(())
}

/// Park–Miller LCG: deterministic noise in ±`lsb`, the same file on every machine.
fn noise(lsb: i32) -> impl FnMut() -> i32 {
    let mut seed: u32 = 12_345;
    move || {
        seed = ((u64::from(seed) * 48_271) % 0x7FFF_FFFF) as u32;
        (seed % (2 * lsb as u32 + 1)) as i32 - lsb
    }
}
