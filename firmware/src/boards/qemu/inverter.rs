//! The QEMU board's three-phase stage, for a PMSM drive: the virtual inverter and PMSM
//! ([`crate::virtual_pmsm`]) behind the board layer's [`PmsmLoopIo`], as the three-phase
//! STM32F4 board puts TIM1 and its ADCs behind it. The motor is the baked machine file's
//! PMSM (`[electrics]`) on its two-inertia machine (`[plant]`), each duty written is held
//! for one current-loop period (after the file's computational delay) while the motor
//! integrates, with all six switches open while the enable output (FPGAIO LED0) is low.
//! The encoder is the DC board's counter ([`super::VirtualEncoder`]), which the velocity
//! loop reads too.

use controller_core::per_unit::Pu;
use controller_core::DriveConfig;
use core::sync::atomic::Ordering;
use embedded_hal::digital::{InputPin, OutputPin};

use super::{pu_bits, read, EnableLed, FaultButton, FPGAIO_BASE, FPGAIO_LED0, MOTOR_COUNTS};
use crate::board::three_phase::PmsmLoopIo;
use crate::virtual_pmsm::{VirtualPmsm, VirtualPmsmConfig};

/// The virtual PMSM for a drive: the baked machine file's motor and its load behind the
/// shaft, stepped at the drive's current-loop period in its PWM period's duties. `None`
/// when the baked file's motor is not a PMSM or the drive has no `[drive.pmsm]`.
#[must_use]
pub fn virtual_pmsm_config(cfg: &DriveConfig) -> Option<VirtualPmsmConfig> {
    let machine = crate::drive::pmsm_machine()?;
    let (motor_inertia_s, coupling) = crate::drive::coupling();
    Some(VirtualPmsmConfig::for_drive(cfg, machine)?.with_coupling(motor_inertia_s, coupling))
}

/// The virtual three-phase stage: the PMSM, its enable output and the fault input.
pub struct VirtualInverter {
    motor: VirtualPmsm,
    enable: EnableLed,
    fault: FaultButton,
}

impl VirtualInverter {
    /// The stage for `config`, the motor at rest, the enable output low.
    #[must_use]
    pub fn new(config: VirtualPmsmConfig) -> Self {
        let mut enable = EnableLed;
        let _ = enable.set_low();
        let motor = VirtualPmsm::new(config);
        MOTOR_COUNTS.store(motor.counts(), Ordering::Relaxed);
        Self {
            motor,
            enable,
            fault: FaultButton,
        }
    }

    /// The virtual motor (thread mode, under the loops' critical section).
    pub fn motor_mut(&mut self) -> &mut VirtualPmsm {
        &mut self.motor
    }
}

impl PmsmLoopIo for VirtualInverter {
    fn encoder_count(&mut self) -> u32 {
        MOTOR_COUNTS.load(Ordering::Relaxed) & 0xFFFF
    }

    fn phase_currents_pu(&mut self) -> Option<[Pu; 2]> {
        Some(
            self.motor
                .phase_current_samples_pu()
                .map(|i| Pu::from_bits(pu_bits(i))),
        )
    }

    fn set_duties(&mut self, duties: [u16; 3]) -> bool {
        let enabled = read(FPGAIO_BASE + FPGAIO_LED0) & 1 != 0;
        self.motor.step(enabled.then_some(duties));
        MOTOR_COUNTS.store(self.motor.counts(), Ordering::Relaxed);
        true
    }

    fn set_enable(&mut self, enabled: bool) -> bool {
        if enabled {
            self.enable.set_high().is_ok()
        } else {
            self.enable.set_low().is_ok()
        }
    }

    fn fault_input(&mut self) -> bool {
        self.fault.is_high().unwrap_or(true)
    }
}
