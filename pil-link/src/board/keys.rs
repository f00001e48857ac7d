//! The console's keys: the machine file's `[drive]` keys, spelled `drive.<key>`, with the
//! ranges of controller-core's one range table ([`controller_core::ranges::RANGES`]). Both
//! sides look a key up here; the wire carries the key as text, so an error names it as the
//! operator typed it. A key is a field of [`DriveConfig`] reached through [`field`].
//!
//! A PMSM drive's motor calibration are keys too ([`PMSM_RANGES`]: `drive.pmsm.pole_pairs`,
//! the d and q inductances, `drive.pmsm.encoder_offset_elec_deg`,
//! `drive.pmsm.encoder_reversed` as 0 or 1), its bus `drive.pmsm.dc_bus_pu` and flux
//! linkage `drive.pmsm.flux_linkage_pu` (what the calibration's sweep speed is chosen for): what the
//! calibration measures, set on the board and saved with the rest; a DC drive has none of
//! them, and an uncalibrated drive has no offset to get.
//!
//! The enumerated settings are keys too ([`CHOICES`]): on the wire their value is the index
//! of the value's name in [`Choice::names`], which are spelled as in the machine file. The
//! kind of a filter and the presence of the notch are not keys: a change of kind needs its
//! corner (and Q) with it, which is a machine-file edit, not one setting.

use controller_core::ranges::{self, Range};
use controller_core::{
    AfbFilterAtLimit, AfbMode, AfbRate, ConfigError, DriveConfig, Estimator, FilterConfig,
    ObserverInertia, ObserverTorque, PiInertia,
};

/// How the machine file spells a key of its `[drive]` table: `drive.` + the range key.
pub const PREFIX: &str = "drive.";

/// The `[drive.pmsm]` keys of the console, with the ranges controller-core's FOC loop
/// checks them against (`controller_core::foc`); `design` checks them as a whole (the pole
/// pairs below the encoder's counts, the loop's formats).
pub static PMSM_RANGES: [Range; 7] = [
    pmsm_range("pmsm.pole_pairs", 1.0, 65_535.0, true),
    pmsm_range("pmsm.flux_linkage_pu", 0.05, 10.0, false),
    pmsm_range("pmsm.d_inductance_pu_s", 1e-6, 10.0, false),
    pmsm_range("pmsm.q_inductance_pu_s", 1e-6, 10.0, false),
    pmsm_range("pmsm.dc_bus_pu", 0.01, 1000.0, false),
    pmsm_range("pmsm.encoder_offset_elec_deg", -360.0, 360.0, false),
    pmsm_range("pmsm.encoder_reversed", 0.0, 1.0, true),
];

const fn pmsm_range(key: &'static str, min: f32, max: f32, whole: bool) -> Range {
    Range {
        key,
        min,
        max,
        min_exclusive: false,
        whole,
    }
}

/// The range table entry of `key` (`drive.velocity_damping`, or without the prefix).
#[must_use]
pub fn range(key: &str) -> Option<&'static Range> {
    let key = key.strip_prefix(PREFIX).unwrap_or(key);
    ranges::range_of(key).or_else(|| PMSM_RANGES.iter().find(|r| r.key == key))
}

/// A setting of a [`DriveConfig`], by reference, in its own type.
#[derive(Debug)]
pub enum Field<'a> {
    /// A real-valued setting.
    Real(&'a mut f32),
    /// A whole-number setting.
    Whole(&'a mut u32),
    /// A whole-number setting stored in a byte (`counter_bits`).
    Byte(&'a mut u8),
    /// A measured setting, `None` until measured (`pmsm.encoder_offset_elec_deg`).
    Measured(&'a mut Option<f32>),
    /// A flag, 0 or 1 (`pmsm.encoder_reversed`).
    Flag(&'a mut bool),
}

/// Why a key cannot be read or written.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum KeyError {
    /// No setting has this key.
    Unknown,
    /// The setting exists, but not in this drive (a notch key without a notch, the `q` of a
    /// first-order filter, the corner of no filter).
    NotPresent(&'static Range),
    /// Outside its range (or not whole for a whole-number key).
    Invalid(ConfigError),
}

/// An enumerated setting: its key below `[drive]` and the names of its values, as the
/// machine file spells them, in the order of their index on the wire.
#[derive(Debug, PartialEq, Eq)]
pub struct Choice {
    /// Dotted path below `[drive]`, e.g. `"accel_feedback.mode"`.
    pub key: &'static str,
    /// The values' names; a value's index here is its number on the wire.
    pub names: &'static [&'static str],
    /// The [`DriveConfig`] field it reads and writes.
    pub field: ChoiceField,
}

/// The [`DriveConfig`] field of a [`Choice`]: a match on it names every field, so an entry
/// added to [`CHOICES`] cannot fall through to another field's arm.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ChoiceField {
    /// `accel_feedback.mode`.
    AfbMode,
    /// `accel_feedback.rate`.
    AfbRate,
    /// `accel_feedback.source`.
    AfbSource,
    /// `accel_feedback.filter_at_limit`.
    AfbFilterAtLimit,
    /// `velocity_estimator`.
    VelocityEstimator,
    /// `velocity_pi_inertia`.
    VelocityPiInertia,
    /// `observer.model_inertia`.
    ObserverModelInertia,
    /// `observer.torque_input`.
    ObserverTorqueInput,
}

impl Choice {
    /// The index of the value called `name`.
    #[must_use]
    pub fn index(&self, name: &str) -> Option<usize> {
        self.names.iter().position(|n| *n == name)
    }

    /// The name of the value with index `value` (a whole number below `names.len()`).
    #[must_use]
    pub fn name(&self, value: f64) -> Option<&'static str> {
        let i = value as usize;
        (i as f64 == value)
            .then(|| self.names.get(i).copied())
            .flatten()
    }

    /// `value` as an index of a value (a whole number below `names.len()`).
    fn index_of_value(&self, value: f64) -> Option<usize> {
        self.name(value).map(|_| value as usize)
    }

    /// The error for an index that names no value: out of `[0, names.len() − 1]`.
    fn out_of_range(&self, value: f64) -> ConfigError {
        ConfigError::OutOfRange {
            param: self.key,
            value: value as f32,
            min: 0.0,
            max: self.names.len().saturating_sub(1) as f32,
            min_exclusive: false,
        }
    }
}

/// The enumerated settings of the console.
pub static CHOICES: [Choice; 8] = [
    Choice {
        key: "accel_feedback.mode",
        names: &["off", "plain", "error"],
        field: ChoiceField::AfbMode,
    },
    Choice {
        key: "accel_feedback.rate",
        names: &["current", "velocity"],
        field: ChoiceField::AfbRate,
    },
    Choice {
        key: "accel_feedback.source",
        names: &["differentiation", "observer"],
        field: ChoiceField::AfbSource,
    },
    Choice {
        key: "accel_feedback.filter_at_limit",
        names: &["track", "hold"],
        field: ChoiceField::AfbFilterAtLimit,
    },
    Choice {
        key: "velocity_estimator",
        names: &["differentiation", "observer"],
        field: ChoiceField::VelocityEstimator,
    },
    Choice {
        key: "velocity_pi_inertia",
        names: &["total", "total_plus_afb"],
        field: ChoiceField::VelocityPiInertia,
    },
    Choice {
        key: "observer.model_inertia",
        names: &["total", "motor"],
        field: ChoiceField::ObserverModelInertia,
    },
    Choice {
        key: "observer.torque_input",
        names: &["command", "measured_current"],
        field: ChoiceField::ObserverTorqueInput,
    },
];

/// The enumerated setting `key` (`drive.accel_feedback.mode`, or without the prefix).
#[must_use]
pub fn choice(key: &str) -> Option<&'static Choice> {
    let key = key.strip_prefix(PREFIX).unwrap_or(key);
    CHOICES.iter().find(|c| c.key == key)
}

/// The key as the range table or [`CHOICES`] spell it (without the prefix), for a key of
/// either kind; `None` for no setting.
#[must_use]
pub fn static_key(key: &str) -> Option<&'static str> {
    choice(key)
        .map(|c| c.key)
        .or_else(|| range(key).map(|r| r.key))
}

/// The index of the enumerated setting `c` in `cfg`.
fn choice_get(cfg: &DriveConfig, c: &Choice) -> usize {
    let estimator = |e: Estimator| match e {
        Estimator::Differentiation => 0,
        Estimator::Observer => 1,
    };
    match c.field {
        ChoiceField::AfbMode => match cfg.accel_feedback.mode {
            AfbMode::Off => 0,
            AfbMode::Plain => 1,
            AfbMode::Error => 2,
        },
        ChoiceField::AfbRate => usize::from(cfg.accel_feedback.rate == AfbRate::Velocity),
        ChoiceField::AfbSource => estimator(cfg.accel_feedback.source),
        ChoiceField::AfbFilterAtLimit => {
            usize::from(cfg.accel_feedback.filter_at_limit == AfbFilterAtLimit::Hold)
        }
        ChoiceField::VelocityEstimator => estimator(cfg.velocity_estimator),
        ChoiceField::VelocityPiInertia => {
            usize::from(cfg.velocity_pi_inertia == PiInertia::TotalPlusAfb)
        }
        ChoiceField::ObserverModelInertia => {
            usize::from(cfg.observer.model_inertia == ObserverInertia::Motor)
        }
        ChoiceField::ObserverTorqueInput => {
            usize::from(cfg.observer.torque_input == ObserverTorque::MeasuredCurrent)
        }
    }
}

/// Sets the enumerated setting `c` of `cfg` to the value with index `i` (< `names.len()`).
fn choice_set(cfg: &mut DriveConfig, c: &Choice, i: usize) {
    let estimator = if i == 0 {
        Estimator::Differentiation
    } else {
        Estimator::Observer
    };
    match c.field {
        ChoiceField::AfbMode => {
            cfg.accel_feedback.mode = match i {
                0 => AfbMode::Off,
                1 => AfbMode::Plain,
                _ => AfbMode::Error,
            }
        }
        ChoiceField::AfbRate => {
            cfg.accel_feedback.rate = if i == 0 {
                AfbRate::Current
            } else {
                AfbRate::Velocity
            }
        }
        ChoiceField::AfbSource => cfg.accel_feedback.source = estimator,
        ChoiceField::AfbFilterAtLimit => {
            cfg.accel_feedback.filter_at_limit = if i == 0 {
                AfbFilterAtLimit::Track
            } else {
                AfbFilterAtLimit::Hold
            }
        }
        ChoiceField::VelocityEstimator => cfg.velocity_estimator = estimator,
        ChoiceField::VelocityPiInertia => {
            cfg.velocity_pi_inertia = if i == 0 {
                PiInertia::Total
            } else {
                PiInertia::TotalPlusAfb
            }
        }
        ChoiceField::ObserverModelInertia => {
            cfg.observer.model_inertia = if i == 0 {
                ObserverInertia::Total
            } else {
                ObserverInertia::Motor
            }
        }
        ChoiceField::ObserverTorqueInput => {
            cfg.observer.torque_input = if i == 0 {
                ObserverTorque::Command
            } else {
                ObserverTorque::MeasuredCurrent
            }
        }
    }
}

/// The field of `cfg` the range `r` belongs to; `None` when this drive lacks it.
pub fn field<'a>(cfg: &'a mut DriveConfig, r: &Range) -> Option<Field<'a>> {
    use ranges as k;
    let key = r.key;
    if key.starts_with("pmsm.") {
        return pmsm_field(cfg, key);
    }
    let f = &mut cfg.faults;
    let real = |x: &'a mut f32| Some(Field::Real(x));
    match key {
        _ if key == k::BASE_SPEED_RPM.key => real(&mut cfg.base_speed_rpm),
        _ if key == k::ENCODER_CPR.key => Some(Field::Whole(&mut cfg.encoder_cpr)),
        _ if key == k::COUNTER_BITS.key => Some(Field::Byte(&mut cfg.counter_bits)),
        _ if key == k::CURRENT_RATE_HZ.key => Some(Field::Whole(&mut cfg.current_rate_hz)),
        _ if key == k::VELOCITY_RATE_HZ.key => Some(Field::Whole(&mut cfg.velocity_rate_hz)),
        _ if key == k::MOTOR_INERTIA_S.key => real(&mut cfg.motor_inertia_s),
        _ if key == k::LOAD_INERTIA_S.key => real(&mut cfg.load_inertia_s),
        _ if key == k::POSITION_BANDWIDTH_RAD_S.key => real(&mut cfg.position_bandwidth_rad_s),
        _ if key == k::VELOCITY_BANDWIDTH_RAD_S.key => real(&mut cfg.velocity_bandwidth_rad_s),
        _ if key == k::VELOCITY_DAMPING.key => real(&mut cfg.velocity_damping),
        _ if key == k::CURRENT_BANDWIDTH_RAD_S.key => real(&mut cfg.current_bandwidth_rad_s),
        _ if key == k::WINDING_RESISTANCE_PU.key => real(&mut cfg.winding_resistance_pu),
        _ if key == k::WINDING_INDUCTANCE_PU_S.key => real(&mut cfg.winding_inductance_pu_s),
        _ if key == k::TORQUE_LIMIT_PU.key => real(&mut cfg.torque_limit_pu),
        _ if key == k::VOLTAGE_LIMIT_PU.key => real(&mut cfg.voltage_limit_pu),
        _ if key == k::VELOCITY_FF_GAIN.key => real(&mut cfg.velocity_ff_gain),
        _ if key == k::ACCEL_FF_GAIN.key => real(&mut cfg.accel_ff_gain),
        _ if key == k::VELOCITY_FILTER_CORNER_HZ.key => corner(&mut cfg.velocity_filter),
        _ if key == k::VELOCITY_FILTER_Q.key => q(&mut cfg.velocity_filter),
        _ if key == k::AFB_GAIN_FRACTION.key => real(&mut cfg.accel_feedback.gain_fraction),
        _ if key == k::AFB_LIMIT_HEADROOM_FRACTION.key => {
            real(&mut cfg.accel_feedback.limit_headroom_fraction)
        }
        _ if key == k::AFB_FILTER_CORNER_HZ.key => corner(&mut cfg.accel_feedback.filter),
        _ if key == k::AFB_FILTER_Q.key => q(&mut cfg.accel_feedback.filter),
        _ if key == k::OBSERVER_BANDWIDTH_HZ.key => real(&mut cfg.observer.bandwidth_hz),
        _ if key == k::OBSERVER_COUNT_INTERVAL_COUNTS.key => {
            real(&mut cfg.observer.count_interval_counts)
        }
        _ if key == k::OVERSPEED_PU.key => real(&mut f.overspeed_pu),
        _ if key == k::FOLLOWING_ERROR_REV.key => real(&mut f.following_error_rev),
        _ if key == k::ENCODER_JUMP_MARGIN.key => real(&mut f.encoder_jump_margin),
        _ if key == k::OVERCURRENT_RATIO.key => real(&mut f.overcurrent_ratio),
        _ if key == k::OVERCURRENT_TICKS.key => Some(Field::Whole(&mut f.overcurrent_ticks)),
        _ if key == k::CONTINUOUS_CURRENT_PU.key => real(&mut f.continuous_current_pu),
        _ if key == k::OVERLOAD_CURRENT_PU.key => real(&mut f.overload_current_pu),
        _ if key == k::OVERLOAD_TIME_S.key => real(&mut f.overload_time_s),
        _ if key == k::THERMAL_WARNING_FRACTION.key => real(&mut f.thermal_warning_fraction),
        _ if key == k::STALL_SPEED_PU.key => real(&mut f.stall_speed_pu),
        _ if key == k::STALL_TORQUE_FRACTION.key => real(&mut f.stall_torque_fraction),
        _ if key == k::STALL_TIME_S.key => real(&mut f.stall_time_s),
        _ if key == k::NOTCH_CENTRE_HZ.key => {
            cfg.notch.as_mut().map(|n| Field::Real(&mut n.centre_hz))
        }
        _ if key == k::NOTCH_WIDTH_HZ.key => {
            cfg.notch.as_mut().map(|n| Field::Real(&mut n.width_hz))
        }
        _ if key == k::NOTCH_DEPTH_DB.key => {
            cfg.notch.as_mut().map(|n| Field::Real(&mut n.depth_db))
        }
        _ => None,
    }
}

/// The `[drive.pmsm]` field of `key` ([`PMSM_RANGES`]); `None` without one.
fn pmsm_field<'a>(cfg: &'a mut DriveConfig, key: &str) -> Option<Field<'a>> {
    let p = cfg.pmsm.as_mut()?;
    Some(match key {
        "pmsm.pole_pairs" => Field::Whole(&mut p.pole_pairs),
        "pmsm.flux_linkage_pu" => Field::Real(&mut p.flux_linkage_pu),
        "pmsm.d_inductance_pu_s" => Field::Real(&mut p.d_inductance_pu_s),
        "pmsm.q_inductance_pu_s" => Field::Real(&mut p.q_inductance_pu_s),
        "pmsm.dc_bus_pu" => Field::Real(&mut p.dc_bus_pu),
        "pmsm.encoder_offset_elec_deg" => Field::Measured(&mut p.encoder_offset_elec_deg),
        "pmsm.encoder_reversed" => Field::Flag(&mut p.encoder_reversed),
        _ => return None,
    })
}

fn corner(f: &mut FilterConfig) -> Option<Field<'_>> {
    match f {
        FilterConfig::None => None,
        FilterConfig::FirstOrder { corner_hz } | FilterConfig::SecondOrder { corner_hz, .. } => {
            Some(Field::Real(corner_hz))
        }
    }
}

fn q(f: &mut FilterConfig) -> Option<Field<'_>> {
    match f {
        FilterConfig::SecondOrder { q, .. } => Some(Field::Real(q)),
        _ => None,
    }
}

/// The value of `key` in `cfg`.
///
/// # Errors
/// [`KeyError::Unknown`] or [`KeyError::NotPresent`].
pub fn get(cfg: &DriveConfig, key: &str) -> Result<f64, KeyError> {
    if let Some(c) = choice(key) {
        return Ok(choice_get(cfg, c) as f64);
    }
    let r = range(key).ok_or(KeyError::Unknown)?;
    let mut copy = *cfg;
    Ok(match field(&mut copy, r).ok_or(KeyError::NotPresent(r))? {
        Field::Real(v) => f64::from(*v),
        Field::Whole(v) => f64::from(*v),
        Field::Byte(v) => f64::from(*v),
        Field::Measured(v) => f64::from(v.ok_or(KeyError::NotPresent(r))?),
        Field::Flag(v) => f64::from(u8::from(*v)),
    })
}

/// Writes `value` into the setting `key` of `cfg`, checked against the key's range (and
/// for a whole-number key, that it is whole). Only that key's own range is checked here:
/// the settings as a whole are checked by the caller (`controller_core::design`).
///
/// # Errors
/// [`KeyError`]; `cfg` is then unchanged.
pub fn set(cfg: &mut DriveConfig, key: &str, value: f64) -> Result<(), KeyError> {
    if let Some(c) = choice(key) {
        let i = c
            .index_of_value(value)
            .ok_or(KeyError::Invalid(c.out_of_range(value)))?;
        choice_set(cfg, c, i);
        return Ok(());
    }
    let r = range(key).ok_or(KeyError::Unknown)?;
    // f32 is the type of every real setting; whole ones are exact in f32 up to 2^24 and
    // every whole bound of the table is a power of two.
    let narrow = value as f32;
    // (`as i64` saturates: a value beyond it is out of every whole range anyway.)
    if r.whole && (value as i64) as f64 != value {
        return Err(KeyError::Invalid(r.out_of_range(narrow)));
    }
    r.check(narrow).map_err(KeyError::Invalid)?;
    match field(cfg, r).ok_or(KeyError::NotPresent(r))? {
        Field::Real(v) => *v = narrow,
        // In range, so within u32 (and within u8 for `counter_bits`, at most 32).
        Field::Whole(v) => *v = value as u32,
        Field::Byte(v) => *v = value as u8,
        Field::Measured(v) => *v = Some(narrow),
        Field::Flag(v) => *v = value != 0.0,
    }
    Ok(())
}
