//! The three-phase power stage: its one table ([`IHM08M1`]: pins and scaling) and the
//! arithmetic between the drive's per-unit values and the stage's counts, host-tested
//! (`firmware/tests/three_phase.rs`). The registers that use them are the STM32F4 board's
//! (`boards::stm32f4::three_phase`, feature `board-stm32f4-3ph`).
//!
//! Timing, for a drive whose current loop runs every `k`-th PWM period:
//!
//! ```text
//! TIM1 counter   /\    /\    /\    /\    /\    /\        centre aligned, up to ARR and down
//! sample (UEV)   ^                        ^              at the peak, every k periods (here 5)
//! current tick    [ tick n: JEOC ISR ]    [ tick n+1 ]
//! duties          ..tick n-1's..........| tick n's ......  preloaded CCRs: loaded at the next UEV
//! ```
//! At the peak of a centre-aligned PWM mode 1 period every low-side switch conducts, so the
//! low-side shunts carry the phase currents. The update event (UEV) every k periods starts
//! the injected conversions of ADC1 and ADC2 together (TRGO), and loads the duties the
//! previous tick computed: a tick's voltage applies over the next tick, sample to its middle
//! 1.5 ticks, as `[drive.pmsm] angle_advance_ticks` (1.5 by default) assumes.

use controller_core::foc::{AlphaBeta, Svpwm};
use controller_core::per_unit::Pu;

/// A pin: GPIO port letter, number, and its alternate function (0 for analog and GPIO).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Pin {
    /// Port letter, `'A'`..`'C'` on the Nucleo-64.
    pub port: char,
    /// Pin number 0..=15.
    pub number: u8,
    /// Alternate function (AF1: TIM1/TIM2, AF7: USART2).
    pub af: u8,
}

/// An analog input: its pin and its ADC channel (ADC123_INx).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AnalogIn {
    /// The pin, in analog mode.
    pub pin: Pin,
    /// ADC channel number.
    pub channel: u8,
}

/// A three-phase inverter board on its MCU board: every pin the drive uses and every value
/// between a count and a per-unit quantity. One table per board; the registers and the
/// arithmetic read only this.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InverterBoard {
    /// For the boot line.
    pub name: &'static str,
    /// TIM1 CH1, CH2, CH3: the high-side switches of phases U, V, W.
    pub high_side: [Pin; 3],
    /// TIM1 CH1N, CH2N, CH3N: the low-side switches.
    pub low_side: [Pin; 3],
    /// TIM1_BKIN: the overcurrent comparator; asserted, the timer drops all six gates.
    pub break_input: Pin,
    /// Whether the break input is asserted high (false: low). Wrong, the stage never
    /// switches on (the break is always asserted): safe.
    pub break_active_high: bool,
    /// Dead time inserted by TIM1 between a switch's off and its partner's on \[ns\].
    pub dead_time_ns: u32,
    /// Shunt amplifier outputs of phases U, V (ADC1 and ADC2 injected, simultaneous) and
    /// W (ADC2's second conversion, unused by the loop).
    pub phase_current: [AnalogIn; 3],
    /// The DC-bus divider's output (ADC1's second injected conversion).
    pub bus_voltage: AnalogIn,
    /// Encoder A and B (TIM2 CH1, CH2: the board's Hall/encoder connector H1, H2).
    pub encoder: [Pin; 2],
    /// Console TX and RX (USART2: the Nucleo's ST-LINK virtual COM port).
    pub console: [Pin; 2],
    /// Shunt resistance \[Ω\].
    pub shunt_ohm: f64,
    /// Shunt amplifier gain \[V/V\]; its output sits at mid-scale at zero current.
    pub amplifier_gain: f64,
    /// Whether a positive phase current (into the motor) lowers the reading: low-side
    /// shunts see it flowing up from ground while the low-side switch conducts.
    pub current_inverted: bool,
    /// Bus divider, upper and lower resistor \[Ω\].
    pub bus_divider_ohm: [f64; 2],
    /// ADC reference \[V\] and resolution \[bits\].
    pub adc_reference_v: f64,
    /// ADC resolution \[bits\].
    pub adc_bits: u8,
    /// The machine's current base: the amperes of 1 pu (set for your motor).
    pub current_base_a: f64,
    /// The machine's voltage base: the volts of 1 pu, the back-EMF at base speed (set for
    /// your motor; `[drive.pmsm] dc_bus_pu` is the bus in it).
    pub voltage_base_v: f64,
}

const fn pin(port: char, number: u8, af: u8) -> Pin {
    Pin { port, number, af }
}

const fn analog(port: char, number: u8, channel: u8) -> AnalogIn {
    AnalogIn {
        pin: pin(port, number, 0),
        channel,
    }
}

/// ST's X-NUCLEO-IHM08M1 (10–48 V, 15 A rms; STL220N6F7 MOSFETs, L6398 gate drivers,
/// three 10 mΩ low-side shunts with op-amps) on a NUCLEO-F446RE, as ST's board manual
/// (UM1996) and Motor Control SDK describe it: the most common three-shunt STM32 power
/// board in the size of a servo axis, with TIM1's six outputs, a break input from its
/// overcurrent comparator and the shunt amplifiers on pins both ADC1 and ADC2 reach.
///
/// ASSUMPTIONS, to check against your board and motor: the break polarity (active low, the
/// comparator's open-drain output), 500 ns dead time on top of the L6398's own, and the
/// per-unit bases: 5 A and 12 V (a 24 V bus is then `dc_bus_pu = 2`, as
/// `configs/machines/table1-pmsm.toml` has it).
pub const IHM08M1: InverterBoard = InverterBoard {
    name: "X-NUCLEO-IHM08M1 on NUCLEO-F446RE",
    high_side: [pin('A', 8, 1), pin('A', 9, 1), pin('A', 10, 1)],
    low_side: [pin('A', 7, 1), pin('B', 0, 1), pin('B', 1, 1)],
    break_input: pin('A', 6, 1),
    break_active_high: false,
    dead_time_ns: 500,
    phase_current: [analog('A', 0, 0), analog('C', 1, 11), analog('C', 0, 10)],
    bus_voltage: analog('A', 1, 1),
    encoder: [pin('A', 15, 1), pin('B', 3, 1)],
    console: [pin('A', 2, 7), pin('A', 3, 7)],
    shunt_ohm: 0.010,
    amplifier_gain: 5.18,
    current_inverted: true,
    bus_divider_ohm: [169_000.0, 9_310.0],
    adc_reference_v: 3.3,
    adc_bits: 12,
    current_base_a: 5.0,
    voltage_base_v: 12.0,
};

/// What a PMSM drive's current-loop interrupt needs of a three-phase stage.
pub trait PmsmLoopIo {
    /// Raw encoder count \[counts\].
    fn encoder_count(&mut self) -> u32;
    /// Phases U and V's currents of this tick's sample \[pu\]; `None` when no conversion
    /// came (a fault).
    fn phase_currents_pu(&mut self) -> Option<[Pu; 2]>;
    /// The three duties \[timer counts\] for the next tick; false if refused.
    fn set_duties(&mut self, duties: [u16; 3]) -> bool;
    /// Switch the six outputs on or off; false if the stage would not do as asked.
    fn set_enable(&mut self, enabled: bool) -> bool;
    /// True while the stage's own protection (the break input) holds it off.
    fn fault_input(&mut self) -> bool;
}

/// ADC counts to per unit: `pu = (raw − offset)·scale`, the scale a Q16.16 fraction of a
/// per-unit bit per count. Built once (floats); applied per tick in integers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AdcScale {
    /// Per-unit Q16.16 bits per count, ×2^16 (negative for an inverted reading).
    bits_per_count_q16: i64,
}

impl AdcScale {
    /// The scale of `pu_per_count` per unit per count.
    #[must_use]
    pub fn new(pu_per_count: f64) -> Self {
        let x = pu_per_count * 65_536.0 * 65_536.0;
        // To nearest (no `f64::round` without std); `as` saturates a NaN or overflow.
        Self {
            bits_per_count_q16: if x < 0.0 { x - 0.5 } else { x + 0.5 } as i64,
        }
    }

    /// A phase current's scale on `board`.
    #[must_use]
    pub fn current(board: &InverterBoard) -> Self {
        let volts_per_count = board.adc_reference_v / f64::from(1_u32 << board.adc_bits);
        let amps_per_count = volts_per_count / (board.shunt_ohm * board.amplifier_gain);
        let sign = if board.current_inverted { -1.0 } else { 1.0 };
        Self::new(sign * amps_per_count / board.current_base_a)
    }

    /// The bus voltage's scale on `board`.
    #[must_use]
    pub fn bus(board: &InverterBoard) -> Self {
        let volts_per_count = board.adc_reference_v / f64::from(1_u32 << board.adc_bits);
        let [top, bottom] = board.bus_divider_ohm;
        Self::new(volts_per_count * (top + bottom) / bottom / board.voltage_base_v)
    }

    /// `(raw − offset)·scale` in per unit, rounded to the nearest Q16.16 bit, saturating.
    #[inline]
    #[must_use]
    pub fn pu(&self, raw: u16, offset: u16) -> Pu {
        let delta = i64::from(raw) - i64::from(offset);
        let bits = (delta * self.bits_per_count_q16 + (1 << 15)) >> 16;
        Pu::from_bits(i32::try_from(bits).unwrap_or(if bits < 0 { i32::MIN } else { i32::MAX }))
    }
}

/// Phases U and V's currents \[pu\] from the two simultaneous readings and their offsets
/// (the readings at zero current, [`current_offset`]).
#[inline]
#[must_use]
pub fn phase_currents_pu(raw: [u16; 2], offset: [u16; 2], scale: AdcScale) -> [Pu; 2] {
    let [a, b] = raw;
    let [oa, ob] = offset;
    [scale.pu(a, oa), scale.pu(b, ob)]
}

/// The DC-bus voltage \[pu\] from its reading (the divider has no offset).
#[inline]
#[must_use]
pub fn bus_voltage_pu(raw: u16, scale: AdcScale) -> Pu {
    scale.pu(raw, 0)
}

/// The three duties \[timer counts\] of a voltage vector: controller-core's modulator, the
/// one `Controller::pmsm_tick` runs; they go to TIM1's CCR1..CCR3 unchanged.
#[inline]
#[must_use]
pub fn duties_for_voltage(modulator: &Svpwm, v: AlphaBeta) -> [u16; 3] {
    modulator.duties(v)
}

/// How far a zero-current reading may sit from mid-scale (a missing amplifier supply or a
/// current flowing at calibration reads far off) \[counts\]: 5 % of full scale.
pub const OFFSET_TOLERANCE_COUNTS: u16 = 205;

/// A current offset out of its range: the mean reading and the channel (0 = U, 1 = V).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct OffsetError {
    /// Which phase.
    pub phase: usize,
    /// Its mean reading \[counts\].
    pub counts: u16,
}

/// The zero-current reading of a channel: the rounded mean of `sum` over `n` readings taken
/// with the stage off, checked to lie within [`OFFSET_TOLERANCE_COUNTS`] of mid-scale.
///
/// # Errors
/// [`OffsetError`] when the mean is out of that range, or `n` is 0.
pub fn current_offset(phase: usize, sum: u32, n: u32, adc_bits: u8) -> Result<u16, OffsetError> {
    let mean = sum.saturating_add(n / 2).checked_div(n);
    let counts = u16::try_from(mean.unwrap_or(0)).unwrap_or(u16::MAX);
    let mid = 1_u16 << (adc_bits.clamp(1, 16) - 1);
    if mean.is_none() || counts.abs_diff(mid) > OFFSET_TOLERANCE_COUNTS {
        return Err(OffsetError { phase, counts });
    }
    Ok(counts)
}

/// The current loop's period in PWM periods is not a whole number, or too many for TIM1's
/// repetition counter: the numbers of the drive that gave it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TickRatioError {
    /// TIM1's clock \[Hz\].
    pub timer_hz: u32,
    /// `[drive.pmsm] pwm_period_counts`.
    pub period_counts: u16,
    /// `[drive] current_rate_hz`.
    pub current_rate_hz: u32,
}

impl core::fmt::Display for TickRatioError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let pwm_hz = f64::from(self.timer_hz) / (2.0 * f64::from(self.period_counts.max(1)));
        write!(
            f,
            "drive.current_rate_hz = {} is not the PWM rate ({pwm_hz} Hz: TIM1 at {} Hz over \
             2 x drive.pmsm.pwm_period_counts = {}) divided by a whole number 1..={}: the \
             current loop runs on every k-th PWM period",
            self.current_rate_hz, self.timer_hz, self.period_counts, MAX_PERIODS_PER_TICK
        )
    }
}

/// TIM1's clock on this board \[Hz\]: the APB2 timers run at the core clock, 168 MHz
/// (`boards::stm32f4::CORE_CLOCK_HZ`, which the board's start-up checks).
pub const TIM1_CLOCK_HZ: u32 = 168_000_000;

/// Why a drive cannot run on this board.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DriveError {
    /// The drive is not a PMSM's (`[electrics] motor = "pmsm"` gives `[drive.pmsm]`).
    NotPmsm,
    /// The current loop is not a whole number of PWM periods.
    TickRatio(TickRatioError),
}

impl core::fmt::Display for DriveError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::NotPmsm => f.write_str(
                "electrics.motor = \"dc\": the three-phase board drives a PMSM (motor = \"pmsm\", \
                 which gives [drive.pmsm]); a DC motor runs on the STM32F4-Discovery's bridge",
            ),
            Self::TickRatio(e) => write!(f, "{e}"),
        }
    }
}

/// The PWM periods per current tick of the drive `cfg` on this board (TIM1 at
/// [`TIM1_CLOCK_HZ`]): what the build of the three-phase image and the host's `flash`
/// check before anything runs.
///
/// # Errors
/// [`DriveError`]: not a PMSM drive, or its current loop is not a whole number of periods.
pub fn drive_periods_per_tick(cfg: &controller_core::DriveConfig) -> Result<u32, DriveError> {
    let p = cfg.pmsm.ok_or(DriveError::NotPmsm)?;
    periods_per_tick(TIM1_CLOCK_HZ, p.pwm_period_counts, cfg.current_rate_hz)
        .map_err(DriveError::TickRatio)
}

/// The most PWM periods per current tick: TIM1's 8-bit repetition counter counts both
/// halves of a centre-aligned period (`RCR = 2k − 1 ≤ 255`).
pub const MAX_PERIODS_PER_TICK: u32 = 128;

/// PWM periods per current tick, `k = timer_hz / (2·period_counts·current_rate_hz)`.
///
/// # Errors
/// [`TickRatioError`] unless that is a whole number in 1..=[`MAX_PERIODS_PER_TICK`].
pub fn periods_per_tick(
    timer_hz: u32,
    period_counts: u16,
    current_rate_hz: u32,
) -> Result<u32, TickRatioError> {
    let err = TickRatioError {
        timer_hz,
        period_counts,
        current_rate_hz,
    };
    let per_tick = 2 * u64::from(period_counts) * u64::from(current_rate_hz);
    if per_tick == 0 || u64::from(timer_hz) % per_tick != 0 {
        return Err(err);
    }
    match u32::try_from(u64::from(timer_hz) / per_tick) {
        Ok(k) if (1..=MAX_PERIODS_PER_TICK).contains(&k) => Ok(k),
        _ => Err(err),
    }
}

/// TIM1's repetition counter for an update event every `k` centre-aligned periods.
#[must_use]
pub fn repetition_counter(k: u32) -> u8 {
    u8::try_from((2 * k.clamp(1, MAX_PERIODS_PER_TICK)).saturating_sub(1)).unwrap_or(u8::MAX)
}

/// TIM1 BDTR.DTG for at least `ns` of dead time at a `timer_hz` clock (t_DTS = one clock),
/// in RM0090's four ranges: `DTG·t`, `(64 + DTG[5:0])·2t`, `(32 + DTG[4:0])·8t`,
/// `(32 + DTG[4:0])·16t`; the longest (1008 t) if more is asked.
#[must_use]
pub fn dead_time_dtg(ns: u32, timer_hz: u32) -> u8 {
    // Clock periods, rounded up: the dead time is never shorter than asked.
    let ticks = (u64::from(ns) * u64::from(timer_hz)).div_ceil(1_000_000_000);
    let ticks = u32::try_from(ticks).unwrap_or(u32::MAX);
    let code = match ticks {
        0..=127 => ticks,
        128..=254 => 0x80 | (ticks.div_ceil(2) - 64),
        255..=504 => 0xC0 | (ticks.div_ceil(8).max(32) - 32),
        505..=1008 => 0xE0 | (ticks.div_ceil(16).max(32) - 32),
        _ => 0xFF,
    };
    u8::try_from(code).unwrap_or(u8::MAX)
}
