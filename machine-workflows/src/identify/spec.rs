//! The `[identify]` table of a machine file: how the measurement is taken. Every key is
//! optional (the defaults below); `--set identify.KEY=VALUE` overrides one. Nothing here
//! describes the machine: these are the test rig's and the excitation's settings.

use serde::{Deserialize, Serialize};
use sim_engine::config::typed::typed;
use sim_engine::error::{HarnessError, Result};
use toml::{Table, Value};

/// The identification settings.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct IdentifySpec {
    /// Velocity-loop bandwidth of the drive during the measurement \[rad/s\], (0, 200]: the
    /// drive runs in speed mode at zero speed, acceleration feedback off, with this soft
    /// loop, so that the torque the encoder's quantization makes the loop chatter with
    /// stays small beside the excitation.
    pub velocity_bandwidth_rad_s: f64,
    /// PRBS amplitude added to the torque reference \[pu\], (0, 1].
    pub amplitude_pu: f64,
    /// PRBS register length \[bits\], 7..=20.
    pub prbs_bits: u8,
    /// Current ticks each PRBS bit is held, 1..=100 (sets the band: flat to about
    /// 0.44·current_rate/hold).
    pub prbs_hold_ticks: u16,
    /// Whole PRBS periods, 1..=1000.
    pub prbs_periods: u16,
    /// Time cut from the start of the record (the loop settling on the preload) \[s\].
    pub settle_s: f64,
    /// Constant load torque during the frequency-response measurement, so the gears stay
    /// in contact \[pu\], 0..=1.5 (0 on a machine without lost motion is fine).
    pub preload_pu: f64,
    /// Welch segment length \[samples\], a power of two, 256..=65536.
    pub segment_len: usize,
    /// Smallest coherence γ² of a bin used by the fit, (0, 1).
    pub min_coherence: f64,
    /// Highest frequency the fit uses \[Hz\], > 0.
    pub max_freq_hz: f64,
    /// Load torque of the lost-motion test: the rig holds ±this and reverses it \[pu\],
    /// (0, 1].
    pub reversal_torque_pu: f64,
    /// Time between the reversals of the lost-motion test \[s\], 0.1..=10.
    pub reversal_hold_s: f64,
    /// Largest lost motion the fit searches \[deg at the motor\], (0, 45].
    pub max_lost_motion_deg: f64,
}

impl Default for IdentifySpec {
    fn default() -> Self {
        Self {
            velocity_bandwidth_rad_s: 15.0,
            amplitude_pu: 0.3,
            prbs_bits: 13,
            prbs_hold_ticks: 1,
            prbs_periods: 32,
            settle_s: 0.5,
            preload_pu: 0.8,
            segment_len: 8192,
            min_coherence: 0.6,
            max_freq_hz: 400.0,
            reversal_torque_pu: 0.2,
            reversal_hold_s: 0.5,
            max_lost_motion_deg: 5.0,
        }
    }
}

/// A value outside its range, as the error that names `identify.KEY`.
fn out_of_range(key: &str, v: f64, range: &str) -> HarnessError {
    HarnessError::config(format!("identify.{key}"), format!("{v} is outside {range}"))
}

impl IdentifySpec {
    /// Takes the `[identify]` table out of a machine file's value tree (so the rest is
    /// the machine) and deserializes and validates it; no table = the defaults.
    pub fn take(doc: &mut Table) -> Result<Self> {
        let spec: Self = match doc.remove("identify") {
            None => Self::default(),
            Some(v @ Value::Table(_)) => typed("identify", v)?,
            Some(_) => return Err(HarnessError::config("identify", "must be a table")),
        };
        spec.validate()?;
        Ok(spec)
    }

    /// Checks every key against its range.
    pub fn validate(&self) -> Result<()> {
        // (key, value, lower bound, lower bound included, upper bound)
        let ranges: [(&str, f64, f64, bool, f64); 12] = [
            (
                "velocity_bandwidth_rad_s",
                self.velocity_bandwidth_rad_s,
                0.0,
                false,
                200.0,
            ),
            ("amplitude_pu", self.amplitude_pu, 0.0, false, 1.0),
            ("prbs_bits", f64::from(self.prbs_bits), 7.0, true, 20.0),
            (
                "prbs_hold_ticks",
                f64::from(self.prbs_hold_ticks),
                1.0,
                true,
                100.0,
            ),
            (
                "prbs_periods",
                f64::from(self.prbs_periods),
                1.0,
                true,
                1000.0,
            ),
            ("settle_s", self.settle_s, 0.0, true, 10.0),
            ("preload_pu", self.preload_pu, 0.0, true, 1.5),
            ("min_coherence", self.min_coherence, 0.0, false, 0.999),
            ("max_freq_hz", self.max_freq_hz, 0.0, false, 1e5),
            (
                "reversal_torque_pu",
                self.reversal_torque_pu,
                0.0,
                false,
                1.0,
            ),
            ("reversal_hold_s", self.reversal_hold_s, 0.1, true, 10.0),
            (
                "max_lost_motion_deg",
                self.max_lost_motion_deg,
                0.0,
                false,
                45.0,
            ),
        ];
        for (key, v, lo, inclusive, hi) in ranges {
            let above = if inclusive { v >= lo } else { v > lo };
            if !(v.is_finite() && above && v <= hi) {
                let open = if inclusive { '[' } else { '(' };
                return Err(out_of_range(key, v, &format!("{open}{lo}, {hi}]")));
            }
        }
        let n = self.segment_len;
        if !n.is_power_of_two() || !(256..=65_536).contains(&n) {
            return Err(out_of_range(
                "segment_len",
                n as f64,
                "the powers of two 256..=65536",
            ));
        }
        Ok(())
    }

    /// Length of the PRBS \[current ticks\].
    pub fn prbs_ticks(&self) -> u64 {
        ((1u64 << self.prbs_bits) - 1)
            * u64::from(self.prbs_hold_ticks)
            * u64::from(self.prbs_periods)
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn take(text: &str) -> Result<IdentifySpec> {
        let mut doc: Table = text.parse().unwrap();
        IdentifySpec::take(&mut doc)
    }

    #[test]
    fn absent_keys_take_the_defaults_and_bad_ones_name_the_key_and_range() {
        assert_eq!(take("").unwrap(), IdentifySpec::default());
        let s = take("[identify]\namplitude_pu = 0.1\n").unwrap();
        assert_eq!(s.amplitude_pu, 0.1);
        for (text, key) in [
            ("[identify]\namplitude_pu = 0.0\n", "identify.amplitude_pu"),
            ("[identify]\nprbs_bits = 30\n", "identify.prbs_bits"),
            ("[identify]\nsegment_len = 1000\n", "identify.segment_len"),
            (
                "[identify]\nmin_coherence = 1.0\n",
                "identify.min_coherence",
            ),
            ("[identify]\nsettle_s = nan\n", "identify.settle_s"),
            ("[identify]\nnosuch = 1\n", "identify.nosuch"),
            ("identify = 3\n", "identify"),
        ] {
            let e = take(text).unwrap_err().to_string();
            assert!(e.contains(key), "{text}: {e}");
        }
        let e = take("[identify]\npreload_pu = 2.0\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("[0, 1.5]"), "{e}");
    }
}
