//! Bring-up of the STM32F4-Discovery's peripherals, one function per peripheral: clocks,
//! pins, the TIM1 bridge PWM, ADC1, the TIM3 encoder counter and the USART2 console.
//! Register values follow RM0090; the loop timers and the watchdog start in
//! [`start`](super::start).

use stm32f4::stm32f407 as pac;

use super::{
    set_clocks, wait, AdcCurrent, Board, ClockSource, Clocks, EnablePin, FaultPin, Tim1Pwm,
    Tim3Encoder, Usart2,
};
use crate::board::{CurrentIo, VelocityIo};

/// 168 MHz through the PLL from the 8 MHz crystal: M = 8, N = 336, P = 2 (Q = 7 for 48 MHz
/// USB); AHB /1, APB1 /4 (42 MHz), APB2 /2 (84 MHz); flash 5 wait states with caches.
///
/// The wait for the crystal is bounded, as ST's `HSE_STARTUP_TIMEOUT` bounds it (a million
/// polls of HSERDY: about 0.3 s on the 16 MHz internal oscillator the core starts on, against
/// ST's 100 ms). A board without a crystal, or with one that does not start, gets the same
/// 168 MHz from the internal 16 MHz oscillator (HSI, M = 16). If the PLL does not lock
/// either, the core stays on the internal oscillator at 16 MHz with every bus /1, the reset
/// state, and the clocks returned say so.
///
/// The NUCLEO-F446RE of the three-phase image (`board-stm32f4-3ph`) has no crystal: its
/// 8 MHz comes from the ST-LINK's clock output, so the oscillator is bypassed (HSEBYP).
pub(super) fn clocks(rcc: &pac::RCC, flash: &pac::FLASH) -> Clocks {
    if cfg!(feature = "board-stm32f4-3ph") {
        rmw!(rcc.cr(), 0, 1 << 18); // HSEBYP: an external clock, not a crystal
    }
    rmw!(rcc.cr(), 0, 1 << 16); // HSEON
    let (source, pllm, pllsrc) = if wait(|| rcc.cr().read().bits() & (1 << 17) != 0) {
        (ClockSource::Crystal, 8, 1 << 22) // PLLSRC[22] = HSE
    } else {
        rmw!(rcc.cr(), 1 << 16, 0); // HSEON off: HSERDY never came
        (ClockSource::Internal, 16, 0) // PLLSRC = HSI
    };
    // PLLCFGR: PLLM[5:0], PLLN[14:6] = 336, PLLP[17:16] = 0 (/2), PLLSRC[22], PLLQ[27:24] = 7;
    // the reserved bits keep their reset values.
    rmw!(
        rcc.pllcfgr(),
        0x0F43_7FFF,
        pllm | (336 << 6) | pllsrc | (7 << 24)
    );
    rmw!(rcc.cr(), 0, 1 << 24); // PLLON
    if !wait(|| rcc.cr().read().bits() & (1 << 25) != 0) {
        rmw!(rcc.cr(), 1 << 24, 0); // PLLON off: PLLRDY never came
        return Clocks::HSI;
    }
    // ACR: LATENCY = 5 WS (168 MHz at 3.3 V), PRFTEN, ICEN, DCEN.
    wr!(flash.acr(), 5 | (1 << 8) | (1 << 9) | (1 << 10));
    // CFGR: PPRE1[12:10] = 101 (/4), PPRE2[15:13] = 100 (/2), SW[1:0] = 10 (PLL).
    rmw!(rcc.cfgr(), 0xFCF3, (0b101 << 10) | (0b100 << 13) | 0b10);
    if wait(|| (rcc.cfgr().read().bits() >> 2) & 0b11 == 0b10) {
        Clocks::pll(source)
    } else {
        // The switch did not happen: back to the reset state (HSI, every bus /1).
        rmw!(rcc.cfgr(), 0xFCF3, 0);
        Clocks::HSI
    }
}

/// Set a pin's mode (2 bits), alternate function (4 bits) and pull (2 bits). A macro: the
/// PAC gives GPIOA, GPIOB and GPIOD/E different register-block types.
macro_rules! pin {
    ($gpio:expr, $n:expr, $mode:expr, $af:expr, $pull:expr) => {{
        let (g, n): (_, u32) = (&$gpio, $n);
        rmw!(g.moder(), 0b11 << (2 * n), $mode << (2 * n));
        rmw!(g.pupdr(), 0b11 << (2 * n), $pull << (2 * n));
        if n < 8 {
            rmw!(g.afrl(), 0xF << (4 * n), $af << (4 * n));
        } else {
            rmw!(g.afrh(), 0xF << (4 * (n - 8)), $af << (4 * (n - 8)));
        }
    }};
}

pub(super) const MODE_IN: u32 = 0b00;
pub(super) const MODE_OUT: u32 = 0b01;
pub(super) const MODE_AF: u32 = 0b10;
pub(super) const MODE_ANALOG: u32 = 0b11;
pub(super) const PULL_NONE: u32 = 0b00;
pub(super) const PULL_DOWN: u32 = 0b10;

/// Clocks, pins, PWM, ADC, encoder, console; the power stage stays disabled and the loop
/// timers stopped until [`start`](super::start).
pub fn init(_core: &mut cortex_m::Peripherals, _cfg: &controller_core::DriveConfig) -> Board {
    let Some(dp) = pac::Peripherals::take() else {
        crate::boards::exit(false)
    };
    let clocks = clocks(&dp.RCC, &dp.FLASH);
    set_clocks(clocks);
    if clocks.source != ClockSource::Crystal {
        defmt::error!("fault: clock: {=str}", clocks.source.describe());
    }
    peripheral_clocks(&dp.RCC, &dp.DBGMCU);
    pins(&dp);
    pwm_tim1(&dp.TIM1, &clocks);
    adc1(&dp.ADC_COMMON, &dp.ADC1);
    encoder_tim3(&dp.TIM3);
    console_usart2(&dp.USART2, clocks.apb1_hz);
    Board {
        current_io: CurrentIo {
            pwm: Tim1Pwm {
                arr: clocks.pwm_arr(),
            },
            current: AdcCurrent,
            encoder: Tim3Encoder,
            enable: EnablePin,
        },
        velocity_io: VelocityIo {
            encoder: Tim3Encoder,
            fault: FaultPin,
        },
        console: Usart2,
    }
}

/// Clock the peripherals the drive uses and freeze the watchdog, the loop timers and TIM1
/// while a debugger halts the core.
fn peripheral_clocks(rcc: &pac::RCC, dbgmcu: &pac::DBGMCU) {
    // AHB1ENR: GPIOA, GPIOB, GPIOD, GPIOE. APB1ENR: TIM3, TIM6, TIM7, USART2.
    // APB2ENR: TIM1, ADC1.
    rmw!(rcc.ahb1enr(), 0, 0b1_1011);
    rmw!(rcc.apb1enr(), 0, (1 << 1) | (1 << 4) | (1 << 5) | (1 << 17));
    rmw!(rcc.apb2enr(), 0, 1 | (1 << 8));
    // Debug halt: stop the watchdog and the loop timers, and disable TIM1's outputs.
    dbgmcu.apb1_fz().modify(|_, w| {
        w.dbg_iwdg_stop()
            .set_bit()
            .dbg_tim6_stop()
            .set_bit()
            .dbg_tim7_stop()
            .set_bit()
    });
    dbgmcu.apb2_fz().modify(|_, w| w.dbg_tim1_stop().set_bit());
    // Read back: the first access to a just-clocked peripheral must wait two bus cycles
    // (STM32F40x errata, "delay after an RCC peripheral clock enabling").
    let _ = rcc.apb2enr().read();
    cortex_m::asm::dsb();
}

/// The drive's pins: enable output (driven low first), fault input, TIM1 CH1/CH1N, TIM3
/// CH1/CH2, the current sense input and the console.
fn pins(dp: &pac::Peripherals) {
    // Enable output low first, then the pins.
    wr!(dp.GPIOD.bsrr(), 1 << (12 + 16));
    pin!(dp.GPIOD, 12, MODE_OUT, 0, PULL_NONE);
    pin!(dp.GPIOE, 15, MODE_IN, 0, PULL_DOWN);
    pin!(dp.GPIOE, 8, MODE_AF, 1, PULL_NONE); // TIM1_CH1N
    pin!(dp.GPIOE, 9, MODE_AF, 1, PULL_NONE); // TIM1_CH1
    pin!(dp.GPIOB, 4, MODE_AF, 2, PULL_NONE); // TIM3_CH1
    pin!(dp.GPIOB, 5, MODE_AF, 2, PULL_NONE); // TIM3_CH2
    pin!(dp.GPIOA, 1, MODE_ANALOG, 0, PULL_NONE); // ADC123_IN1
    pin!(dp.GPIOA, 2, MODE_AF, 7, PULL_NONE); // USART2_TX
    pin!(dp.GPIOA, 3, MODE_AF, 7, PULL_NONE); // USART2_RX
}

/// TIM1: the 20 kHz centre-aligned bridge PWM at 0 V, with dead time, and the ADC trigger,
/// for the clocks `c`.
fn pwm_tim1(t1: &pac::TIM1, c: &Clocks) {
    // TIM1: centre-aligned mode 1 (CMS = 01), ARPE; PWM mode 1 with preload on CH1;
    // CH1 + CH1N on; dead time 500 ns (DTG = 84 × 5.95 ns at 168 MHz, 8 × 62.5 ns on the
    // internal oscillator alone); MOE; TRGO = update (MMS = 010).
    let arr = c.pwm_arr();
    let dead_time = (c.apb2_timer_hz / 2_000_000).min(127);
    wr!(t1.psc(), 0);
    wr!(t1.arr(), u32::from(arr));
    wr!(t1.rcr(), 1); // one update per PWM period (at the counter underflow: mid low-side)
    wr!(t1.ccr1(), u32::from(arr / 2)); // 0 V
    wr!(t1.ccmr1_output(), (0b110 << 4) | (1 << 3));
    wr!(t1.ccer(), 1 | (1 << 2));
    wr!(t1.bdtr(), (1 << 15) | dead_time);
    wr!(t1.cr2(), 0b010 << 4);
    wr!(t1.egr(), 1);
    wr!(t1.cr1(), (0b01 << 5) | (1 << 7) | 1);
}

/// ADC1: the current sample, one injected conversion per PWM period.
fn adc1(common: &pac::ADC_COMMON, adc: &pac::ADC1) {
    // ADC1: clock /4 = 21 MHz; IN1 as the single injected conversion (JL = 0 → JSQ4),
    // 56-cycle sampling, triggered on TIM1 TRGO rising (JEXTSEL = 0001, JEXTEN = 01).
    wr!(common.ccr(), 0b01 << 16);
    wr!(adc.smpr2(), 0b011 << 3);
    wr!(adc.jsqr(), 1 << 15);
    wr!(adc.cr2(), 1 | (0b0001 << 16) | (0b01 << 20));
}

/// TIM3: the 16-bit quadrature encoder counter.
fn encoder_tim3(t3: &pac::TIM3) {
    // TIM3: encoder mode 3 (SMS = 011), CC1S = CC2S = 01 (TI1, TI2), input filter 0011.
    wr!(t3.arr(), 0xFFFF);
    wr!(
        t3.ccmr1_input(),
        0b01 | (0b0011 << 4) | (0b01 << 8) | (0b0011 << 12)
    );
    wr!(t3.smcr(), 0b011);
    wr!(t3.cr1(), 1);
}

/// USART2: the console, 115200 Bd from the APB1 clock `apb1_hz`, receive interrupt on.
pub(super) fn console_usart2(usart: &pac::USART2, apb1_hz: u32) {
    // USART2: 115200 Bd (BRR = 42e6/115200 = 364.6 → 22 + 13/16 at 42 MHz; 139 on the
    // internal oscillator alone), TE, RE, RXNEIE, UE.
    let brr = ((apb1_hz + 57_600) / 115_200) as u16;
    wr!(usart.brr(), brr);
    wr!(usart.cr1(), (1 << 13) | (1 << 5) | (1 << 3) | (1 << 2));
}
