//! The figures of a `fw-bench` run from its trace: per tick, per period (one current tick
//! and its share of a velocity tick), and the report's lines with their bounds.

use std::fmt::Write as _;

use super::price::{
    DIVIDE_CYCLES, EXCEPTION_CYCLES, EXCEPTION_ENTRY, EXCEPTION_EXIT, FLASH_WAIT_STATES,
    PIPELINE_REFILL,
};
use super::trace::Trace;
use super::tracker::Which;

/// Mean and worst case of one figure over the windows.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Stat {
    /// Windows.
    pub n: usize,
    /// Mean.
    pub mean: f64,
    /// Worst case.
    pub max: u32,
}

impl Stat {
    /// Over `values`.
    pub fn of(values: impl Iterator<Item = u32>) -> Self {
        let (mut n, mut sum, mut max) = (0_usize, 0_u64, 0_u32);
        for v in values {
            n += 1;
            sum += u64::from(v);
            max = max.max(v);
        }
        let mean = if n == 0 { 0.0 } else { sum as f64 / n as f64 };
        Self { n, mean, max }
    }
}

/// The figures of one tick kind.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TickFigures {
    /// Instructions of the body.
    pub instructions: Stat,
    /// Cycles of the body.
    pub cycles: Stat,
    /// Taken branches (for the flash bound).
    pub taken: Stat,
}

impl TickFigures {
    /// Over the windows of `which`.
    #[must_use]
    pub fn of(trace: &Trace, which: Which) -> Self {
        Self {
            instructions: Stat::of(trace.of(which).map(|w| w.instructions)),
            cycles: Stat::of(trace.of(which).map(|w| w.cycles)),
            taken: Stat::of(trace.of(which).map(|w| w.taken)),
        }
    }
}

/// The cycle figures of a `fw-bench` run: per tick and per period.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BenchFigures {
    /// The current tick.
    pub current: TickFigures,
    /// The velocity tick.
    pub velocity: TickFigures,
    /// Current ticks per velocity tick: a period holds a current tick and this share of a
    /// velocity tick.
    pub share: u32,
    /// Mean period: current + velocity / share, with each interrupt's entry and exit
    /// \[cycles\].
    pub period_mean: f64,
    /// Worst period: worst current + worst velocity / share (rounded up), with each
    /// interrupt's entry and exit \[cycles\].
    pub period_worst: u32,
    /// Mean and worst period \[instructions\], as the cycles.
    pub period_instructions_mean: f64,
    /// Worst period \[instructions\].
    pub period_instructions_worst: u32,
    /// Windows dropped (an interrupt came into them).
    pub dropped: u32,
    /// Instructions of no known class over the run (priced 1).
    pub unknown: u32,
}

impl BenchFigures {
    /// From a trace of `fw-bench`, a period holding `share` current ticks per velocity tick
    /// (at least 1).
    #[must_use]
    pub fn of(trace: &Trace, share: u32) -> Self {
        let share = share.max(1);
        let current = TickFigures::of(trace, Which::Current);
        let velocity = TickFigures::of(trace, Which::Velocity);
        let exc = f64::from(EXCEPTION_CYCLES);
        let n = f64::from(share);
        let period_mean = current.cycles.mean + exc + (velocity.cycles.mean + exc) / n;
        let period_worst = current.cycles.max
            + EXCEPTION_CYCLES
            + (velocity.cycles.max + EXCEPTION_CYCLES).div_ceil(share);
        Self {
            current,
            velocity,
            share,
            period_mean,
            period_worst,
            period_instructions_mean: current.instructions.mean + velocity.instructions.mean / n,
            period_instructions_worst: current.instructions.max
                + velocity.instructions.max.div_ceil(share),
            dropped: trace.dropped,
            unknown: trace.windows.iter().map(|(_, w)| w.unknown).sum(),
        }
    }

    /// The report's lines.
    #[must_use]
    pub fn lines(&self) -> Vec<String> {
        let mut out = vec![format!(
            "cycle estimate: every instruction QEMU executed in each measured window (TCG plugin), \
             priced by the Cortex-M4 TRM's timings: pipeline refill P = {PIPELINE_REFILL} per taken branch, \
             divides at their worst case ({DIVIDE_CYCLES}), flash at 0 wait states (ART accelerator hits), \
             exception entry {EXCEPTION_ENTRY} + exit {EXCEPTION_EXIT} per interrupt (lazy FP stacking); \
             windows as the SysTick figures (net of the measuring code)"
        )];
        for (name, t) in [("current", &self.current), ("velocity", &self.velocity)] {
            out.push(format!(
                "{name}_tick_cycles: mean {:.0} worst {} (body; {} with exception entry/exit: mean {:.0} worst {}); \
                 instructions mean {:.1} worst {}; over {} ticks",
                t.cycles.mean,
                t.cycles.max,
                name,
                t.cycles.mean + f64::from(EXCEPTION_CYCLES),
                t.cycles.max + EXCEPTION_CYCLES,
                t.instructions.mean,
                t.instructions.max,
                t.cycles.n
            ));
        }
        let k = self.share;
        out.push(format!(
            "period_cycles: mean {:.0} worst {} (one period: current + velocity/{k}, each with exception entry/exit; \
             worst = worst current + worst velocity/{k})",
            self.period_mean, self.period_worst
        ));
        out.push(format!(
            "period_instructions (traced): mean {:.1} worst {}",
            self.period_instructions_mean, self.period_instructions_worst
        ));
        let taken = self.current.taken.mean + self.velocity.taken.mean / f64::from(k);
        let flash = f64::from(FLASH_WAIT_STATES) * taken;
        let mut note = format!(
            "cycle bounds: P = 1 or 3 instead of {PIPELINE_REFILL} moves the mean period by ∓/± {:.0}; \
             a flash miss ({FLASH_WAIT_STATES} wait states at 168 MHz) on every taken branch would add up to {flash:.0}",
            taken
        );
        if self.dropped > 0 || self.unknown > 0 {
            let _ = write!(
                note,
                "; {} windows dropped (interrupted), {} instructions of no known class priced 1",
                self.dropped, self.unknown
            );
        }
        out.push(note);
        out
    }
}

/// The value of a `name: N` line of the firmware's log, if there is one.
#[must_use]
pub fn log_value(lines: &[String], name: &str) -> Option<u32> {
    log_values(lines, name).first().copied()
}

/// The values of every `name: N` line of the firmware's log, in order (one per group of
/// windows when the firmware logs one per drive).
#[must_use]
pub fn log_values(lines: &[String], name: &str) -> Vec<u32> {
    lines
        .iter()
        .filter_map(|l| {
            l.strip_prefix(name)
                .and_then(|r| r.strip_prefix(':'))
                .and_then(|r| r.split_whitespace().next())
                .and_then(|v| v.parse().ok())
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cycles::{window_line, Window};

    #[test]
    fn the_trace_file_round_trips_and_the_period_adds_a_share_of_a_velocity_tick() {
        let w = |i, c| Window {
            instructions: i,
            cycles: c,
            ..Window::default()
        };
        let mut text = String::new();
        for (which, win) in [
            (Which::Current, w(400, 500)),
            (Which::Current, w(420, 540)),
            (Which::Velocity, w(470, 600)),
        ] {
            text.push_str(&window_line(which, &win));
            text.push('\n');
        }
        text.push_str("dropped 2\n");
        let trace = Trace::parse(&text).unwrap_or_default();
        assert_eq!(trace.windows.len(), 3);
        assert_eq!(trace.dropped, 2);
        let f = BenchFigures::of(&trace, 2);
        assert_eq!(f.current.cycles.max, 540);
        assert!((f.current.cycles.mean - 520.0).abs() < 1e-9);
        assert_eq!(f.period_worst, 540 + 22 + (600 + 22) / 2);
        assert_eq!(f.period_instructions_worst, 420 + 235);
        // A tenth of a velocity tick (a 20 kHz current loop, a 2 kHz velocity loop).
        let f = BenchFigures::of(&trace, 10);
        assert_eq!(f.period_worst, 540 + 22 + (600 + 22_u32).div_ceil(10));
        assert_eq!(f.period_instructions_worst, 420 + 47);
        assert!(Trace::parse("current 1 2\n").is_err());
        let lines = vec![
            "period_cycle_budget: 900".to_string(),
            "period_cycle_budget: 1260 (second drive)".to_string(),
        ];
        assert_eq!(log_value(&lines, "period_cycle_budget"), Some(900));
        assert_eq!(log_values(&lines, "period_cycle_budget"), vec![900, 1260]);
        assert_eq!(log_value(&lines, "period_cycles"), None);
        // Groups split at the `group` lines.
        text.push_str("group\n");
        text.push_str(&window_line(Which::Current, &w(900, 1000)));
        let groups = Trace::parse_groups(&text).unwrap_or_default();
        assert_eq!(groups.len(), 2);
        assert_eq!(
            groups.first().map(|g| (g.windows.len(), g.dropped)),
            Some((3, 2))
        );
        assert_eq!(groups.get(1).map(|g| g.windows.len()), Some(1));
    }
}
