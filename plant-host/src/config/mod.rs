//! The plant's settings as plain data, one serde struct per TOML table: `[plant]`
//! ([`MechanicsConfig`]: the paper's mechanical parameters and the motor encoder),
//! `[electrics]`, `[sensors]` and `[lost_motion]`. The allowed range of every key is in
//! [`RANGES`]; [`PlantConfig::validate`] checks them and [`PlantConfig::from_table`] reads a
//! machine file's value tree. Nothing here knows the model or the integrator: the model is
//! built from these structs ([`crate::model`]), not the other way round.

mod ranges;

pub(crate) use ranges::MAX_COUNTS_PER_REV;
pub use ranges::{Allowed, KeyRange, RANGES, Reading, range_of};

use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// The mechanical plant of the paper's Fig. 3, reflected to the motor side, and the motor
/// encoder on its shaft: the `[plant]` table. Every key is required.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct MechanicsConfig {
    /// Base speed in rpm; 1 pu speed.
    pub base_speed_rpm: f64,
    /// Motor inertia Jm in seconds (time for rated torque to reach base speed).
    pub motor_inertia_s: f64,
    /// Load inertia Jl reflected to the motor, in seconds.
    pub load_inertia_s: f64,
    /// Anti-resonance frequency f_ar in Hz (load resonating against a locked motor).
    pub anti_resonance_hz: f64,
    /// Shaft damping ratio ζ of the load-side mode (D = 2·ζ·Jl·ω_ar).
    pub shaft_damping_ratio: f64,
    /// Total lost motion at the motor side in degrees (the dead zone is ±backlash/2).
    pub backlash_deg: f64,
    /// Motor viscous friction Bm, pu torque per pu speed.
    pub motor_viscous_pu: f64,
    /// Load viscous friction Bl, pu torque per pu speed.
    pub load_viscous_pu: f64,
    /// Motor encoder counts per motor revolution: lines × 4 of a square-wave encoder, or the
    /// sin/cos periods × 4 of an analog one. The drive sees
    /// [`PlantConfig::counts_per_rev`] (after `sensors.encoder_interpolation`).
    pub encoder_cpr: u32,
}

/// The motor winding and its drive (the `[electrics]` table). Voltage and current are in
/// pu; back-EMF equals speed in pu and torque equals current in pu. The computational delay
/// is required (it is a number of the drive's paper); the others default to the assumed
/// winding and ADC.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct ElectricsConfig {
    /// Winding resistance R in pu (voltage per current). Default 0.05 pu.
    #[serde(default = "ElectricsConfig::default_resistance")]
    pub winding_resistance_pu: f64,
    /// Winding inductance L in pu·s (L/R is the electrical time constant in seconds).
    /// Default 5e-4 pu·s (L/R = 10 ms).
    #[serde(default = "ElectricsConfig::default_inductance")]
    pub winding_inductance_pu_s: f64,
    /// Delay from sampling to applying the new voltage (PWM zero-order hold), seconds.
    pub computational_delay_s: f64,
    /// Current ADC resolution in bits. Default 12.
    #[serde(default = "ElectricsConfig::default_adc_bits")]
    pub current_adc_bits: u32,
    /// Current ADC full scale: codes span ±full scale, in pu. Default 4 pu.
    #[serde(default = "ElectricsConfig::default_full_scale")]
    pub current_full_scale_pu: f64,
    /// Which motor: `"dc"` (the winding above, the default) or `"pmsm"` (a three-phase
    /// permanent-magnet synchronous motor behind an averaged inverter, [`crate::PmsmPlant`]).
    /// For a PMSM, `winding_resistance_pu` is the phase resistance and
    /// `winding_inductance_pu_s` is not used.
    #[serde(default, skip_serializing_if = "MotorKind::is_dc")]
    pub motor: MotorKind,
    /// PMSM: pole pairs p (electrical angle = p × mechanical angle). Required for a PMSM,
    /// refused for a DC motor, as every key below.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pole_pairs: Option<u32>,
    /// PMSM: d-axis inductance Ld in pu·s (pu voltage per pu current per second).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub d_inductance_pu_s: Option<f64>,
    /// PMSM: q-axis inductance Lq in pu·s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub q_inductance_pu_s: Option<f64>,
    /// PMSM: flux linkage λ in pu: the back-EMF (peak phase voltage) at base speed, which
    /// is also the torque per pu of q current. Default 1 pu.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub flux_linkage_pu: Option<f64>,
    /// PMSM: the inverter's DC-bus voltage in the voltage base where the back-EMF at base
    /// speed is λ = 1 pu (peak phase voltage); the linear (space-vector) limit of the
    /// voltage vector is `dc_bus_pu/√3`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dc_bus_pu: Option<f64>,
    /// PMSM: the machine's true electrical angle at encoder count 0, degrees (the d axis
    /// on the phase-a axis is 0). The plant's truth; a drive measures it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub encoder_offset_elec_deg: Option<f64>,
    /// PMSM: the encoder counts while the electrical angle falls (default false). The plant
    /// models it as two motor leads swapped at the inverter (the drive's phases b and c are
    /// the motor's c and b), so the electrical angle the drive sees turns against the counts
    /// and `encoder_offset_elec_deg` is the angle at count 0 in the drive's phase order. The
    /// plant's truth; a drive measures it (`[drive.pmsm] encoder_reversed`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub encoder_reversed: Option<bool>,
    /// PMSM: the inverter's dead time per switching edge, seconds. Default 0 (none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dead_time_s: Option<f64>,
}

/// The motor kind of `electrics.motor`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(rename_all = "snake_case")]
pub enum MotorKind {
    /// One DC winding: L·di/dt = v − R·i − ωm ([`crate::TwoInertiaPlant::voltage_driven`]).
    #[default]
    Dc,
    /// A permanent-magnet synchronous motor in d/q with its inverter ([`crate::PmsmPlant`]).
    Pmsm,
}

impl MotorKind {
    /// The word of the config file.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Dc => "dc",
            Self::Pmsm => "pmsm",
        }
    }
    /// The default, DC (not written out).
    pub fn is_dc(&self) -> bool {
        *self == Self::Dc
    }
}

impl ElectricsConfig {
    /// The assumed winding and current ADC (R = 0.05 pu, L/R = 10 ms, 12 bits over ±4 pu)
    /// with the given computational delay.
    pub fn with_delay(computational_delay_s: f64) -> Self {
        Self {
            winding_resistance_pu: Self::default_resistance(),
            winding_inductance_pu_s: Self::default_inductance(),
            computational_delay_s,
            current_adc_bits: Self::default_adc_bits(),
            current_full_scale_pu: Self::default_full_scale(),
            motor: MotorKind::Dc,
            pole_pairs: None,
            d_inductance_pu_s: None,
            q_inductance_pu_s: None,
            flux_linkage_pu: None,
            dc_bus_pu: None,
            encoder_offset_elec_deg: None,
            encoder_reversed: None,
            dead_time_s: None,
        }
    }
    fn default_resistance() -> f64 {
        0.05
    }
    fn default_inductance() -> f64 {
        5e-4
    }
    fn default_adc_bits() -> u32 {
        12
    }
    fn default_full_scale() -> f64 {
        4.0
    }
}

/// Sensor details beyond the motor encoder's counts (the `[sensors]` table, optional; every
/// key defaults to a noise-free plain encoder without a load encoder).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields, default)]
pub struct SensorsConfig {
    /// Sin/cos interpolation factor of the motor encoder: the drive resolves each count
    /// into this many (1 = plain counts).
    pub encoder_interpolation: u32,
    /// Load-side encoder, counts per revolution of the physical load shaft (0 = none).
    pub load_encoder_cpr: u32,
    /// Motor revolutions per load revolution (only the load encoder uses it).
    pub gear_ratio: f64,
    /// Standard deviation of Gaussian noise added to the motor encoder, in the counts the
    /// drive sees (after interpolation).
    pub encoder_noise_counts: f64,
    /// Standard deviation of Gaussian noise added to the current before the ADC, in pu.
    pub current_noise_pu: f64,
    /// Seed of the (deterministic) noise.
    pub noise_seed: u64,
}

impl Default for SensorsConfig {
    /// Plain counts, no load encoder, no noise, seed 1.
    fn default() -> Self {
        Self {
            encoder_interpolation: 1,
            load_encoder_cpr: 0,
            gear_ratio: 1.0,
            encoder_noise_counts: 0.0,
            current_noise_pu: 0.0,
            noise_seed: 1,
        }
    }
}

impl SensorsConfig {
    /// The load encoder's counts per load revolution, if one is fitted.
    pub fn load_encoder(&self) -> Option<u32> {
        (self.load_encoder_cpr > 0).then_some(self.load_encoder_cpr)
    }
}

/// Which lost-motion law transmits torque across the gap (`lost_motion.model`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(rename_all = "snake_case")]
pub enum BacklashModel {
    /// The paper's Simulink "Dead Zone" on the twist: Ts = K·dz(δ) + D·(ωm − ωl) while
    /// |δ| > g. The damping term can momentarily pull the gears apart.
    #[default]
    DeadZone,
    /// As Modelica's ElastoBacklash: the same law, but the contact can only push
    /// (the shaft torque never changes sign against the twist).
    Clamped,
}

impl BacklashModel {
    /// The word of the config file.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::DeadZone => "dead_zone",
            Self::Clamped => "clamped",
        }
    }
}

/// The `[lost_motion]` table (optional; the paper's dead zone by default).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields, default)]
pub struct LostMotionConfig {
    /// The law across the gap.
    pub model: BacklashModel,
}

/// Everything plant-host reads from a machine file: its tables `[plant]`, `[electrics]`,
/// `[sensors]` and `[lost_motion]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct PlantConfig {
    /// `[plant]`.
    #[serde(rename = "plant")]
    pub mechanics: MechanicsConfig,
    /// `[electrics]`.
    pub electrics: ElectricsConfig,
    /// `[sensors]` (optional table).
    #[serde(default)]
    pub sensors: SensorsConfig,
    /// `[lost_motion]` (optional table).
    #[serde(default)]
    pub lost_motion: LostMotionConfig,
}

impl PlantConfig {
    /// The tables of a machine file that plant-host reads.
    pub const TABLES: [&'static str; 4] = ["plant", "electrics", "sensors", "lost_motion"];

    /// Counts per motor revolution as the drive sees them: `plant.encoder_cpr ×
    /// sensors.encoder_interpolation` (validation keeps the product within 2^30, the
    /// drive's range).
    pub fn counts_per_rev(&self) -> u32 {
        self.mechanics
            .encoder_cpr
            .saturating_mul(self.sensors.encoder_interpolation)
    }

    /// The lost-motion law.
    pub fn backlash(&self) -> BacklashModel {
        self.lost_motion.model
    }
}

/// Constants derived once from [`MechanicsConfig`] (the formulas in `plant-host/README.md`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MechanicsDerived {
    /// ω_b = 2π·base_speed_rpm/60, rad/s per pu speed.
    pub base_speed_rad_s: f64,
    /// ω_ar = 2π·f_ar, rad/s.
    pub anti_resonance_rad_s: f64,
    /// ω_r = ω_ar·√(1 + Jl/Jm), rad/s: the engaged resonance.
    pub resonance_rad_s: f64,
    /// K = Jl·ω_ar²/ω_b, pu torque per rad of motor-side twist.
    pub stiffness_pu_per_rad: f64,
    /// D = 2·ζ·Jl·ω_ar, pu torque per pu speed difference (ωm − ωl).
    pub damping_pu: f64,
    /// g = backlash/2 in rad at the motor side.
    pub half_gap_rad: f64,
}

impl MechanicsConfig {
    /// K, D, g, ω_b, ω_ar, ω_r.
    pub fn derived(&self) -> MechanicsDerived {
        let wb = 2.0 * PI * self.base_speed_rpm / 60.0;
        let war = 2.0 * PI * self.anti_resonance_hz;
        MechanicsDerived {
            base_speed_rad_s: wb,
            anti_resonance_rad_s: war,
            resonance_rad_s: war * (1.0 + self.load_inertia_s / self.motor_inertia_s).sqrt(),
            stiffness_pu_per_rad: self.load_inertia_s * war * war / wb,
            damping_pu: 2.0 * self.shaft_damping_ratio * self.load_inertia_s * war,
            half_gap_rad: 0.5 * self.backlash_deg.to_radians(),
        }
    }
}
