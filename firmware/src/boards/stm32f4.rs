//! STM32F4-Discovery (STM32F407VGT6, 8 MHz crystal, run at 168 MHz): the real board.
//! Flash with `cargo fw-flash` (`probe-rs run --chip STM32F407VGTx`, defmt over RTT).
//!
//! Register values follow RM0090 (STM32F405/407 reference manual); the PAC (`stm32f4`)
//! gives the typed register blocks, the interrupt numbers and the vector table.
//!
//! | drive signal    | STM32F407 resource                                              |
//! |-----------------|-----------------------------------------------------------------|
//! | PWM duty        | TIM1 CH1 PE9 / CH1N PE8 (AF1), 20 kHz centre-aligned, 500 ns dead time |
//! | current sample  | ADC1 IN1 PA1, injected conversion triggered by TIM1 TRGO (update) |
//! | encoder counter | TIM3 encoder mode, CH1 PB4 / CH2 PB5 (AF2), 16 bits            |
//! | fault input     | PE15, pull-down, high = fault                                   |
//! | enable output   | PD12 (the green LED), high = power stage enabled                |
//! | 4 kHz tick      | TIM6 update, IRQ 54, priority 0x20 (higher)                     |
//! | 2 kHz tick      | TIM7 update, IRQ 55, priority 0x40                              |
//! | console         | USART2 TX PA2 / RX PA3 (AF7), 115200 Bd, RX IRQ 38, priority 0x80 |
//! | watchdog        | IWDG, ≈ 5 ms (LSI 32 kHz / 4, reload 40), refreshed by every current tick |
//!
//! The current scaling assumes a shunt amplifier centred at mid-scale with ±2 pu at the ADC
//! rails (1024 LSB per pu); set [`ADC_LSB_PER_PU`] and [`ADC_OFFSET`] for the real stage.

use core::convert::Infallible;
use core::sync::atomic::{AtomicU8, Ordering};

use controller_core::per_unit::Pu;
use cortex_m::peripheral::NVIC;
use stm32f4::stm32f407::{self as pac, Interrupt};

use crate::board::{CurrentIo, CurrentSense, EncoderCounter, VelocityIo};

/// Core clock [Hz] with the PLL locked (from the crystal or, without one, the internal
/// oscillator); [`Clocks::now`] gives the clock the board runs at.
pub const CORE_CLOCK_HZ: u32 = 168_000_000;
/// Board name for logs.
pub const NAME: &str = "stm32f4-discovery";
/// Bridge PWM frequency [Hz] (TIM1, centre aligned).
const PWM_HZ: u32 = 20_000;

/// Where the core clock comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, defmt::Format)]
pub enum ClockSource {
    /// The 8 MHz crystal (HSE) through the PLL.
    Crystal,
    /// No crystal answered: the internal 16 MHz RC oscillator (HSI) through the PLL.
    Internal,
    /// Neither the crystal nor the PLL answered: the internal oscillator alone, 16 MHz on
    /// every bus (QEMU's STM32F405 machine, which models no clock controller, boots here).
    InternalWithoutPll,
}

impl ClockSource {
    /// For the boot line on the console.
    pub const fn describe(self) -> &'static str {
        match self {
            Self::Crystal => "crystal (HSE 8 MHz) through the PLL, 168 MHz",
            Self::Internal => {
                "internal oscillator (HSI 16 MHz) through the PLL, 168 MHz: no crystal"
            }
            Self::InternalWithoutPll => {
                "internal oscillator (HSI 16 MHz) without the PLL: no crystal, PLL not locked"
            }
        }
    }
}

/// The bus and timer clocks `init` set up [Hz].
#[derive(Clone, Copy, Debug, PartialEq, Eq, defmt::Format)]
pub struct Clocks {
    /// Where they come from.
    pub source: ClockSource,
    /// Core clock (AHB).
    pub sysclk_hz: u32,
    /// APB1 peripheral clock (USART2).
    pub apb1_hz: u32,
    /// APB1 timer clock (TIM3, TIM6, TIM7): ×2 when APB1 is divided.
    pub apb1_timer_hz: u32,
    /// APB2 timer clock (TIM1).
    pub apb2_timer_hz: u32,
}

impl Clocks {
    /// 168 MHz through the PLL: AHB /1, APB1 /4 (42 MHz, timers 84 MHz), APB2 /2 (timers
    /// 168 MHz).
    pub const fn pll(source: ClockSource) -> Self {
        Self {
            source,
            sysclk_hz: CORE_CLOCK_HZ,
            apb1_hz: 42_000_000,
            apb1_timer_hz: 84_000_000,
            apb2_timer_hz: CORE_CLOCK_HZ,
        }
    }

    /// The internal oscillator alone: 16 MHz, every bus /1 (the reset state).
    pub const HSI: Self = Self {
        source: ClockSource::InternalWithoutPll,
        sysclk_hz: 16_000_000,
        apb1_hz: 16_000_000,
        apb1_timer_hz: 16_000_000,
        apb2_timer_hz: 16_000_000,
    };

    /// TIM1 auto-reload for [`PWM_HZ`] centre aligned: f = timer clock / (2·ARR) (4200 at
    /// 168 MHz).
    pub const fn pwm_arr(&self) -> u16 {
        let arr = self.apb2_timer_hz / (2 * PWM_HZ);
        if arr > u16::MAX as u32 {
            u16::MAX
        } else {
            arr as u16
        }
    }

    /// The clocks `init` set up (the reset state's before it ran).
    pub fn now() -> Self {
        match CLOCK_SOURCE.load(Ordering::Relaxed) {
            1 => Self::pll(ClockSource::Crystal),
            2 => Self::pll(ClockSource::Internal),
            _ => Self::HSI,
        }
    }
}

/// [`Clocks::now`]'s source, set once by `init`: 0 the internal oscillator alone, 1 the
/// crystal, 2 the internal oscillator through the PLL.
static CLOCK_SOURCE: AtomicU8 = AtomicU8::new(0);

fn set_clocks(c: Clocks) {
    let code = match c.source {
        ClockSource::InternalWithoutPll => 0,
        ClockSource::Crystal => 1,
        ClockSource::Internal => 2,
    };
    CLOCK_SOURCE.store(code, Ordering::Relaxed);
}

/// ADC counts at zero current.
pub const ADC_OFFSET: i32 = 2048;
/// ADC counts per pu of current.
pub const ADC_LSB_PER_PU: i32 = 1024;

/// NVIC priority of the current loop (lower number = more urgent).
pub const PRIO_CURRENT: u8 = 0x20;
/// NVIC priority of the velocity loop.
pub const PRIO_VELOCITY: u8 = 0x40;
/// NVIC priority of the console receive interrupt.
pub const PRIO_UART: u8 = 0x80;

/// The current-loop I/O of this board.
pub type CurrentIoImpl = CurrentIo<Tim1Pwm, AdcCurrent, Tim3Encoder, EnablePin>;
/// The velocity-loop I/O of this board.
pub type VelocityIoImpl = VelocityIo<Tim3Encoder, FaultPin>;
/// Text console for trace dumps.
pub type Console = Usart2;
/// The encoder counter type.
pub type Encoder = Tim3Encoder;

/// A read-only handle on the encoder counter (for thread mode and the setpoint logic).
pub const fn encoder() -> Encoder {
    Tim3Encoder
}

/// Raw 32-bit register write through the PAC.
macro_rules! wr {
    ($reg:expr, $value:expr) => {
        // SAFETY: the value is a documented RM0090 setting for this register (see the
        // comment at each use); no reserved bit is set.
        #[allow(unsafe_code)]
        unsafe {
            $reg.write(|w| w.bits($value))
        }
    };
}

/// Raw read-modify-write: clear `clear`, then set `set`.
macro_rules! rmw {
    ($reg:expr, $clear:expr, $set:expr) => {
        // SAFETY: as for `wr!`: only the named, documented bits change.
        #[allow(unsafe_code)]
        unsafe {
            $reg.modify(|r, w| w.bits((r.bits() & !($clear)) | ($set)))
        }
    };
}

/// Bounded wait for a hardware flag: false on timeout.
fn wait(mut ready: impl FnMut() -> bool) -> bool {
    for _ in 0..1_000_000 {
        if ready() {
            return true;
        }
    }
    false
}

mod setup;
pub use setup::init;

/// `fn $name() -> &'static pac::$block::RegisterBlock`, the registers of `pac::$periph`.
/// Each call carries a `SAFETY:` line: why a shared `'static` reference to that block is
/// sound (who writes which registers after `init`).
macro_rules! register_block {
    ($name:ident: $periph:ident => $block:ident) => {
        fn $name() -> &'static pac::$block::RegisterBlock {
            // SAFETY: the `SAFETY:` line above the macro call.
            #[allow(unsafe_code)]
            unsafe {
                &*pac::$periph::ptr()
            }
        }
    };
}

mod flash;
#[cfg(feature = "board-stm32f4-3ph")]
pub mod three_phase;
pub use flash::{
    read_settings_sector, write_settings_sector, SETTINGS_SECTOR, SETTINGS_SECTOR_LEN,
};

// SAFETY: TIM1 is configured once in `init`; afterwards the current loop's `Tim1Pwm`
// writes CCR1 and only `emergency_stop` (fault handlers) writes BDTR: a shared reference
// to the MMIO block is sound (vcell).
register_block!(tim1: TIM1 => tim1);
// SAFETY: after `init`, TIM3 (encoder) is only read (CNT).
register_block!(tim3: TIM3 => tim3);
// SAFETY: after `init`, ADC1 is touched only by the current loop's `AdcCurrent`.
register_block!(adc1: ADC1 => adc1);
// SAFETY: USART2 TX is used by thread mode only, RX by its interrupt only; SR/DR reads and
// DR writes do not race on shared bits.
register_block!(usart2: USART2 => usart1);
// SAFETY: after `init`, GPIOD is written only through BSRR (atomic set/reset).
register_block!(gpiod: GPIOD => gpioi);
// SAFETY: after `init`, GPIOE is only read (IDR).
register_block!(gpioe: GPIOE => gpioi);
// SAFETY: the watchdog is started in `start` and afterwards only refreshed (KR writes) by
// the current loop, and reloaded with a longer timeout by a settings save (thread mode,
// loop timers stopped).
register_block!(iwdg: IWDG => iwdg);
// SAFETY: after `init`, TIM6 SR is cleared only by its own interrupt.
register_block!(tim6: TIM6 => tim6);
// SAFETY: after `init`, TIM7 SR is cleared only by its own interrupt.
register_block!(tim7: TIM7 => tim6);

/// TIM1 channel 1 (complementary) as the bridge PWM; `arr` is its auto-reload, full duty.
pub struct Tim1Pwm {
    arr: u16,
}

impl embedded_hal::pwm::ErrorType for Tim1Pwm {
    type Error = Infallible;
}

impl embedded_hal::pwm::SetDutyCycle for Tim1Pwm {
    fn max_duty_cycle(&self) -> u16 {
        self.arr
    }

    fn set_duty_cycle(&mut self, duty: u16) -> Result<(), Infallible> {
        // Preloaded (OC1PE): takes effect at the next update, glitch free.
        wr!(tim1().ccr1(), u32::from(duty.min(self.arr)));
        Ok(())
    }
}

/// ADC1 injected channel (IN1), converted at each TIM1 update.
pub struct AdcCurrent;

/// The ADC produced no conversion since the last read (trigger or ADC dead).
#[derive(Debug, Clone, Copy)]
pub struct NoConversion;

impl CurrentSense for AdcCurrent {
    type Error = NoConversion;

    fn sample_current(&mut self) -> Result<Pu, NoConversion> {
        let adc = adc1();
        // SR.JEOC (bit 2): an injected conversion completed since we last cleared it.
        if adc.sr().read().bits() & (1 << 2) == 0 {
            return Err(NoConversion);
        }
        let raw = (adc.jdr1().read().bits() & 0x0FFF) as i32;
        wr!(adc.sr(), !(1_u32 << 2) & 0x3F); // rc_w0: clear JEOC only
                                             // pu = (raw − offset)/LSB_PER_PU, as Q16.16 bits: ×65536/1024 = ×64.
        Ok(Pu::from_bits(
            (raw - ADC_OFFSET) * (65_536 / ADC_LSB_PER_PU),
        ))
    }
}

/// TIM3 in encoder mode (16-bit counter).
#[derive(Clone, Copy)]
pub struct Tim3Encoder;

impl EncoderCounter for Tim3Encoder {
    const COUNTER_BITS: u8 = 16;
    fn count(&mut self) -> u32 {
        tim3().cnt().read().bits() & 0xFFFF
    }
}

/// PD12: power-stage enable (green LED).
pub struct EnablePin;

impl embedded_hal::digital::ErrorType for EnablePin {
    type Error = Infallible;
}

impl embedded_hal::digital::OutputPin for EnablePin {
    fn set_low(&mut self) -> Result<(), Infallible> {
        wr!(gpiod().bsrr(), 1 << (12 + 16));
        Ok(())
    }
    fn set_high(&mut self) -> Result<(), Infallible> {
        wr!(gpiod().bsrr(), 1 << 12);
        Ok(())
    }
}

/// PE15: external fault input (high = fault).
pub struct FaultPin;

impl embedded_hal::digital::ErrorType for FaultPin {
    type Error = Infallible;
}

impl embedded_hal::digital::InputPin for FaultPin {
    fn is_high(&mut self) -> Result<bool, Infallible> {
        Ok(gpioe().idr().read().bits() & (1 << 15) != 0)
    }
    fn is_low(&mut self) -> Result<bool, Infallible> {
        Ok(gpioe().idr().read().bits() & (1 << 15) == 0)
    }
}

/// USART2 console (the board console's frames, the boot line).
#[derive(Clone, Copy)]
pub struct Usart2;

impl Usart2 {
    /// Send bytes, waiting while the transmit register is full.
    pub fn write_bytes(self, bytes: &[u8]) {
        let u = usart2();
        for &b in bytes {
            // SR.TXE (bit 7): data register empty.
            while u.sr().read().bits() & (1 << 7) == 0 {}
            wr!(u.dr(), u16::from(b));
        }
    }
}

impl core::fmt::Write for Usart2 {
    fn write_str(&mut self, s: &str) -> core::fmt::Result {
        self.write_bytes(s.as_bytes());
        Ok(())
    }
}

/// The board console's hardware on this board: USART2, flash sector 11, TIM6/TIM7.
#[derive(Debug, Default)]
pub struct BoardConsole;

impl crate::board::ConsoleBoard for BoardConsole {
    const PORT: &'static str = "USART2";

    fn send(&mut self, bytes: &[u8]) {
        Usart2.write_bytes(bytes);
    }

    fn read_settings(&mut self, record: &mut [u8; pil_link::board::store::RECORD_LEN]) {
        read_settings_sector(record);
    }

    fn write_settings(
        &mut self,
        record: &[u8; pil_link::board::store::RECORD_LEN],
    ) -> Result<(), pil_link::board::store::SaveError> {
        write_settings_sector(record)
    }

    fn set_loop_rates(&mut self, current_hz: u32, velocity_hz: u32) {
        set_loop_rates(current_hz, velocity_hz);
    }

    /// The boot line on USART2 (defmt goes over RTT, which needs a probe): what the board
    /// runs, on which clock, and where its settings come from.
    fn booted(&mut self, note: &str) {
        use core::fmt::Write as _;
        let _ = write!(
            Usart2,
            "stiffdrive firmware {} on {}: drive {}; clock: {}; settings: {}; board console on \
             USART2 (board protocol {})\r\n",
            env!("CARGO_PKG_VERSION"),
            NAME,
            crate::drive::NAME,
            Clocks::now().source.describe(),
            note,
            pil_link::board::BOARD_VERSION
        );
    }
}

/// The board's drive I/O, split per interrupt, and its console.
pub struct Board {
    /// Owned by the current-loop interrupt.
    pub current_io: CurrentIoImpl,
    /// Owned by the velocity-loop interrupt.
    pub velocity_io: VelocityIoImpl,
    /// Dump output.
    pub console: Console,
}

/// Configure TIM6/TIM7 for the loop rates (stopped; started by the caller).
fn configure_loop_timers(current_rate_hz: u32, velocity_rate_hz: u32) {
    for (tim, rate) in [(tim6(), current_rate_hz), (tim7(), velocity_rate_hz)] {
        wr!(tim.cr1(), 0);
        wr!(tim.psc(), 0);
        wr!(
            tim.arr(),
            (Clocks::now().apb1_timer_hz / rate.max(1)).saturating_sub(1)
        );
        wr!(tim.egr(), 1); // load ARR
        wr!(tim.sr(), 0);
        wr!(tim.dier(), 1); // UIE
    }
}

/// Runs the loop timers at new rates, restarted together (TIM6 first, as in [`start`]).
pub fn set_loop_rates(current_rate_hz: u32, velocity_rate_hz: u32) {
    configure_loop_timers(current_rate_hz, velocity_rate_hz);
    wr!(tim6().cr1(), 1);
    wr!(tim7().cr1(), 1);
}

/// Configure TIM6/TIM7 for the loop rates, set priorities, unmask, start (TIM6 first, so
/// at every shared instant the current loop's update comes first).
pub fn start(nvic: &mut NVIC, current_rate_hz: u32, velocity_rate_hz: u32) {
    configure_loop_timers(current_rate_hz, velocity_rate_hz);
    wr!(iwdg().kr(), 0xCCCC); // start the watchdog
    set_watchdog(WATCHDOG_DRIVE);
    // SAFETY: priorities are set before unmasking; the handlers share data only through
    // `critical_section::Mutex` cells, atomics and `TaskLocal`s.
    #[allow(unsafe_code)]
    unsafe {
        nvic.set_priority(Interrupt::TIM6_DAC, PRIO_CURRENT);
        nvic.set_priority(Interrupt::TIM7, PRIO_VELOCITY);
        nvic.set_priority(Interrupt::USART2, PRIO_UART);
        NVIC::unmask(Interrupt::TIM6_DAC);
        NVIC::unmask(Interrupt::TIM7);
        NVIC::unmask(Interrupt::USART2);
    }
    wr!(tim6().cr1(), 1);
    wr!(tim7().cr1(), 1);
}

/// Power stage off from a fault handler: gate-driver enable (PD12) low, TIM1 main output
/// off (BDTR.MOE = 0: both bridge outputs to their idle state), loop timers stopped.
/// Plain register writes, callable from any context.
pub fn emergency_stop() {
    wr!(gpiod().bsrr(), 1 << (12 + 16));
    rmw!(tim1().bdtr(), 1 << 15, 0);
    stop();
}

/// Stop the loop timers and switch the power stage off.
pub fn stop() {
    wr!(tim6().cr1(), 0);
    wr!(tim7().cr1(), 0);
    wr!(gpiod().bsrr(), 1 << (12 + 16));
}

/// A watchdog timeout: prescaler code (PR: 0 = /4 … 6 = /256) and reload (RLR).
#[derive(Clone, Copy, Debug)]
pub struct Watchdog {
    prescaler: u16,
    reload: u16,
}

/// Independent watchdog while the loops run: if the current loop stops refreshing it for
/// ≈ 5 ms (nominal LSI 32 kHz / 4, reload 40; the LSI may run 17–47 kHz, so 3.4–9.4 ms),
/// the MCU resets and the PWM pins fall back to their reset state (inputs: the gate
/// driver's pulls hold the bridge off). It stops while a debugger halts the core.
pub const WATCHDOG_DRIVE: Watchdog = Watchdog {
    prescaler: 0,
    reload: 40,
};
/// While a settings save erases flash (the core stalls up to 2 s): /256, reload 4095,
/// 22 s at the LSI's fastest 47 kHz.
pub const WATCHDOG_SAVE: Watchdog = Watchdog {
    prescaler: 6,
    reload: 4095,
};

/// Loads a watchdog timeout (the watchdog runs on if started) and refreshes it.
pub fn set_watchdog(t: Watchdog) {
    let w = iwdg();
    wr!(w.kr(), 0x5555); // unlock PR and RLR
    wr!(w.pr(), t.prescaler);
    wr!(w.rlr(), t.reload);
    // SR.PVU / SR.RVU: wait until the new values reached the LSI domain.
    let _ = wait(|| w.sr().read().bits() & 0b11 == 0);
    wr!(w.kr(), 0xAAAA); // refresh
}

/// Acknowledge the current-loop timer interrupt and refresh the watchdog.
pub fn ack_current() {
    wr!(tim6().sr(), 0);
    wr!(iwdg().kr(), 0xAAAA);
}

/// Acknowledge the velocity-loop timer interrupt.
pub fn ack_velocity() {
    wr!(tim7().sr(), 0);
}

/// A command byte from the console, if one arrived (SR.RXNE, bit 5).
pub fn read_command() -> Option<u8> {
    let u = usart2();
    if u.sr().read().bits() & (1 << 5) != 0 {
        Some((u.dr().read().bits() & 0xFF) as u8)
    } else {
        None
    }
}

/// Bind the board's interrupt lines to the tick functions of a binary:
/// `bind_interrupts!(current: path, velocity: path, command: path);`
#[macro_export]
macro_rules! bind_interrupts {
    (current: $current:path, velocity: $velocity:path, command: $command:path $(,)?) => {
        #[allow(unsafe_code, non_snake_case, missing_docs)]
        #[no_mangle]
        extern "C" fn TIM6_DAC() {
            $crate::boards::stm32f4::ack_current();
            $current();
        }
        #[allow(unsafe_code, non_snake_case, missing_docs)]
        #[no_mangle]
        extern "C" fn TIM7() {
            $crate::boards::stm32f4::ack_velocity();
            $velocity();
        }
        #[allow(unsafe_code, non_snake_case, missing_docs)]
        #[no_mangle]
        extern "C" fn USART2() {
            $command();
        }
    };
}
