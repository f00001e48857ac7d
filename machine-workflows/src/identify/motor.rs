//! The motor calibration of a PMSM machine, `identify`'s first step: the sequence of
//! [`crate::calibrate`] run on the machine with the inverter alone (no current loop, no
//! encoder offset needed), its estimates put into the drive, which then runs the mechanical
//! measurement with the measured phase resistance, d and q inductances, pole pairs, encoder
//! direction and offset. A DC machine has no calibration: its identification is unchanged.
//!
//! The sequence runs at the drive's current rate with [`CalibrationSettings`]' defaults
//! otherwise (0.5 pu test current, 0.1 pu square wave, three electrical turns each way at
//! 2 turns/s), its voltage held within the inverter's linear range `dc_bus_pu/√3`.

use super::write::Estimate;
use crate::calibrate::{estimate, record_on_plant, MotorEstimates};
use controller_core::foc::calibration::CalibrationSettings;
use controller_core::DriveConfig;
use sim_engine::config::RunConfig;
use sim_engine::error::{HarnessError, Result};

/// The drive's motor before its calibration (its settings, the machine file's nominal
/// values): what the sweep's speed is chosen for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Nominal {
    /// `[drive] current_rate_hz`.
    pub current_rate_hz: f64,
    /// `[drive.pmsm] dc_bus_pu`.
    pub dc_bus_pu: f64,
    /// `[drive] winding_resistance_pu`.
    pub resistance_pu: f64,
    /// `[drive.pmsm] flux_linkage_pu`.
    pub flux_linkage_pu: f64,
    /// `[drive.pmsm] pole_pairs`.
    pub pole_pairs: f64,
    /// `[drive] base_speed_rpm`.
    pub base_speed_rpm: f64,
}

/// The fastest sweep \[electrical turns/s\].
const SWEEP_HZ_MAX: f64 = 2.0;
/// The slowest sweep \[electrical turns/s\] (a nearly resistance-free motor).
const SWEEP_HZ_MIN: f64 = 0.1;

impl Nominal {
    /// The nominal motor of the drive `d` (`None` without `[drive.pmsm]`).
    #[must_use]
    pub fn of(d: &DriveConfig) -> Option<Self> {
        let p = d.pmsm?;
        Some(Self {
            current_rate_hz: f64::from(d.current_rate_hz),
            dc_bus_pu: f64::from(p.dc_bus_pu),
            resistance_pu: f64::from(d.winding_resistance_pu),
            flux_linkage_pu: f64::from(p.flux_linkage_pu),
            pole_pairs: f64::from(p.pole_pairs),
            base_speed_rpm: f64::from(d.base_speed_rpm),
        })
    }

    /// The sweep's top electrical speed for a test current `current_pu` \[turns/s\]. The
    /// sweep sets a voltage, not a current, so the back-EMF of the turning rotor drives a
    /// q current against the vector: a drag `λ²·ω/R` (pu torque at ω pu of speed) that the
    /// vector's pull `λ·I·sin δ` must meet with the rotor lagging by δ. At `ω = R·I/(4λ)`
    /// the drag is a quarter of the pull's largest (δ ≈ 15°); faster, a light winding on a
    /// strong magnet slips poles (Table 1's PMSM at 2 turns/s: drag 0.6 pu against a pull
    /// of 0.5). In electrical turns/s that speed is `ω·pole_pairs·base_speed_rpm/60`;
    /// within `SWEEP_HZ_MIN..=SWEEP_HZ_MAX`.
    #[must_use]
    pub fn sweep_hz(&self, current_pu: f64) -> f64 {
        let w = self.resistance_pu * current_pu / (4.0 * self.flux_linkage_pu);
        let hz = w * self.pole_pairs * self.base_speed_rpm / 60.0;
        if hz.is_nan() {
            SWEEP_HZ_MIN
        } else {
            hz.clamp(SWEEP_HZ_MIN, SWEEP_HZ_MAX)
        }
    }
}

/// The calibration's settings on the drive of `base` ([`settings_for`] its nominal motor);
/// [`CalibrationSettings`]' defaults for a DC drive.
pub fn settings(base: &RunConfig) -> CalibrationSettings {
    Nominal::of(&base.drive).map_or_else(CalibrationSettings::default, |n| settings_for(&n))
}

/// The calibration's settings for the nominal motor `n`: its current rate, the inverter's
/// linear range `dc_bus_pu/√3` as the voltage limit, the sweep's speed by
/// [`Nominal::sweep_hz`], [`CalibrationSettings`]' defaults otherwise: [`settings`], and
/// the board's (`crate::calibrate::board`).
#[must_use]
pub fn settings_for(n: &Nominal) -> CalibrationSettings {
    let d = CalibrationSettings::default();
    CalibrationSettings {
        current_rate_hz: n.current_rate_hz as f32,
        voltage_limit_pu: (n.dc_bus_pu / 3f64.sqrt()) as f32,
        sweep_hz: n.sweep_hz(f64::from(d.current_pu)) as f32,
        ..d
    }
}

/// Calibrates the motor of `base` on its simulated machine: `None` for a DC machine.
pub fn calibrate(base: &RunConfig) -> Result<Option<MotorEstimates>> {
    if base.drive.pmsm.is_none() {
        return Ok(None);
    }
    let record = record_on_plant(&base.plant, &settings(base))?;
    estimate(&record).map(Some)
}

/// `drive` with the calibration `est`: `winding_resistance_pu` and `[drive.pmsm]`'s
/// `pole_pairs`, `d_inductance_pu_s`, `q_inductance_pu_s`, `encoder_offset_elec_deg` and
/// `encoder_reversed` set to the measurement, checked as a drive is (an estimate a drive
/// cannot take is an error naming its key).
pub fn calibrated(drive: &DriveConfig, est: &MotorEstimates) -> Result<DriveConfig> {
    let mut d = *drive;
    let Some(p) = d.pmsm.as_mut() else {
        return Err(HarnessError::config(
            "drive.pmsm",
            "the calibration measured a PMSM, and the drive has no [drive.pmsm] table",
        ));
    };
    p.pole_pairs = est.pole_pairs;
    p.d_inductance_pu_s = est.d_inductance_pu_s.value as f32;
    p.q_inductance_pu_s = est.q_inductance_pu_s.value as f32;
    p.encoder_offset_elec_deg = Some(est.encoder_offset_elec_deg.value as f32);
    p.encoder_reversed = est.encoder_reversed;
    d.winding_resistance_pu = est.winding_resistance_pu.value as f32;
    d.validate().map_err(|e| {
        HarnessError::config(
            format!("drive.{}", e.param()),
            format!("the calibration's value does not make a valid drive: {e}"),
        )
    })?;
    controller_core::Controller::new(&d).map_err(sim_engine::engine::runner::drive_error)?;
    Ok(d)
}

/// `base` with its drive [`calibrated`] by `est` (unchanged when `None`).
pub fn with_calibration(base: &RunConfig, est: Option<&MotorEstimates>) -> Result<RunConfig> {
    let mut cfg = base.clone();
    if let Some(est) = est {
        cfg.drive = calibrated(&base.drive, est)?;
    }
    Ok(cfg)
}

/// The probability that a normal variable lies more than `t` standard deviations on the
/// other side of zero, `Φ(−|t|)` (Abramowitz and Stegun 7.1.26, error below 1.5e-7 of erfc).
fn tail(t: f64) -> f64 {
    let x = t.abs() / std::f64::consts::SQRT_2;
    let k = 1.0 / (1.0 + 0.327_591_1 * x);
    let poly = k
        * (0.254_829_592
            + k * (-0.284_496_736
                + k * (1.421_413_741 + k * (-1.453_152_027 + k * 1.061_405_429))));
    0.5 * poly * (-x * x).exp()
}

/// The calibration's estimates under the machine-file keys that take them, each with its
/// standard error: the pole pairs' is that of `encoder_cpr / counts per electrical turn`
/// before it is rounded to the whole number, the direction's that of a bit whose chance of
/// being wrong is the slope's normal tail beyond zero, `√(p·(1 − p))`.
pub fn estimates(est: &MotorEstimates) -> Vec<Estimate> {
    let cpt = est.counts_per_electrical_turn;
    let pp_se = f64::from(est.pole_pairs) * cpt.std_error / cpt.value;
    let p_wrong = if cpt.std_error > 0.0 {
        tail(cpt.value / cpt.std_error)
    } else {
        0.0
    };
    let e = |name, x: crate::calibrate::Estimate, unit| Estimate {
        name,
        value: x.value,
        std_error: x.std_error,
        unit,
    };
    vec![
        e("winding_resistance_pu", est.winding_resistance_pu, "pu"),
        e("d_inductance_pu_s", est.d_inductance_pu_s, "pu·s"),
        e("q_inductance_pu_s", est.q_inductance_pu_s, "pu·s"),
        e(
            "encoder_offset_elec_deg",
            est.encoder_offset_elec_deg,
            "deg electrical",
        ),
        Estimate {
            name: "encoder_reversed",
            value: if est.encoder_reversed { 1.0 } else { 0.0 },
            std_error: (p_wrong * (1.0 - p_wrong)).sqrt(),
            unit: "1 = the counts fall as the electrical angle rises",
        },
        Estimate {
            name: "pole_pairs",
            value: f64::from(est.pole_pairs),
            std_error: pp_se,
            unit: "1",
        },
        e(
            "counts_per_electrical_turn",
            cpt,
            "counts (encoder_cpr / pole_pairs)",
        ),
    ]
}

#[cfg(test)]
mod tests {
    use super::tail;

    #[test]
    fn the_tail_is_the_normal_distributions() {
        // Φ(0) = 0.5, Φ(−1) = 0.158655254, Φ(−3) = 0.001349898, symmetric in t; the
        // approximation's stated error is 1.5e-7 of erfc, half that of Φ.
        for (t, p) in [(0.0, 0.5), (1.0, 0.158_655_254), (-3.0, 0.001_349_898)] {
            assert!((tail(t) - p).abs() < 1e-7, "{t}: {}", tail(t));
        }
        assert!(tail(1e4) < 1e-300);
    }
}
