//! The PMSM recording of `lil-record`: the App's PMSM tick around plant-host's PMSM of the
//! machine file `STIFFDRIVE_DRIVE` names (see the binary's text).

use controller_core::{DriveConfig, Pu};
use firmware::app::{velocity_inputs, App, DEFAULT_TRACE};
use firmware::lil::words::{self, PmsmLilInput};
use firmware::lil::PmsmReplayIo;
use plant_host::PmsmPlant;

use crate::{FAULT_FROM_PERIOD, LOAD_STEP_PERIOD, LOAD_STEP_PU, PERIODS};

/// Where the motor starts [counts]: the DC recording's 65,000 on the 16-bit counter, so
/// the run crosses the wrap.
const START_COUNTS: i64 = 65_000 - 65_536;
/// Noise on each phase current [ADC LSB].
const NOISE_LSB: i32 = 2;
/// The PWM timer's clock [Hz] (`pwm_period_counts` counts up and down make one period);
/// only the plant's dead time depends on the PWM frequency.
const PWM_TIMER_CLOCK_HZ: f64 = 168e6;

/// Record the PMSM drive `cfg` on the machine file's plant.
pub(crate) fn run(cfg: &DriveConfig) -> Result<(), String> {
    let plant_cfg = plant_config()?;
    let period_counts = cfg.pmsm.map_or(1, |p| p.pwm_period_counts.max(1));
    let mut plant = PmsmPlant::new(
        &plant_cfg,
        PWM_TIMER_CLOCK_HZ / (2.0 * f64::from(period_counts)),
    )
    .map_err(|e| format!("plant: {e}"))?;
    // The motor and the load at rest mid-way in the start count: the counter reads what the
    // plant's encoder reads, so the drive's electrical angle is the plant's.
    let cpr = f64::from(plant_cfg.mechanics.encoder_cpr);
    let start_rad = (START_COUNTS as f64 + 0.5) * std::f64::consts::TAU / cpr;
    plant.set_state(start_rad, start_rad, 0.0, 0.0, 0.0, 0.0);
    let mut app =
        App::new_pmsm(cfg, cfg.counter_bits, DEFAULT_TRACE).map_err(|e| format!("{e:?}"))?;
    app.set_enable_request(true);
    let mut profile =
        controller_core::Profile::new(&words::profile_config(), cfg).map_err(|e| e.to_string())?;
    let ratio = words::tick_ratio(cfg);
    let dt = 1.0 / f64::from(cfg.current_rate_hz);
    let lsb = 2.0 * plant_cfg.electrics.current_full_scale_pu
        / f64::from(1_u32 << plant_cfg.electrics.current_adc_bits);
    let mut noise = crate::noise(NOISE_LSB);
    println!("# stiffdrive loop-in-the-loop recording of a PMSM drive: written by `STIFFDRIVE_DRIVE=configs/machines/table1-pmsm.toml cargo run -p firmware --features record --bin lil-record`");
    println!("# one line per current period; i_a/i_b_pu_bits = Q16.16 bits; see firmware/src/bin/lil_record/pmsm.rs");
    println!("period,encoder_count,i_a_pu_bits,i_b_pu_bits,fault_input");
    let mut io = PmsmReplayIo::default();
    let mut load = 0.0;
    for k in 0..PERIODS {
        if k == LOAD_STEP_PERIOD {
            load = f64::from(LOAD_STEP_PU);
        }
        let [a, b] = plant.phase_current_samples();
        let mut sample = |x: f64| Pu::from_num(x + f64::from(noise()) * lsb);
        let rec = PmsmLilInput {
            encoder_count: (plant.encoder_count() & 0xFFFF) as u32,
            phase_current_pu: [sample(a), sample(b)],
            fault_input: k >= FAULT_FROM_PERIOD,
        };
        let [ia, ib] = rec.phase_current_pu.map(Pu::to_bits);
        println!(
            "{k},{},{ia},{ib},{}",
            rec.encoder_count,
            u8::from(rec.fault_input)
        );
        io.record = rec;
        app.on_pmsm_tick(&mut io);
        if words::velocity_after(k, ratio) {
            app.on_velocity_tick(velocity_inputs(&mut io, &mut profile));
        }
        if plant.enabled() != io.enabled {
            plant.set_enabled(io.enabled);
        }
        let duties = io.duties.map(|d| f64::from(d) / f64::from(period_counts));
        plant
            .advance_period(dt, duties, load)
            .map_err(|e| format!("plant: {e}"))?;
    }
    eprintln!(
        "lil-record: {PERIODS} PMSM periods, final speed {:.3} pu, i_q {:.3} pu, fault {:?}",
        plant.motor_vel_pu(),
        plant.i_q_pu(),
        app.fault()
    );
    Ok(())
}

/// The plant of the machine file `STIFFDRIVE_DRIVE` names (relative to the working
/// directory: run from the workspace root), which must be a PMSM.
fn plant_config() -> Result<plant_host::PlantConfig, String> {
    let path = std::env::var("STIFFDRIVE_DRIVE").map_err(|_| {
        "a PMSM drive is baked: set STIFFDRIVE_DRIVE to its machine file".to_string()
    })?;
    let machine =
        machine_file::load(std::path::Path::new(&path)).map_err(|e| format!("{path}: {e}"))?;
    if machine.plant.electrics.motor != plant_host::MotorKind::Pmsm {
        return Err(format!("{path}: electrics.motor is not \"pmsm\""));
    }
    Ok(machine.plant)
}
