//! The motor calibration's excitation: a tick-by-tick voltage sequence that lets the host
//! measure the phase resistance, the d and q inductances, the encoder's direction and
//! offset and the pole-pair count, as a drive's commissioning does before it closes the
//! current loop. The sequencer only sets voltages (in the stationary frame, so it needs no
//! electrical angle) and says which stage each tick belongs to; the host records the
//! currents and the counts beside it and estimates (the estimation lives in the host, once).
//!
//! 1. **Resistance** ([`Stage::Level`] 0 and 1): the voltage on the α axis ramps towards
//!    the current `I/2`, then `I` (`v ← v ± ramp·Ts` by the sign of the current's error),
//!    each level held for `settle + record` ticks. The torque turns the rotor's d axis onto
//!    α, so it also aligns the rotor. R is Δv/Δi between the two levels, which cancels a
//!    constant voltage error such as the inverter's dead time.
//! 2. **Inductance** ([`Stage::Square`]): on top of the second level's voltage, which holds
//!    the rotor, ±V_L on α and, independently, ±V_L on β, by a pseudo-random binary
//!    sequence (a 16-bit maximal LFSR, stepped once for each axis) coded in pairs: a bit b
//!    sets +b for one tick and −b for the next. The pairs leave no volt-seconds behind, so
//!    the currents stay within one tick's step of the hold, and the q current's torque,
//!    which the hold's magnetic spring must resist, stays small and changes sign every
//!    tick (a plain sequence lets the current wander by several steps and twists the rotor
//!    by tens of degrees). The current's
//!    step over each tick, regressed on the voltages of that tick and the one before (the
//!    computational delay splits a tick between them), gives the stator-frame matrix
//!    Ts·L⁻¹; its eigenvalues are Ts/L_d and Ts/L_q whatever the angle at which the rotor
//!    stands (a rotor a few degrees off the α axis would mix L_q into an α-only
//!    measurement of L_d).
//! 3. **Sweep** ([`Stage::Forward`], [`Stage::Backward`]): the second level's voltage
//!    vector turns `turns` electrical turns forwards, then back; the rotor follows. Each
//!    way its speed rises linearly from 0 to `sweep_hz` over the time of one turn at that
//!    speed, holds, and falls back to 0 the same way (half a turn in each ramp), so the
//!    rotor and its load are brought up to speed and stopped, not kicked: a step to
//!    `sweep_hz` sets the whole inertia swinging on the vector's magnetic spring, and on a
//!    heavy load (Table 1's) that swing slips poles. Counts against the commanded angle
//!    give the direction and the counts per electrical turn (so the pole pairs), and the
//!    angle at count 0 (the offset): the lag behind the vector is opposite on the way
//!    back, so the mean of the two cancels it.

use super::transforms::{AlphaBeta, CosSin, Dq, inverse_park};
use crate::error::ConfigError;
use crate::per_unit::{Pu, quantize};
use fixed::types::I32F32;

/// The stage of a calibration tick.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    /// A current level on the α axis (0: half the test current, 1: the test current);
    /// `recording` once it has settled.
    Level {
        /// Which level.
        index: u8,
        /// Whether this tick is in the recorded part.
        recording: bool,
    },
    /// ±V_L, pseudo-random, on α and on β.
    Square,
    /// The vector turning forwards.
    Forward,
    /// The vector turning back.
    Backward,
    /// Finished: zero voltage.
    Done,
}

/// The calibration's settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CalibrationSettings {
    /// The test current I \[pu\] (the resistance levels are I/2 and I; the sweep's torque).
    pub current_pu: f32,
    /// The voltage ramp of the current levels \[pu/s\].
    pub ramp_pu_per_s: f32,
    /// Ticks each level settles, then ticks it records.
    pub settle_s: f32,
    /// Seconds each level records.
    pub record_s: f32,
    /// The square wave's amplitude V_L \[pu\].
    pub square_pu: f32,
    /// Seconds of square wave (both axes at once).
    pub square_s: f32,
    /// Electrical turns of the sweep each way, its two half-turn ramps included, ≥ 3 for
    /// an estimate (which uses the whole turns at full speed after the first turn: two of
    /// the default four).
    pub turns: u32,
    /// The sweep's top electrical speed \[turns/s\] (reached after a ramp of one turn's
    /// time at it).
    pub sweep_hz: f32,
    /// The current tick rate \[Hz\].
    pub current_rate_hz: f32,
    /// The largest voltage the sequence may set \[pu\] (the inverter's linear range).
    pub voltage_limit_pu: f32,
}

impl Default for CalibrationSettings {
    /// 0.5 pu test current, 1 pu/s ramp, 0.3 s settling and 0.1 s recording per level,
    /// 0.1 pu square wave for 0.1 s, four electrical turns each way at up to 2 turns/s,
    /// at 4 kHz with a 1 pu voltage limit.
    fn default() -> Self {
        Self {
            current_pu: 0.5,
            ramp_pu_per_s: 1.0,
            settle_s: 0.3,
            record_s: 0.1,
            square_pu: 0.1,
            square_s: 0.1,
            turns: 4,
            sweep_hz: 2.0,
            current_rate_hz: 4000.0,
            voltage_limit_pu: 1.0,
        }
    }
}

/// The sequencer's coefficients (ticks and raw steps).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Calibration {
    level_current: [Pu; 2],
    /// The level voltage's step per tick, Q32.32 (a 1 pu/s ramp at 20 kHz is 5e-5 pu).
    ramp: I32F32,
    settle_ticks: u32,
    record_ticks: u32,
    square: Pu,
    square_ticks: u32,
    /// Ticks of each way: the turns at full speed and one more turn's time for the two
    /// ramps.
    sweep_ticks: u32,
    /// Ticks of each ramp (one turn's time at full speed), ≥ 1.
    ramp_ticks: u32,
    /// Phase step per tick of the sweep at full speed (2^32 per turn).
    sweep_step: u32,
    limit: Pu,
}

/// The sequencer's state.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CalibrationState {
    /// Ticks since the start.
    pub tick: u32,
    /// The α voltage of the current level (held through the square waves and the sweep),
    /// Q32.32.
    pub level_voltage: I32F32,
    /// The commanded electrical angle of the sweep.
    pub phase: u32,
    /// The pseudo-random sequence's register (0 is taken as its seed).
    pub lfsr: u16,
    /// The square wave's voltages of the first tick of the present pair (α, β).
    pub square: [Pu; 2],
}

/// One tick's command.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CalibrationTick {
    /// The stage.
    pub stage: Stage,
    /// The voltage to set, stationary frame.
    pub voltage: AlphaBeta,
    /// The commanded electrical angle (the sweep's; 0 before it).
    pub phase: u32,
}

fn ticks(s: f32, rate: f32, param: &'static str) -> Result<u32, ConfigError> {
    let t = s * rate;
    if !(t.is_finite() && (1.0..=1.0e8).contains(&t)) {
        return Err(ConfigError::OutOfRange {
            param,
            value: s,
            min: 1.0 / rate,
            max: 1.0e8 / rate,
            min_exclusive: false,
        });
    }
    Ok(t as u32)
}

impl Calibration {
    /// The sequence of `s`; a bad setting is an error naming it.
    pub fn new(s: &CalibrationSettings) -> Result<Self, ConfigError> {
        let rate = s.current_rate_hz;
        crate::ranges::Range::real("current_rate_hz", 100.0, 200_000.0, false).check(rate)?;
        let turn_ticks = ticks(1.0 / s.sweep_hz, rate, "calibration sweep_hz (turns/s)")?;
        Ok(Self {
            level_current: [
                quantize(s.current_pu / 2.0, "calibration current_pu")?,
                quantize(s.current_pu, "calibration current_pu")?,
            ],
            ramp: quantize(s.ramp_pu_per_s / rate, "calibration ramp_pu_per_s")?,
            settle_ticks: ticks(s.settle_s, rate, "calibration settle_s")?,
            record_ticks: ticks(s.record_s, rate, "calibration record_s")?,
            square: quantize(s.square_pu, "calibration square_pu")?,
            square_ticks: ticks(s.square_s, rate, "calibration square_s")?,
            sweep_ticks: turn_ticks.saturating_mul(s.turns.max(1).saturating_add(1)),
            ramp_ticks: turn_ticks.max(1),
            sweep_step: (4_294_967_296.0 / turn_ticks as f64 + 0.5) as u32,
            limit: quantize(s.voltage_limit_pu, "calibration voltage_limit_pu")?,
        })
    }

    /// Ticks of the whole sequence.
    #[must_use]
    pub fn total_ticks(&self) -> u32 {
        let level = self.settle_ticks + self.record_ticks;
        2 * level + self.square_ticks + 2 * self.sweep_ticks
    }

    /// The stage of tick `k`.
    #[must_use]
    pub fn stage(&self, k: u32) -> Stage {
        let level = self.settle_ticks + self.record_ticks;
        let mut k = k;
        for index in 0..2 {
            if k < level {
                return Stage::Level {
                    index,
                    recording: k >= self.settle_ticks,
                };
            }
            k -= level;
        }
        if k < self.square_ticks {
            return Stage::Square;
        }
        k -= self.square_ticks;
        if k < self.sweep_ticks {
            return Stage::Forward;
        }
        k -= self.sweep_ticks;
        if k < self.sweep_ticks {
            Stage::Backward
        } else {
            Stage::Done
        }
    }

    /// The phase step of the sweep's tick `k` (0 at the start of either way): full speed
    /// between a linear ramp up over the first [`Self::ramp_ticks`] ticks and one down
    /// over the last.
    fn sweep_step_at(&self, k: u32) -> u32 {
        let r = self.ramp_ticks.max(1);
        let m = k
            .saturating_add(1)
            .min(self.sweep_ticks.saturating_sub(k))
            .min(r);
        (u64::from(self.sweep_step) * u64::from(m) / u64::from(r)) as u32
    }

    /// One tick: `i_alpha` is the α current sampled this tick.
    pub fn tick(&self, st: &mut CalibrationState, i_alpha: Pu) -> CalibrationTick {
        let stage = self.stage(st.tick);
        let k = st.tick;
        st.tick = st.tick.saturating_add(1);
        let hold = Pu::saturating_from_num(st.level_voltage);
        let [square_a, square_b] = if stage != Stage::Square {
            [Pu::ZERO; 2]
        } else if st.tick % 2 == 1 {
            // The first tick of a pair (st.tick already counts this one): new bits.
            // x^16 + x^14 + x^13 + x^11 + 1, a maximal sequence (period 65535), one step
            // for each axis.
            let mut r = if st.lfsr == 0 { 0xACE1 } else { st.lfsr };
            for b in &mut st.square {
                let bit = (r ^ (r >> 2) ^ (r >> 3) ^ (r >> 5)) & 1;
                r = (r >> 1) | (bit << 15);
                *b = if bit == 1 { self.square } else { -self.square };
            }
            st.lfsr = r;
            st.square
        } else {
            st.square.map(|b| -b)
        };
        let (voltage, phase) = match stage {
            Stage::Level { index, .. } => {
                let [half, full] = self.level_current;
                let target = if index == 0 { half } else { full };
                let v = if i_alpha < target {
                    st.level_voltage.saturating_add(self.ramp)
                } else {
                    st.level_voltage.saturating_sub(self.ramp)
                };
                let limit = I32F32::from(self.limit);
                st.level_voltage = v.clamp(-limit, limit);
                (
                    AlphaBeta {
                        alpha: Pu::saturating_from_num(st.level_voltage),
                        beta: Pu::ZERO,
                    },
                    0,
                )
            }
            Stage::Square => (
                AlphaBeta {
                    alpha: hold.saturating_add(square_a),
                    beta: square_b,
                },
                0,
            ),
            Stage::Forward | Stage::Backward => {
                // Ticks into the present way of the sweep.
                let into_sweep = k
                    .wrapping_sub(2 * (self.settle_ticks + self.record_ticks) + self.square_ticks)
                    % self.sweep_ticks.max(1);
                let step = self.sweep_step_at(into_sweep);
                st.phase = if stage == Stage::Forward {
                    st.phase.wrapping_add(step)
                } else {
                    st.phase.wrapping_sub(step)
                };
                let v = inverse_park(
                    Dq {
                        d: hold,
                        q: Pu::ZERO,
                    },
                    CosSin::of(st.phase),
                );
                (v, st.phase)
            }
            Stage::Done => (AlphaBeta::default(), st.phase),
        };
        CalibrationTick {
            stage,
            voltage,
            phase,
        }
    }
}
