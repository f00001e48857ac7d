//! The three-phase power stage on the STM32F4 (feature `board-stm32f4-3ph`): the registers
//! behind [`crate::board::three_phase`]'s table ([`IHM08M1`]) and arithmetic. Values follow
//! RM0090 (the F446's RM0390 has the same TIM1, ADC, GPIO and RCC bits for everything set
//! here, at the same addresses, so the `stm32f407` PAC's register blocks serve).
//!
//! | what             | resource                                                        |
//! |------------------|-----------------------------------------------------------------|
//! | PWM              | TIM1 CH1–CH3 + CH1N–CH3N, centre aligned, PWM mode 1, CCRs preloaded, `ARR = [drive.pmsm] pwm_period_counts` (4200: 20 kHz) |
//! | dead time, break | BDTR.DTG from the table; BKIN (the stage's overcurrent comparator) drops MOE; MOE off → all six outputs low (OSSI) |
//! | sampling         | TIM1 update every k periods at the counter's peak (RCR = 2k − 1) → TRGO → ADC1 + ADC2 injected, simultaneous |
//! | conversions      | ADC1: I_U then V_bus; ADC2: I_V then I_W; 15 cycles at 21 MHz each |
//! | current loop     | ADC interrupt (IRQ 18) on ADC1's JEOC, priority 0x20             |
//! | velocity loop    | TIM7's vector pended by the current loop every current/velocity-th tick, priority 0x40 (TIM7 itself does not run) |
//! | encoder          | TIM2 CH1/CH2 in encoder mode, wrapping at 16 bits                |
//! | console, watchdog| USART2 (the ST-LINK's virtual COM port), IWDG refreshed by the current loop |

use controller_core::per_unit::Pu;
use controller_core::DriveConfig;
use cortex_m::peripheral::NVIC;
use stm32f4::stm32f407::{self as pac, Interrupt};

use super::setup::{console_usart2, MODE_AF, MODE_ANALOG, PULL_NONE};
use super::{
    iwdg, set_clocks, set_watchdog, tim1, wait, ClockSource, Usart2, PRIO_CURRENT, PRIO_UART,
    PRIO_VELOCITY, WATCHDOG_DRIVE,
};
use crate::board::three_phase::{
    current_offset, dead_time_dtg, periods_per_tick, phase_currents_pu, repetition_counter,
    AdcScale, OffsetError, Pin, PmsmLoopIo, TickRatioError, IHM08M1,
};
use crate::board::EncoderCounter;

// The clock the host's checks assume for TIM1 (`three_phase::TIM1_CLOCK_HZ`) is the one
// `init` requires.
const _: () = assert!(crate::board::three_phase::TIM1_CLOCK_HZ == super::CORE_CLOCK_HZ);

// SAFETY: after `init`, ADC1's SR (JEOC) and JDRs are touched only by the current loop.
register_block!(adc1: ADC1 => adc1);
// SAFETY: after `init`, ADC2's SR and JDRs are touched only by the current loop.
register_block!(adc2: ADC2 => adc1);
// SAFETY: after `init`, TIM2 (encoder) is only read (CNT).
register_block!(tim2: TIM2 => tim2);

/// Readings at zero current averaged for each offset (64 ticks: 16 ms at 4 kHz).
const OFFSET_SAMPLES: u32 = 64;

/// Why the three-phase stage did not come up; the stage stays off.
#[derive(Clone, Copy, Debug)]
pub enum InitError {
    /// The drive has no `[drive.pmsm]`.
    NotPmsm,
    /// The clock is not the 168 MHz the PWM period is counted in.
    Clock(ClockSource),
    /// The current loop is not a whole number of PWM periods.
    TickRatio(TickRatioError),
    /// A current offset out of range (the amplifier, or a current flowing at start).
    Offset(OffsetError),
    /// No conversion came while measuring the offsets.
    NoConversion,
}

/// The stage's I/O, owned by the current-loop interrupt.
pub struct ThreePhaseIo {
    offsets: [u16; 2],
    scale: AdcScale,
    arr: u16,
}

/// TIM2 as the encoder counter, 16 bits.
#[derive(Clone, Copy)]
pub struct Tim2Encoder;

impl EncoderCounter for Tim2Encoder {
    const COUNTER_BITS: u8 = 16;
    fn count(&mut self) -> u32 {
        tim2().cnt().read().bits() & 0xFFFF
    }
}

/// What `init` set up.
pub struct ThreePhaseBoard {
    /// The current loop's I/O.
    pub io: ThreePhaseIo,
    /// PWM periods per current tick.
    pub periods_per_tick: u32,
    /// The zero-current readings of phases U and V \[counts\].
    pub offsets: [u16; 2],
    /// The console.
    pub console: Usart2,
}

/// TIM1's break flag (SR.BIF): the overcurrent comparator tripped since the last reset.
fn break_latched() -> bool {
    tim1().sr().read().bits() & (1 << 7) != 0
}

/// Clear the break flag (the operator's reset); it sets again while BKIN is asserted.
pub fn clear_break() {
    wr!(tim1().sr(), !(1_u32 << 7) & 0x1FFF);
}

impl PmsmLoopIo for ThreePhaseIo {
    fn encoder_count(&mut self) -> u32 {
        Tim2Encoder.count()
    }

    fn phase_currents_pu(&mut self) -> Option<[Pu; 2]> {
        let (a1, a2) = (adc1(), adc2());
        // SR.JEOC (bit 2): this trigger's injected sequence completed.
        if a1.sr().read().bits() & (1 << 2) == 0 {
            return None;
        }
        let raw = [a1.jdr1().read().bits(), a2.jdr1().read().bits()].map(|r| (r & 0x0FFF) as u16);
        Some(phase_currents_pu(raw, self.offsets, self.scale))
    }

    fn set_duties(&mut self, duties: [u16; 3]) -> bool {
        let t = tim1();
        // Preloaded: they take effect at the next update, the next tick's sample instant.
        let [a, b, c] = duties.map(|d| u32::from(d.min(self.arr)));
        wr!(t.ccr1(), a);
        wr!(t.ccr2(), b);
        wr!(t.ccr3(), c);
        true
    }

    fn set_enable(&mut self, enabled: bool) -> bool {
        // Never switch on over a latched break: the comparator's trip stands until reset.
        let on = enabled && !break_latched();
        rmw!(tim1().bdtr(), 1 << 15, if on { 1 << 15 } else { 0 });
        on == enabled
    }

    fn fault_input(&mut self) -> bool {
        break_latched()
    }
}

/// Set one table pin's mode and alternate function.
fn pin(dp: &pac::Peripherals, p: Pin, mode: u32) {
    macro_rules! set {
        ($g:expr) => {{
            let (g, n) = (&$g, u32::from(p.number));
            rmw!(g.moder(), 0b11 << (2 * n), mode << (2 * n));
            rmw!(g.pupdr(), 0b11 << (2 * n), PULL_NONE << (2 * n));
            let af = u32::from(p.af);
            if n < 8 {
                rmw!(g.afrl(), 0xF << (4 * n), af << (4 * n));
            } else {
                rmw!(g.afrh(), 0xF << (4 * (n - 8)), af << (4 * (n - 8)));
            }
        }};
    }
    match p.port {
        'A' => set!(dp.GPIOA),
        'B' => set!(dp.GPIOB),
        _ => set!(dp.GPIOC),
    }
}

/// Clocks, pins, TIM1, the ADCs, the encoder and the console; the offsets measured with the
/// stage off. The stage stays off (MOE = 0) and the loop interrupts masked until [`start`].
///
/// # Errors
/// [`InitError`]: the drive or the clock does not fit the stage, or an offset is off.
pub fn init(cfg: &DriveConfig) -> Result<ThreePhaseBoard, InitError> {
    let Some(dp) = pac::Peripherals::take() else {
        crate::boards::exit(false)
    };
    let clocks = super::setup::clocks(&dp.RCC, &dp.FLASH);
    set_clocks(clocks);
    console_usart2(&dp.USART2, clocks.apb1_hz);
    let pmsm = cfg.pmsm.ok_or(InitError::NotPmsm)?;
    if clocks.sysclk_hz != super::CORE_CLOCK_HZ {
        return Err(InitError::Clock(clocks.source));
    }
    let k = periods_per_tick(
        clocks.apb2_timer_hz,
        pmsm.pwm_period_counts,
        cfg.current_rate_hz,
    )
    .map_err(InitError::TickRatio)?;
    // AHB1ENR: GPIOA, B, C. APB1ENR: TIM2, USART2. APB2ENR: TIM1, ADC1, ADC2.
    rmw!(dp.RCC.ahb1enr(), 0, 0b111);
    rmw!(dp.RCC.apb1enr(), 0, 1 | (1 << 17));
    rmw!(dp.RCC.apb2enr(), 0, 1 | (1 << 8) | (1 << 9));
    dp.DBGMCU
        .apb1_fz()
        .modify(|_, w| w.dbg_iwdg_stop().set_bit());
    dp.DBGMCU
        .apb2_fz()
        .modify(|_, w| w.dbg_tim1_stop().set_bit());
    let _ = dp.RCC.apb2enr().read();
    cortex_m::asm::dsb();
    let b = IHM08M1;
    for p in b
        .high_side
        .iter()
        .chain(&b.low_side)
        .chain(&[b.break_input])
    {
        pin(&dp, *p, MODE_AF);
    }
    for a in b.phase_current.iter().chain(&[b.bus_voltage]) {
        pin(&dp, a.pin, MODE_ANALOG);
    }
    for p in b.encoder.iter().chain(&b.console) {
        pin(&dp, *p, MODE_AF);
    }
    pwm(&dp.TIM1, pmsm.pwm_period_counts, k, clocks.apb2_timer_hz);
    adcs(&dp.ADC_COMMON, &dp.ADC1, &dp.ADC2);
    encoder(&dp.TIM2);
    let offsets = measure_offsets()?;
    Ok(ThreePhaseBoard {
        io: ThreePhaseIo {
            offsets,
            scale: AdcScale::current(&b),
            arr: pmsm.pwm_period_counts,
        },
        periods_per_tick: k,
        offsets,
        console: Usart2,
    })
}

/// TIM1: three complementary pairs, centre aligned, all at half duty, outputs off; an
/// update (and TRGO) at every k-th counter peak.
fn pwm(t1: &pac::TIM1, arr: u16, k: u32, timer_hz: u32) {
    let b = IHM08M1;
    wr!(t1.psc(), 0);
    wr!(t1.arr(), u32::from(arr));
    for ccr in [t1.ccr1(), t1.ccr2(), t1.ccr3()] {
        wr!(ccr, u32::from(arr / 2));
    }
    // CH1..CH3: PWM mode 1 (OCxM = 110: high side on while CNT < CCR), preload (OCxPE).
    let pwm1 = (0b110 << 4) | (1 << 3);
    wr!(t1.ccmr1_output(), pwm1 | (pwm1 << 8));
    wr!(t1.ccmr2_output(), pwm1);
    // CCxE and CCxNE of the three channels, active high (the L6398's HIN and LIN).
    wr!(t1.ccer(), 0b0101_0101_0101);
    // BDTR: dead time; break enabled (BKE) with the table's polarity (BKP); OSSI: with
    // MOE = 0 every output at its idle level, low (OISx = 0): all six switches off.
    let bkp = if b.break_active_high { 1 << 13 } else { 0 };
    let dtg = u32::from(dead_time_dtg(b.dead_time_ns, timer_hz));
    wr!(t1.bdtr(), (1 << 12) | bkp | (1 << 10) | dtg);
    // TRGO = update (MMS = 010).
    wr!(t1.cr2(), 0b010 << 4);
    // The repetition counter runs on both the peaks and the valleys. With RCR = 0 when UG
    // reloads it, the first event (the first peak) updates and reloads 2k − 1: every
    // update then falls on every k-th peak, where all low-side switches conduct.
    wr!(t1.rcr(), 0);
    wr!(t1.egr(), 1);
    wr!(t1.rcr(), u32::from(repetition_counter(k)));
    wr!(t1.sr(), 0);
    // Centre-aligned mode 1 (CMS = 01), ARPE, CEN.
    wr!(t1.cr1(), (0b01 << 5) | (1 << 7) | 1);
}

/// ADC1 and ADC2 in injected simultaneous mode, two conversions each on TIM1's TRGO.
fn adcs(common: &pac::ADC_COMMON, a1: &pac::ADC1, a2: &pac::ADC2) {
    let b = IHM08M1;
    let [u, v, w] = b.phase_current.map(|a| u32::from(a.channel));
    let bus = u32::from(b.bus_voltage.channel);
    // CCR: ADCPRE = /4 (84 MHz APB2 → 21 MHz), MULTI = 00101 (injected simultaneous).
    wr!(common.ccr(), (0b01 << 16) | 0b00101);
    // 15-cycle sampling (001) on every channel used: SMPR2 holds 0..=9, SMPR1 10..=18.
    let smp = |ch: u32| -> (u32, u32) {
        if ch < 10 {
            (0, 1 << (3 * ch))
        } else {
            (1 << (3 * (ch - 10)), 0)
        }
    };
    let (s1a, s2a) = [u, bus].iter().fold((0, 0), |(x, y), &c| {
        let (p, q) = smp(c);
        (x | p, y | q)
    });
    let (s1b, s2b) = [v, w].iter().fold((0, 0), |(x, y), &c| {
        let (p, q) = smp(c);
        (x | p, y | q)
    });
    wr!(a1.smpr1(), s1a);
    wr!(a1.smpr2(), s2a);
    wr!(a2.smpr1(), s1b);
    wr!(a2.smpr2(), s2b);
    // JSQR: JL = 01 (two conversions: JSQ3 then JSQ4, results in JDR1 then JDR2).
    wr!(a1.jsqr(), (0b01 << 20) | (u << 10) | (bus << 15));
    wr!(a2.jsqr(), (0b01 << 20) | (v << 10) | (w << 15));
    // CR1: SCAN. CR2: ADON; the master (ADC1) triggers both on TIM1 TRGO rising
    // (JEXTSEL = 0001, JEXTEN = 01); the slave's own trigger stays off.
    wr!(a1.cr1(), 1 << 8);
    wr!(a2.cr1(), 1 << 8);
    wr!(a2.cr2(), 1);
    wr!(a1.cr2(), 1 | (0b0001 << 16) | (0b01 << 20));
}

/// TIM2: the quadrature encoder, wrapping at 16 bits.
fn encoder(t2: &pac::TIM2) {
    wr!(t2.arr(), 0xFFFF);
    wr!(
        t2.ccmr1_input(),
        0b01 | (0b0011 << 4) | (0b01 << 8) | (0b0011 << 12)
    );
    wr!(t2.smcr(), 0b011);
    wr!(t2.cr1(), 1);
}

/// The zero-current readings of phases U and V, the stage off (polled, before the ADC
/// interrupt is unmasked).
fn measure_offsets() -> Result<[u16; 2], InitError> {
    let (a1, a2) = (adc1(), adc2());
    let mut sums = [0_u32; 2];
    for _ in 0..OFFSET_SAMPLES {
        wr!(a1.sr(), 0);
        wr!(a2.sr(), 0);
        if !wait(|| a1.sr().read().bits() & (1 << 2) != 0) {
            return Err(InitError::NoConversion);
        }
        sums[0] += a1.jdr1().read().bits() & 0x0FFF;
        sums[1] += a2.jdr1().read().bits() & 0x0FFF;
    }
    let bits = IHM08M1.adc_bits;
    let u = current_offset(0, sums[0], OFFSET_SAMPLES, bits).map_err(InitError::Offset)?;
    let v = current_offset(1, sums[1], OFFSET_SAMPLES, bits).map_err(InitError::Offset)?;
    Ok([u, v])
}

/// Start the watchdog, set the priorities and unmask the loop interrupts: the current loop
/// on ADC1's JEOC, the velocity loop on TIM7's vector (pended by the current loop).
pub fn start(nvic: &mut NVIC) {
    wr!(iwdg().kr(), 0xCCCC);
    set_watchdog(WATCHDOG_DRIVE);
    wr!(adc1().sr(), 0);
    wr!(adc2().sr(), 0);
    rmw!(adc1().cr1(), 0, 1 << 7); // JEOCIE
                                   // SAFETY: priorities are set before unmasking; the handlers share data only through
                                   // critical sections and atomics.
    #[allow(unsafe_code)]
    unsafe {
        nvic.set_priority(Interrupt::ADC, PRIO_CURRENT);
        nvic.set_priority(Interrupt::TIM7, PRIO_VELOCITY);
        nvic.set_priority(Interrupt::USART2, PRIO_UART);
        NVIC::unmask(Interrupt::ADC);
        NVIC::unmask(Interrupt::TIM7);
        NVIC::unmask(Interrupt::USART2);
    }
}

/// Acknowledge the current-loop interrupt (ADC1's and ADC2's JEOC, after the loop read
/// them) and refresh the watchdog.
pub fn ack_current() {
    wr!(adc1().sr(), !(1_u32 << 2) & 0x3F);
    wr!(adc2().sr(), !(1_u32 << 2) & 0x3F);
    wr!(iwdg().kr(), 0xAAAA);
}

/// Run the velocity loop after this current tick (TIM7's vector, lower priority).
pub fn pend_velocity() {
    NVIC::pend(Interrupt::TIM7);
}

/// Bind the three-phase image's interrupts:
/// `bind_three_phase_interrupts!(current: path, velocity: path, command: path);` the
/// current loop on the ADC vector (ADC1's JEOC), the velocity loop on TIM7's.
#[macro_export]
macro_rules! bind_three_phase_interrupts {
    (current: $current:path, velocity: $velocity:path, command: $command:path $(,)?) => {
        #[allow(unsafe_code, non_snake_case, missing_docs)]
        #[no_mangle]
        extern "C" fn ADC() {
            $current();
            $crate::boards::stm32f4::three_phase::ack_current();
        }
        #[allow(unsafe_code, non_snake_case, missing_docs)]
        #[no_mangle]
        extern "C" fn TIM7() {
            $velocity();
        }
        #[allow(unsafe_code, non_snake_case, missing_docs)]
        #[no_mangle]
        extern "C" fn USART2() {
            $command();
        }
    };
}
