//! Scope payloads: [`ScopeInfo`] answers `ScopeStart`; [`ScopeChunk`]s follow in
//! `ScopeData` frames. Each sample carries the firmware's sample counter (one per trace
//! sample the drive produced since `ScopeStart`, so a sample the firmware could not send
//! shows as a gap), the current-loop tick and the raw values of the trace channels.

use crate::wire::{Reader, Writer};
use crate::{FrameKind, LinkError};

/// Channels per scope sample (the firmware's trace channels).
pub const SCOPE_CHANNELS: usize = 4;
/// Samples in one `ScopeData` frame: 5 + 8 × 20 = 165 bytes, below `MAX_PAYLOAD`.
pub const CHUNK_SAMPLES: usize = 8;

/// One scope sample.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ScopeSample {
    /// Current-loop tick at capture.
    pub tick: u32,
    /// Raw channel values (counts, or Q16.16 bits of per-unit signals).
    pub values: [i32; SCOPE_CHANNELS],
}

/// What `ScopeStart` answers: the sample rate and the channel names.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ScopeInfo<'a> {
    /// Samples per second (the trace rate).
    pub rate_hz: u32,
    /// Channel names, comma separated, in channel order.
    pub channels: &'a str,
}

impl<'a> ScopeInfo<'a> {
    /// Writes the body.
    ///
    /// # Errors
    /// `BufferTooSmall`.
    pub fn encode(&self, w: &mut Writer) -> Result<(), LinkError> {
        w.u32(self.rate_hz)?.bytes(self.channels.as_bytes())?;
        Ok(())
    }

    /// Parses the body.
    ///
    /// # Errors
    /// `BadPayload`.
    pub fn decode(body: &'a [u8]) -> Result<Self, LinkError> {
        let mut r = Reader::new(FrameKind::BoardReply, body);
        let rate_hz = r.u32()?;
        let channels = core::str::from_utf8(r.rest()).map_err(|_| LinkError::BadPayload {
            kind: FrameKind::BoardReply as u8,
            len: u8::try_from(body.len()).unwrap_or(u8::MAX),
        })?;
        Ok(Self { rate_hz, channels })
    }
}

/// Up to [`CHUNK_SAMPLES`] consecutive samples, the first with counter `first`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ScopeChunk {
    /// Sample counter of `samples[0]`.
    pub first: u32,
    /// Samples in use.
    pub len: u8,
    /// The samples (the first `len`).
    pub samples: [ScopeSample; CHUNK_SAMPLES],
}

impl ScopeChunk {
    /// An empty chunk starting at counter `first`.
    #[must_use]
    pub fn new(first: u32) -> Self {
        Self {
            first,
            ..Self::default()
        }
    }

    /// Adds a sample; false when the chunk is full.
    pub fn push(&mut self, sample: ScopeSample) -> bool {
        match self.samples.get_mut(usize::from(self.len)) {
            Some(slot) => {
                *slot = sample;
                self.len += 1;
                true
            }
            None => false,
        }
    }

    /// The samples in use.
    #[must_use]
    pub fn samples(&self) -> &[ScopeSample] {
        self.samples.get(..usize::from(self.len)).unwrap_or(&[])
    }

    /// Writes the `ScopeData` payload.
    ///
    /// # Errors
    /// `BufferTooSmall` (never for [`CHUNK_SAMPLES`] samples).
    pub fn encode(&self, w: &mut Writer) -> Result<(), LinkError> {
        w.u32(self.first)?.u8(self.len)?;
        for s in self.samples() {
            w.u32(s.tick)?;
            for v in s.values {
                w.i32(v)?;
            }
        }
        Ok(())
    }

    /// Parses a `ScopeData` payload.
    ///
    /// # Errors
    /// `BadPayload` when the length does not match the sample count.
    pub fn decode(payload: &[u8]) -> Result<Self, LinkError> {
        let mut r = Reader::new(FrameKind::ScopeData, payload);
        let mut chunk = Self::new(r.u32()?);
        let n = r.u8()?;
        for _ in 0..n {
            let tick = r.u32()?;
            let mut values = [0; SCOPE_CHANNELS];
            for v in &mut values {
                *v = r.i32()?;
            }
            if !chunk.push(ScopeSample { tick, values }) {
                return Err(LinkError::BadPayload {
                    kind: FrameKind::ScopeData as u8,
                    len: u8::try_from(payload.len()).unwrap_or(u8::MAX),
                });
            }
        }
        r.finish()?;
        Ok(chunk)
    }
}
