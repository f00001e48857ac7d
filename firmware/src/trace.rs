//! Trend buffer: a fixed-size capture of chosen signals, as a drive's trend/trace function
//! keeps one. It records continuously into a ring (pre-trigger history); a trigger (a dump
//! request or a fault) lets it run on for a set number of post-trigger samples and then
//! freezes it, so the dump shows what led up to the event and what followed. No heap: the
//! ring is a `heapless::Deque` of `N` samples used as a history buffer (the oldest dropped
//! when full): unlike `heapless::HistoryBuffer::write`, its pop and push carry no bounds
//! check, so the interrupt that records has no panic path.

use heapless::Deque;

/// Number of signals captured per sample.
pub const TRACE_CHANNELS: usize = 4;

/// A signal the trend buffer can capture. Values are stored as raw `i32`: encoder counts as
/// counts, per-unit signals as the raw bits of their fixed-point type (scale named in
/// `TraceSignal::frac_bits`), so a dump is bit-exact.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TraceSignal {
    /// Encoder count sampled by the current loop [counts, wrapping].
    EncoderCounts,
    /// Measured current \[pu\].
    CurrentPu,
    /// Current reference from the velocity loop \[pu\].
    CurrentRefPu,
    /// Voltage command to the PWM \[pu\].
    VoltageCmdPu,
    /// Acceleration-feedback torque term \[pu\].
    AccelFbPu,
    /// Velocity setpoint from the profile \[pu\].
    VelocitySetpointPu,
    /// Position setpoint from the profile \[counts\].
    PositionSetpointCounts,
    /// Latched fault code (0 = none).
    FaultCode,
}

impl TraceSignal {
    /// Name used in dump headers.
    pub const fn name(self) -> &'static str {
        match self {
            Self::EncoderCounts => "encoder_counts",
            Self::CurrentPu => "current_pu",
            Self::CurrentRefPu => "current_ref_pu",
            Self::VoltageCmdPu => "voltage_cmd_pu",
            Self::AccelFbPu => "accel_fb_pu",
            Self::VelocitySetpointPu => "velocity_setpoint_pu",
            Self::PositionSetpointCounts => "position_setpoint_counts",
            Self::FaultCode => "fault_code",
        }
    }
}

/// One value of every traceable signal at one tick, raw (see [`TraceSignal`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
// In the order of `TraceSignal`, laid out as written: `words` is then the struct's own memory,
// and a channel a load at its index.
#[repr(C)]
pub struct SignalSnapshot {
    /// Encoder count \[counts\].
    pub encoder_counts: u32,
    /// Measured current, raw fixed-point bits.
    pub current_pu: i32,
    /// Current reference, raw fixed-point bits.
    pub current_ref_pu: i32,
    /// Voltage command, raw fixed-point bits.
    pub voltage_cmd_pu: i32,
    /// Acceleration-feedback term, raw fixed-point bits.
    pub accel_fb_pu: i32,
    /// Velocity setpoint, raw fixed-point bits.
    pub velocity_setpoint_pu: i32,
    /// Position setpoint \[counts\].
    pub position_setpoint_counts: i32,
    /// Fault code (0 = none).
    pub fault_code: i32,
}

impl SignalSnapshot {
    /// Every signal as a word, indexed by `TraceSignal as usize`: `words()[s as usize]` is
    /// `get(s)` (tested), so the store picks a channel with one indexed load instead of a
    /// jump table.
    #[inline(always)]
    pub const fn words(&self) -> [i32; 8] {
        [
            self.encoder_counts as i32,
            self.current_pu,
            self.current_ref_pu,
            self.voltage_cmd_pu,
            self.accel_fb_pu,
            self.velocity_setpoint_pu,
            self.position_setpoint_counts,
            self.fault_code,
        ]
    }

    /// The raw value of one signal.
    pub const fn get(&self, signal: TraceSignal) -> i32 {
        match signal {
            // Counts wrap: the bit pattern is kept, the reader takes differences.
            TraceSignal::EncoderCounts => self.encoder_counts as i32,
            TraceSignal::CurrentPu => self.current_pu,
            TraceSignal::CurrentRefPu => self.current_ref_pu,
            TraceSignal::VoltageCmdPu => self.voltage_cmd_pu,
            TraceSignal::AccelFbPu => self.accel_fb_pu,
            TraceSignal::VelocitySetpointPu => self.velocity_setpoint_pu,
            TraceSignal::PositionSetpointCounts => self.position_setpoint_counts,
            TraceSignal::FaultCode => self.fault_code,
        }
    }
}

/// One captured sample.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TraceSample {
    /// Current-loop tick index at capture (4 kHz ticks).
    pub tick: u32,
    /// Raw values of the chosen channels, in channel order.
    pub values: [i32; TRACE_CHANNELS],
}

/// Why a capture was triggered.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TriggerCause {
    /// An operator asked for a dump (UART command or API call).
    Request,
    /// The controller latched a fault.
    Fault,
}

/// Where the capture stands.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TraceState {
    /// Recording into the ring, waiting for a trigger.
    Armed,
    /// Triggered: recording `remaining` more samples, then frozen.
    PostTrigger {
        /// Samples still to record.
        remaining: u16,
        /// What triggered.
        cause: TriggerCause,
    },
    /// Full and frozen until [`TraceBuffer::rearm`]: ready to dump.
    Frozen {
        /// What triggered.
        cause: TriggerCause,
        /// Tick index of the trigger.
        trigger_tick: u32,
    },
}

/// A bad trend-buffer setting.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TraceConfigError {
    /// `decimation` must be 1..=1000 ticks per sample.
    Decimation,
    /// `post_trigger` must be 0..=N samples.
    PostTrigger,
}

/// Settings of a capture.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TraceConfig {
    /// The captured signals, in channel order.
    pub channels: [TraceSignal; TRACE_CHANNELS],
    /// Current-loop ticks per sample (1 = every 250 µs tick at 4 kHz).
    pub decimation: u16,
    /// Samples recorded after the trigger (the rest of the ring is pre-trigger history).
    pub post_trigger: u16,
}

/// The trend buffer of `N` samples.
pub struct TraceBuffer<const N: usize> {
    ring: Deque<TraceSample, N>,
    config: TraceConfig,
    /// Ticks until the next stored sample (1..=decimation; counts down, so a tick that
    /// does not record only decrements it and compares with zero).
    countdown: u16,
    state: TraceState,
    trigger_tick: u32,
}

impl<const N: usize> TraceBuffer<N> {
    /// A new armed, empty buffer.
    ///
    /// # Errors
    /// [`TraceConfigError`] naming the out-of-range setting.
    pub fn new(config: TraceConfig) -> Result<Self, TraceConfigError> {
        // A ring of no samples is refused when it is compiled (heapless' deque needs N > 0).
        const { assert!(N > 0, "a trend buffer holds at least one sample") };
        if config.decimation == 0 || config.decimation > 1000 {
            return Err(TraceConfigError::Decimation);
        }
        if usize::from(config.post_trigger) > N {
            return Err(TraceConfigError::PostTrigger);
        }
        Ok(Self {
            ring: Deque::new(),
            config,
            countdown: config.decimation,
            state: TraceState::Armed,
            trigger_tick: 0,
        })
    }

    /// The settings.
    pub const fn config(&self) -> &TraceConfig {
        &self.config
    }

    /// Where the capture stands.
    pub const fn state(&self) -> TraceState {
        self.state
    }

    /// Offer the signals of one current-loop tick. Stores every `decimation`-th tick while
    /// armed or post-trigger; does nothing once frozen. Constant time, no allocation.
    pub fn record(&mut self, tick: u32, signals: &SignalSnapshot) {
        self.record_with(tick, || *signals);
    }

    /// As [`TraceBuffer::record`], building the snapshot only on the ticks that store one.
    /// The test for those is inlined into the interrupt (a decrement of the countdown and a compare with zero);
    /// the snapshot and the store run only on every `decimation`-th tick.
    #[inline(always)]
    pub fn record_with(&mut self, tick: u32, signals: impl FnOnce() -> SignalSnapshot) {
        // A tick that does not record: one decrement and a compare with zero. The frozen
        // test is needed only on the ticks that would store (the countdown then stays at 1
        // until `rearm` resets it); `decimation` ≥ 1, so the countdown never wraps.
        let countdown = self.countdown.wrapping_sub(1);
        if countdown != 0 {
            self.countdown = countdown;
            return;
        }
        if matches!(self.state, TraceState::Frozen { .. }) {
            return;
        }
        self.countdown = self.config.decimation;
        self.store(tick, &signals());
    }

    /// Store one sample of the chosen channels and count down the post-trigger samples.
    #[inline(always)]
    fn store(&mut self, tick: u32, signals: &SignalSnapshot) {
        let mut values = [0_i32; TRACE_CHANNELS];
        let words = signals.words();
        for (value, signal) in values.iter_mut().zip(self.config.channels.iter()) {
            // A `TraceSignal` is below 8, so `get` always finds the word (no branch left).
            *value = words.get(*signal as usize).copied().unwrap_or(0);
        }
        if self.ring.is_full() {
            let _ = self.ring.pop_front();
        }
        // Not full now, so the push succeeds.
        let _ = self.ring.push_back(TraceSample { tick, values });
        if let TraceState::PostTrigger { remaining, cause } = self.state {
            let remaining = remaining.saturating_sub(1);
            self.state = if remaining == 0 {
                TraceState::Frozen {
                    cause,
                    trigger_tick: self.trigger_tick,
                }
            } else {
                TraceState::PostTrigger { remaining, cause }
            };
        }
    }

    /// Trigger the capture at `tick`. Ignored unless armed (the first trigger wins, as in
    /// a drive's trend buffer). With no post-trigger samples it freezes at once.
    pub fn trigger(&mut self, tick: u32, cause: TriggerCause) {
        if self.state != TraceState::Armed {
            return;
        }
        self.trigger_tick = tick;
        self.state = if self.config.post_trigger == 0 {
            TraceState::Frozen {
                cause,
                trigger_tick: tick,
            }
        } else {
            TraceState::PostTrigger {
                remaining: self.config.post_trigger,
                cause,
            }
        };
    }

    /// Number of stored samples.
    pub fn len(&self) -> usize {
        self.ring.len()
    }

    /// True when nothing is stored.
    pub fn is_empty(&self) -> bool {
        self.ring.is_empty()
    }

    /// The `index`-th stored sample, oldest first (`None` past the end).
    pub fn sample(&self, index: usize) -> Option<TraceSample> {
        // `as_slices` gives the ring in age order as two runs: constant time per sample.
        let (older, newer) = self.ring.as_slices();
        match older.get(index) {
            Some(s) => Some(*s),
            None => newer.get(index.checked_sub(older.len())?).copied(),
        }
    }

    /// The newest stored sample (the board console's scope taps it).
    pub fn newest(&self) -> Option<TraceSample> {
        self.ring.back().copied()
    }

    /// The stored samples, oldest first.
    pub fn samples(&self) -> impl Iterator<Item = &TraceSample> + '_ {
        self.ring.iter()
    }

    /// Empty the ring and arm again (after a dump).
    pub fn rearm(&mut self) {
        self.ring.clear();
        self.countdown = self.config.decimation;
        self.state = TraceState::Armed;
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, clippy::panic)]
    use super::*;

    fn config(decimation: u16, post_trigger: u16) -> TraceConfig {
        TraceConfig {
            channels: [
                TraceSignal::EncoderCounts,
                TraceSignal::CurrentPu,
                TraceSignal::FaultCode,
                TraceSignal::PositionSetpointCounts,
            ],
            decimation,
            post_trigger,
        }
    }

    /// `words()[s as usize]` is `get(s)` for every signal: the store's indexed pick is the
    /// named field.
    #[test]
    fn words_are_indexed_by_signal() {
        let all = [
            TraceSignal::EncoderCounts,
            TraceSignal::CurrentPu,
            TraceSignal::CurrentRefPu,
            TraceSignal::VoltageCmdPu,
            TraceSignal::AccelFbPu,
            TraceSignal::VelocitySetpointPu,
            TraceSignal::PositionSetpointCounts,
            TraceSignal::FaultCode,
        ];
        let s = SignalSnapshot {
            encoder_counts: 0xFFFF_FFF0,
            current_pu: 2,
            current_ref_pu: -3,
            voltage_cmd_pu: 4,
            accel_fb_pu: -5,
            velocity_setpoint_pu: 6,
            position_setpoint_counts: -7,
            fault_code: 8,
        };
        for signal in all {
            assert_eq!(s.words()[signal as usize], s.get(signal), "{signal:?}");
        }
        assert_eq!(s.words().len(), all.len());
    }

    fn snapshot(k: u32) -> SignalSnapshot {
        SignalSnapshot {
            encoder_counts: k.wrapping_mul(3),
            current_pu: -(k as i32),
            fault_code: 0,
            position_setpoint_counts: 7,
            ..SignalSnapshot::default()
        }
    }

    #[test]
    fn rejects_bad_settings() {
        assert_eq!(
            TraceBuffer::<8>::new(config(0, 2)).err(),
            Some(TraceConfigError::Decimation)
        );
        assert_eq!(
            TraceBuffer::<8>::new(config(1, 9)).err(),
            Some(TraceConfigError::PostTrigger)
        );
    }

    #[test]
    fn keeps_the_latest_n_samples_with_decimation() {
        let mut trace = TraceBuffer::<4>::new(config(2, 1)).unwrap();
        for k in 1..=20 {
            trace.record(k, &snapshot(k));
        }
        // Every 2nd tick stored (2, 4, ... 20); the ring holds the last 4.
        let ticks: Vec<u32> = trace.samples().map(|s| s.tick).collect();
        assert_eq!(ticks, vec![14, 16, 18, 20]);
        let first = trace.sample(0).unwrap();
        assert_eq!(first.values, [42, -14, 0, 7]);
    }

    /// The ring before and after it wraps: `sample(i)` is the i-th oldest, past the end
    /// `None`, and `len` counts up to N.
    #[test]
    fn ring_keeps_age_order_across_the_wrap() {
        let mut trace = TraceBuffer::<3>::new(config(1, 0)).unwrap();
        assert!(trace.is_empty());
        for k in 0..7u32 {
            trace.record(k, &snapshot(k));
            let ticks: Vec<u32> = trace.samples().map(|s| s.tick).collect();
            let first = k.saturating_sub(2);
            assert_eq!(ticks, (first..=k).collect::<Vec<_>>());
            assert_eq!(trace.len(), ticks.len());
            for (i, t) in ticks.iter().enumerate() {
                assert_eq!(trace.sample(i).unwrap().tick, *t);
            }
            assert_eq!(trace.sample(ticks.len()), None);
        }
    }

    #[test]
    fn freezes_after_post_trigger_samples() {
        let mut trace = TraceBuffer::<6>::new(config(1, 2)).unwrap();
        for k in 0..10 {
            trace.record(k, &snapshot(k));
        }
        trace.trigger(9, TriggerCause::Fault);
        trace.trigger(9, TriggerCause::Request); // ignored: first trigger wins
        for k in 10..20 {
            trace.record(k, &snapshot(k));
        }
        assert_eq!(
            trace.state(),
            TraceState::Frozen {
                cause: TriggerCause::Fault,
                trigger_tick: 9
            }
        );
        // 4 pre-trigger samples (6..=9) and 2 post-trigger (10, 11); 12.. were not stored.
        let ticks: Vec<u32> = trace.samples().map(|s| s.tick).collect();
        assert_eq!(ticks, vec![6, 7, 8, 9, 10, 11]);
        trace.rearm();
        assert!(trace.is_empty());
        assert_eq!(trace.state(), TraceState::Armed);
    }
}
