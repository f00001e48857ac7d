//! When and why a run's drive tripped, and the protections' own figures checked from the
//! outside: the first current sample over the overcurrent level, and the I²t model's
//! prediction of its trip.
//!
//! The prediction integrates the thermal model of `controller_core::protection` in `f64`
//! on the current samples the drive was given, tick by tick: H += (i² − i_cont²)·Tc, held at
//! 0 from below, trips at H_trip = (i_ol² − i_cont²)·t_ol. It shares no arithmetic with the
//! fixed-point integrator in the core, so `predicted_trip_s` against the fault's own time
//! checks that one against the model it implements.

use controller_core::{DriveConfig, Fault};
use serde::Serialize;

/// The fault a run latched first: `summary.json`'s `fault` object.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FaultRecord {
    /// What tripped: the fault's stable name, `controller_core::Fault::name` (`overload`,
    /// `overcurrent`, `stall`, ...); `cause` in `summary.json`.
    #[serde(rename = "cause")]
    pub kind: &'static str,
    /// Its code in the tick outputs' fault word (1..).
    pub code: u8,
    /// What it means.
    pub description: String,
    /// Simulated time of the current tick that first reported it \[s\].
    pub t_s: f64,
    /// That current tick's index (0 = the first tick).
    pub tick: u64,
}

/// `summary.json`'s `protection` object.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct ProtectionSummary {
    /// Overcurrent level, `faults.overcurrent_ratio × torque_limit_pu` \[pu\].
    pub overcurrent_level_pu: f64,
    /// Consecutive current ticks over the level that trip.
    pub overcurrent_ticks: u32,
    /// The first current sample over the level: its tick and time; `None` if none was.
    pub first_over_current_tick: Option<u64>,
    /// Time of that sample \[s\].
    pub first_over_current_s: Option<f64>,
    /// The I²t model's trip level H_trip = (i_ol² − i_cont²)·t_ol \[pu²·s\].
    pub thermal_trip_pu2_s: f64,
    /// Largest heat of the `f64` model over the run, as a fraction of H_trip.
    pub thermal_peak_fraction: f64,
    /// When the `f64` model reaches the warning level \[s\]; `None` if it does not.
    pub thermal_warning_s: Option<f64>,
    /// When the `f64` model reaches H_trip \[s\]: the thermal model's prediction of the
    /// overload trip; `None` if it does not within the run.
    pub predicted_trip_s: Option<f64>,
}

/// Follows a run tick by tick.
#[derive(Clone, Debug)]
pub struct ProtectionWatch {
    tc_s: f64,
    continuous_sq: f64,
    warn_pu2_s: f64,
    heat_pu2_s: f64,
    fault: Option<FaultRecord>,
    summary: ProtectionSummary,
}

impl ProtectionWatch {
    /// For a run of `drive`. The overcurrent level is the core's own quantized one
    /// (so "over" means what it means to the drive); the thermal model is the settings'.
    pub fn new(drive: &DriveConfig) -> Self {
        let f = &drive.faults;
        let level = controller_core::protection::Protection::new(drive)
            .map(|p| f64::from(p.overcurrent_pu()))
            .unwrap_or(f64::INFINITY);
        let (ic, iol) = (
            f64::from(f.continuous_current_pu),
            f64::from(f.overload_current_pu),
        );
        let trip = (iol * iol - ic * ic) * f64::from(f.overload_time_s);
        Self {
            tc_s: 1.0 / f64::from(drive.current_rate_hz.max(1)),
            continuous_sq: ic * ic,
            warn_pu2_s: trip * f64::from(f.thermal_warning_fraction),
            heat_pu2_s: 0.0,
            fault: None,
            summary: ProtectionSummary {
                overcurrent_level_pu: level,
                overcurrent_ticks: f.overcurrent_ticks,
                thermal_trip_pu2_s: trip,
                ..ProtectionSummary::default()
            },
        }
    }

    /// Current tick `k` at `t_s`: the current sample the drive read and the fault it reported.
    pub fn tick(&mut self, k: u64, t_s: f64, current_pu: f64, fault: Option<Fault>) {
        let s = &mut self.summary;
        if s.first_over_current_tick.is_none() && current_pu.abs() > s.overcurrent_level_pu {
            s.first_over_current_tick = Some(k);
            s.first_over_current_s = Some(t_s);
        }
        let heat =
            (self.heat_pu2_s + (current_pu * current_pu - self.continuous_sq) * self.tc_s).max(0.0);
        self.heat_pu2_s = heat;
        let trip = s.thermal_trip_pu2_s;
        s.thermal_peak_fraction = s.thermal_peak_fraction.max(heat / trip);
        let now = t_s + self.tc_s;
        if s.thermal_warning_s.is_none() && heat >= self.warn_pu2_s {
            s.thermal_warning_s = Some(now);
        }
        if s.predicted_trip_s.is_none() && heat >= trip {
            s.predicted_trip_s = Some(now);
        }
        if let (None, Some(f)) = (&self.fault, fault) {
            self.fault = Some(FaultRecord {
                kind: f.name(),
                code: f.code(),
                description: f.to_string(),
                t_s,
                tick: k,
            });
        }
    }

    /// The first fault and the summary.
    pub fn finish(self) -> (Option<FaultRecord>, ProtectionSummary) {
        (self.fault, self.summary)
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn drive() -> DriveConfig {
        toml::from_str(include_str!(
            "../../../controller-core/doc/example-drive.toml"
        ))
        .unwrap()
    }

    #[test]
    fn the_f64_model_predicts_the_closed_form_trip_at_constant_current() {
        let d = drive();
        let mut w = ProtectionWatch::new(&d);
        let tc = 1.0 / f64::from(d.current_rate_hz);
        let closed = 60.0 * (1.5f64.powi(2) - 1.0) / (2.5f64.powi(2) - 1.0);
        let mut k = 0;
        while w.summary.predicted_trip_s.is_none() && k < 10_000_000 {
            w.tick(k, k as f64 * tc, 2.5, None);
            k += 1;
        }
        let t = w.summary.predicted_trip_s.unwrap();
        assert!((t - closed).abs() < 2.0 * tc, "{t} against {closed}");
        let warn = w.summary.thermal_warning_s.unwrap();
        assert!((warn - 0.8 * closed).abs() < 2.0 * tc, "{warn}");
    }

    #[test]
    fn the_first_sample_over_the_level_and_the_first_fault_are_recorded_once() {
        let d = drive();
        let mut w = ProtectionWatch::new(&d);
        let level = w.summary.overcurrent_level_pu;
        w.tick(0, 0.0, level, None);
        w.tick(1, 1e-3, -level - 1e-3, None);
        w.tick(2, 2e-3, level + 1.0, Some(Fault::Overcurrent));
        w.tick(3, 3e-3, 0.0, Some(Fault::Overload));
        let (f, s) = w.finish();
        assert_eq!(s.first_over_current_tick, Some(1));
        let f = f.unwrap();
        assert_eq!((f.kind, f.tick, f.code), ("overcurrent", 2, 5));
    }
}
