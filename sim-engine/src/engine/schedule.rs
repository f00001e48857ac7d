//! What the plant is given each tick: its two sub-steps, checked and given their exact
//! maps once, and the load torque without a scan of the scenario's load steps.

use crate::config::scenario::ScenarioSpec;
use crate::error::Result;
use plant_host::{FixedStep, TwoInertiaPlant};

/// The plant's two sub-steps of a tick (the computational delay's remainder, then the rest
/// of the tick), each checked and given its exact maps once.
pub(crate) struct TickSteps {
    pub(crate) delay: Option<FixedStep>,
    pub(crate) rest: Option<FixedStep>,
}

impl TickSteps {
    /// The sub-steps of `delay_s` and `rest_s` (none for a length that is not positive).
    pub(crate) fn new(plant: &mut TwoInertiaPlant, delay_s: f64, rest_s: f64) -> Result<Self> {
        let mut step = |dt_s: f64| -> Result<Option<FixedStep>> {
            if dt_s > 0.0 {
                let s = plant
                    .fixed_step(dt_s)
                    .map_err(crate::engine::plant::plant_error)?;
                Ok(Some(s))
            } else {
                Ok(None)
            }
        };
        let delay = step(delay_s)?;
        let rest = step(rest_s)?;
        Ok(Self { delay, rest })
    }
}

/// [`ScenarioSpec::load_torque_pu`] for the queries of a run, whose times move forward a
/// fraction of a tick at a time: the steps' part from the segment between two of their
/// distinct times (sorted) that the last query fell in, instead of a scan of the list.
/// Between two such times the steps at or before `t` are the same set, so the value is the
/// scan's at the segment's start, bit for bit.
pub(crate) struct LoadCursor<'a> {
    spec: &'a ScenarioSpec,
    /// The steps' distinct times, ascending, and the scan's value at each.
    times: Vec<f64>,
    values: Vec<f64>,
    /// The segment of the last query: [from, until), its steps' value, and the value with
    /// the sine's 0 added when there is no sine (the sum the scan forms).
    from: f64,
    until: f64,
    step: f64,
    no_sine: Option<f64>,
}

impl<'a> LoadCursor<'a> {
    pub(crate) fn new(spec: &'a ScenarioSpec) -> Self {
        // A NaN time is never at or before a query: the scan skips it, and so does this.
        let mut times: Vec<f64> = spec
            .load
            .iter()
            .map(|s| s.t_s)
            .filter(|t| !t.is_nan())
            .collect();
        times.sort_by(f64::total_cmp);
        times.dedup();
        let values = times.iter().map(|&t| spec.load_step_pu(t)).collect();
        let mut cursor = Self {
            spec,
            times,
            values,
            from: f64::NAN,
            until: f64::NAN,
            step: 0.0,
            no_sine: None,
        };
        cursor.seek(0.0);
        cursor
    }

    /// Moves to the segment that holds `t_s`.
    #[cold]
    fn seek(&mut self, t_s: f64) {
        // How many of the times are at or before t_s (all of them, for t_s = +inf).
        let at = self.times.partition_point(|&b| b <= t_s);
        self.from = at
            .checked_sub(1)
            .and_then(|i| self.times.get(i))
            .copied()
            .unwrap_or(f64::NEG_INFINITY);
        self.until = self.times.get(at).copied().unwrap_or(f64::INFINITY);
        self.step = at
            .checked_sub(1)
            .and_then(|i| self.values.get(i))
            .copied()
            .unwrap_or(0.0);
        self.no_sine = self.spec.sine_load.is_none().then_some(self.step + 0.0);
    }

    /// The load torque at `t_s` (pu), as [`ScenarioSpec::load_torque_pu`] gives it.
    #[inline]
    pub(crate) fn torque_pu(&mut self, t_s: f64) -> f64 {
        // A NaN query fails both tests and seeks: no time is at or before it.
        if !(t_s >= self.from && t_s < self.until) {
            self.seek(t_s);
        }
        match self.no_sine {
            Some(v) => v,
            None => self.step + self.spec.load_sine_pu(t_s),
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::LoadCursor;
    use crate::config::scenario::{LoadStep, SineLoad};

    /// The cursor gives the scan's value bit for bit: steps out of order, at equal times,
    /// a -0.0 torque, with and without a sine, queries forwards, backwards and on the edges.
    #[test]
    fn the_cursor_is_the_scan_bit_for_bit() {
        let mut spec = crate::resolve("fig6", None, &[]).unwrap().scenario;
        let step = |t_s, torque_pu| LoadStep { t_s, torque_pu };
        let lists = [
            vec![],
            vec![step(0.5, -0.0)],
            vec![
                step(1.0, 0.3),
                step(0.2, -0.1),
                step(1.0, 0.7),
                step(0.0, 0.05),
            ],
            vec![
                step(0.2, 0.1),
                step(0.2, -0.2),
                step(f64::NAN, 9.0),
                step(1.5, 0.0),
            ],
        ];
        let mut queries = vec![-1.0, 0.0, 0.2, 1.0, 1.5, 2.0, 1.0, 0.1999, f64::NAN, 0.5];
        queries.extend((0..4000).map(|k| f64::from(k) * 1e-3 * if k % 3 == 0 { 0.5 } else { 1.0 }));
        for sine in [
            None,
            Some(SineLoad {
                bias_pu: 0.1,
                amplitude_pu: 0.2,
                freq_rad_s: 60.0,
                start_s: 0.3,
            }),
        ] {
            for load in &lists {
                spec.load = load.clone();
                spec.sine_load = sine;
                let mut cursor = LoadCursor::new(&spec);
                for &t in &queries {
                    let (got, want) = (cursor.torque_pu(t), spec.load_torque_pu(t));
                    assert_eq!(got.to_bits(), want.to_bits(), "{load:?} {sine:?} t = {t}");
                }
            }
        }
    }
}
