//! Per-tick payloads: controller-core's inputs (harness → firmware, `Sensors` frames) and
//! outputs (firmware → harness, `Commands` frames), each a tag byte and then the record's
//! words ([`controller_core::words`], the one layout of every tick record), little-endian.
//! Fixed-point values travel as their raw bits, so both sides hold the very same numbers.
//!
//! ```text
//! Sensors, current tick   (9 bytes):  tag 1 | CurrentInputs words (2)
//! Sensors, velocity tick (29 bytes):  tag 2 | VelocityInputs words (7)
//! Commands, current tick (33 bytes):  tag 1 | CurrentOutputs words (4) | Applied words (4)
//!                                     (Applied: what the board layer applied: voltage,
//!                                     enable, isr_ticks, and the controller's latest
//!                                     excitation sample, 0 without one)
//! Commands, velocity tick (33 bytes): tag 2 | VelocityOutputs words (8)
//! Sensors, PMSM current tick   (13 bytes): tag 3 | PmsmInputs words (3)
//! Commands, PMSM current tick  (69 bytes): tag 3 | PmsmOutputs words (13) | Applied words (4)
//!                                     (Applied: voltage 0, the enable pin, isr_ticks, the
//!                                     excitation sample)
//! ```
//!
//! A PMSM drive (`[drive.pmsm]`) runs its current ticks with tag 3 in place of tag 1.

use crate::wire::{Reader, Writer};
use crate::{FrameKind, LinkError};
use controller_core::words::{BadWord, WordField};
use controller_core::{
    CurrentInputs, CurrentOutputs, PmsmInputs, PmsmOutputs, Pu, VelocityInputs, VelocityOutputs,
};

const TAG_CURRENT: u8 = 1;
const TAG_VELOCITY: u8 = 2;
const TAG_PMSM: u8 = 3;

/// A tick's inputs, harness → firmware.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Sensors {
    /// Inputs of a current tick.
    Current(CurrentInputs),
    /// Inputs of a velocity tick.
    Velocity(VelocityInputs),
    /// Inputs of a PMSM drive's current tick.
    Pmsm(PmsmInputs),
}

/// What the board layer applied in a current tick, read back from its outputs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Applied {
    /// Voltage written to the PWM, raw Q16.16 bits.
    pub voltage_bits: i32,
    /// Level of the power stage's enable pin.
    pub enabled: bool,
    /// Current-loop interrupts run so far.
    pub isr_ticks: u32,
    /// The controller's latest excitation sample, raw Q16.16 bits (0 without one).
    pub excitation_bits: i32,
}

/// `Applied`'s words: the voltage and the excitation as Q16.16 values.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct AppliedWords {
    voltage: Pu,
    enabled: bool,
    isr_ticks: u32,
    excitation: Pu,
}

controller_core::tick_words!(AppliedWords {
    voltage: Pu,
    enabled: bool,
    isr_ticks: u32,
    excitation: Pu,
});

impl From<Applied> for AppliedWords {
    fn from(a: Applied) -> Self {
        Self {
            voltage: Pu::from_bits(a.voltage_bits),
            enabled: a.enabled,
            isr_ticks: a.isr_ticks,
            excitation: Pu::from_bits(a.excitation_bits),
        }
    }
}

impl From<AppliedWords> for Applied {
    fn from(a: AppliedWords) -> Self {
        Self {
            voltage_bits: a.voltage.to_bits(),
            enabled: a.enabled,
            isr_ticks: a.isr_ticks,
            excitation_bits: a.excitation.to_bits(),
        }
    }
}

/// A tick's outputs, firmware → harness.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Commands {
    /// Outputs of a current tick and what the board applied.
    Current(CurrentOutputs, Applied),
    /// Outputs of a velocity tick.
    Velocity(VelocityOutputs),
    /// Outputs of a PMSM drive's current tick and what the board applied.
    Pmsm(PmsmOutputs, Applied),
}

/// Writes a record's words.
fn put<T: WordField>(w: &mut Writer, v: &T, scratch: &mut [u32]) -> Result<(), LinkError> {
    let n = T::WIDTH.min(scratch.len());
    let words = scratch.get_mut(..n).unwrap_or_default();
    v.put(words, 0);
    for x in words.iter() {
        w.u32(*x)?;
    }
    Ok(())
}

/// Reads a record's words; a word that names no value is a bad payload.
fn take<T: WordField>(r: &mut Reader<'_>, kind: FrameKind) -> Result<T, LinkError> {
    let mut scratch = [0_u32; MAX_WORDS];
    let n = T::WIDTH.min(MAX_WORDS);
    for x in scratch.iter_mut().take(n) {
        *x = r.u32()?;
    }
    T::take(scratch.get(..n).unwrap_or_default(), 0)
        .map(|(v, _)| v)
        .map_err(|BadWord { .. }| LinkError::BadPayload {
            kind: kind as u8,
            len: 0,
        })
}

/// The widest record on the link (words).
const MAX_WORDS: usize = 16;

impl Sensors {
    /// Writes the payload.
    pub fn encode(&self, w: &mut Writer) -> Result<(), LinkError> {
        let mut scratch = [0_u32; MAX_WORDS];
        match self {
            Self::Current(i) => put(w.u8(TAG_CURRENT)?, i, &mut scratch),
            Self::Velocity(i) => put(w.u8(TAG_VELOCITY)?, i, &mut scratch),
            Self::Pmsm(i) => put(w.u8(TAG_PMSM)?, i, &mut scratch),
        }
    }

    /// Parses a `Sensors` payload.
    pub fn decode(payload: &[u8]) -> Result<Self, LinkError> {
        let k = FrameKind::Sensors;
        let mut r = Reader::new(k, payload);
        let out = match r.u8()? {
            TAG_CURRENT => Self::Current(take(&mut r, k)?),
            TAG_VELOCITY => Self::Velocity(take(&mut r, k)?),
            TAG_PMSM => Self::Pmsm(take(&mut r, k)?),
            _ => return Err(bad(k, payload)),
        };
        r.finish()?;
        Ok(out)
    }
}

impl Commands {
    /// Writes the payload.
    pub fn encode(&self, w: &mut Writer) -> Result<(), LinkError> {
        let mut scratch = [0_u32; MAX_WORDS];
        match self {
            Self::Current(o, a) => {
                put(w.u8(TAG_CURRENT)?, o, &mut scratch)?;
                put(w, &AppliedWords::from(*a), &mut scratch)
            }
            Self::Velocity(o) => put(w.u8(TAG_VELOCITY)?, o, &mut scratch),
            Self::Pmsm(o, a) => {
                put(w.u8(TAG_PMSM)?, o, &mut scratch)?;
                put(w, &AppliedWords::from(*a), &mut scratch)
            }
        }
    }

    /// Parses a `Commands` payload.
    pub fn decode(payload: &[u8]) -> Result<Self, LinkError> {
        let k = FrameKind::Commands;
        let mut r = Reader::new(k, payload);
        let out = match r.u8()? {
            TAG_CURRENT => {
                let o = take(&mut r, k)?;
                Self::Current(o, take::<AppliedWords>(&mut r, k)?.into())
            }
            TAG_VELOCITY => Self::Velocity(take(&mut r, k)?),
            TAG_PMSM => {
                let o = take(&mut r, k)?;
                Self::Pmsm(o, take::<AppliedWords>(&mut r, k)?.into())
            }
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
