//! The fault history: the last [`HISTORY_LEN`] faults the drive latched, each with the time
//! since boot, oldest first, and how many there were in all. The firmware records one entry
//! per latch; `Faults` answers with the whole ring.

use crate::wire::{Reader, Writer};
use crate::{FrameKind, LinkError};

/// Entries the ring keeps.
pub const HISTORY_LEN: usize = 16;
/// The cause code of a link fault (a corrupt console frame while enabled), beside
/// controller-core's fault codes.
pub const LINK_FAULT_CODE: u8 = 0xFE;

/// One latched fault.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FaultEntry {
    /// Milliseconds since boot when it latched.
    pub ms: u32,
    /// Cause: controller-core's fault code, or [`LINK_FAULT_CODE`].
    pub code: u8,
}

/// A ring of the latest faults.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FaultHistory {
    entries: [FaultEntry; HISTORY_LEN],
    /// Faults recorded since boot (the ring holds the last `HISTORY_LEN`).
    total: u32,
}

impl FaultHistory {
    /// An empty history.
    #[must_use]
    pub const fn new() -> Self {
        Self {
            entries: [FaultEntry { ms: 0, code: 0 }; HISTORY_LEN],
            total: 0,
        }
    }

    /// Records a fault.
    pub fn push(&mut self, entry: FaultEntry) {
        if let Some(slot) = self.entries.get_mut(self.total as usize % HISTORY_LEN) {
            *slot = entry;
        }
        self.total = self.total.wrapping_add(1);
    }

    /// Faults recorded since boot.
    #[must_use]
    pub const fn total(&self) -> u32 {
        self.total
    }

    /// The kept entries, oldest first.
    pub fn entries(&self) -> impl Iterator<Item = FaultEntry> + '_ {
        let kept = (self.total as usize).min(HISTORY_LEN);
        let start = self.total as usize - kept;
        (start..self.total as usize).filter_map(|i| self.entries.get(i % HISTORY_LEN).copied())
    }

    /// Writes the `Faults` body: total u32, count u8, count × (ms u32, code u8).
    ///
    /// # Errors
    /// `BufferTooSmall` (never: 5 + 16 × 5 bytes).
    pub fn encode(&self, w: &mut Writer) -> Result<(), LinkError> {
        let kept = (self.total as usize).min(HISTORY_LEN) as u8;
        w.u32(self.total)?.u8(kept)?;
        for e in self.entries() {
            w.u32(e.ms)?.u8(e.code)?;
        }
        Ok(())
    }

    /// Parses a `Faults` body.
    ///
    /// # Errors
    /// `BadPayload`.
    pub fn decode(body: &[u8]) -> Result<Self, LinkError> {
        let mut r = Reader::new(FrameKind::BoardReply, body);
        let total = r.u32()?;
        let kept = r.u8()?;
        if usize::from(kept) > HISTORY_LEN {
            return Err(LinkError::BadPayload {
                kind: FrameKind::BoardReply as u8,
                len: u8::try_from(body.len()).unwrap_or(u8::MAX),
            });
        }
        let mut h = Self::new();
        // Replayed so that `total` and the ring positions come out as sent.
        h.total = total.wrapping_sub(u32::from(kept));
        for _ in 0..kept {
            let ms = r.u32()?;
            let code = r.u8()?;
            h.push(FaultEntry { ms, code });
        }
        r.finish()?;
        Ok(h)
    }
}
