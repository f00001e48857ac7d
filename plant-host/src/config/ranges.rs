//! The one range table of the plant's settings: every key of the four tables, what it
//! accepts, its unit, whether a file must set it, and how to read it from a
//! [`PlantConfig`]. [`PlantConfig::validate`] walks it; a JSON Schema can take its bounds.

use super::PlantConfig;

/// What a key accepts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Allowed {
    /// A finite number in `min..=max`.
    Real {
        /// Smallest allowed value.
        min: f64,
        /// Largest allowed value.
        max: f64,
    },
    /// An integer in `min..=max`.
    Integer {
        /// Smallest allowed value.
        min: i64,
        /// Largest allowed value.
        max: i64,
    },
    /// One of these words.
    Words(&'static [&'static str]),
}

/// A key's value as [`KeyRange::get`] reads it from a config.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Reading {
    /// A real key.
    Real(f64),
    /// An integer key (wide enough for every integer field).
    Integer(i128),
    /// A word key.
    Word(&'static str),
}

/// One key of the range table.
#[derive(Debug, Clone, Copy)]
pub struct KeyRange {
    /// `table.key`, as in the file.
    pub key: &'static str,
    /// What it accepts.
    pub allowed: Allowed,
    /// Its unit (may be empty), for messages and schemas.
    pub unit: &'static str,
    /// Whether a file must set it (else it has a default).
    pub required: bool,
    /// The key's value in a config.
    pub get: fn(&PlantConfig) -> Reading,
}

impl KeyRange {
    /// The allowed values as text: "a number in 0.1..=5000 Hz", "one of \"a\", \"b\"".
    pub fn describe(&self) -> String {
        let text = match self.allowed {
            Allowed::Real { min, max } => format!("a number in {min}..={max} {}", self.unit),
            Allowed::Integer { min, max } => format!("an integer in {min}..={max} {}", self.unit),
            Allowed::Words(words) => {
                let quoted: Vec<String> = words.iter().map(|w| format!("\"{w}\"")).collect();
                format!("one of {}", quoted.join(", "))
            }
        };
        text.trim_end().to_string()
    }

    /// The table part of the key (`plant` of `plant.encoder_cpr`).
    pub fn table(&self) -> &'static str {
        self.key.split_once('.').map_or(self.key, |(t, _)| t)
    }

    /// The name part of the key (`encoder_cpr` of `plant.encoder_cpr`).
    pub fn name(&self) -> &'static str {
        self.key.split_once('.').map_or(self.key, |(_, n)| n)
    }
}

/// The entry of `key` (`table.key`), if it is one.
pub fn range_of(key: &str) -> Option<&'static KeyRange> {
    RANGES.iter().find(|r| r.key == key)
}

const fn real(min: f64, max: f64) -> Allowed {
    Allowed::Real { min, max }
}

/// Largest counts per motor revolution the drive takes (controller-core `design()`).
pub(crate) const MAX_COUNTS_PER_REV: i64 = 1 << 30;

/// Every key of the plant's tables, in file order.
pub const RANGES: &[KeyRange] = &[
    KeyRange {
        key: "plant.base_speed_rpm",
        allowed: real(1.0, 100_000.0),
        unit: "rpm",
        required: true,
        get: |c| Reading::Real(c.mechanics.base_speed_rpm),
    },
    KeyRange {
        // The drive's range (controller-core design()) is (0, 1000] s.
        key: "plant.motor_inertia_s",
        allowed: real(1e-5, 1e3),
        unit: "s",
        required: true,
        get: |c| Reading::Real(c.mechanics.motor_inertia_s),
    },
    KeyRange {
        key: "plant.load_inertia_s",
        allowed: real(1e-5, 1e3),
        unit: "s",
        required: true,
        get: |c| Reading::Real(c.mechanics.load_inertia_s),
    },
    KeyRange {
        key: "plant.anti_resonance_hz",
        allowed: real(0.1, 5000.0),
        unit: "Hz",
        required: true,
        get: |c| Reading::Real(c.mechanics.anti_resonance_hz),
    },
    KeyRange {
        key: "plant.shaft_damping_ratio",
        allowed: real(0.0, 2.0),
        unit: "",
        required: true,
        get: |c| Reading::Real(c.mechanics.shaft_damping_ratio),
    },
    KeyRange {
        key: "plant.backlash_deg",
        allowed: real(0.0, 45.0),
        unit: "deg",
        required: true,
        get: |c| Reading::Real(c.mechanics.backlash_deg),
    },
    KeyRange {
        key: "plant.motor_viscous_pu",
        allowed: real(0.0, 100.0),
        unit: "pu torque/pu speed",
        required: true,
        get: |c| Reading::Real(c.mechanics.motor_viscous_pu),
    },
    KeyRange {
        key: "plant.load_viscous_pu",
        allowed: real(0.0, 100.0),
        unit: "pu torque/pu speed",
        required: true,
        get: |c| Reading::Real(c.mechanics.load_viscous_pu),
    },
    KeyRange {
        // The drive's range (controller-core design()): up to 2^30 counts/rev.
        key: "plant.encoder_cpr",
        allowed: Allowed::Integer {
            min: 4,
            max: MAX_COUNTS_PER_REV,
        },
        unit: "counts/rev",
        required: true,
        get: |c| Reading::Integer(c.mechanics.encoder_cpr.into()),
    },
    KeyRange {
        key: "electrics.winding_resistance_pu",
        allowed: real(1e-4, 10.0),
        unit: "pu",
        required: false,
        get: |c| Reading::Real(c.electrics.winding_resistance_pu),
    },
    KeyRange {
        key: "electrics.winding_inductance_pu_s",
        allowed: real(1e-6, 1.0),
        unit: "pu*s",
        required: false,
        get: |c| Reading::Real(c.electrics.winding_inductance_pu_s),
    },
    KeyRange {
        key: "electrics.computational_delay_s",
        allowed: real(0.0, 0.01),
        unit: "s",
        required: true,
        get: |c| Reading::Real(c.electrics.computational_delay_s),
    },
    KeyRange {
        key: "electrics.current_adc_bits",
        allowed: Allowed::Integer { min: 4, max: 24 },
        unit: "bits",
        required: false,
        get: |c| Reading::Integer(c.electrics.current_adc_bits.into()),
    },
    KeyRange {
        key: "electrics.current_full_scale_pu",
        allowed: real(0.1, 100.0),
        unit: "pu",
        required: false,
        get: |c| Reading::Real(c.electrics.current_full_scale_pu),
    },
    KeyRange {
        // 1 (a square-wave encoder) up to 4096, a 12-bit interpolator.
        key: "sensors.encoder_interpolation",
        allowed: Allowed::Integer { min: 1, max: 4096 },
        unit: "interpolated counts per encoder count",
        required: false,
        get: |c| Reading::Integer(c.sensors.encoder_interpolation.into()),
    },
    KeyRange {
        key: "sensors.load_encoder_cpr",
        allowed: Allowed::Integer {
            min: 0,
            max: 1 << 31,
        },
        unit: "counts/rev (0 = no load encoder)",
        required: false,
        get: |c| Reading::Integer(c.sensors.load_encoder_cpr.into()),
    },
    KeyRange {
        key: "sensors.gear_ratio",
        allowed: real(1e-3, 1e4),
        unit: "motor rev/load rev",
        required: false,
        get: |c| Reading::Real(c.sensors.gear_ratio),
    },
    KeyRange {
        key: "sensors.encoder_noise_counts",
        allowed: real(0.0, 1e6),
        unit: "counts rms",
        required: false,
        get: |c| Reading::Real(c.sensors.encoder_noise_counts),
    },
    KeyRange {
        key: "sensors.current_noise_pu",
        allowed: real(0.0, 10.0),
        unit: "pu rms",
        required: false,
        get: |c| Reading::Real(c.sensors.current_noise_pu),
    },
    KeyRange {
        key: "sensors.noise_seed",
        allowed: Allowed::Integer {
            min: 0,
            max: i64::MAX,
        },
        unit: "",
        required: false,
        get: |c| Reading::Integer(c.sensors.noise_seed.into()),
    },
    KeyRange {
        key: "lost_motion.model",
        allowed: Allowed::Words(&["dead_zone", "clamped"]),
        unit: "",
        required: false,
        get: |c| Reading::Word(c.lost_motion.model.as_str()),
    },
];
