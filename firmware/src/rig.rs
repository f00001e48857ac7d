//! The QEMU board console's rig (`crate::board_console`, module docs): the virtual
//! machine behind the bridge with the baked machine file's load, the rig's load torque
//! during an `Identify` run and its record, and the velocity tick run from the current
//! tick so the two loops stay in step however late QEMU runs.
//!
//! The console owns the DC drive's loops ([`ConsoleLoops`]) and hands them to the rig's
//! calls: the rig depends on the board layer and the interrupt glue, never on the console,
//! and the board layer on neither.
//!
//! A PMSM drive (the baked machine file's `[electrics]` motor = "pmsm") runs on the virtual
//! three-phase stage instead ([`PmsmRig`], its loops [`PMSM_LOOPS`]): the same rig (the
//! load torque of an `Identify` run, its record, the velocity tick from the current tick),
//! and the motor calibration (`crate::calibrate`), whose ticks replace the drive's while it
//! runs.

use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use controller_core::{CurrentOutputs, DriveConfig, Pu, Setpoint};

use crate::app::App;
use crate::board::three_phase::PmsmLoopIo;
use crate::board::CurrentLoopIo;
use crate::boards::qemu::inverter::{virtual_pmsm_config, VirtualInverter};
use crate::boards::qemu::{CurrentIoImpl, PeriodicTimer, VelocityIoImpl};
use crate::calibrate::CalibrationRun;
use crate::identify::{Recorder, RECORD_CAPACITY};
use crate::isr::{Loops, Shared};
use crate::virtual_motor::VirtualMotor;
use crate::virtual_pmsm::VirtualPmsm;

/// The board console's loops on the QEMU board: the app, its I/O, a fixed setpoint.
pub type ConsoleLoops = Loops<CurrentIoImpl, VelocityIoImpl, Setpoint>;

/// The record of an `Identify` run.
pub static RECORD: Recorder<RECORD_CAPACITY> = Recorder::new();
/// The PMSM drive's loops: the app and the virtual three-phase stage.
pub type PmsmLoops = Loops<VirtualInverter, VelocityIoImpl, Setpoint>;
/// The loops of a PMSM drive (installed instead of the console's DC loops).
pub static PMSM_LOOPS: PmsmLoops = Loops::new();
/// A PMSM drive is installed in [`PMSM_LOOPS`].
static PMSM: AtomicBool = AtomicBool::new(false);
/// The motor calibration running (its ticks replace the drive's).
static CALIBRATION: Shared<CalibrationRun> = Shared::new();
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
        if velocity_due() {
            let _ = loops.velocity_isr();
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

/// After each current tick: whether the velocity tick is due (every
/// `current_rate_hz / velocity_rate_hz`-th).
fn velocity_due() -> bool {
    let since = PHASE.load(Ordering::Relaxed).wrapping_add(1);
    let due = since >= VELOCITY_EVERY.load(Ordering::Relaxed);
    PHASE.store(if due { 0 } else { since }, Ordering::Relaxed);
    due
}

/// The rig of a PMSM drive: its loops on the virtual three-phase stage.
pub struct PmsmRig;

impl PmsmRig {
    /// Whether the board runs a PMSM drive.
    pub fn active() -> bool {
        PMSM.load(Ordering::Relaxed)
    }

    /// Installs the PMSM drive `app` of `cfg` on the baked file's virtual PMSM (before the
    /// timers start); false when the baked machine is not a PMSM.
    pub fn install(app: App, cfg: &DriveConfig, velocity_io: VelocityIoImpl) -> bool {
        let Some(machine) = virtual_pmsm_config(cfg) else {
            return false;
        };
        PMSM_LOOPS.install(
            app,
            VirtualInverter::new(machine),
            velocity_io,
            Setpoint::default(),
        );
        PMSM.store(true, Ordering::Relaxed);
        true
    }

    /// The current-loop interrupt: a calibration's tick while one runs, else the drive's
    /// (with an `Identify` run's load torque and record); then the velocity tick when due.
    pub fn tick() {
        if !Self::calibration_tick() {
            let inputs = RECORD.load_now().and_then(|load| {
                PMSM_LOOPS.with_current_io(|io| {
                    io.motor_mut().set_load_torque_pu(load);
                    io.encoder_count()
                })
            });
            let out = PMSM_LOOPS.pmsm_isr();
            if let (Some(counts), Some(out)) = (inputs, out) {
                // As the host's record: the torque of the measured currents in the drive's
                // motor model and the torque reference, both in the counts' direction.
                let (excitation, current, reference) = PMSM_LOOPS
                    .with_app(|app| {
                        (
                            app.excitation_pu().to_bits(),
                            app.measured_torque_pu(),
                            out.torque_ref_pu,
                        )
                    })
                    .unwrap_or((0, Pu::ZERO, out.torque_ref_pu));
                let values = [
                    excitation,
                    current.to_bits(),
                    reference.to_bits(),
                    counts as i32,
                ];
                if RECORD.record(values) {
                    PMSM_LOOPS.with_app(|app| app.set_enable_request(false));
                }
            }
        }
        if velocity_due() {
            let _ = PMSM_LOOPS.velocity_isr();
        }
    }

    /// A calibration tick, its row into the record (its stage off after the last, or when
    /// the stage fails or the ring overruns); false when no calibration runs. After the
    /// last tick the rig brakes the machine where it stands, as it does before an
    /// `Identify` run: what follows starts from the same state however late the host asks
    /// for it.
    fn calibration_tick() -> bool {
        critical_section::with(|cs| {
            CALIBRATION.with_slot(cs, |slot| {
                let Some(run) = slot.as_mut() else {
                    return false;
                };
                let over = PMSM_LOOPS.with_current_io(|io| match run.tick(io) {
                    Ok(row) => {
                        let [first, second] = row.to_samples();
                        let over = RECORD.record(first) || RECORD.record(second);
                        if over {
                            run.stop(io);
                            io.motor_mut().stop();
                        }
                        over
                    }
                    Err(_) => {
                        RECORD.abort();
                        true
                    }
                });
                if over != Some(false) {
                    *slot = None;
                }
                true
            })
        })
        .unwrap_or(false)
    }

    /// Starts the calibration `run` at the next tick (the record armed first).
    pub fn start_calibration(run: CalibrationRun) {
        critical_section::with(|cs| CALIBRATION.with_slot(cs, |slot| *slot = Some(run)));
    }

    /// Ends a calibration early: the stage off.
    pub fn end_calibration() {
        critical_section::with(|cs| {
            CALIBRATION.with_slot(cs, |slot| {
                if let Some(run) = slot.take() {
                    PMSM_LOOPS.with_current_io(|io| run.stop(io));
                }
            })
        });
    }

    /// The rig's load torque \[pu\] on the motor from now on.
    pub fn set_load(load_pu: f32) {
        PMSM_LOOPS.with_current_io(|io| io.motor_mut().set_load_torque_pu(load_pu));
    }

    /// The rig's brake: the motor at rest where it is, no current.
    pub fn brake() {
        PMSM_LOOPS.with_current_io(|io| io.motor_mut().stop());
    }

    /// The virtual PMSM stepped at `cfg`'s current-loop period, at rest where it was.
    pub fn rebuild_machine(cfg: &DriveConfig) {
        PMSM_LOOPS.with_current_io(|io| {
            let counts = io.motor_mut().counts();
            if let Some(machine) = virtual_pmsm_config(cfg) {
                *io.motor_mut() = VirtualPmsm::new(machine).with_counts(counts);
            }
        });
    }
}
