//! Per-tick payloads: controller-core's inputs (harness → firmware, `Sensors` frames) and
//! outputs (firmware → harness, `Commands` frames). Fixed-point values travel as their raw
//! bits, so both sides hold the very same numbers; a fault travels as its
//! [`controller_core::words::fault_code`].
//!
//! ```text
//! Sensors, current tick   (9 bytes):  tag 1 | encoder u32 | current_pu i32
//! Sensors, velocity tick (22 bytes):  tag 2 | encoder u32 | position_counts i64 |
//!                                     velocity_pu i32 | acceleration_pu_s i32 | fault_input u8
//! Commands, current tick (24 bytes):  tag 1 | voltage_cmd i32 | current_ref i32 | accel_fb i32 |
//!                                     fault u8 | applied_voltage i32 | enabled u8 | isr_ticks u32 |
//!                                     excitation i32
//!                                     (applied_voltage, enabled, isr_ticks: what the board
//!                                     layer applied; excitation: the controller's latest
//!                                     excitation sample, 0 without one)
//! Commands, velocity tick (30 bytes): tag 2 | current_ref i32 | accel_fb i32 | velocity_cmd i32 |
//!                                     velocity_est i32 | acceleration_est i32 |
//!                                     position_error i32 (Q24.8) | disturbance_est i32 | fault u8
//! ```

use crate::wire::{Reader, Writer};
use crate::{FrameKind, LinkError};
use controller_core::per_unit::{Counts, CountsErr, Pu, PuPerS};
use controller_core::words::{fault_code, fault_from_code};
use controller_core::{
    CurrentInputs, CurrentOutputs, Fault, Setpoint, VelocityInputs, VelocityOutputs,
};

const TAG_CURRENT: u8 = 1;
const TAG_VELOCITY: u8 = 2;

/// A fault code byte ([`controller_core::words::fault_from_code`]); an unknown code is a
/// `BadPayload` of `kind`.
const fn fault_from_byte(b: u8, kind: FrameKind) -> Result<Option<Fault>, LinkError> {
    match fault_from_code(b) {
        Ok(f) => Ok(f),
        Err(_) => Err(LinkError::BadPayload {
            kind: kind as u8,
            len: 0,
        }),
    }
}

/// A `Sensors` payload: the inputs of one controller tick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Sensors {
    /// Inputs of a current tick.
    Current(CurrentInputs),
    /// Inputs of a velocity tick.
    Velocity(VelocityInputs),
}

impl Sensors {
    /// Payload bytes.
    pub fn encode(&self, w: &mut Writer) -> Result<(), LinkError> {
        match self {
            Self::Current(i) => {
                w.u8(TAG_CURRENT)?
                    .u32(i.encoder_count)?
                    .i32(i.current_pu.to_bits())?;
            }
            Self::Velocity(i) => {
                w.u8(TAG_VELOCITY)?
                    .u32(i.encoder_count)?
                    .i64(i.setpoint.position_counts.to_bits())?
                    .i32(i.setpoint.velocity_pu.to_bits())?
                    .i32(i.setpoint.acceleration_pu_s.to_bits())?
                    .u8(u8::from(i.fault_input))?;
            }
        }
        Ok(())
    }

    /// Parses a `Sensors` payload.
    pub fn decode(payload: &[u8]) -> Result<Self, LinkError> {
        let mut r = Reader::new(FrameKind::Sensors, payload);
        let out = match r.u8()? {
            TAG_CURRENT => Self::Current(CurrentInputs {
                encoder_count: r.u32()?,
                current_pu: Pu::from_bits(r.i32()?),
            }),
            TAG_VELOCITY => Self::Velocity(VelocityInputs {
                encoder_count: r.u32()?,
                setpoint: Setpoint {
                    position_counts: Counts::from_bits(r.i64()?),
                    velocity_pu: Pu::from_bits(r.i32()?),
                    acceleration_pu_s: PuPerS::from_bits(r.i32()?),
                },
                fault_input: bool_byte(r.u8()?, FrameKind::Sensors)?,
            }),
            _ => return Err(bad(FrameKind::Sensors, payload)),
        };
        r.finish()?;
        Ok(out)
    }
}

/// What the board layer did with a current tick's command (the firmware's view of its
/// power stage).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Applied {
    /// Voltage written to the PWM [pu, Q16.16 bits] (0 when the stage is off).
    pub voltage_bits: i32,
    /// Power stage enabled.
    pub enabled: bool,
    /// Current-loop interrupts run so far (proves the tick ran in the interrupt).
    pub isr_ticks: u32,
    /// The identification excitation's latest sample after the tick [pu, Q16.16 bits]
    /// (`Controller::excitation_pu`; 0 without an excitation).
    pub excitation_bits: i32,
}

/// A `Commands` payload: the outputs of one controller tick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Commands {
    /// Outputs of a current tick, and what the board layer applied.
    Current(CurrentOutputs, Applied),
    /// Outputs of a velocity tick.
    Velocity(VelocityOutputs),
}

impl Commands {
    /// Payload bytes.
    pub fn encode(&self, w: &mut Writer) -> Result<(), LinkError> {
        match self {
            Self::Current(o, a) => {
                w.u8(TAG_CURRENT)?
                    .i32(o.voltage_cmd_pu.to_bits())?
                    .i32(o.current_ref_pu.to_bits())?
                    .i32(o.accel_fb_pu.to_bits())?
                    .u8(fault_code(o.fault))?
                    .i32(a.voltage_bits)?
                    .u8(u8::from(a.enabled))?
                    .u32(a.isr_ticks)?
                    .i32(a.excitation_bits)?;
            }
            Self::Velocity(o) => {
                w.u8(TAG_VELOCITY)?
                    .i32(o.current_ref_pu.to_bits())?
                    .i32(o.accel_fb_pu.to_bits())?
                    .i32(o.velocity_cmd_pu.to_bits())?
                    .i32(o.velocity_est_pu.to_bits())?
                    .i32(o.acceleration_est_pu_s.to_bits())?
                    .i32(o.position_error_counts.to_bits())?
                    .i32(o.disturbance_est_pu.to_bits())?
                    .u8(fault_code(o.fault))?;
            }
        }
        Ok(())
    }

    /// Parses a `Commands` payload.
    pub fn decode(payload: &[u8]) -> Result<Self, LinkError> {
        let k = FrameKind::Commands;
        let mut r = Reader::new(k, payload);
        let out = match r.u8()? {
            TAG_CURRENT => Self::Current(
                CurrentOutputs {
                    voltage_cmd_pu: Pu::from_bits(r.i32()?),
                    current_ref_pu: Pu::from_bits(r.i32()?),
                    accel_fb_pu: Pu::from_bits(r.i32()?),
                    fault: fault_from_byte(r.u8()?, k)?,
                },
                Applied {
                    voltage_bits: r.i32()?,
                    enabled: bool_byte(r.u8()?, k)?,
                    isr_ticks: r.u32()?,
                    excitation_bits: r.i32()?,
                },
            ),
            TAG_VELOCITY => Self::Velocity(VelocityOutputs {
                current_ref_pu: Pu::from_bits(r.i32()?),
                accel_fb_pu: Pu::from_bits(r.i32()?),
                velocity_cmd_pu: Pu::from_bits(r.i32()?),
                velocity_est_pu: Pu::from_bits(r.i32()?),
                acceleration_est_pu_s: PuPerS::from_bits(r.i32()?),
                position_error_counts: CountsErr::from_bits(r.i32()?),
                disturbance_est_pu: Pu::from_bits(r.i32()?),
                fault: fault_from_byte(r.u8()?, k)?,
            }),
            _ => return Err(bad(k, payload)),
        };
        r.finish()?;
        Ok(out)
    }
}

fn bad(kind: FrameKind, payload: &[u8]) -> LinkError {
    LinkError::BadPayload {
        kind: kind as u8,
        len: u8::try_from(payload.len()).unwrap_or(u8::MAX),
    }
}

const fn bool_byte(b: u8, kind: FrameKind) -> Result<bool, LinkError> {
    match b {
        0 => Ok(false),
        1 => Ok(true),
        _ => Err(LinkError::BadPayload {
            kind: kind as u8,
            len: 0,
        }),
    }
}
