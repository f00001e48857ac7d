//! The board console's drive-side pieces that need no hardware (the `board` image binds
//! them to its interrupts, `src/bin/board.rs`): the scope tap on the trend buffer, the
//! fault tracker that fills the fault history, the scope's channel names.

use controller_core::Fault;
use pil_link::board::faults::{FaultEntry, FaultHistory};
use pil_link::board::scope::{ScopeSample, SCOPE_CHANNELS};

use crate::app::fault_code;
use crate::trace::{TraceConfig, TraceSample, TRACE_CHANNELS};

// A scope sample is a trace sample.
const _: () = assert!(SCOPE_CHANNELS == TRACE_CHANNELS);

/// Turns the trend buffer's newest sample, looked at every current tick, into the scope's
/// numbered stream: each sample once, counted from the scope's start.
#[derive(Clone, Copy, Debug, Default)]
pub struct ScopeTap {
    last_tick: Option<u32>,
    counter: u32,
}

impl ScopeTap {
    /// A tap that has seen nothing.
    #[must_use]
    pub const fn new() -> Self {
        Self {
            last_tick: None,
            counter: 0,
        }
    }

    /// The newest trace sample; `Some((counter, sample))` when it is one not seen before.
    /// The counter counts every new sample, also one the caller then cannot queue, so a
    /// lost sample is a gap in the stream.
    pub fn offer(&mut self, newest: Option<TraceSample>) -> Option<(u32, ScopeSample)> {
        let s = newest?;
        if self.last_tick == Some(s.tick) {
            return None;
        }
        self.last_tick = Some(s.tick);
        let counter = self.counter;
        self.counter = self.counter.wrapping_add(1);
        Some((
            counter,
            ScopeSample {
                tick: s.tick,
                values: s.values,
            },
        ))
    }
}

/// Records each fault latch in the history once, with the time it was seen.
#[derive(Clone, Copy, Debug, Default)]
pub struct FaultTracker {
    latched: Option<(u8, u32)>,
}

impl FaultTracker {
    /// Nothing latched.
    #[must_use]
    pub const fn new() -> Self {
        Self { latched: None }
    }

    /// The app's latched fault and its tick (`App::fault_record`), looked at `now_ms`;
    /// a new latch goes into `history`.
    pub fn poll(&mut self, record: Option<(Fault, u32)>, now_ms: u32, history: &mut FaultHistory) {
        let now = record.map(|(f, tick)| (fault_code(Some(f)), tick));
        if now.is_some() && now != self.latched {
            if let Some((code, _)) = now {
                history.push(FaultEntry { ms: now_ms, code });
            }
        }
        self.latched = now;
    }
}

/// Milliseconds in `ticks` current-loop ticks at `rate_hz`.
#[must_use]
pub fn ticks_to_ms(ticks: u64, rate_hz: u32) -> u32 {
    u32::try_from(ticks.saturating_mul(1000) / u64::from(rate_hz.max(1))).unwrap_or(u32::MAX)
}

/// The trace's channel names, comma separated (the scope's column names).
#[must_use]
pub fn channel_names(trace: &TraceConfig) -> heapless::String<128> {
    let mut s = heapless::String::new();
    for (i, c) in trace.channels.iter().enumerate() {
        if i > 0 {
            let _ = s.push(',');
        }
        let _ = s.push_str(c.name());
    }
    s
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;
    use crate::app::DEFAULT_TRACE;

    #[test]
    fn the_tap_numbers_each_new_sample_once() {
        let mut tap = ScopeTap::new();
        let s = |tick| TraceSample {
            tick,
            values: [tick as i32; TRACE_CHANNELS],
        };
        assert_eq!(tap.offer(None), None);
        assert_eq!(tap.offer(Some(s(4))).unwrap().0, 0);
        assert_eq!(tap.offer(Some(s(4))), None);
        let (n, sample) = tap.offer(Some(s(8))).unwrap();
        assert_eq!((n, sample.tick, sample.values[0]), (1, 8, 8));
    }

    #[test]
    fn a_latch_is_recorded_once_and_a_new_one_again() {
        let (mut t, mut h) = (FaultTracker::new(), FaultHistory::new());
        t.poll(Some((Fault::Overspeed, 10)), 3, &mut h);
        t.poll(Some((Fault::Overspeed, 10)), 4, &mut h);
        assert_eq!(h.total(), 1);
        t.poll(None, 5, &mut h);
        t.poll(Some((Fault::Overspeed, 90)), 22, &mut h);
        let e: Vec<_> = h.entries().collect();
        assert_eq!(e.len(), 2);
        assert_eq!(e[1].ms, 22);
        assert_eq!(e[1].code, fault_code(Some(Fault::Overspeed)));
    }

    #[test]
    fn channel_names_follow_the_trace_config() {
        assert_eq!(
            channel_names(&DEFAULT_TRACE).as_str(),
            "encoder_counts,current_pu,current_ref_pu,voltage_cmd_pu"
        );
        assert_eq!(ticks_to_ms(4000, 4000), 1000);
    }
}
