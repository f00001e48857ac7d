//! The sweep's designs: acceleration-feedback designs as typed drive settings, made from
//! the sweep's grid (`[sweep]` of `configs/grids.toml`, [`sim_engine::config::grids`]).

use controller_core::{AfbMode, DriveConfig, Estimator, FilterConfig};
use sim_engine::config::Grid;

/// One acceleration-feedback design: the `[drive.accel_feedback]` settings it changes, and
/// the observer bandwidth.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AfbDesign {
    /// Form of the feedback (`Off`: the config's other AFB settings stay, unused).
    pub mode: AfbMode,
    /// Ka / J_total.
    pub gain_fraction: f32,
    /// Low-pass filter on the acceleration.
    pub filter: FilterConfig,
    /// Source of the acceleration.
    pub source: Estimator,
    /// Observer bandwidth (Hz); 0 = the config's.
    pub observer_hz: f32,
}

/// A word for an enum value in labels and CSV columns: its name in lower case.
pub fn word(value: impl core::fmt::Debug) -> String {
    format!("{value:?}").to_lowercase()
}

/// The filter's kind and corner for labels and CSV columns.
pub fn filter_parts(f: FilterConfig) -> (&'static str, f32) {
    match f {
        FilterConfig::None => ("none", 0.0),
        FilterConfig::FirstOrder { corner_hz } => ("first_order", corner_hz),
        FilterConfig::SecondOrder { corner_hz, .. } => ("second_order", corner_hz),
    }
}

impl serde::Serialize for AfbDesign {
    /// The design as words and numbers: mode, Ka / J_total, filter kind and corner (Hz),
    /// acceleration source, observer bandwidth (Hz, 0 = the config's).
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeStruct as _;
        let (kind, corner) = filter_parts(self.filter);
        let mut st = s.serialize_struct("AfbDesign", 6)?;
        st.serialize_field("mode", &word(self.mode))?;
        st.serialize_field("gain_fraction", &self.gain_fraction)?;
        st.serialize_field("filter", kind)?;
        st.serialize_field("filter_corner_hz", &corner)?;
        st.serialize_field("source", &word(self.source))?;
        st.serialize_field("observer_hz", &self.observer_hz)?;
        st.end()
    }
}

impl AfbDesign {
    /// No acceleration feedback.
    pub const OFF: Self = Self {
        mode: AfbMode::Off,
        gain_fraction: 0.0,
        filter: FilterConfig::None,
        source: Estimator::Observer,
        observer_hz: 0.0,
    };

    /// Short label.
    pub fn label(&self) -> String {
        if self.mode == AfbMode::Off {
            return if self.observer_hz > 0.0 {
                format!("no AFB, observer {}Hz", self.observer_hz)
            } else {
                "no AFB".into()
            };
        }
        let observer = if self.observer_hz > 0.0 {
            format!(" {}Hz", self.observer_hz)
        } else {
            String::new()
        };
        let (kind, corner) = filter_parts(self.filter);
        format!(
            "{} Ka={}J {}-order {corner}Hz {}{observer}",
            word(self.mode),
            self.gain_fraction,
            if kind == "first_order" { "1st" } else { "2nd" },
            word(self.source)
        )
    }

    /// Sets this design's fields in `drive`.
    pub fn apply(&self, drive: &mut DriveConfig) {
        let afb = &mut drive.accel_feedback;
        afb.mode = self.mode;
        if self.mode != AfbMode::Off {
            afb.gain_fraction = self.gain_fraction;
            afb.filter = self.filter;
            afb.source = self.source;
        }
        // The observer also gives the velocity feedback, with AFB or without.
        if self.observer_hz > 0.0 {
            drive.observer.bandwidth_hz = self.observer_hz;
        }
    }
}

/// The run without AFB that is the same drive as `d` without its AFB: the observer (which
/// also gives the velocity feedback) at `d`'s bandwidth, or at `default_observer_hz`, the
/// config's (then written as 0, so that each run without AFB appears once).
pub fn without_afb_of(d: &AfbDesign, default_observer_hz: f32) -> AfbDesign {
    let hz = if d.observer_hz > 0.0 && d.observer_hz != default_observer_hz {
        d.observer_hz
    } else {
        0.0
    };
    AfbDesign {
        observer_hz: hz,
        ..AfbDesign::OFF
    }
}

/// The designs of `grid`: error-form AFB over source (differentiation, or the observer at
/// each of `grid.observer_hz`) × gain × filter, and without AFB at each observer bandwidth
/// the AFB designs use ([`without_afb_of`]; `default_observer_hz` is the configs' observer).
pub fn designs(grid: &Grid, default_observer_hz: f32) -> Vec<AfbDesign> {
    let mut v = vec![AfbDesign::OFF];
    for &hz in &grid.observer_hz {
        let off = without_afb_of(
            &AfbDesign {
                observer_hz: hz,
                ..AfbDesign::OFF
            },
            default_observer_hz,
        );
        if !v.contains(&off) {
            v.push(off);
        }
    }
    let sources = [(Estimator::Differentiation, 0.0)]
        .into_iter()
        .chain(grid.observer_hz.iter().map(|hz| (Estimator::Observer, *hz)));
    let filters = grid.filter_configs();
    for (source, observer_hz) in sources {
        for &gain_fraction in &grid.gains {
            for &filter in &filters {
                v.push(AfbDesign {
                    mode: AfbMode::Error,
                    gain_fraction,
                    filter,
                    source,
                    observer_hz,
                });
            }
        }
    }
    v
}
