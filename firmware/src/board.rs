//! The board layer: the five pieces of drive hardware the control path touches, each behind
//! a trait, so the same tick code runs on the QEMU board, the STM32F4 board, the benchmark's
//! synthetic sensors and the loop-in-the-loop replay.
//!
//! | signal            | trait                                     | unit            |
//! |-------------------|-------------------------------------------|-----------------|
//! | PWM duty          | `embedded_hal::pwm::SetDutyCycle`         | 0..=max_duty    |
//! | enable output     | `embedded_hal::digital::OutputPin`        | high = enabled  |
//! | fault input       | `embedded_hal::digital::InputPin`         | high = fault    |
//! | current samples   | [`CurrentSense`] (embedded-hal 1 has no ADC trait) | pu     |
//! | encoder counter   | [`EncoderCounter`] (no QEI trait either)  | raw counts      |
//!
//! A read error on a sensor is a fault: the tick reports it and the power stage is disabled.
//! The voltage command maps to the duty of a bipolar bridge: 0 pu → 50 %, ±1 pu → 100 %/0 %.
//! A three-phase stage (`board-stm32f4-3ph`) has its table and arithmetic in [`three_phase`].

pub mod three_phase;

use controller_core::per_unit::Pu;
use embedded_hal::digital::{InputPin, OutputPin};
use embedded_hal::pwm::SetDutyCycle;
use pil_link::board::store::{SaveError, RECORD_LEN};

/// A phase-current measurement, already scaled to per unit by the board (ADC counts ×
/// the shunt/amplifier gain, offset removed).
pub trait CurrentSense {
    /// The board's error type.
    type Error: core::fmt::Debug;
    /// The current sampled for this PWM period \[pu\].
    ///
    /// # Errors
    /// A conversion that did not complete or overran.
    fn sample_current(&mut self) -> Result<Pu, Self::Error>;
}

/// A quadrature encoder counter.
pub trait EncoderCounter {
    /// Width of the hardware counter in bits (16 or 32); the core differences wrap-safely.
    const COUNTER_BITS: u8;
    /// The raw counter value [counts, wraps at `COUNTER_BITS`].
    fn count(&mut self) -> u32;
}

/// What a current-loop interrupt needs: sample the current and the encoder, drive the PWM.
pub trait CurrentLoopIo {
    /// Raw encoder count \[counts\].
    fn encoder_count(&mut self) -> u32;
    /// Measured current \[pu\]; `None` on a sensor error (treated as a fault).
    fn current_pu(&mut self) -> Option<Pu>;
    /// Apply the voltage command \[pu\] to the PWM; returns false if the PWM refused it.
    fn set_voltage_pu(&mut self, voltage_pu: Pu) -> bool;
    /// Switch the power stage on or off; returns false if the output refused it.
    fn set_enable(&mut self, enabled: bool) -> bool;
}

/// What a velocity-loop interrupt needs: the encoder and the external fault input.
pub trait VelocityLoopIo {
    /// Raw encoder count \[counts\].
    fn encoder_count(&mut self) -> u32;
    /// True while the external fault input is active (or unreadable: fail safe).
    fn fault_input(&mut self) -> bool;
}

/// What a board gives the board console besides its drive I/O: the serial port, the
/// settings sector and the loop timers. The board layer defines it and each board
/// implements it; the console (`board_console`, the app layer) only calls it, so the
/// dependency runs one way.
pub trait ConsoleBoard {
    /// The serial port's name, for the boot log (`UART0`, `USART2`).
    const PORT: &'static str;
    /// Sends `bytes` on the console's serial port, waiting while it is busy.
    fn send(&mut self, bytes: &[u8]);
    /// Reads the start of the settings sector into `record`.
    fn read_settings(&mut self, record: &mut [u8; RECORD_LEN]);
    /// Writes `record` at the start of the settings sector and reads it back.
    ///
    /// # Errors
    /// Why the sector does not hold the record.
    fn write_settings(&mut self, record: &[u8; RECORD_LEN]) -> Result<(), SaveError>;
    /// Runs the loop timers at new rates \[Hz\], both restarted together.
    fn set_loop_rates(&mut self, current_hz: u32, velocity_hz: u32);
    /// Called once the board is set up, with the boot's word on the settings it runs
    /// (`note`), before the loops start: a board whose log cannot be read over its serial
    /// port says it there.
    fn booted(&mut self, _note: &str) {}
}

/// Duty for a voltage command on a bipolar bridge: `max·(1 + v)/2`, `v` clamped to ±1 pu.
/// Pure integer arithmetic on the Q16.16 bits, so it is exact and cannot overflow.
///
/// ```
/// use controller_core::per_unit::Pu;
/// use firmware::board::duty_for_voltage;
/// assert_eq!(duty_for_voltage(Pu::ZERO, 1000), 500);
/// assert_eq!(duty_for_voltage(Pu::from_num(1), 1000), 1000);
/// assert_eq!(duty_for_voltage(Pu::from_num(-3), 1000), 0);
/// ```
#[must_use]
pub fn duty_for_voltage(voltage_pu: Pu, max_duty: u16) -> u16 {
    let one = Pu::ONE.to_bits();
    let v = voltage_pu.to_bits().clamp(-one, one);
    // (v + one) ∈ [0, 2·one]; times max ≤ 2^17·2^16 = 2^33: use u64.
    let num = u64::from((v + one).unsigned_abs()) * u64::from(max_duty);
    let duty = num / (2 * u64::from(one.unsigned_abs()));
    u16::try_from(duty).unwrap_or(max_duty)
}

/// The current-loop half of one axis's drive hardware, generic over the embedded-hal PWM
/// channel and enable pin and the board's current and encoder readers. It is owned by the
/// current-loop interrupt.
pub struct CurrentIo<P, C, E, N> {
    /// PWM channel of the bridge.
    pub pwm: P,
    /// Current measurement.
    pub current: C,
    /// Encoder counter (a read-only handle; the velocity half holds another).
    pub encoder: E,
    /// Power-stage enable output (high = enabled).
    pub enable: N,
}

impl<P, C, E, N> CurrentLoopIo for CurrentIo<P, C, E, N>
where
    P: SetDutyCycle,
    C: CurrentSense,
    E: EncoderCounter,
    N: OutputPin,
{
    fn encoder_count(&mut self) -> u32 {
        self.encoder.count()
    }

    fn current_pu(&mut self) -> Option<Pu> {
        self.current.sample_current().ok()
    }

    fn set_voltage_pu(&mut self, voltage_pu: Pu) -> bool {
        let duty = duty_for_voltage(voltage_pu, self.pwm.max_duty_cycle());
        self.pwm.set_duty_cycle(duty).is_ok()
    }

    fn set_enable(&mut self, enabled: bool) -> bool {
        if enabled {
            self.enable.set_high().is_ok()
        } else {
            self.enable.set_low().is_ok()
        }
    }
}

/// The velocity-loop half: an encoder handle and the external fault input (high = fault).
/// It is owned by the velocity-loop interrupt.
pub struct VelocityIo<E, F> {
    /// Encoder counter (read-only handle).
    pub encoder: E,
    /// External fault input (high = fault).
    pub fault: F,
}

impl<E, F> VelocityLoopIo for VelocityIo<E, F>
where
    E: EncoderCounter,
    F: InputPin,
{
    fn encoder_count(&mut self) -> u32 {
        self.encoder.count()
    }

    fn fault_input(&mut self) -> bool {
        // An unreadable fault input counts as a fault.
        self.fault.is_high().unwrap_or(true)
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use embedded_hal::digital::{ErrorKind, ErrorType};

    /// A pin or PWM that can be told to fail.
    #[derive(Default)]
    struct Fake {
        level: bool,
        fail: bool,
        duty: u16,
    }

    #[derive(Debug)]
    struct FakeError;

    impl embedded_hal::digital::Error for FakeError {
        fn kind(&self) -> ErrorKind {
            ErrorKind::Other
        }
    }

    impl embedded_hal::pwm::Error for FakeError {
        fn kind(&self) -> embedded_hal::pwm::ErrorKind {
            embedded_hal::pwm::ErrorKind::Other
        }
    }

    impl ErrorType for Fake {
        type Error = FakeError;
    }

    impl embedded_hal::pwm::ErrorType for Fake {
        type Error = FakeError;
    }

    impl InputPin for Fake {
        fn is_high(&mut self) -> Result<bool, FakeError> {
            if self.fail {
                Err(FakeError)
            } else {
                Ok(self.level)
            }
        }
        fn is_low(&mut self) -> Result<bool, FakeError> {
            self.is_high().map(|h| !h)
        }
    }

    impl OutputPin for Fake {
        fn set_low(&mut self) -> Result<(), FakeError> {
            self.level = false;
            if self.fail {
                Err(FakeError)
            } else {
                Ok(())
            }
        }
        fn set_high(&mut self) -> Result<(), FakeError> {
            self.level = true;
            if self.fail {
                Err(FakeError)
            } else {
                Ok(())
            }
        }
    }

    impl SetDutyCycle for Fake {
        fn max_duty_cycle(&self) -> u16 {
            4200
        }
        fn set_duty_cycle(&mut self, duty: u16) -> Result<(), FakeError> {
            self.duty = duty;
            if self.fail {
                Err(FakeError)
            } else {
                Ok(())
            }
        }
    }

    struct Adc(Option<Pu>);

    impl CurrentSense for Adc {
        type Error = FakeError;
        fn sample_current(&mut self) -> Result<Pu, FakeError> {
            self.0.ok_or(FakeError)
        }
    }

    #[derive(Clone, Copy)]
    struct Counter(u32);

    impl EncoderCounter for Counter {
        const COUNTER_BITS: u8 = 16;
        fn count(&mut self) -> u32 {
            self.0
        }
    }

    #[test]
    fn current_half_maps_voltage_to_duty_and_reports_errors() {
        let mut io = CurrentIo {
            pwm: Fake::default(),
            current: Adc(Some(Pu::from_num(0.5))),
            encoder: Counter(1234),
            enable: Fake::default(),
        };
        assert_eq!(CurrentLoopIo::encoder_count(&mut io), 1234);
        assert_eq!(io.current_pu(), Some(Pu::from_num(0.5)));
        assert!(io.set_voltage_pu(Pu::from_num(-0.5)));
        assert_eq!(io.pwm.duty, 1050);
        assert!(io.set_enable(true) && io.enable.level);
        io.current.0 = None;
        assert_eq!(io.current_pu(), None, "a failed conversion is reported");
        io.pwm.fail = true;
        assert!(!io.set_voltage_pu(Pu::ZERO));
        io.enable.fail = true;
        assert!(!io.set_enable(false));
    }

    #[test]
    fn velocity_half_treats_an_unreadable_fault_input_as_a_fault() {
        let mut io = VelocityIo {
            encoder: Counter(7),
            fault: Fake::default(),
        };
        assert_eq!(VelocityLoopIo::encoder_count(&mut io), 7);
        assert!(!io.fault_input());
        io.fault.level = true;
        assert!(io.fault_input());
        io.fault = Fake {
            fail: true,
            ..Fake::default()
        };
        assert!(io.fault_input(), "fail safe");
    }

    #[test]
    fn duty_is_monotonic_and_bounded() {
        let mut last = 0;
        for k in -70_000..=70_000 {
            let v = Pu::from_bits(k);
            let d = duty_for_voltage(v, 8400);
            assert!(d >= last && d <= 8400);
            last = d;
        }
        assert_eq!(duty_for_voltage(Pu::MAX, 8400), 8400);
        assert_eq!(duty_for_voltage(Pu::MIN, 8400), 0);
        assert_eq!(duty_for_voltage(Pu::from_num(0.5), 8400), 6300);
    }
}
