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
    /// `true` or `false`.
    Bool,
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
    /// A true-or-false key.
    Bool(bool),
    /// A key of the other motor kind, not set (`electrics.pole_pairs` of a DC motor).
    Unset,
}

impl<T: Into<Reading>> From<Option<T>> for Reading {
    fn from(v: Option<T>) -> Self {
        v.map_or(Self::Unset, Into::into)
    }
}

impl From<f64> for Reading {
    fn from(v: f64) -> Self {
        Self::Real(v)
    }
}

impl From<u32> for Reading {
    fn from(v: u32) -> Self {
        Self::Integer(v.into())
    }
}

impl From<u64> for Reading {
    fn from(v: u64) -> Self {
        Self::Integer(v.into())
    }
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
            Allowed::Bool => "true or false".to_string(),
        };
        text.trim_end().to_string()
    }

    /// A key a file must set.
    const fn new(
        key: &'static str,
        allowed: Allowed,
        unit: &'static str,
        get: fn(&PlantConfig) -> Reading,
    ) -> Self {
        Self {
            key,
            allowed,
            unit,
            required: true,
            get,
        }
    }

    /// The same key with a default, so a file may leave it out.
    const fn optional(self) -> Self {
        Self {
            required: false,
            ..self
        }
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

const fn integer(min: i64, max: i64) -> Allowed {
    Allowed::Integer { min, max }
}

/// Largest counts per motor revolution the drive takes (controller-core `design()`).
pub(crate) const MAX_COUNTS_PER_REV: i64 = 1 << 30;

/// Every key of the plant's tables, in file order.
#[rustfmt::skip] // a table: one key a line
pub const RANGES: &[KeyRange] = &[
    KeyRange::new("plant.base_speed_rpm", real(1.0, 100_000.0), "rpm", |c| c.mechanics.base_speed_rpm.into()),
    // The drive's range (controller-core design()) is (0, 1000] s.
    KeyRange::new("plant.motor_inertia_s", real(1e-5, 1e3), "s", |c| c.mechanics.motor_inertia_s.into()),
    KeyRange::new("plant.load_inertia_s", real(1e-5, 1e3), "s", |c| c.mechanics.load_inertia_s.into()),
    KeyRange::new("plant.anti_resonance_hz", real(0.1, 5000.0), "Hz", |c| c.mechanics.anti_resonance_hz.into()),
    KeyRange::new("plant.shaft_damping_ratio", real(0.0, 2.0), "", |c| c.mechanics.shaft_damping_ratio.into()),
    KeyRange::new("plant.backlash_deg", real(0.0, 45.0), "deg", |c| c.mechanics.backlash_deg.into()),
    KeyRange::new("plant.motor_viscous_pu", real(0.0, 100.0), "pu torque/pu speed", |c| c.mechanics.motor_viscous_pu.into()),
    KeyRange::new("plant.load_viscous_pu", real(0.0, 100.0), "pu torque/pu speed", |c| c.mechanics.load_viscous_pu.into()),
    // The drive's range (controller-core design()): up to 2^30 counts/rev.
    KeyRange::new("plant.encoder_cpr", integer(4, MAX_COUNTS_PER_REV), "counts/rev", |c| c.mechanics.encoder_cpr.into()),
    KeyRange::new("electrics.winding_resistance_pu", real(1e-4, 10.0), "pu", |c| c.electrics.winding_resistance_pu.into()).optional(),
    KeyRange::new("electrics.winding_inductance_pu_s", real(1e-6, 1.0), "pu*s", |c| c.electrics.winding_inductance_pu_s.into()).optional(),
    KeyRange::new("electrics.computational_delay_s", real(0.0, 0.01), "s", |c| c.electrics.computational_delay_s.into()),
    KeyRange::new("electrics.current_adc_bits", integer(4, 24), "bits", |c| c.electrics.current_adc_bits.into()).optional(),
    KeyRange::new("electrics.current_full_scale_pu", real(0.1, 100.0), "pu", |c| c.electrics.current_full_scale_pu.into()).optional(),
    KeyRange::new("electrics.motor", Allowed::Words(&["dc", "pmsm"]), "", |c| Reading::Word(c.electrics.motor.as_str())).optional(),
    // The PMSM's keys: required with motor = "pmsm" (flux_linkage_pu and dead_time_s have
    // defaults), refused with "dc" (PlantConfig::validate).
    KeyRange::new("electrics.pole_pairs", integer(1, 64), "pole pairs", |c| c.electrics.pole_pairs.into()).optional(),
    KeyRange::new("electrics.d_inductance_pu_s", real(1e-6, 1.0), "pu*s", |c| c.electrics.d_inductance_pu_s.into()).optional(),
    KeyRange::new("electrics.q_inductance_pu_s", real(1e-6, 1.0), "pu*s", |c| c.electrics.q_inductance_pu_s.into()).optional(),
    KeyRange::new("electrics.flux_linkage_pu", real(0.01, 10.0), "pu", |c| c.electrics.flux_linkage_pu.into()).optional(),
    KeyRange::new("electrics.dc_bus_pu", real(0.1, 100.0), "pu", |c| c.electrics.dc_bus_pu.into()).optional(),
    KeyRange::new("electrics.encoder_offset_elec_deg", real(-360.0, 360.0), "deg", |c| c.electrics.encoder_offset_elec_deg.into()).optional(),
    KeyRange::new("electrics.encoder_reversed", Allowed::Bool, "", |c| c.electrics.encoder_reversed.map_or(Reading::Unset, Reading::Bool)).optional(),
    // Up to 10 µs; with the PWM frequency (PmsmPlant::new) t_d·f_pwm is at most 0.1.
    KeyRange::new("electrics.dead_time_s", real(0.0, 1e-5), "s", |c| c.electrics.dead_time_s.into()).optional(),
    // 1 (a square-wave encoder) up to 4096, a 12-bit interpolator.
    KeyRange::new("sensors.encoder_interpolation", integer(1, 4096), "interpolated counts per encoder count", |c| c.sensors.encoder_interpolation.into()).optional(),
    KeyRange::new("sensors.load_encoder_cpr", integer(0, 1 << 31), "counts/rev (0 = no load encoder)", |c| c.sensors.load_encoder_cpr.into()).optional(),
    KeyRange::new("sensors.gear_ratio", real(1e-3, 1e4), "motor rev/load rev", |c| c.sensors.gear_ratio.into()).optional(),
    KeyRange::new("sensors.encoder_noise_counts", real(0.0, 1e6), "counts rms", |c| c.sensors.encoder_noise_counts.into()).optional(),
    KeyRange::new("sensors.current_noise_pu", real(0.0, 10.0), "pu rms", |c| c.sensors.current_noise_pu.into()).optional(),
    KeyRange::new("sensors.noise_seed", integer(0, i64::MAX), "", |c| c.sensors.noise_seed.into()).optional(),
    KeyRange::new("lost_motion.model", Allowed::Words(&["dead_zone", "clamped"]), "", |c| Reading::Word(c.lost_motion.model.as_str())).optional(),
];
