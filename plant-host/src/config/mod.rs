//! Plant configuration from TOML: the tables `[plant]` (mechanics, exactly the paper's
//! parameters), `[electrics]`, `[sensors]` and `[lost_motion]`. Other top-level tables
//! (`[drive]`, scenarios...) belong to other crates and are ignored here; unknown keys inside
//! these four tables are errors.

mod reader;

use crate::error::{ConfigError, PlantError};
pub use crate::model::BacklashModel;
use crate::model::{Model, Shaft, Winding};
use reader::{IntSpec, RealSpec, TableReader};
use std::f64::consts::PI;
use std::path::Path;

/// The mechanical plant of the paper's Fig. 3 (the `[plant]` table), reflected to the motor side.
#[derive(Debug, Clone, Copy, PartialEq)]
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
}

/// The motor winding and its drive (the `[electrics]` table). Voltage and current are in pu;
/// back-EMF equals speed in pu and torque equals current in pu.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ElectricsConfig {
    /// Winding resistance R in pu (voltage per current).
    pub winding_resistance_pu: f64,
    /// Winding inductance L in pu·s (L/R is the electrical time constant in seconds).
    pub winding_inductance_pu_s: f64,
    /// Delay from sampling to applying the new voltage (PWM zero-order hold), seconds.
    pub computational_delay_s: f64,
    /// Current ADC resolution in bits.
    pub current_adc_bits: u32,
    /// Current ADC full scale: codes span ±full scale, in pu.
    pub current_full_scale_pu: f64,
}

impl Default for ElectricsConfig {
    /// The assumed winding: R = 0.05 pu, L/R = 10 ms, 0.18 ms computational delay (Table 1),
    /// 12-bit current ADC over ±4 pu.
    fn default() -> Self {
        Self {
            winding_resistance_pu: 0.05,
            winding_inductance_pu_s: 5e-4,
            computational_delay_s: 180e-6,
            current_adc_bits: 12,
            current_full_scale_pu: 4.0,
        }
    }
}

/// Position and current sensors (the `[sensors]` table, plus `plant.encoder_cpr`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorsConfig {
    /// Motor encoder counts per motor revolution (from `plant.encoder_cpr`): lines × 4 of a
    /// square-wave encoder, or the sin/cos periods × 4 of an analog one.
    pub encoder_cpr: u32,
    /// Sin/cos interpolation factor of the motor encoder (`sensors.encoder_interpolation`):
    /// the drive resolves each count into this many (1 = plain counts). The drive sees
    /// [`SensorsConfig::counts_per_rev`] = `encoder_cpr × encoder_interpolation` counts.
    pub encoder_interpolation: u32,
    /// Optional load-side encoder, counts per revolution of the physical load shaft.
    pub load_encoder_cpr: Option<u32>,
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

impl SensorsConfig {
    /// Noise-free sensors with a motor encoder of `encoder_cpr` counts and no load encoder.
    pub fn with_cpr(encoder_cpr: u32) -> Self {
        Self {
            encoder_cpr,
            encoder_interpolation: 1,
            load_encoder_cpr: None,
            gear_ratio: 1.0,
            encoder_noise_counts: 0.0,
            current_noise_pu: 0.0,
            noise_seed: 1,
        }
    }

    /// Counts per motor revolution as the drive sees them: `encoder_cpr ×
    /// encoder_interpolation` (the config check keeps the product within 2^30, the drive's range).
    pub fn counts_per_rev(&self) -> u32 {
        self.encoder_cpr.saturating_mul(self.encoder_interpolation)
    }
}

/// Everything plant-host reads from a config file.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlantConfig {
    /// `[plant]`.
    pub mechanics: MechanicsConfig,
    /// `[electrics]` (optional table; defaults as documented).
    pub electrics: ElectricsConfig,
    /// `plant.encoder_cpr` and `[sensors]` (optional table).
    pub sensors: SensorsConfig,
    /// `lost_motion.model` (optional table; default dead zone as in the paper).
    pub backlash: BacklashModel,
}

const PLANT_REAL: [RealSpec; 8] = [
    RealSpec {
        name: "base_speed_rpm",
        min: 1.0,
        max: 100_000.0,
        unit: "rpm",
    },
    RealSpec {
        name: "motor_inertia_s",
        min: 1e-5,
        // The drive's range (controller-core design()) is (0, 1000] s.
        max: 1e3,
        unit: "s",
    },
    RealSpec {
        name: "load_inertia_s",
        min: 1e-5,
        max: 1e3,
        unit: "s",
    },
    RealSpec {
        name: "anti_resonance_hz",
        min: 0.1,
        max: 5000.0,
        unit: "Hz",
    },
    RealSpec {
        name: "shaft_damping_ratio",
        min: 0.0,
        max: 2.0,
        unit: "",
    },
    RealSpec {
        name: "backlash_deg",
        min: 0.0,
        max: 45.0,
        unit: "deg",
    },
    RealSpec {
        name: "motor_viscous_pu",
        min: 0.0,
        max: 100.0,
        unit: "pu torque/pu speed",
    },
    RealSpec {
        name: "load_viscous_pu",
        min: 0.0,
        max: 100.0,
        unit: "pu torque/pu speed",
    },
];
const CPR_SPEC: IntSpec = IntSpec {
    name: "encoder_cpr",
    min: 4,
    // The drive's range (controller-core design()): up to 2^30 counts/rev.
    max: 1 << 30,
    unit: "counts/rev",
};

const R_SPEC: RealSpec = RealSpec {
    name: "winding_resistance_pu",
    min: 1e-4,
    max: 10.0,
    unit: "pu",
};
const L_SPEC: RealSpec = RealSpec {
    name: "winding_inductance_pu_s",
    min: 1e-6,
    max: 1.0,
    unit: "pu*s",
};
const DELAY_SPEC: RealSpec = RealSpec {
    name: "computational_delay_s",
    min: 0.0,
    max: 0.01,
    unit: "s",
};
const ADC_BITS_SPEC: IntSpec = IntSpec {
    name: "current_adc_bits",
    min: 4,
    max: 24,
    unit: "bits",
};
const FS_SPEC: RealSpec = RealSpec {
    name: "current_full_scale_pu",
    min: 0.1,
    max: 100.0,
    unit: "pu",
};

/// Sin/cos interpolation: 1 (a square-wave encoder) up to 4096, a 12-bit interpolator.
const INTERPOLATION_SPEC: IntSpec = IntSpec {
    name: "encoder_interpolation",
    min: 1,
    max: 4096,
    unit: "interpolated counts per encoder count",
};

const LOAD_CPR_SPEC: IntSpec = IntSpec {
    name: "load_encoder_cpr",
    min: 0,
    max: 1 << 31,
    unit: "counts/rev (0 = no load encoder)",
};
const GEAR_SPEC: RealSpec = RealSpec {
    name: "gear_ratio",
    min: 1e-3,
    max: 1e4,
    unit: "motor rev/load rev",
};
const ENC_NOISE_SPEC: RealSpec = RealSpec {
    name: "encoder_noise_counts",
    min: 0.0,
    max: 1e6,
    unit: "counts rms",
};
const CUR_NOISE_SPEC: RealSpec = RealSpec {
    name: "current_noise_pu",
    min: 0.0,
    max: 10.0,
    unit: "pu rms",
};
const SEED_SPEC: IntSpec = IntSpec {
    name: "noise_seed",
    min: 0,
    max: i64::MAX,
    unit: "",
};

impl PlantConfig {
    /// The paper's Table 1 plant (dead zone, default electrics, noise-free 4096-count encoder).
    pub fn table1() -> Self {
        Self {
            mechanics: MechanicsConfig {
                base_speed_rpm: 1000.0,
                motor_inertia_s: 0.117,
                load_inertia_s: 0.863,
                anti_resonance_hz: 22.5,
                shaft_damping_ratio: 0.05,
                backlash_deg: 0.5,
                motor_viscous_pu: 0.0,
                load_viscous_pu: 0.0,
            },
            electrics: ElectricsConfig::default(),
            sensors: SensorsConfig::with_cpr(4096),
            backlash: BacklashModel::DeadZone,
        }
    }

    /// Parses the plant-host tables of a TOML document; other top-level tables are ignored.
    pub fn from_toml_str(text: &str) -> Result<Self, ConfigError> {
        let doc: toml::Table = text
            .parse()
            .map_err(|e: toml::de::Error| ConfigError::Syntax {
                message: e.message().to_string(),
            })?;

        let mut plant = TableReader::open(&doc, "plant", true)?;
        let [base, jm, jl, far, zeta, backlash, bm, bl] = PLANT_REAL;
        let mechanics = MechanicsConfig {
            base_speed_rpm: plant.real(base)?,
            motor_inertia_s: plant.real(jm)?,
            load_inertia_s: plant.real(jl)?,
            anti_resonance_hz: plant.real(far)?,
            shaft_damping_ratio: plant.real(zeta)?,
            backlash_deg: plant.real(backlash)?,
            motor_viscous_pu: plant.real(bm)?,
            load_viscous_pu: plant.real(bl)?,
        };
        let encoder_cpr = to_u32(plant.int(CPR_SPEC)?);
        plant.finish()?;

        let d = ElectricsConfig::default();
        let mut el = TableReader::open(&doc, "electrics", false)?;
        let electrics = ElectricsConfig {
            winding_resistance_pu: el.real_or(R_SPEC, d.winding_resistance_pu)?,
            winding_inductance_pu_s: el.real_or(L_SPEC, d.winding_inductance_pu_s)?,
            computational_delay_s: el.real_or(DELAY_SPEC, d.computational_delay_s)?,
            current_adc_bits: to_u32(el.int_or(ADC_BITS_SPEC, i64::from(d.current_adc_bits))?),
            current_full_scale_pu: el.real_or(FS_SPEC, d.current_full_scale_pu)?,
        };
        el.finish()?;

        let s0 = SensorsConfig::with_cpr(encoder_cpr);
        let mut se = TableReader::open(&doc, "sensors", false)?;
        let load_cpr = se.int_or(LOAD_CPR_SPEC, 0)?;
        if (1..4).contains(&load_cpr) {
            return Err(ConfigError::OutOfRange {
                key: "sensors.load_encoder_cpr".into(),
                value: load_cpr.to_string(),
                allowed: "0 (no load encoder) or an integer in 4..=2147483648 counts/rev".into(),
            });
        }
        let interpolation = se.int_or(INTERPOLATION_SPEC, 1)?;
        if i64::from(encoder_cpr) * interpolation > CPR_SPEC.max {
            return Err(ConfigError::OutOfRange {
                key: "sensors.encoder_interpolation".into(),
                value: interpolation.to_string(),
                allowed: format!(
                    "an integer in {}..={} with plant.encoder_cpr × encoder_interpolation \
                     <= {} counts/rev (plant.encoder_cpr = {encoder_cpr})",
                    INTERPOLATION_SPEC.min, INTERPOLATION_SPEC.max, CPR_SPEC.max
                ),
            });
        }
        let sensors = SensorsConfig {
            encoder_cpr,
            encoder_interpolation: to_u32(interpolation),
            load_encoder_cpr: (load_cpr > 0).then(|| to_u32(load_cpr)),
            gear_ratio: se.real_or(GEAR_SPEC, s0.gear_ratio)?,
            encoder_noise_counts: se.real_or(ENC_NOISE_SPEC, 0.0)?,
            current_noise_pu: se.real_or(CUR_NOISE_SPEC, 0.0)?,
            noise_seed: se.int_or(SEED_SPEC, 1)?.unsigned_abs(),
        };
        se.finish()?;

        let mut lm = TableReader::open(&doc, "lost_motion", false)?;
        let backlash = match lm.choice_or("model", &["dead_zone", "clamped"], "dead_zone")? {
            "clamped" => BacklashModel::Clamped,
            _ => BacklashModel::DeadZone,
        };
        lm.finish()?;

        let config = Self {
            mechanics,
            electrics,
            sensors,
            backlash,
        };
        config.check_speed_of_dynamics()?;
        Ok(config)
    }

    /// Cross-key check: each key may be in range while the combination is absurdly stiff
    /// (e.g. a tiny motor inertia under a stiff, heavy load). The integrator sub-steps at
    /// ‖A‖·h ≤ 0.5, so ‖A‖ is capped at [`MAX_RATE_PER_S`] (sub-steps ≥ 0.5 µs).
    pub fn check_speed_of_dynamics(&self) -> Result<(), ConfigError> {
        let winding = self.electrics.winding();
        let rate = self
            .mechanics
            .model(self.backlash, Some(winding))
            .fastest_rate_per_s();
        if rate > MAX_RATE_PER_S || !rate.is_finite() {
            return Err(ConfigError::Inconsistent {
                keys: "plant.motor_inertia_s, plant.load_inertia_s, plant.anti_resonance_hz, \
                       plant.base_speed_rpm, electrics.winding_inductance_pu_s"
                    .into(),
                message: format!(
                    "the plant's fastest rate ‖A‖ = {rate:.3e} 1/s exceeds {MAX_RATE_PER_S:e} 1/s \
                     (K/Jm = {:.3e}, (1 + R)/L = {:.3e}); raise motor_inertia_s or \
                     winding_inductance_pu_s, or lower anti_resonance_hz or load_inertia_s",
                    self.mechanics.derived().stiffness_pu_per_rad / self.mechanics.motor_inertia_s,
                    (1.0 + winding.r_pu) / winding.l_pu_s,
                ),
            });
        }
        Ok(())
    }

    /// Reads and parses a config file.
    pub fn from_file(path: &Path) -> Result<Self, PlantError> {
        let text = std::fs::read_to_string(path).map_err(|e| PlantError::Io {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
        Ok(Self::from_toml_str(&text)?)
    }
}

/// Largest allowed ‖A‖∞ of the plant, 1/s (see [`PlantConfig::check_speed_of_dynamics`]).
pub const MAX_RATE_PER_S: f64 = 1e6;

/// Values already range-checked to fit; saturate rather than panic all the same.
fn to_u32(v: i64) -> u32 {
    u32::try_from(v).unwrap_or(u32::MAX)
}

/// Constants derived once from [`MechanicsConfig`] (the design notes' formulas).
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

impl ElectricsConfig {
    /// R and L of the winding the integrator models.
    pub(crate) fn winding(&self) -> Winding {
        Winding {
            r_pu: self.winding_resistance_pu,
            l_pu_s: self.winding_inductance_pu_s,
        }
    }
}

impl MechanicsConfig {
    /// The linear model of each contact mode, for this mechanics under `law` (with the
    /// winding, when the electrics are modelled).
    pub(crate) fn model(&self, law: BacklashModel, winding: Option<Winding>) -> Model {
        let dv = self.derived();
        Model {
            motor_inertia_s: self.motor_inertia_s,
            load_inertia_s: self.load_inertia_s,
            motor_viscous_pu: self.motor_viscous_pu,
            load_viscous_pu: self.load_viscous_pu,
            base_speed_rad_s: dv.base_speed_rad_s,
            shaft: Shaft {
                k: dv.stiffness_pu_per_rad,
                d: dv.damping_pu,
                g: dv.half_gap_rad,
            },
            law,
            winding,
        }
    }

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
