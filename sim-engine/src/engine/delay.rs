//! The computational delay between a current tick and its command reaching the plant.

use std::collections::VecDeque;

/// The computational delay D = n·Tc + r (0 <= r < Tc) between a current tick and its
/// command reaching the plant: the command of tick k arrives r into the interval of tick
/// k + n. [`DelayLine::push`] takes tick k's command and returns the one that arrives
/// during this interval. The command is whatever the motor's plant takes: the DC
/// winding's voltage (`f64`), a PMSM inverter's three duties or its switches off.
#[derive(Clone, Debug)]
pub struct DelayLine<T = f64> {
    whole_ticks: usize,
    remainder_s: f64,
    in_flight: VecDeque<T>,
}

impl<T: Copy> DelayLine<T> {
    /// A delay of `delay_s` (negative counts as 0) at tick period `tick_s`.
    pub fn new(delay_s: f64, tick_s: f64) -> Self {
        let delay_s = delay_s.max(0.0);
        let whole = (delay_s / tick_s).floor();
        let whole_ticks = whole as usize;
        Self {
            whole_ticks,
            remainder_s: delay_s - whole * tick_s,
            in_flight: VecDeque::with_capacity(whole_ticks + 1),
        }
    }

    /// r, the part of the delay within one tick (s).
    pub fn remainder_s(&self) -> f64 {
        self.remainder_s
    }

    /// n, the whole ticks of the delay.
    pub fn whole_ticks(&self) -> usize {
        self.whole_ticks
    }

    /// Takes this tick's command; returns the command that arrives r into this interval
    /// (`held`, the one applied so far, while the line is still filling).
    #[inline]
    pub fn push(&mut self, command: T, held: T) -> T {
        if self.whole_ticks == 0 {
            // Shorter than a tick: this tick's command, as the queue would return it.
            return command;
        }
        self.in_flight.push_back(command);
        if self.in_flight.len() > self.whole_ticks {
            self.in_flight.pop_front().unwrap_or(held)
        } else {
            held
        }
    }
}

#[cfg(test)]
mod tests {
    use super::DelayLine;

    #[test]
    fn a_delay_shorter_than_a_tick_applies_this_ticks_command_after_the_remainder() {
        let mut d = DelayLine::new(180e-6, 250e-6);
        assert_eq!((d.whole_ticks(), d.remainder_s()), (0, 180e-6));
        assert_eq!(d.push(1.0, 0.0), 1.0);
        assert_eq!(d.push(2.0, 1.0), 2.0);
    }

    #[test]
    fn a_longer_delay_is_whole_ticks_plus_the_remainder() {
        // 5 ms at 4 kHz: 20 whole ticks, no remainder; 0.5 ms + 30 µs: 2 ticks + 30 µs.
        let d = DelayLine::<f64>::new(5e-3, 250e-6);
        assert_eq!(d.whole_ticks(), 20);
        assert!(d.remainder_s().abs() < 1e-12);
        let mut d = DelayLine::new(530e-6, 250e-6);
        assert_eq!(d.whole_ticks(), 2);
        assert!((d.remainder_s() - 30e-6).abs() < 1e-12);
        // Commands 1, 2, 3, ... : tick k's command arrives in the interval of tick k + 2.
        let mut held = 0.0;
        let arrived: Vec<f64> = (1..=6)
            .map(|k| {
                held = d.push(f64::from(k), held);
                held
            })
            .collect();
        assert_eq!(arrived, vec![0.0, 0.0, 1.0, 2.0, 3.0, 4.0]);
    }

    #[test]
    fn a_delay_of_exactly_one_tick_holds_the_previous_command_for_the_whole_tick() {
        let mut d = DelayLine::new(250e-6, 250e-6);
        assert_eq!((d.whole_ticks(), d.remainder_s()), (1, 0.0));
        assert_eq!(d.push(1.0, 0.0), 0.0);
        assert_eq!(d.push(2.0, 0.0), 1.0);
    }

    /// Any command type goes through the same line: a PMSM's duties, or its switches off
    /// (`None`), arrive whole ticks late, in order.
    #[test]
    fn an_inverter_command_is_delayed_as_a_voltage_is() {
        type Command = Option<[f64; 3]>;
        let mut d = DelayLine::<Command>::new(530e-6, 250e-6);
        let sent: [Command; 4] = [Some([0.1; 3]), None, Some([0.3, 0.4, 0.5]), Some([0.9; 3])];
        let mut held: Command = Some([0.5; 3]);
        let arrived: Vec<Command> = sent
            .iter()
            .map(|&c| {
                held = d.push(c, held);
                held
            })
            .collect();
        let start = Some([0.5; 3]);
        assert_eq!(arrived, vec![start, start, sent[0], sent[1]]);
    }
}
