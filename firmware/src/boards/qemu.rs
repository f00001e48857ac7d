//! QEMU's mps2-an386 (Cortex-M4F, 25 MHz): the board CI runs.
//!
//! Addresses and interrupt lines as QEMU's `hw/arm/mps2.c` wires them for the AN385/AN386
//! images: CMSDK APB TIMER0 at 0x4000_0000 (IRQ 8) and TIMER1 at 0x4000_1000 (IRQ 9), both
//! clocked at SYSCLK = 25 MHz; CMSDK UART0 at 0x4000_4000 (RX IRQ 0, TX IRQ 1); the FPGA
//! I/O block at 0x4002_8000 (LED0 register at +0x0, BUTTON register at +0x8, which QEMU
//! reads as 0). The machine has no PWM, ADC or encoder: the power stage and motor are the
//! [`crate::virtual_motor::VirtualMotor`] behind the PWM, current and encoder handles here,
//! or for a PMSM drive the three-phase stage of [`inverter`] (the baked file's PMSM).
//!
//! | drive signal    | QEMU resource                         |
//! |-----------------|---------------------------------------|
//! | 4 kHz tick      | TIMER0, IRQ 8, priority 0x20 (higher) |
//! | 2 kHz tick      | TIMER1, IRQ 9, priority 0x40          |
//! | dump request    | UART0 RX, IRQ 0, priority 0x80        |
//! | trace dump text | UART0 TX (polled, thread mode)        |
//! | enable output   | FPGAIO LED0 bit 0                     |
//! | fault input     | FPGAIO BUTTON bit 0                   |

use core::convert::Infallible;
use core::sync::atomic::{AtomicI32, AtomicU32, Ordering};

use controller_core::per_unit::Pu;
use cortex_m::peripheral::NVIC;

use pil_link::board::store::{SaveError, RECORD_LEN};

use crate::board::{CurrentIo, CurrentSense, EncoderCounter, VelocityIo};
use crate::virtual_motor::{VirtualMotor, VirtualMotorConfig};

pub mod inverter;

/// Core clock and APB timer clock [Hz].
pub const SYSCLK_HZ: u32 = 25_000_000;
/// Core clock [Hz] (SysTick counts it).
pub const CORE_CLOCK_HZ: u32 = SYSCLK_HZ;
/// Board name for logs.
pub const NAME: &str = "qemu-mps2-an386";

const TIMER0_BASE: usize = 0x4000_0000;
const TIMER1_BASE: usize = 0x4000_1000;
const UART0_BASE: usize = 0x4000_4000;
const FPGAIO_BASE: usize = 0x4002_8000;

// CMSDK APB timer registers (ARM DDI0479C): CTRL bit0 enable, bit3 interrupt enable;
// RELOAD also loads VALUE; INTSTATUS bit0 is write-one-to-clear.
const TIMER_CTRL: usize = 0x0;
const TIMER_RELOAD: usize = 0x8;
const TIMER_INTCLEAR: usize = 0xC;
const TIMER_CTRL_EN: u32 = 1 << 0;
const TIMER_CTRL_IRQEN: u32 = 1 << 3;

// CMSDK APB UART registers: STATE bit0 TX full, bit1 RX full; CTRL bit0 TX enable,
// bit1 RX enable, bit3 RX interrupt enable; INTCLEAR bit1 RX.
const UART_DATA: usize = 0x0;
const UART_STATE: usize = 0x4;
const UART_CTRL: usize = 0x8;
const UART_INTCLEAR: usize = 0xC;
const UART_BAUDDIV: usize = 0x10;
const UART_STATE_TXFULL: u32 = 1 << 0;
const UART_STATE_RXFULL: u32 = 1 << 1;
const UART_CTRL_TXEN: u32 = 1 << 0;
const UART_CTRL_RXEN: u32 = 1 << 1;
const UART_CTRL_RXIRQEN: u32 = 1 << 3;
const UART_INT_RX: u32 = 1 << 1;

const FPGAIO_LED0: usize = 0x0;
const FPGAIO_BUTTON: usize = 0x8;

/// NVIC priority of the current loop (lower number = more urgent: it preempts the rest).
pub const PRIO_CURRENT: u8 = 0x20;
/// NVIC priority of the velocity loop.
pub const PRIO_VELOCITY: u8 = 0x40;
/// NVIC priority of the UART dump-request interrupt.
pub const PRIO_UART: u8 = 0x80;

fn read(addr: usize) -> u32 {
    // SAFETY: every caller passes one of the fixed, aligned device register addresses above,
    // which QEMU maps for this machine; a volatile read has no other effect.
    #[allow(unsafe_code)]
    unsafe {
        core::ptr::read_volatile(addr as *const u32)
    }
}

fn write(addr: usize, value: u32) {
    // SAFETY: as in `read`: a fixed device register of this machine, written volatile.
    #[allow(unsafe_code)]
    unsafe {
        core::ptr::write_volatile(addr as *mut u32, value);
    }
}

/// The mps2-an386 device interrupts this firmware uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u16)]
pub enum Irq {
    /// UART0 receive.
    Uart0Rx = 0,
    /// CMSDK TIMER0: the current loop.
    Timer0 = 8,
    /// CMSDK TIMER1: the velocity loop.
    Timer1 = 9,
}

// SAFETY: the numbers are the device interrupt lines QEMU's mps2.c wires (see module docs),
// all below the 32 vectors of `__INTERRUPTS`.
#[allow(unsafe_code)]
unsafe impl cortex_m::interrupt::InterruptNumber for Irq {
    fn number(self) -> u16 {
        self as u16
    }
}

/// Signature of an interrupt vector.
pub type Vector = unsafe extern "C" fn();

extern "C" {
    fn DefaultHandler();
    fn TIMER0();
    fn TIMER1();
    fn UART0RX();
}

/// The device part of the vector table: 32 lines, the three used ones bound to the symbols
/// `TIMER0`, `TIMER1`, `UART0RX` (see `device.x`: they default to `DefaultHandler`; a binary
/// overrides them with [`crate::bind_interrupts!`]).
#[allow(unsafe_code)]
#[link_section = ".vector_table.interrupts"]
#[no_mangle]
#[used]
pub static __INTERRUPTS: [Vector; 32] = {
    const D: Vector = DefaultHandler;
    [
        UART0RX, D, D, D, D, D, D, D, // 0: UART0 RX
        TIMER0, TIMER1, D, D, D, D, D, D, // 8: TIMER0, 9: TIMER1
        D, D, D, D, D, D, D, D, //
        D, D, D, D, D, D, D, D, //
    ]
};

/// A CMSDK APB timer as a periodic interrupt source.
#[derive(Clone, Copy, Debug)]
pub struct PeriodicTimer {
    base: usize,
}

impl PeriodicTimer {
    /// TIMER0 (current loop).
    pub const TIMER0: Self = Self { base: TIMER0_BASE };
    /// TIMER1 (velocity loop).
    pub const TIMER1: Self = Self { base: TIMER1_BASE };

    /// Start interrupting at `rate_hz` (the counter reloads every SYSCLK/rate − 1 + 1 clocks:
    /// QEMU's model holds 0 for one clock before reloading).
    pub fn start(self, rate_hz: u32) {
        let reload = (SYSCLK_HZ / rate_hz.max(1)).saturating_sub(1);
        write(self.base + TIMER_CTRL, 0);
        write(self.base + TIMER_RELOAD, reload);
        write(self.base + TIMER_INTCLEAR, 1);
        write(self.base + TIMER_CTRL, TIMER_CTRL_EN | TIMER_CTRL_IRQEN);
    }

    /// Stop the timer and its interrupt.
    pub fn stop(self) {
        write(self.base + TIMER_CTRL, 0);
        write(self.base + TIMER_INTCLEAR, 1);
    }

    /// Acknowledge the interrupt (first thing in the handler).
    pub fn clear_interrupt(self) {
        write(self.base + TIMER_INTCLEAR, 1);
    }
}

/// UART0: dump text out (polled), one-byte commands in (RX interrupt).
#[derive(Clone, Copy, Debug)]
pub struct Uart0;

impl Uart0 {
    /// 115200 Bd at 25 MHz (QEMU ignores the rate but needs BAUDDIV ≥ 16 to transmit).
    pub fn init(self) {
        write(UART0_BASE + UART_BAUDDIV, SYSCLK_HZ / 115_200);
        write(
            UART0_BASE + UART_CTRL,
            UART_CTRL_TXEN | UART_CTRL_RXEN | UART_CTRL_RXIRQEN,
        );
    }

    /// Send bytes, waiting while the transmit buffer is full.
    pub fn write_bytes(self, bytes: &[u8]) {
        for &b in bytes {
            while read(UART0_BASE + UART_STATE) & UART_STATE_TXFULL != 0 {}
            write(UART0_BASE + UART_DATA, u32::from(b));
        }
    }

    /// A received byte, if any (clears the RX interrupt).
    pub fn read_byte(self) -> Option<u8> {
        write(UART0_BASE + UART_INTCLEAR, UART_INT_RX);
        if read(UART0_BASE + UART_STATE) & UART_STATE_RXFULL != 0 {
            Some((read(UART0_BASE + UART_DATA) & 0xFF) as u8)
        } else {
            None
        }
    }
}

impl core::fmt::Write for Uart0 {
    fn write_str(&mut self, s: &str) -> core::fmt::Result {
        self.write_bytes(s.as_bytes());
        Ok(())
    }
}

/// Power-stage enable output: FPGAIO LED0 bit 0 (an LED on the real MPS2 board).
#[derive(Debug)]
pub struct EnableLed;

impl embedded_hal::digital::ErrorType for EnableLed {
    type Error = Infallible;
}

impl embedded_hal::digital::OutputPin for EnableLed {
    fn set_low(&mut self) -> Result<(), Infallible> {
        write(
            FPGAIO_BASE + FPGAIO_LED0,
            read(FPGAIO_BASE + FPGAIO_LED0) & !1,
        );
        Ok(())
    }

    fn set_high(&mut self) -> Result<(), Infallible> {
        write(
            FPGAIO_BASE + FPGAIO_LED0,
            read(FPGAIO_BASE + FPGAIO_LED0) | 1,
        );
        Ok(())
    }
}

/// External fault input: FPGAIO BUTTON bit 0 (a push button on the real board; QEMU
/// does not model the buttons and reads 0, i.e. no fault).
#[derive(Debug)]
pub struct FaultButton;

impl embedded_hal::digital::ErrorType for FaultButton {
    type Error = Infallible;
}

impl embedded_hal::digital::InputPin for FaultButton {
    fn is_high(&mut self) -> Result<bool, Infallible> {
        Ok(read(FPGAIO_BASE + FPGAIO_BUTTON) & 1 != 0)
    }

    fn is_low(&mut self) -> Result<bool, Infallible> {
        Ok(read(FPGAIO_BASE + FPGAIO_BUTTON) & 1 == 0)
    }
}

/// Set the priorities of the three interrupts and unmask them.
pub fn enable_interrupts(nvic: &mut NVIC) {
    // SAFETY: priorities are set before the lines are unmasked, and the handlers only share
    // data through `critical_section::Mutex` cells and atomics, so a change of priority
    // cannot break a priority-based critical section.
    #[allow(unsafe_code)]
    unsafe {
        nvic.set_priority(Irq::Timer0, PRIO_CURRENT);
        nvic.set_priority(Irq::Timer1, PRIO_VELOCITY);
        nvic.set_priority(Irq::Uart0Rx, PRIO_UART);
        NVIC::unmask(Irq::Timer0);
        NVIC::unmask(Irq::Timer1);
        NVIC::unmask(Irq::Uart0Rx);
    }
}

/// The current-loop I/O of this board.
pub type CurrentIoImpl = CurrentIo<VirtualPwm, VirtualCurrent, VirtualEncoder, EnableLed>;
/// The velocity-loop I/O of this board.
pub type VelocityIoImpl = VelocityIo<VirtualEncoder, FaultButton>;
/// Text console for trace dumps.
pub type Console = Uart0;
/// The encoder counter type (its `COUNTER_BITS` must match the drive settings).
pub type Encoder = VirtualEncoder;

/// A read-only handle on the encoder counter (for thread mode and the setpoint logic).
pub const fn encoder() -> Encoder {
    VirtualEncoder
}

/// Latest virtual-motor current, raw Q16.16 bits (published by the PWM, read by the ADC).
static MOTOR_CURRENT_BITS: AtomicI32 = AtomicI32::new(0);
/// Latest virtual encoder count.
static MOTOR_COUNTS: AtomicU32 = AtomicU32::new(0);

/// PWM period in timer clocks at 20 kHz: the duty resolution of the virtual bridge.
const PWM_MAX_DUTY: u16 = (SYSCLK_HZ / 20_000) as u16;

/// The virtual bridge: each duty written is held for one current-loop period, during which
/// the virtual motor integrates (with 0 V while the enable output, FPGAIO LED0, is low).
pub struct VirtualPwm {
    motor: VirtualMotor,
}

impl VirtualPwm {
    /// The virtual machine behind the bridge (thread mode, under the loops' critical
    /// section): another machine, the rig's load torque, the rig's brake.
    pub fn motor_mut(&mut self) -> &mut VirtualMotor {
        &mut self.motor
    }

    /// The rig's brake ([`VirtualMotor::stop`]), the current and encoder the next tick
    /// samples published at once (not only after the next step).
    pub fn brake(&mut self) {
        self.motor.stop();
        MOTOR_CURRENT_BITS.store(pu_bits(self.motor.current_pu()), Ordering::Relaxed);
        MOTOR_COUNTS.store(self.motor.counts(), Ordering::Relaxed);
    }
}

impl embedded_hal::pwm::ErrorType for VirtualPwm {
    type Error = Infallible;
}

impl embedded_hal::pwm::SetDutyCycle for VirtualPwm {
    fn max_duty_cycle(&self) -> u16 {
        PWM_MAX_DUTY
    }

    fn set_duty_cycle(&mut self, duty: u16) -> Result<(), Infallible> {
        let enabled = read(FPGAIO_BASE + FPGAIO_LED0) & 1 != 0;
        // Bipolar bridge: duty/max = (1 + v)/2.
        let voltage_pu = if enabled {
            2.0 * f32::from(duty) / f32::from(PWM_MAX_DUTY) - 1.0
        } else {
            0.0
        };
        self.motor.step(voltage_pu);
        MOTOR_CURRENT_BITS.store(pu_bits(self.motor.current_pu()), Ordering::Relaxed);
        MOTOR_COUNTS.store(self.motor.counts(), Ordering::Relaxed);
        Ok(())
    }
}

/// `x` as raw Q16.16 bits, saturated at the range ends, 0 for NaN (a diverged model): what
/// `Pu::saturating_from_num` gives for every other value, without its panic on NaN (this
/// runs in the current-loop interrupt).
fn pu_bits(x: f32) -> i32 {
    match Pu::checked_from_num(x) {
        Some(v) => v.to_bits(),
        None if x > 0.0 => i32::MAX,
        None if x < 0.0 => i32::MIN,
        None => 0,
    }
}

/// The virtual motor's position [counts, 32-bit]: what the shaft did, for run checks.
pub fn motor_counts() -> u32 {
    MOTOR_COUNTS.load(Ordering::Relaxed)
}

/// The virtual current ADC: reads the virtual motor's winding current.
pub struct VirtualCurrent;

impl CurrentSense for VirtualCurrent {
    type Error = Infallible;
    fn sample_current(&mut self) -> Result<Pu, Infallible> {
        Ok(Pu::from_bits(MOTOR_CURRENT_BITS.load(Ordering::Relaxed)))
    }
}

/// The virtual encoder counter (16 bits wide, like a 16-bit timer in encoder mode).
#[derive(Clone, Copy)]
pub struct VirtualEncoder;

impl EncoderCounter for VirtualEncoder {
    const COUNTER_BITS: u8 = 16;
    fn count(&mut self) -> u32 {
        MOTOR_COUNTS.load(Ordering::Relaxed) & 0xFFFF
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

/// The virtual motor for a drive ([`VirtualMotorConfig::for_drive`]).
pub fn virtual_motor_config(cfg: &controller_core::DriveConfig) -> VirtualMotorConfig {
    VirtualMotorConfig::for_drive(cfg)
}

/// Bring the board up for a drive (UART, outputs off, virtual motor at rest); timers and
/// interrupts start later with [`start`].
pub fn init(_core: &mut cortex_m::Peripherals, cfg: &controller_core::DriveConfig) -> Board {
    let motor = virtual_motor_config(cfg);
    Uart0.init();
    let mut enable = EnableLed;
    let _ = embedded_hal::digital::OutputPin::set_low(&mut enable);
    Board {
        current_io: CurrentIo {
            pwm: VirtualPwm {
                motor: VirtualMotor::new(motor),
            },
            current: VirtualCurrent,
            encoder: VirtualEncoder,
            enable,
        },
        velocity_io: VelocityIo {
            encoder: VirtualEncoder,
            fault: FaultButton,
        },
        console: Uart0,
    }
}

/// Start the loop timers and unmask their interrupts (current loop preempts velocity loop).
pub fn start(nvic: &mut NVIC, current_rate_hz: u32, velocity_rate_hz: u32) {
    enable_interrupts(nvic);
    // Start both at once so their ticks stay aligned: every velocity tick coincides with a
    // current tick, and the higher-priority current tick runs first.
    PeriodicTimer::TIMER1.start(velocity_rate_hz);
    PeriodicTimer::TIMER0.start(current_rate_hz);
}

/// Power stage off from a fault handler: enable output (LED0) low, loop timers stopped.
/// Plain register writes, callable from any context.
pub fn emergency_stop() {
    write(FPGAIO_BASE + FPGAIO_LED0, 0);
    stop();
}

/// Stop the loop timers.
pub fn stop() {
    PeriodicTimer::TIMER0.stop();
    PeriodicTimer::TIMER1.stop();
}

/// The board console's settings sector: the last 4 KiB of the SRAM, outside every section
/// of the image (root `memory.x`, region `SETTINGS`; `link/check-qemu.x` holds the two to
/// the same address). QEMU's system reset reloads the image's segments but leaves other RAM
/// as it was, so a record written here is read back after `SCB::sys_reset`; a cold start
/// finds it zeroed.
pub const SETTINGS_SECTOR: usize = 0x203F_F000;
/// Bytes of the settings sector.
pub const SETTINGS_SECTOR_LEN: usize = 4096;

/// Reads the start of the settings sector into `buf` (at most its length).
pub fn read_settings_sector(buf: &mut [u8]) {
    for (i, b) in buf.iter_mut().take(SETTINGS_SECTOR_LEN).enumerate() {
        // SAFETY: inside the 4 KiB SETTINGS region of memory.x, which is RAM on this machine
        // and no Rust object occupies; a volatile byte read has no other effect.
        #[allow(unsafe_code)]
        unsafe {
            *b = core::ptr::read_volatile((SETTINGS_SECTOR + i) as *const u8);
        }
    }
}

/// Writes `record` at the start of the settings sector and reads it back.
///
/// # Errors
/// [`SaveError::Verify`] with the first byte that did not read back.
pub fn write_settings_sector(record: &[u8; RECORD_LEN]) -> Result<(), SaveError> {
    for (i, &b) in record.iter().enumerate() {
        // SAFETY: as in `read_settings_sector`: a byte of the SETTINGS region (the record
        // fits in it, asserted below), written volatile.
        #[allow(unsafe_code)]
        unsafe {
            core::ptr::write_volatile((SETTINGS_SECTOR + i) as *mut u8, b);
        }
    }
    let mut back = [0_u8; RECORD_LEN];
    read_settings_sector(&mut back);
    match record.iter().zip(back).position(|(w, r)| *w != r) {
        Some(i) => Err(SaveError::Verify {
            offset: u32::try_from(i).unwrap_or(u32::MAX),
        }),
        None => Ok(()),
    }
}

const _: () = assert!(RECORD_LEN <= SETTINGS_SECTOR_LEN);

/// The board console's hardware on this board: UART0, the SRAM settings sector, TIMER0/1.
#[derive(Debug, Default)]
pub struct BoardConsole;

impl crate::board::ConsoleBoard for BoardConsole {
    const PORT: &'static str = "UART0";

    fn send(&mut self, bytes: &[u8]) {
        Uart0.write_bytes(bytes);
    }

    fn read_settings(&mut self, record: &mut [u8; RECORD_LEN]) {
        read_settings_sector(record);
    }

    fn write_settings(&mut self, record: &[u8; RECORD_LEN]) -> Result<(), SaveError> {
        write_settings_sector(record)
    }

    fn set_loop_rates(&mut self, current_hz: u32, velocity_hz: u32) {
        // Both at once, as `start` does, so their ticks stay aligned.
        PeriodicTimer::TIMER1.start(velocity_hz);
        PeriodicTimer::TIMER0.start(current_hz);
    }
}

/// A command byte from the console, if one arrived.
pub fn read_command() -> Option<u8> {
    Uart0.read_byte()
}

/// Bind the board's interrupt lines to the tick functions of a binary:
/// `bind_interrupts!(current: path, velocity: path, command: path);`
/// Each handler acknowledges its peripheral, then calls the function.
#[macro_export]
macro_rules! bind_interrupts {
    (current: $current:path, velocity: $velocity:path, command: $command:path $(,)?) => {
        #[allow(unsafe_code, non_snake_case, missing_docs)]
        #[no_mangle]
        extern "C" fn TIMER0() {
            $crate::boards::qemu::PeriodicTimer::TIMER0.clear_interrupt();
            $current();
        }
        #[allow(unsafe_code, non_snake_case, missing_docs)]
        #[no_mangle]
        extern "C" fn TIMER1() {
            $crate::boards::qemu::PeriodicTimer::TIMER1.clear_interrupt();
            $velocity();
        }
        #[allow(unsafe_code, non_snake_case, missing_docs)]
        #[no_mangle]
        extern "C" fn UART0RX() {
            $command();
        }
    };
}
