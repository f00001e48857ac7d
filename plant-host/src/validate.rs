//! The one check of a [`PlantConfig`], wherever it comes from (a file or code): every key
//! against [`RANGES`], the two cross-key rules of the sensors, and the speed of the
//! dynamics the integrator must follow.

use crate::config::{Allowed, KeyRange, MotorKind, PlantConfig, RANGES, Reading, range_of};
use crate::error::ConfigError;
use crate::model::{Model, Winding};

/// Largest allowed ‖A‖∞ of the plant, 1/s (see [`PlantConfig::check_speed_of_dynamics`]).
pub const MAX_RATE_PER_S: f64 = 1e6;

/// Smallest load encoder (besides 0 = none), counts per load revolution.
const MIN_LOAD_CPR: u32 = 4;

impl PlantConfig {
    /// Checks every key against its entry in [`RANGES`] (the first failure in table order
    /// is returned), then the cross-key rules: a load encoder has 0 or at least 4 counts,
    /// `plant.encoder_cpr × sensors.encoder_interpolation` is at most 2^30 (the drive's
    /// range), and [`Self::check_speed_of_dynamics`].
    pub fn validate(&self) -> Result<(), ConfigError> {
        for range in RANGES {
            check_key(range, (range.get)(self))?;
        }
        let load_cpr = self.sensors.load_encoder_cpr;
        if (1..MIN_LOAD_CPR).contains(&load_cpr) {
            return Err(ConfigError::OutOfRange {
                key: "sensors.load_encoder_cpr".into(),
                value: load_cpr.to_string(),
                allowed: format!(
                    "0 (no load encoder) or an integer in {MIN_LOAD_CPR}..={} counts/rev",
                    1_u64 << 31
                ),
            });
        }
        self.check_counts_per_rev()?;
        self.check_motor_keys()?;
        self.check_speed_of_dynamics()
    }

    /// The PMSM's keys belong to `electrics.motor = "pmsm"`: there, `pole_pairs`,
    /// `d_inductance_pu_s`, `q_inductance_pu_s`, `dc_bus_pu` and `encoder_offset_elec_deg`
    /// are required (`flux_linkage_pu` defaults to 1, `dead_time_s` to 0); with `"dc"` every
    /// one of them is refused, naming it, rather than silently ignored.
    fn check_motor_keys(&self) -> Result<(), ConfigError> {
        let e = &self.electrics;
        let keys: [(&'static str, bool, bool); 8] = [
            ("electrics.pole_pairs", e.pole_pairs.is_some(), true),
            (
                "electrics.d_inductance_pu_s",
                e.d_inductance_pu_s.is_some(),
                true,
            ),
            (
                "electrics.q_inductance_pu_s",
                e.q_inductance_pu_s.is_some(),
                true,
            ),
            (
                "electrics.flux_linkage_pu",
                e.flux_linkage_pu.is_some(),
                false,
            ),
            ("electrics.dc_bus_pu", e.dc_bus_pu.is_some(), true),
            (
                "electrics.encoder_offset_elec_deg",
                e.encoder_offset_elec_deg.is_some(),
                true,
            ),
            (
                "electrics.encoder_reversed",
                e.encoder_reversed.is_some(),
                false,
            ),
            ("electrics.dead_time_s", e.dead_time_s.is_some(), false),
        ];
        for (key, set, required) in keys {
            match e.motor {
                MotorKind::Dc if set => {
                    return Err(ConfigError::Inconsistent {
                        keys: vec![key, "electrics.motor"],
                        message: format!(
                            "`{key}` describes a PMSM and is refused with electrics.motor = \"dc\" \
                             (the default); set electrics.motor = \"pmsm\" or remove the key"
                        ),
                    });
                }
                MotorKind::Pmsm if required && !set => {
                    let allowed = range_of(key).map_or_else(String::new, KeyRange::describe);
                    return Err(ConfigError::Missing {
                        key: key.into(),
                        allowed: format!("{allowed}; required with electrics.motor = \"pmsm\""),
                    });
                }
                _ => {}
            }
        }
        Ok(())
    }

    fn check_counts_per_rev(&self) -> Result<(), ConfigError> {
        let key = "sensors.encoder_interpolation";
        let cpr = self.mechanics.encoder_cpr;
        let interpolation = self.sensors.encoder_interpolation;
        let max = crate::config::MAX_COUNTS_PER_REV;
        if i64::from(cpr) * i64::from(interpolation) <= max {
            return Ok(());
        }
        let Some(Allowed::Integer {
            min,
            max: max_interp,
        }) = range_of(key).map(|r| r.allowed)
        else {
            return Ok(());
        };
        Err(ConfigError::OutOfRange {
            key: key.into(),
            value: interpolation.to_string(),
            allowed: format!(
                "an integer in {min}..={max_interp} with plant.encoder_cpr × \
                 encoder_interpolation <= {max} counts/rev (plant.encoder_cpr = {cpr})"
            ),
        })
    }

    /// Cross-key check: each key may be in range while the combination is absurdly stiff
    /// (e.g. a tiny motor inertia under a stiff, heavy load). The integrator sub-steps at
    /// ‖A‖·h ≤ 0.5, so ‖A‖ is capped at [`MAX_RATE_PER_S`] (sub-steps ≥ 0.5 µs).
    pub fn check_speed_of_dynamics(&self) -> Result<(), ConfigError> {
        let winding = self.rate_winding();
        let rate = Model::new(&self.mechanics, self.backlash(), Some(winding)).fastest_rate_per_s();
        if rate <= MAX_RATE_PER_S && rate.is_finite() {
            return Ok(());
        }
        let shaft_rate =
            self.mechanics.derived().stiffness_pu_per_rad / self.mechanics.motor_inertia_s;
        let winding_rate = (1.0 + winding.r_pu) / winding.l_pu_s;
        let mechanics = [
            "plant.motor_inertia_s",
            "plant.load_inertia_s",
            "plant.anti_resonance_hz",
            "plant.base_speed_rpm",
        ];
        let inductance = match self.electrics.motor {
            MotorKind::Dc => "electrics.winding_inductance_pu_s",
            MotorKind::Pmsm => "electrics.d_inductance_pu_s",
        };
        // The key most to blame first: the faster of the two rates.
        let keys = if winding_rate > shaft_rate {
            std::iter::once(inductance).chain(mechanics).collect()
        } else {
            mechanics.into_iter().chain([inductance]).collect()
        };
        Err(ConfigError::Inconsistent {
            keys,
            message: format!(
                "the plant's fastest rate ‖A‖ = {rate:.3e} 1/s exceeds {MAX_RATE_PER_S:e} 1/s \
                 (K/Jm = {shaft_rate:.3e}, (1 + R)/L = {winding_rate:.3e}); raise \
                 motor_inertia_s or {}, or lower anti_resonance_hz or load_inertia_s",
                inductance.trim_start_matches("electrics.")
            ),
        })
    }
}

impl PlantConfig {
    /// The winding whose rate [`Self::check_speed_of_dynamics`] bounds: the DC winding, or
    /// for a PMSM the phase resistance over the smaller of Ld and Lq.
    fn rate_winding(&self) -> Winding {
        let e = &self.electrics;
        let dc = Winding::from(e);
        match (e.motor, e.d_inductance_pu_s, e.q_inductance_pu_s) {
            (MotorKind::Pmsm, Some(ld), Some(lq)) => Winding {
                r_pu: e.winding_resistance_pu,
                l_pu_s: ld.min(lq),
            },
            _ => dc,
        }
    }
}

/// One key's value against its range.
fn check_key(range: &KeyRange, value: Reading) -> Result<(), ConfigError> {
    let key = || range.key.to_string();
    let out_of_range = |value: String| ConfigError::OutOfRange {
        key: key(),
        value,
        allowed: range.describe(),
    };
    match (range.allowed, value) {
        (Allowed::Real { .. }, Reading::Real(v)) if !v.is_finite() => Err(ConfigError::NotFinite {
            key: key(),
            allowed: range.describe(),
        }),
        (Allowed::Real { min, max }, Reading::Real(v)) if v < min || v > max => {
            Err(out_of_range(format!("{v}")))
        }
        (Allowed::Integer { min, max }, Reading::Integer(v))
            if v < i128::from(min) || v > i128::from(max) =>
        {
            Err(out_of_range(v.to_string()))
        }
        (Allowed::Words(words), Reading::Word(w)) if !words.contains(&w) => {
            Err(out_of_range(format!("\"{w}\"")))
        }
        _ => Ok(()),
    }
}
