//! The board console's measurement record (`pil_link::board::identify`): the current-loop
//! interrupt writes one sample per tick of the run into a fixed buffer and counts it; thread
//! mode streams what is written, [`CHUNK_SAMPLES`] to a `ScopeData` frame, numbered from 0.
//! The buffer holds the whole run, so the stream has no gap however slow the line is.
//!
//! Lock-free: the interrupt is the only writer of the samples and of the count (released
//! after the sample), thread mode reads below the count (acquired) and starts a run only
//! while none is active.

use core::cell::Cell;
use core::sync::atomic::{AtomicBool, AtomicI32, AtomicU32, Ordering};

use critical_section::Mutex;

use pil_link::board::identify::{IdentifyError, IdentifyRun};
use pil_link::board::scope::{ScopeChunk, ScopeSample, CHUNK_SAMPLES, SCOPE_CHANNELS};

/// Samples the `board` image's record holds: 65,536 current ticks (16.4 s at 4 kHz; 1 MiB
/// of QEMU's 4 MiB SRAM).
pub const RECORD_CAPACITY: usize = 65_536;

/// One run's record (up to `N` ticks) and its progress.
pub struct Recorder<const N: usize> {
    samples: [[AtomicI32; SCOPE_CHANNELS]; N],
    /// Ticks recorded.
    written: AtomicU32,
    /// Ticks the run lasts.
    ticks: AtomicU32,
    /// The run (its load-torque schedule).
    run: Mutex<Cell<Option<IdentifyRun>>>,
    active: AtomicBool,
}

impl<const N: usize> Default for Recorder<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> Recorder<N> {
    /// Empty, no run.
    #[must_use]
    pub const fn new() -> Self {
        Self {
            samples: [const { [const { AtomicI32::new(0) }; SCOPE_CHANNELS] }; N],
            written: AtomicU32::new(0),
            ticks: AtomicU32::new(0),
            run: Mutex::new(Cell::new(None)),
            active: AtomicBool::new(false),
        }
    }

    /// Arms a run of `run.ticks` (thread mode, before the drive is enabled for it).
    ///
    /// # Errors
    /// [`IdentifyError::TooLong`] beyond `N` ticks (or zero ticks).
    pub fn start(&self, run: &IdentifyRun) -> Result<(), IdentifyError> {
        let max = u32::try_from(N).unwrap_or(u32::MAX);
        if run.ticks == 0 || run.ticks > max {
            return Err(IdentifyError::TooLong {
                ticks: run.ticks,
                max,
                prbs_period_ticks: run.prbs_period_ticks(),
            });
        }
        self.written.store(0, Ordering::Relaxed);
        self.ticks.store(run.ticks, Ordering::Relaxed);
        critical_section::with(|cs| self.run.borrow(cs).set(Some(*run)));
        self.active.store(true, Ordering::Release);
        Ok(())
    }

    /// Ends the run early (the drive disabled).
    pub fn abort(&self) {
        self.active.store(false, Ordering::Release);
    }

    /// Whether a run is recording.
    #[must_use]
    pub fn active(&self) -> bool {
        self.active.load(Ordering::Acquire)
    }

    /// Before a tick of an active run: the rig's load torque for it \[pu\]; `None` when no
    /// run is recording.
    #[must_use]
    pub fn load_now(&self) -> Option<f32> {
        if !self.active() {
            return None;
        }
        let run = critical_section::with(|cs| self.run.borrow(cs).get())?;
        Some(run.load_at(self.written.load(Ordering::Relaxed)))
    }

    /// After a tick of an active run: its sample. Returns true when that was the run's
    /// last tick (the run is then over: the caller disables the drive).
    pub fn record(&self, values: [i32; SCOPE_CHANNELS]) -> bool {
        if !self.active() {
            return false;
        }
        let n = self.written.load(Ordering::Relaxed);
        if let Some(slot) = self.samples.get(n as usize) {
            for (cell, v) in slot.iter().zip(values) {
                cell.store(v, Ordering::Relaxed);
            }
        }
        let n = n.saturating_add(1);
        self.written.store(n, Ordering::Release);
        let done = n >= self.ticks.load(Ordering::Relaxed);
        if done {
            self.active.store(false, Ordering::Release);
        }
        done
    }

    /// The next chunk to send from sample `sent` on: up to [`CHUNK_SAMPLES`] recorded
    /// samples (fewer only at the end of the run); `None` while fewer are ready.
    #[must_use]
    pub fn chunk(&self, sent: u32) -> Option<ScopeChunk> {
        let written = self.written.load(Ordering::Acquire);
        let ready = written.saturating_sub(sent);
        let full = CHUNK_SAMPLES as u32;
        if ready == 0 || (ready < full && self.active()) {
            return None;
        }
        let mut chunk = ScopeChunk::new(sent);
        for n in sent..sent.saturating_add(ready.min(full)) {
            let slot = self.samples.get(n as usize)?;
            let mut values = [0; SCOPE_CHANNELS];
            for (v, cell) in values.iter_mut().zip(slot) {
                *v = cell.load(Ordering::Relaxed);
            }
            chunk.push(ScopeSample { tick: n, values });
        }
        Some(chunk)
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;

    fn run(ticks: u32) -> IdentifyRun {
        IdentifyRun {
            amplitude_pu: 0.0,
            prbs_bits: 7,
            prbs_hold_ticks: 1,
            prbs_periods: 1,
            velocity_bandwidth_rad_s: 15.0,
            load_pu: 0.2,
            reverse_every_ticks: 4,
            ticks,
        }
    }

    #[test]
    fn a_run_is_recorded_in_order_and_streamed_without_a_gap() {
        let r = Recorder::<16>::new();
        assert!(r.start(&run(0)).is_err());
        assert!(r.start(&run(17)).is_err());
        r.start(&run(11)).unwrap();
        let mut loads = Vec::new();
        let mut done = Vec::new();
        for i in 0..11 {
            loads.push(r.load_now().unwrap());
            done.push(r.record([i, -i, 2 * i, 3 * i]));
        }
        // The load reverses every 4 ticks; the last tick ends the run.
        assert_eq!(
            &loads[..9],
            &[0.2, 0.2, 0.2, 0.2, -0.2, -0.2, -0.2, -0.2, 0.2]
        );
        assert_eq!(done.iter().filter(|d| **d).count(), 1);
        assert!(done[10] && !r.active() && r.load_now().is_none());
        assert!(!r.record([9; 4]), "nothing recorded after the run");
        let first = r.chunk(0).unwrap();
        assert_eq!((first.first, first.len), (0, 8));
        let rest = r.chunk(8).unwrap();
        assert_eq!((rest.first, rest.len), (8, 3));
        assert_eq!(rest.samples()[2].values, [10, -10, 20, 30]);
        assert!(r.chunk(11).is_none());
    }

    #[test]
    fn an_active_run_sends_only_whole_chunks() {
        let r = Recorder::<100>::new();
        r.start(&run(100)).unwrap();
        for i in 0..12 {
            r.record([i; 4]);
        }
        assert_eq!(r.chunk(0).map(|c| c.len), Some(8));
        assert!(r.chunk(8).is_none(), "4 ready of an active run wait for 8");
        r.abort();
        assert_eq!(r.chunk(8).map(|c| c.len), Some(4));
    }
}
