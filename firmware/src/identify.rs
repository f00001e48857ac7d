//! The board console's measurement record (`pil_link::board::identify`, and a PMSM's
//! calibration, `pil_link::board::calibrate`, two samples a tick): the current-loop
//! interrupt writes the samples of each tick of the run into a ring of `N` samples and counts
//! it; thread mode streams what is written, [`CHUNK_SAMPLES`] to a `ScopeData` frame,
//! numbered from 0, and so frees the slots it has sent. A run is as long as the console
//! link keeps up with it, whatever `N`: the ring only has to hold what the link is behind.
//!
//! The stream has no gap, whatever the line: a tick that finds the ring full of unsent
//! samples is not recorded and ends the run ([`Recorder::overran`]; the caller disables
//! the drive, and the console records a link fault). After the run's last sample thread
//! mode sends an empty chunk numbered with the samples recorded when the run ended before
//! its ticks ([`StreamEnd::Cut`]), so the host knows at once that no more will come.
//!
//! Lock-free: the interrupt is the only writer of the samples and of the count (released
//! after the sample); thread mode reads below the count (acquired) and releases the slots
//! it has sent (the interrupt acquires that before it writes one again), and starts a run
//! only while none is active.

use core::cell::Cell;
use core::sync::atomic::{AtomicBool, AtomicI32, AtomicU32, Ordering};

use critical_section::Mutex;

use pil_link::board::identify::{IdentifyError, IdentifyRun};
use pil_link::board::scope::{ScopeChunk, ScopeSample, CHUNK_SAMPLES, SCOPE_CHANNELS};

/// Samples the `board` image's ring holds: 65,536 current ticks (16.4 s at 4 kHz; 1 MiB
/// of QEMU's 4 MiB SRAM), what the console link may fall behind the record.
pub const RECORD_CAPACITY: usize = 65_536;

/// Where the stream of a run stands ([`Recorder::stream_end`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StreamEnd {
    /// The run records, or samples wait to be sent.
    Open,
    /// Every tick of the run recorded and sent.
    Whole,
    /// The run ended after this many ticks, before its last (the ring overran, or the
    /// drive was disabled), and those are sent.
    Cut(u32),
}

/// One run's record (a ring of `N` ticks) and its progress.
pub struct Recorder<const N: usize> {
    samples: [[AtomicI32; SCOPE_CHANNELS]; N],
    /// Ticks recorded.
    written: AtomicU32,
    /// Ticks sent: their slots may be written again.
    released: AtomicU32,
    /// Ticks the run lasts.
    ticks: AtomicU32,
    /// The run (its load-torque schedule).
    run: Mutex<Cell<Option<IdentifyRun>>>,
    active: AtomicBool,
    /// The run ended on a full ring.
    overran: AtomicBool,
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
            released: AtomicU32::new(0),
            ticks: AtomicU32::new(0),
            run: Mutex::new(Cell::new(None)),
            active: AtomicBool::new(false),
            overran: AtomicBool::new(false),
        }
    }

    /// Slot of sample `n`.
    fn slot(&self, n: u32) -> Option<&[AtomicI32; SCOPE_CHANNELS]> {
        self.samples.get((n as usize).checked_rem(N)?)
    }

    /// Arms a run of `run.ticks` (thread mode, before the drive is enabled for it).
    ///
    /// # Errors
    /// [`IdentifyError::NoTicks`] for a run of zero ticks.
    pub fn start(&self, run: &IdentifyRun) -> Result<(), IdentifyError> {
        self.arm(run.ticks, Some(*run))
    }

    /// Arms a run of `samples` samples without a load-torque schedule (a calibration).
    ///
    /// # Errors
    /// [`IdentifyError::NoTicks`] for zero samples.
    pub fn start_samples(&self, samples: u32) -> Result<(), IdentifyError> {
        self.arm(samples, None)
    }

    fn arm(&self, ticks: u32, run: Option<IdentifyRun>) -> Result<(), IdentifyError> {
        if ticks == 0 {
            return Err(IdentifyError::NoTicks);
        }
        self.written.store(0, Ordering::Relaxed);
        self.released.store(0, Ordering::Relaxed);
        self.overran.store(false, Ordering::Relaxed);
        self.ticks.store(ticks, Ordering::Relaxed);
        critical_section::with(|cs| self.run.borrow(cs).set(run));
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

    /// Whether the last run ended because the ring was full of unsent samples.
    #[must_use]
    pub fn overran(&self) -> bool {
        self.overran.load(Ordering::Acquire)
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

    /// After a tick of an active run: its sample. Returns true when the run is over (its
    /// last tick, or a ring full of unsent samples: [`Self::overran`]); the caller then
    /// disables the drive.
    pub fn record(&self, values: [i32; SCOPE_CHANNELS]) -> bool {
        if !self.active() {
            return false;
        }
        let n = self.written.load(Ordering::Relaxed);
        let unsent = n.wrapping_sub(self.released.load(Ordering::Acquire));
        let slot = self.slot(n).filter(|_| (unsent as usize) < N);
        let Some(slot) = slot else {
            self.overran.store(true, Ordering::Release);
            self.active.store(false, Ordering::Release);
            return true;
        };
        for (cell, v) in slot.iter().zip(values) {
            cell.store(v, Ordering::Relaxed);
        }
        let n = n.saturating_add(1);
        self.written.store(n, Ordering::Release);
        let done = n >= self.ticks.load(Ordering::Relaxed);
        if done {
            self.active.store(false, Ordering::Release);
        }
        done
    }

    /// The next chunk to send from sample `sent` on (every sample before `sent` is sent:
    /// their slots are freed): up to [`CHUNK_SAMPLES`] recorded samples (fewer only at
    /// the end of the run); `None` while fewer are ready.
    #[must_use]
    pub fn chunk(&self, sent: u32) -> Option<ScopeChunk> {
        // `active` before `written`: a run seen over has its final count.
        let active = self.active();
        let written = self.written.load(Ordering::Acquire);
        self.released.store(sent.min(written), Ordering::Release);
        let ready = written.saturating_sub(sent);
        let full = CHUNK_SAMPLES as u32;
        if ready == 0 || (ready < full && active) {
            return None;
        }
        let mut chunk = ScopeChunk::new(sent);
        for n in sent..sent.saturating_add(ready.min(full)) {
            let slot = self.slot(n)?;
            let mut values = [0; SCOPE_CHANNELS];
            for (v, cell) in values.iter_mut().zip(slot) {
                *v = cell.load(Ordering::Relaxed);
            }
            chunk.push(ScopeSample { tick: n, values });
        }
        Some(chunk)
    }

    /// Whether the stream is over once `sent` samples are sent, and how.
    #[must_use]
    pub fn stream_end(&self, sent: u32) -> StreamEnd {
        if self.active() {
            return StreamEnd::Open;
        }
        let written = self.written.load(Ordering::Acquire);
        let ticks = self.ticks.load(Ordering::Relaxed);
        match (sent >= written, written >= ticks) {
            (false, _) => StreamEnd::Open,
            (true, true) => StreamEnd::Whole,
            (true, false) => StreamEnd::Cut(written),
        }
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

    /// Sends everything ready from `sent` on; the samples' values.
    fn drain<const N: usize>(r: &Recorder<N>, sent: &mut u32) -> Vec<[i32; 4]> {
        let mut out = Vec::new();
        while let Some(c) = r.chunk(*sent) {
            assert_eq!(c.first, *sent, "numbered without a gap");
            *sent += u32::from(c.len);
            out.extend(c.samples().iter().map(|s| s.values));
        }
        out
    }

    #[test]
    fn a_run_is_recorded_in_order_and_streamed_without_a_gap() {
        let r = Recorder::<16>::new();
        assert_eq!(r.start(&run(0)), Err(IdentifyError::NoTicks));
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
        assert_eq!(r.stream_end(0), StreamEnd::Open, "samples wait");
        let first = r.chunk(0).unwrap();
        assert_eq!((first.first, first.len), (0, 8));
        let rest = r.chunk(8).unwrap();
        assert_eq!((rest.first, rest.len), (8, 3));
        assert_eq!(rest.samples()[2].values, [10, -10, 20, 30]);
        assert!(r.chunk(11).is_none());
        assert_eq!(r.stream_end(11), StreamEnd::Whole);
        assert!(!r.overran());
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
        assert_eq!(r.stream_end(8), StreamEnd::Open);
        r.abort();
        assert_eq!(r.chunk(8).map(|c| c.len), Some(4));
        // Disabled after 12 of its 100 ticks: the stream says where it ended.
        assert_eq!(r.stream_end(12), StreamEnd::Cut(12));
        assert!(!r.overran(), "an abort is not an overrun");
    }

    #[test]
    fn a_run_many_times_the_ring_streams_whole_while_the_link_keeps_up() {
        // 1,000 ticks through a ring of 16, the link sending every third tick.
        let r = Recorder::<16>::new();
        r.start(&run(1_000)).unwrap();
        let (mut sent, mut got) = (0, Vec::new());
        let mut over = false;
        for i in 0..1_000 {
            assert!(!over, "recorded past the end");
            over = r.record([i, i + 1, i + 2, i + 3]);
            if i % 3 == 0 {
                got.extend(drain(&r, &mut sent));
            }
        }
        assert!(over && !r.overran());
        got.extend(drain(&r, &mut sent));
        assert_eq!(r.stream_end(sent), StreamEnd::Whole);
        let want: Vec<[i32; 4]> = (0..1_000).map(|i| [i, i + 1, i + 2, i + 3]).collect();
        assert_eq!(got, want, "every tick, in order, with its own values");
    }

    #[test]
    fn a_link_that_falls_a_ring_behind_ends_the_run_and_never_sends_a_gap() {
        let r = Recorder::<16>::new();
        r.start(&run(1_000)).unwrap();
        let mut sent = 0;
        // 8 sent after the first 10 ticks, then the link stalls.
        for i in 0..10 {
            assert!(!r.record([i; 4]));
        }
        let got = drain(&r, &mut sent);
        assert_eq!(sent, 8);
        // Ticks 10..=23 fill the ring (16 unsent from sample 8 on); tick 24 finds it full.
        for i in 10..24 {
            assert!(!r.record([i; 4]), "tick {i}");
        }
        assert!(r.active());
        assert!(r.record([24; 4]), "the full ring ends the run");
        assert!(r.overran() && !r.active() && r.load_now().is_none());
        assert!(!r.record([25; 4]));
        // What was recorded is sent whole; the stream then says it was cut at 24 ticks.
        let rest = drain(&r, &mut sent);
        let values: Vec<i32> = got.iter().chain(&rest).map(|v| v[0]).collect();
        assert_eq!(values, (0..24).collect::<Vec<_>>());
        assert_eq!(r.stream_end(sent), StreamEnd::Cut(24));
        // A new run starts clean.
        r.start(&run(3)).unwrap();
        assert!(!r.overran());
        assert_eq!(r.stream_end(0), StreamEnd::Open);
    }
}
