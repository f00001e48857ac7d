//! The `[drive.pmsm]` table: the settings of the field-oriented current loop that replaces
//! the DC winding's current PI when the motor is a three-phase permanent-magnet motor.
//!
//! The motor's keys (`pole_pairs`, `d_inductance_pu_s`, `q_inductance_pu_s`,
//! `flux_linkage_pu`, `dc_bus_pu`) default, in a machine file, to the `[electrics]` values
//! of the motor, as the other machine keys do. `encoder_offset_elec_deg` and
//! `encoder_reversed` never default from the plant: they are what calibration measures
//! (`stiffdrive identify`, written into `drive.toml` by `stiffdrive commission`). A drive
//! without `encoder_offset_elec_deg` does not align by itself: it refuses to enable
//! ([`crate::Controller::new`] returns [`crate::ConfigError::Missing`] naming the key and
//! the command that measures it), because an alignment that turns the shaft may not be
//! safe on a coupled machine with backlash.

use super::current_loop::FocSettings;
use crate::config::DriveConfig;
use crate::error::ConfigError;

/// The PMSM current loop's settings (`[drive.pmsm]`).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
pub struct PmsmConfig {
    /// Pole pairs p (electrical angle = p × mechanical angle), 1..encoder_cpr.
    pub pole_pairs: u32,
    /// d-axis inductance \[pu·s\], 1e-6..=10.
    pub d_inductance_pu_s: f32,
    /// q-axis inductance \[pu·s\], 1e-6..=10.
    pub q_inductance_pu_s: f32,
    /// Magnet flux linkage \[pu\]: the back-EMF at base speed, and the torque per pu of q
    /// current; 0.05..=10.
    #[cfg_attr(feature = "serde", serde(default = "defaults::flux_linkage_pu"))]
    pub flux_linkage_pu: f32,
    /// DC-bus voltage in the voltage base where the back-EMF at base speed is λ; the
    /// voltage vector's linear limit is `dc_bus_pu/√3`.
    pub dc_bus_pu: f32,
    /// The machine's electrical angle at encoder count 0 \[deg\], −360..=360: measured by
    /// calibration, never defaulted. `None`: the drive refuses to enable. Count 0 is the
    /// counter's value at the drive's first reading (from there the angle follows the
    /// counter, across resets too), so a saved offset stays true across a power cycle only
    /// where count 0 is the same shaft angle at every power-up (an absolute encoder); an
    /// incremental encoder needs a calibration after each power-up.
    #[cfg_attr(
        feature = "serde",
        serde(default, skip_serializing_if = "Option::is_none")
    )]
    pub encoder_offset_elec_deg: Option<f32>,
    /// Whether the counts fall while the electrical angle rises (measured by calibration).
    #[cfg_attr(feature = "serde", serde(default))]
    pub encoder_reversed: bool,
    /// From the current sample to the middle of the voltage it sets \[current ticks\],
    /// 0..=4: the inverse Park turns the voltage by ω_e times this. 1.5 (the default) when
    /// the new duties take effect at the next PWM period.
    #[cfg_attr(feature = "serde", serde(default = "defaults::angle_advance_ticks"))]
    pub angle_advance_ticks: f32,
    /// Timer counts of one PWM period (the duties' full scale), 2..=65535.
    #[cfg_attr(feature = "serde", serde(default = "defaults::pwm_period_counts"))]
    pub pwm_period_counts: u16,
    /// The speed \[pu\] above which the commutation check judges the angle, 0.001..=10.
    #[cfg_attr(
        feature = "serde",
        serde(default = "defaults::commutation_min_speed_pu")
    )]
    pub commutation_min_speed_pu: f32,
    /// How long \[s\] the angle must look more than 30° electrical off before the
    /// `commutation` fault latches, 1e-4..=1.
    #[cfg_attr(feature = "serde", serde(default = "defaults::commutation_trip_s"))]
    pub commutation_trip_s: f32,
}

/// The defaults of `[drive.pmsm]`'s optional keys.
pub mod defaults {
    /// λ = 1 pu: the voltage base is the back-EMF at base speed.
    #[must_use]
    pub const fn flux_linkage_pu() -> f32 {
        1.0
    }
    /// 1.5 ticks: sampled at the period's centre, applied over the next period.
    #[must_use]
    pub const fn angle_advance_ticks() -> f32 {
        1.5
    }
    /// 4200 counts: a 168 MHz timer counting up and down at 20 kHz.
    #[must_use]
    pub const fn pwm_period_counts() -> u16 {
        4200
    }
    /// 0.05 pu: below it the back-EMF is too small to judge the angle by.
    #[must_use]
    pub const fn commutation_min_speed_pu() -> f32 {
        0.05
    }
    /// 20 ms: well inside the 0.5 s a wrong angle may run, and longer than a current
    /// transient's disagreement with the model.
    #[must_use]
    pub const fn commutation_trip_s() -> f32 {
        0.02
    }
}

/// The FOC loop's settings of a drive: `[drive.pmsm]` with the drive's own rates, encoder,
/// resistance, bandwidth and torque limit. `offset_deg` is the encoder offset to use (the
/// drive's own, or a trial value during calibration).
#[must_use]
pub fn foc_settings(cfg: &DriveConfig, p: &PmsmConfig, offset_deg: f32) -> FocSettings {
    FocSettings {
        pole_pairs: p.pole_pairs,
        encoder_cpr: cfg.encoder_cpr,
        encoder_offset_elec_deg: offset_deg,
        encoder_reversed: p.encoder_reversed,
        base_speed_rpm: cfg.base_speed_rpm,
        resistance_pu: cfg.winding_resistance_pu,
        d_inductance_pu_s: p.d_inductance_pu_s,
        q_inductance_pu_s: p.q_inductance_pu_s,
        flux_linkage_pu: p.flux_linkage_pu,
        dc_bus_pu: p.dc_bus_pu,
        current_bandwidth_rad_s: cfg.current_bandwidth_rad_s,
        current_rate_hz: cfg.current_rate_hz as f32,
        delay_ticks: p.angle_advance_ticks,
        current_limit_pu: cfg.torque_limit_pu / p.flux_linkage_pu,
        pwm_period: p.pwm_period_counts,
        commutation_min_speed_pu: p.commutation_min_speed_pu,
        commutation_trip_s: p.commutation_trip_s,
    }
}

/// The checks of `[drive.pmsm]` that need no calibration: every key against its range and
/// the loop's coefficients against their formats (with the offset at 0 if not measured).
pub fn check(cfg: &DriveConfig, p: &PmsmConfig) -> Result<(), ConfigError> {
    let offset = match p.encoder_offset_elec_deg {
        Some(o) => crate::ranges::Range::real("pmsm.encoder_offset_elec_deg", -360.0, 360.0, false)
            .check(o)?,
        None => 0.0,
    };
    super::FocCoefficients::new(&foc_settings(cfg, p, offset)).map(|_| ())
}
