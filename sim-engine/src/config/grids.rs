//! The search grids of `sweep` and `tune` (`configs/grids.toml`, one table each): the
//! velocity bandwidths, the acceleration-feedback gains and filters and the observer
//! bandwidths each command tries. Read and checked on every use; an error names the key
//! (`sweep.gains[2]`) and its allowed range. The JSON Schema of the file is
//! `configs/grids.schema.json` (`hil-harness schema --grids`), with the same ranges.

use super::files::{configs_dir, read_table};
use super::typed::typed;
use crate::error::{HarnessError, Result};
use controller_core::FilterConfig;
use core::f32::consts::FRAC_1_SQRT_2;
use serde::Deserialize;
use std::path::PathBuf;
use toml::Table;

/// The grids file: the sweep's grid and `tune`'s.
#[derive(Clone, Debug, Deserialize, schemars::JsonSchema, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct GridsFile {
    /// `hil-harness sweep`: the probe run at each bandwidth, without AFB and with each
    /// error-form design (acceleration from differentiation, or from the observer at each
    /// of `observer_hz`) × `gains` × `filters`.
    pub sweep: Grid,
    /// `hil-harness tune` (and `commission`): the bandwidths searched without
    /// `--target-bandwidth`, and the candidates at each bandwidth: without AFB, and the
    /// error and plain forms × `gains` × `filters` × (observer, differentiation), at every
    /// one of `observer_hz`.
    pub tune: Grid,
}

/// One search grid.
#[derive(Clone, Debug, Deserialize, schemars::JsonSchema, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Grid {
    /// Velocity bandwidths tried \[rad/s\], ascending.
    pub bandwidths_rad_s: Vec<f64>,
    /// Acceleration-feedback gains tried (Ka / J_total), ascending.
    pub gains: Vec<f32>,
    /// Low-pass filters on the acceleration tried, each once.
    pub filters: Vec<GridFilter>,
    /// Observer bandwidths tried \[Hz\], ascending.
    pub observer_hz: Vec<f32>,
}

/// A low-pass filter of a grid: `{ kind = "first_order", corner_hz = 25.0 }`.
#[derive(Clone, Copy, Debug, Deserialize, schemars::JsonSchema, PartialEq)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum GridFilter {
    /// First-order low-pass.
    FirstOrder {
        /// Corner frequency \[Hz\].
        corner_hz: f32,
    },
    /// Second-order Butterworth low-pass (Q = 1/√2).
    SecondOrder {
        /// Corner frequency \[Hz\].
        corner_hz: f32,
    },
}

impl GridFilter {
    /// The drive's filter setting.
    #[must_use]
    pub fn config(self) -> FilterConfig {
        match self {
            Self::FirstOrder { corner_hz } => FilterConfig::FirstOrder { corner_hz },
            Self::SecondOrder { corner_hz } => FilterConfig::SecondOrder {
                corner_hz,
                q: FRAC_1_SQRT_2,
            },
        }
    }

    fn corner_hz(self) -> f32 {
        match self {
            Self::FirstOrder { corner_hz } | Self::SecondOrder { corner_hz } => corner_hz,
        }
    }
}

/// The allowed values of one list of a grid: each value in (min, max] (or [min, max]), and
/// 1 to [`MAX_VALUES`] values.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ListRange {
    /// Key in a grid table (`filters.corner_hz`: each filter's corner).
    pub key: &'static str,
    /// Lower bound.
    pub min: f64,
    /// Whether the lower bound itself is excluded.
    pub min_exclusive: bool,
    /// Upper bound (included).
    pub max: f64,
    /// Unit, for the message.
    pub unit: &'static str,
}

/// The most values a list may hold: a bound on a grid's run time (the sweep runs every
/// bandwidth × design on each plant).
pub const MAX_VALUES: usize = 32;

/// Velocity bandwidth: at most 3000 rad/s, below the 2 kHz velocity loop's Nyquist
/// (π·2000 ≈ 6283 rad/s) by a factor of two; a drive rejects a point too fast for its own
/// loop (the sweep lists it in `sweep.csv`'s `error`).
pub const BANDWIDTH: ListRange = ListRange {
    key: "bandwidths_rad_s",
    min: 0.0,
    min_exclusive: true,
    max: 3000.0,
    unit: "rad/s",
};
/// Ka / J_total: above 0 (a zero gain is the run without AFB, always in the grid) and at
/// most controller-core's own bound on `accel_feedback.gain_fraction`.
pub const GAIN: ListRange = ListRange {
    key: "gains",
    min: 0.0,
    min_exclusive: true,
    max: controller_core::ranges::AFB_GAIN_FRACTION.max as f64,
    unit: "",
};
/// Filter corner: at most 500 Hz, half the Nyquist frequency of the 2 kHz velocity loop
/// the filter runs in.
pub const CORNER: ListRange = ListRange {
    key: "filters.corner_hz",
    min: 0.0,
    min_exclusive: true,
    max: 500.0,
    unit: "Hz",
};
/// Observer bandwidth: at most 1000 Hz, the 2 kHz velocity loop's Nyquist frequency.
pub const OBSERVER: ListRange = ListRange {
    key: "observer_hz",
    min: 0.0,
    min_exclusive: true,
    max: 1000.0,
    unit: "Hz",
};

/// Every list's range, for the checks and the schema.
pub const RANGES: [ListRange; 4] = [BANDWIDTH, GAIN, CORNER, OBSERVER];

impl ListRange {
    /// The range as text: `(0, 3000] rad/s`.
    #[must_use]
    pub fn text(&self) -> String {
        let open = if self.min_exclusive { '(' } else { '[' };
        format!("{open}{}, {}] {}", self.min, self.max, self.unit)
            .trim_end()
            .to_string()
    }

    fn contains(&self, v: f64) -> bool {
        let above = if self.min_exclusive {
            v > self.min
        } else {
            v >= self.min
        };
        v.is_finite() && above && v <= self.max
    }

    /// Checks the values of `table.KEY` (`values`), each in range; `ascending`: each
    /// larger than the one before it.
    fn check(&self, table: &str, values: &[f64], ascending: bool) -> Result<()> {
        let list = self.key.split('.').next().unwrap_or(self.key);
        let key = format!("{table}.{list}");
        if values.is_empty() || values.len() > MAX_VALUES {
            return Err(HarnessError::config(
                key,
                format!(
                    "holds {} values; give 1 to {MAX_VALUES}, each in {}",
                    values.len(),
                    self.text()
                ),
            ));
        }
        for (i, v) in values.iter().enumerate() {
            let at = match self.key.split_once('.') {
                Some((_, field)) => format!("{key}[{i}].{field}"),
                None => format!("{key}[{i}]"),
            };
            if !self.contains(*v) {
                return Err(HarnessError::config(
                    at,
                    format!("{v} is outside {}", self.text()),
                ));
            }
            let before = i.checked_sub(1).and_then(|j| values.get(j));
            if ascending && before.is_some_and(|p| *p >= *v) {
                return Err(HarnessError::config(
                    at,
                    format!("{v}: the values must be ascending, each once"),
                ));
            }
        }
        Ok(())
    }
}

impl Grid {
    /// Checks every list of the table `table` (`sweep` or `tune`) against its range.
    pub fn validate(&self, table: &str) -> Result<()> {
        BANDWIDTH.check(table, &self.bandwidths_rad_s, true)?;
        let wide = |v: &[f32]| v.iter().map(|x| f64::from(*x)).collect::<Vec<_>>();
        GAIN.check(table, &wide(&self.gains), true)?;
        OBSERVER.check(table, &wide(&self.observer_hz), true)?;
        CORNER.check(
            table,
            &self
                .filters
                .iter()
                .map(|f| f64::from(f.corner_hz()))
                .collect::<Vec<_>>(),
            false,
        )?;
        // Two filters of different kinds may share a corner, the same filter twice not.
        for (i, f) in self.filters.iter().enumerate() {
            if self.filters.get(..i).unwrap_or_default().contains(f) {
                return Err(HarnessError::config(
                    format!("{table}.filters[{i}]"),
                    "the same filter twice: each filter once",
                ));
            }
        }
        Ok(())
    }

    /// The filters as the drive's settings.
    #[must_use]
    pub fn filter_configs(&self) -> Vec<FilterConfig> {
        self.filters.iter().map(|f| f.config()).collect()
    }
}

/// The grids file's path: `configs/grids.toml`.
#[must_use]
pub fn grids_path() -> PathBuf {
    configs_dir().join("grids.toml")
}

/// The grids of a grids file's value tree, checked.
pub fn grids_of(doc: Table) -> Result<GridsFile> {
    let file: GridsFile = typed("", toml::Value::Table(doc))?;
    file.sweep.validate("sweep")?;
    file.tune.validate("tune")?;
    Ok(file)
}

/// Reads and checks `configs/grids.toml`.
pub fn load_grids() -> Result<GridsFile> {
    grids_of(read_table(&grids_path())?)
}

/// The sweep's grid (`[sweep]` of `configs/grids.toml`).
pub fn sweep_grid() -> Result<Grid> {
    Ok(load_grids()?.sweep)
}

/// `tune`'s grid (`[tune]` of `configs/grids.toml`).
pub fn tune_grid() -> Result<Grid> {
    Ok(load_grids()?.tune)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;

    /// The shipped file with `edit` applied to its value tree; the error's text.
    fn error_of(edit: impl FnOnce(&mut Table)) -> String {
        let mut doc = read_table(&grids_path()).unwrap();
        edit(&mut doc);
        grids_of(doc).unwrap_err().to_string()
    }

    fn table<'a>(doc: &'a mut Table, name: &str) -> &'a mut Table {
        doc.get_mut(name).unwrap().as_table_mut().unwrap()
    }

    #[test]
    fn the_shipped_grids_load() {
        let g = load_grids().unwrap();
        assert_eq!(g.sweep.bandwidths_rad_s.len(), 17);
        assert_eq!(g.sweep.gains, [0.25, 0.5, 1.0, 2.0, 4.0]);
        assert_eq!(g.sweep.filters.len(), 6);
        assert_eq!(g.sweep.observer_hz, [75.0, 150.0]);
        assert_eq!(g.tune.bandwidths_rad_s.len(), 11);
        assert_eq!(g.tune.gains, [0.25, 0.5, 1.0, 2.0]);
        assert_eq!(g.tune.filters.len(), 7);
        assert_eq!(g.tune.observer_hz, [75.0, 100.0, 150.0, 250.0]);
        // Table 1's 15 Hz velocity loop is a point of both grids, written alike.
        for grid in [&g.sweep, &g.tune] {
            assert!(grid.bandwidths_rad_s.contains(&94.25), "{grid:?}");
        }
        assert_eq!(
            g.tune.filter_configs()[5],
            FilterConfig::SecondOrder {
                corner_hz: 100.0,
                q: FRAC_1_SQRT_2
            }
        );
    }

    #[test]
    fn an_unknown_key_is_an_error_naming_it_and_the_allowed_ones() {
        let e = error_of(|d| {
            table(d, "sweep").insert("gain".into(), toml::Value::Float(1.0));
        });
        assert!(
            e.contains("sweep") && e.contains("gain") && e.contains("gains"),
            "{e}"
        );
        let e = error_of(|d| {
            d.insert("tunes".into(), toml::Value::Table(Table::new()));
        });
        assert!(e.contains("tunes"), "{e}");
        let e = error_of(|d| {
            let f = &mut table(d, "tune")["filters"].as_array_mut().unwrap()[0];
            f.as_table_mut()
                .unwrap()
                .insert("q".into(), toml::Value::Float(0.5));
        });
        assert!(e.contains("tune.filters[0]") && e.contains('q'), "{e}");
    }

    #[test]
    fn a_value_out_of_range_is_an_error_naming_the_key_and_the_range() {
        let e = error_of(|d| {
            table(d, "sweep")["gains"].as_array_mut().unwrap()[4] = toml::Value::Float(40.0);
        });
        assert!(e.contains("sweep.gains[4]") && e.contains("(0, 20]"), "{e}");
        let e = error_of(|d| {
            table(d, "tune")["bandwidths_rad_s"].as_array_mut().unwrap()[0] =
                toml::Value::Float(-1.0);
        });
        assert!(
            e.contains("tune.bandwidths_rad_s[0]") && e.contains("(0, 3000] rad/s"),
            "{e}"
        );
        let e = error_of(|d| {
            let f = &mut table(d, "sweep")["filters"].as_array_mut().unwrap()[1];
            f.as_table_mut()
                .unwrap()
                .insert("corner_hz".into(), toml::Value::Float(5000.0));
        });
        assert!(
            e.contains("sweep.filters[1].corner_hz") && e.contains("(0, 500] Hz"),
            "{e}"
        );
        let e = error_of(|d| {
            table(d, "tune")["observer_hz"].as_array_mut().unwrap()[1] = toml::Value::Float(0.0);
        });
        assert!(
            e.contains("tune.observer_hz[1]") && e.contains("(0, 1000] Hz"),
            "{e}"
        );
    }

    #[test]
    fn an_empty_list_a_repeat_or_a_wrong_order_is_an_error() {
        let e = error_of(|d| {
            table(d, "sweep").insert("gains".into(), toml::Value::Array(Vec::new()));
        });
        assert!(
            e.contains("sweep.gains") && e.contains("1 to 32") && e.contains("(0, 20]"),
            "{e}"
        );
        let e = error_of(|d| {
            table(d, "tune").insert("filters".into(), toml::Value::Array(Vec::new()));
        });
        assert!(
            e.contains("tune.filters") && e.contains("(0, 500] Hz"),
            "{e}"
        );
        let e = error_of(|d| {
            table(d, "sweep")["bandwidths_rad_s"]
                .as_array_mut()
                .unwrap()[1] = toml::Value::Float(1.0);
        });
        assert!(
            e.contains("sweep.bandwidths_rad_s[1]") && e.contains("ascending"),
            "{e}"
        );
        let e = error_of(|d| {
            let f = table(d, "tune")["filters"].as_array_mut().unwrap();
            let first = f[0].clone();
            f.push(first);
        });
        assert!(e.contains("tune.filters[7]") && e.contains("once"), "{e}");
        let e = error_of(|d| {
            table(d, "tune").remove("gains");
        });
        assert!(e.contains("gains"), "{e}");
    }
}
