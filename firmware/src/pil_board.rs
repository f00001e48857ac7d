//! The processor-in-the-loop board: the drive I/O of the `pil` image, fed by the link
//! instead of hardware. The thread-mode link loop puts the sampled sensors of a frame into
//! mailboxes, pends the loop's interrupt, and the real interrupt body (`Loops::current_isr`
//! / `velocity_isr` → `App::on_current_tick` / `on_velocity_tick`; for a PMSM drive
//! `Loops::pmsm_isr` → `App::on_pmsm_tick`) reads them through the board-layer traits and
//! writes its commands back, exactly as it would drive a PWM or a three-phase stage.
//!
//! Sharing: the mailboxes are `critical_section::Mutex<Cell<_>>` of plain `Copy` data,
//! written by thread mode only while the interrupt is not pending and read by the interrupt
//! (single core, so a critical section is enough).

use core::cell::Cell;
use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use controller_core::per_unit::Pu;
use controller_core::{
    CurrentInputs, CurrentOutputs, PmsmInputs, PmsmOutputs, Setpoint, VelocityInputs,
    VelocityOutputs,
};
use critical_section::Mutex;
use firmware::app::SetpointSource;
use firmware::board::three_phase::PmsmLoopIo;
use firmware::board::{CurrentLoopIo, VelocityLoopIo};
use pil_link::tick::Applied;

/// Sensors of the current tick being run.
pub static CURRENT_IN: Mutex<Cell<CurrentInputs>> = Mutex::new(Cell::new(CurrentInputs {
    encoder_count: 0,
    current_pu: Pu::ZERO,
}));
/// Sensors of the PMSM current tick being run.
pub static PMSM_IN: Mutex<Cell<PmsmInputs>> = Mutex::new(Cell::new(PmsmInputs {
    encoder_count: 0,
    phase_current_pu: [Pu::ZERO; 2],
}));
/// Outputs of the last PMSM current-loop interrupt (taken by thread mode).
pub static PMSM_OUT: Mutex<Cell<Option<PmsmOutputs>>> = Mutex::new(Cell::new(None));
/// Sensors and setpoint of the velocity tick being run.
pub static VELOCITY_IN: Mutex<Cell<Option<VelocityInputs>>> = Mutex::new(Cell::new(None));
/// Outputs of the last current-loop interrupt (taken by thread mode).
pub static CURRENT_OUT: Mutex<Cell<Option<CurrentOutputs>>> = Mutex::new(Cell::new(None));
/// Outputs of the last velocity-loop interrupt (taken by thread mode).
pub static VELOCITY_OUT: Mutex<Cell<Option<VelocityOutputs>>> = Mutex::new(Cell::new(None));
/// What the current loop last applied to the (virtual) power stage.
pub static APPLIED: Mutex<Cell<Applied>> = Mutex::new(Cell::new(Applied {
    voltage_bits: 0,
    enabled: false,
    isr_ticks: 0,
    excitation_bits: 0,
}));
/// Set once the link is faulted: the velocity loop then sees its fault input active, so the
/// controller latches `Fault::External` and commands zero torque.
pub static LINK_FAULT: AtomicBool = AtomicBool::new(false);
/// Current-loop interrupts run.
pub static CURRENT_ISR_TICKS: AtomicU32 = AtomicU32::new(0);

/// Current-loop I/O: sensors from the mailbox, commands into [`APPLIED`].
#[derive(Debug, Default)]
pub struct LinkCurrentIo;

impl CurrentLoopIo for LinkCurrentIo {
    fn encoder_count(&mut self) -> u32 {
        critical_section::with(|cs| CURRENT_IN.borrow(cs).get().encoder_count)
    }

    fn current_pu(&mut self) -> Option<Pu> {
        Some(critical_section::with(|cs| {
            CURRENT_IN.borrow(cs).get().current_pu
        }))
    }

    fn set_voltage_pu(&mut self, voltage_pu: Pu) -> bool {
        critical_section::with(|cs| {
            let cell = APPLIED.borrow(cs);
            cell.set(Applied {
                voltage_bits: voltage_pu.to_bits(),
                ..cell.get()
            });
        });
        true
    }

    fn set_enable(&mut self, enabled: bool) -> bool {
        critical_section::with(|cs| {
            let cell = APPLIED.borrow(cs);
            cell.set(Applied {
                enabled,
                ..cell.get()
            });
        });
        true
    }
}

/// The same link board as a three-phase stage, for a PMSM drive: the encoder and two phase
/// currents from [`PMSM_IN`], the duties and the enable into [`APPLIED`] (its voltage word
/// is the duties' spread, largest minus smallest \[timer counts\]: 0 when the stage applies
/// no line voltage).
impl PmsmLoopIo for LinkCurrentIo {
    fn encoder_count(&mut self) -> u32 {
        critical_section::with(|cs| PMSM_IN.borrow(cs).get().encoder_count)
    }

    fn phase_currents_pu(&mut self) -> Option<[Pu; 2]> {
        Some(critical_section::with(|cs| {
            PMSM_IN.borrow(cs).get().phase_current_pu
        }))
    }

    fn set_duties(&mut self, duties: [u16; 3]) -> bool {
        let (hi, lo) = duties
            .iter()
            .fold((0, u16::MAX), |(h, l), &d| (h.max(d), l.min(d)));
        let spread = hi.saturating_sub(lo);
        critical_section::with(|cs| {
            let cell = APPLIED.borrow(cs);
            cell.set(Applied {
                voltage_bits: i32::from(spread),
                ..cell.get()
            });
        });
        true
    }

    fn set_enable(&mut self, enabled: bool) -> bool {
        CurrentLoopIo::set_enable(self, enabled)
    }

    fn fault_input(&mut self) -> bool {
        LINK_FAULT.load(Ordering::Relaxed)
    }
}

/// Velocity-loop I/O: encoder and fault input from the mailbox (fault also on a link fault).
#[derive(Debug, Default)]
pub struct LinkVelocityIo;

impl VelocityLoopIo for LinkVelocityIo {
    fn encoder_count(&mut self) -> u32 {
        critical_section::with(|cs| VELOCITY_IN.borrow(cs).get()).map_or(0, |i| i.encoder_count)
    }

    fn fault_input(&mut self) -> bool {
        // No inputs yet counts as a fault too (fail safe).
        let input = critical_section::with(|cs| VELOCITY_IN.borrow(cs).get());
        LINK_FAULT.load(Ordering::Relaxed) || input.is_none_or(|i| i.fault_input)
    }
}

/// The harness's motion profile, one setpoint per velocity frame.
#[derive(Debug, Default)]
pub struct LinkSetpoint;

impl SetpointSource for LinkSetpoint {
    fn next_setpoint(&mut self) -> Setpoint {
        critical_section::with(|cs| VELOCITY_IN.borrow(cs).get())
            .map_or_else(Setpoint::default, |i| i.setpoint)
    }
}
