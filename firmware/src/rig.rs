//! The QEMU board console's rig (`crate::board_console`, module docs): the virtual
//! machine behind the bridge with the baked machine file's load, the rig's load torque
//! during an `Identify` run and its record, and the velocity tick run from the current
//! tick so the two loops stay in step however late QEMU runs.
//!
//! The console owns the loops ([`ConsoleLoops`]) and hands them to the rig's calls: the
//! rig depends on the board layer and the interrupt glue, never on the console, and the
//! board layer on neither.

use core::sync::atomic::{AtomicU32, Ordering};

use controller_core::{CurrentOutputs, DriveConfig, Pu, Setpoint};

use crate::board::CurrentLoopIo;
use crate::boards::qemu::{CurrentIoImpl, PeriodicTimer, VelocityIoImpl};
use crate::identify::{Recorder, RECORD_CAPACITY};
use crate::isr::Loops;
use crate::virtual_motor::VirtualMotor;

/// The board console's loops on the QEMU board: the app, its I/O, a fixed setpoint.
pub type ConsoleLoops = Loops<CurrentIoImpl, VelocityIoImpl, Setpoint>;

/// The record of an `Identify` run.
pub static RECORD: Recorder<RECORD_CAPACITY> = Recorder::new();
/// Current ticks per velocity tick, and the current ticks since the last velocity tick.
static VELOCITY_EVERY: AtomicU32 = AtomicU32::new(1);
static PHASE: AtomicU32 = AtomicU32::new(0);

/// The rig's part of the loop interrupts.
pub struct Rig;

impl Rig {
    /// Before a current tick of a measurement: the rig's load torque for it, and the
    /// inputs the tick reads (the virtual sensors, read again: nothing changes them in
    /// between).
    pub fn before_tick(loops: &ConsoleLoops) -> Option<(u32, Option<Pu>)> {
        let load = RECORD.load_now()?;
        loops.with_current_io(|io| {
            io.pwm.motor_mut().set_load_torque_pu(load);
            (io.encoder_count(), io.current_pu())
        })
    }

    /// After a current tick: its sample into the record (after the run's last, the
    /// drive off); the velocity tick when one is due.
    pub fn after_tick(
        loops: &ConsoleLoops,
        inputs: Option<(u32, Option<Pu>)>,
        out: Option<CurrentOutputs>,
    ) {
        if let (Some((counts, current)), Some(out)) = (inputs, out) {
            let excitation = loops.with_app(|app| app.excitation_pu().to_bits());
            let values = [
                excitation.unwrap_or(0),
                current.map_or(0, |i| i.to_bits()),
                out.current_ref_pu.to_bits(),
                counts as i32,
            ];
            if RECORD.record(values) {
                loops.with_app(|app| app.set_enable_request(false));
            }
        }
        let since = PHASE.load(Ordering::Relaxed).wrapping_add(1);
        if since >= VELOCITY_EVERY.load(Ordering::Relaxed) {
            PHASE.store(0, Ordering::Relaxed);
            let _ = loops.velocity_isr();
        } else {
            PHASE.store(since, Ordering::Relaxed);
        }
    }

    /// The velocity tick from the current tick: TIMER1 stopped, the ratio set.
    pub fn lock_velocity_to_current(cfg: &DriveConfig) {
        PeriodicTimer::TIMER1.stop();
        let every = cfg.current_rate_hz / cfg.velocity_rate_hz.max(1);
        VELOCITY_EVERY.store(every.max(1), Ordering::Relaxed);
    }

    /// The run's velocity ticks before its ticks `every`, 2·`every`, ...
    pub fn align_velocity() {
        PHASE.store(0, Ordering::Relaxed);
    }

    /// The virtual machine: the drive's winding and encoder stepped at its current-loop
    /// period, the baked machine file's inertias and shaft, at rest with the counter
    /// at `counts`.
    pub fn machine(cfg: &DriveConfig, counts: u32) -> VirtualMotor {
        let (motor_inertia_s, coupling) = crate::drive::coupling();
        VirtualMotor::new(
            crate::boards::qemu::virtual_motor_config(cfg).with_coupling(motor_inertia_s, coupling),
        )
        .with_counts(counts)
    }
}
