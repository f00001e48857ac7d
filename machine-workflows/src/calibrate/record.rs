//! The calibration record, and running the sequence on the simulated machine.

use controller_core::foc::calibration::{
    Calibration, CalibrationSettings, CalibrationState, Stage,
};
use controller_core::foc::{clarke, Svpwm};
use controller_core::per_unit::Pu;
use pil_host::board_calibrate::BoardCalibration;
use plant_host::{PlantConfig, PmsmPlant};
use sim_engine::error::{HarnessError, Result};

/// One tick of the calibration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Row {
    /// The stage the tick belongs to.
    pub stage: Stage,
    /// The voltage set this tick (stationary frame) \[pu\]; it acts from the next sample.
    pub v_alpha: f64,
    /// β voltage \[pu\].
    pub v_beta: f64,
    /// The commanded electrical angle \[turns\], unwrapped.
    pub phase_turns: f64,
    /// Phase current a as sampled at the tick's start \[pu\].
    pub i_a: f64,
    /// Phase current b \[pu\].
    pub i_b: f64,
    /// The motor encoder's count at the tick's start.
    pub count: i64,
}

/// A whole calibration: its rows, the tick rate, and the encoder's counts per revolution.
#[derive(Clone, Debug, PartialEq)]
pub struct Record {
    /// Current ticks per second.
    pub rate_hz: f64,
    /// Encoder counts per mechanical revolution.
    pub encoder_cpr: u32,
    /// Every tick, in order.
    pub rows: Vec<Row>,
}

/// The PWM period in timer counts of the simulated inverter (168 MHz over 2·20 kHz).
const PWM_PERIOD: u16 = 4200;

/// Runs the calibration `settings` on the PMSM of `config` (its load free, no load torque).
pub fn record_on_plant(config: &PlantConfig, settings: &CalibrationSettings) -> Result<Record> {
    let seq = Calibration::new(settings)
        .map_err(|e| HarnessError::config("calibration", e.to_string()))?;
    let mut plant = PmsmPlant::new(config, f64::from(settings.current_rate_hz))
        .map_err(|e| HarnessError::config("electrics", e.to_string()))?;
    let bus = plant.inverter().dc_bus_pu() as f32;
    let svpwm = Svpwm::new(bus, PWM_PERIOD)
        .map_err(|e| HarnessError::config("electrics.dc_bus_pu", e.to_string()))?;
    let dt = 1.0 / f64::from(settings.current_rate_hz);
    let mut st = CalibrationState::default();
    let mut rows = Vec::with_capacity(seq.total_ticks() as usize);
    let mut turns = 0.0;
    let mut last_phase = 0u32;
    for _ in 0..seq.total_ticks() {
        let [i_a, i_b] = plant.phase_current_samples();
        let count = plant.encoder_count();
        let ab = clarke(Pu::from_num(i_a), Pu::from_num(i_b));
        let t = seq.tick(&mut st, ab.alpha);
        // The phase steps by less than half a turn a tick: its wrapped difference unwraps it.
        turns += f64::from(t.phase.wrapping_sub(last_phase) as i32) / 4_294_967_296.0;
        last_phase = t.phase;
        let duties = svpwm
            .duties(t.voltage)
            .map(|d| f64::from(d) / f64::from(PWM_PERIOD));
        plant
            .advance_period(dt, duties, 0.0)
            .map_err(|e| HarnessError::Backend(format!("calibration: {e}")))?;
        rows.push(Row {
            stage: t.stage,
            v_alpha: t.voltage.alpha.to_num(),
            v_beta: t.voltage.beta.to_num(),
            phase_turns: turns,
            i_a,
            i_b,
            count,
        });
    }
    Ok(Record {
        rate_hz: f64::from(settings.current_rate_hz),
        encoder_cpr: config.counts_per_rev(),
        rows,
    })
}

impl Record {
    /// The board's record (`pil_host::board_calibrate`) as [`super::estimate()`] reads it:
    /// per-unit values from their Q16.16 bits, the commanded angle unwrapped into turns, the
    /// encoder counter (`counter_bits` wide) read signed at the first tick, as the drive
    /// primes its position, and unwrapped from there; `encoder_cpr` the drive's.
    #[must_use]
    pub fn from_board(board: &BoardCalibration, encoder_cpr: u32, counter_bits: u8) -> Self {
        let pu = |x: Pu| f64::from(x.to_bits()) / 65_536.0;
        let span = 1_i64 << counter_bits.clamp(1, 32);
        let (mut turns, mut last_phase) = (0.0, 0_u32);
        let mut unwrapped: Option<(i64, i64)> = None;
        let rows = board
            .rows
            .iter()
            .map(|r| {
                // Less than half a turn (or half the counter) a tick: the wrapped step
                // unwraps it.
                turns += f64::from(r.phase.wrapping_sub(last_phase) as i32) / 4_294_967_296.0;
                last_phase = r.phase;
                let raw = i64::from(r.count) & (span - 1);
                let count = match unwrapped {
                    // Signed, as the drive primes its position from the counter (so the
                    // offset is the one the drive's angle needs).
                    None if raw >= span / 2 => raw - span,
                    None => raw,
                    Some((last_raw, last)) => {
                        let step = (raw - last_raw).rem_euclid(span);
                        last + if step >= span / 2 { step - span } else { step }
                    }
                };
                unwrapped = Some((raw, count));
                Row {
                    stage: r.stage,
                    v_alpha: pu(r.v_alpha),
                    v_beta: pu(r.v_beta),
                    phase_turns: turns,
                    i_a: pu(r.i_a),
                    i_b: pu(r.i_b),
                    count,
                }
            })
            .collect();
        Self {
            rate_hz: f64::from(board.rate_hz),
            encoder_cpr,
            rows,
        }
    }
}
