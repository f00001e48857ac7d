//! The `[drive]` table of a configuration file, mapped onto
//! `controller_core::DriveConfig`. Every key is checked: unknown keys and out-of-range
//! values are errors naming `drive.key` and the allowed range. Keys that describe the
//! machine (inertias, encoder, base speed, winding) default to the plant's values so
//! there is one source of truth; set them here only to model a mis-tuned drive.

use crate::error::{HarnessError, Result};
use controller_core::{
    AfbMode, AfbRate, DriveConfig, Estimator, FilterConfig, ObserverInertia, ObserverTorque,
    PiInertia,
};
use toml::{Table, Value};

/// What the plant tells the drive by default.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MachineDefaults {
    /// Base speed (rpm).
    pub base_speed_rpm: f32,
    /// Encoder counts per revolution.
    pub encoder_cpr: u32,
    /// Motor inertia (s).
    pub motor_inertia_s: f32,
    /// Load inertia reflected to the motor (s).
    pub load_inertia_s: f32,
    /// Winding resistance (pu).
    pub winding_resistance_pu: f32,
    /// Winding inductance (pu·s).
    pub winding_inductance_pu_s: f32,
}

struct Real {
    key: &'static str,
    min: f64,
    max: f64,
    /// Counts, bits and rates: a fractional value is an error, never truncated.
    whole: bool,
    set: fn(&mut DriveConfig, f64),
}

const fn real(key: &'static str, min: f64, max: f64, set: fn(&mut DriveConfig, f64)) -> Real {
    Real {
        key,
        min,
        max,
        whole: false,
        set,
    }
}

const fn whole(key: &'static str, min: f64, max: f64, set: fn(&mut DriveConfig, f64)) -> Real {
    Real {
        key,
        min,
        max,
        whole: true,
        set,
    }
}

/// Real-valued keys of `[drive]` with their allowed ranges (units in the names).
const REALS: &[Real] = &[
    real("base_speed_rpm", 1.0, 100_000.0, |c, v| {
        c.base_speed_rpm = v as f32
    }),
    whole("encoder_cpr", 4.0, 4_294_967_295.0, |c, v| {
        c.encoder_cpr = v as u32
    }),
    whole("counter_bits", 16.0, 32.0, |c, v| c.counter_bits = v as u8),
    whole("current_rate_hz", 100.0, 100_000.0, |c, v| {
        c.current_rate_hz = v as u32
    }),
    whole("velocity_rate_hz", 10.0, 100_000.0, |c, v| {
        c.velocity_rate_hz = v as u32
    }),
    real("motor_inertia_s", 1e-6, 1000.0, |c, v| {
        c.motor_inertia_s = v as f32
    }),
    real("load_inertia_s", 0.0, 1000.0, |c, v| {
        c.load_inertia_s = v as f32
    }),
    real("position_bandwidth_rad_s", 0.0, 10_000.0, |c, v| {
        c.position_bandwidth_rad_s = v as f32
    }),
    real("velocity_bandwidth_rad_s", 0.01, 100_000.0, |c, v| {
        c.velocity_bandwidth_rad_s = v as f32
    }),
    real("velocity_damping", 0.1, 10.0, |c, v| {
        c.velocity_damping = v as f32
    }),
    real("current_bandwidth_rad_s", 1.0, 1_000_000.0, |c, v| {
        c.current_bandwidth_rad_s = v as f32
    }),
    real("winding_resistance_pu", 1e-6, 100.0, |c, v| {
        c.winding_resistance_pu = v as f32
    }),
    real("winding_inductance_pu_s", 1e-9, 100.0, |c, v| {
        c.winding_inductance_pu_s = v as f32
    }),
    real("torque_limit_pu", 0.01, 100.0, |c, v| {
        c.torque_limit_pu = v as f32
    }),
    real("voltage_limit_pu", 0.01, 100.0, |c, v| {
        c.voltage_limit_pu = v as f32
    }),
    real("velocity_ff_gain", 0.0, 1.0, |c, v| {
        c.velocity_ff_gain = v as f32
    }),
    real("accel_ff_gain", 0.0, 1.0, |c, v| c.accel_ff_gain = v as f32),
    real("velocity_filter_corner_hz", 0.01, 50_000.0, |c, v| {
        c.velocity_filter = with_corner(c.velocity_filter, v as f32)
    }),
    real("velocity_filter_q", 0.1, 10.0, |c, v| {
        c.velocity_filter = with_q(c.velocity_filter, v as f32)
    }),
];

/// Real-valued keys of `[drive.accel_feedback]`, `[drive.observer]`, `[drive.faults]`.
const AFB_REALS: &[Real] = &[
    real("gain_fraction", 0.0, 20.0, |c, v| {
        c.accel_feedback.gain_fraction = v as f32
    }),
    real("filter_corner_hz", 0.01, 50_000.0, |c, v| {
        c.accel_feedback.filter = with_corner(c.accel_feedback.filter, v as f32)
    }),
    real("filter_q", 0.1, 10.0, |c, v| {
        c.accel_feedback.filter = with_q(c.accel_feedback.filter, v as f32)
    }),
];
const OBSERVER_REALS: &[Real] = &[real("bandwidth_hz", 0.01, 50_000.0, |c, v| {
    c.observer.bandwidth_hz = v as f32
})];
const FAULT_REALS: &[Real] = &[
    real("overspeed_pu", 0.01, 100.0, |c, v| {
        c.faults.overspeed_pu = v as f32
    }),
    real("following_error_counts", 1.0, 8_000_000.0, |c, v| {
        c.faults.following_error_counts = v as f32
    }),
    real("encoder_jump_margin", 1.0, 1000.0, |c, v| {
        c.faults.encoder_jump_margin = v as f32
    }),
];

fn corner_of(f: FilterConfig) -> f32 {
    match f {
        FilterConfig::None => 100.0,
        FilterConfig::FirstOrder { corner_hz } | FilterConfig::SecondOrder { corner_hz, .. } => {
            corner_hz
        }
    }
}

fn with_corner(f: FilterConfig, corner_hz: f32) -> FilterConfig {
    match f {
        FilterConfig::None => FilterConfig::None,
        FilterConfig::FirstOrder { .. } => FilterConfig::FirstOrder { corner_hz },
        FilterConfig::SecondOrder { q, .. } => FilterConfig::SecondOrder { corner_hz, q },
    }
}

fn with_q(f: FilterConfig, q: f32) -> FilterConfig {
    match f {
        FilterConfig::SecondOrder { corner_hz, .. } => FilterConfig::SecondOrder { corner_hz, q },
        other => other,
    }
}

fn filter_kind(f: FilterConfig, kind: &str) -> Option<FilterConfig> {
    let corner_hz = corner_of(f);
    let q = match f {
        FilterConfig::SecondOrder { q, .. } => q,
        _ => core::f32::consts::FRAC_1_SQRT_2,
    };
    match kind {
        "none" => Some(FilterConfig::None),
        "first_order" => Some(FilterConfig::FirstOrder { corner_hz }),
        "second_order" => Some(FilterConfig::SecondOrder { corner_hz, q }),
        _ => None,
    }
}

fn estimator(s: &str) -> Option<Estimator> {
    match s {
        "differentiation" => Some(Estimator::Differentiation),
        "observer" => Some(Estimator::Observer),
        _ => None,
    }
}

fn number(key: &str, v: &Value, min: f64, max: f64) -> Result<f64> {
    let x = match v {
        Value::Integer(i) => *i as f64,
        Value::Float(f) => *f,
        _ => {
            return Err(HarnessError::config(
                key,
                format!("must be a number in {min}..={max}"),
            ));
        }
    };
    if !x.is_finite() || x < min || x > max {
        return Err(HarnessError::config(
            key,
            format!("{x} is outside the allowed range {min}..={max}"),
        ));
    }
    Ok(x)
}

fn word<'a>(key: &str, v: &'a Value, allowed: &[&str]) -> Result<&'a str> {
    match v.as_str() {
        Some(s) if allowed.contains(&s) => Ok(s),
        _ => Err(HarnessError::config(
            key,
            format!("must be one of {}", allowed.join(", ")),
        )),
    }
}

/// Applies one table of reals and words; `words` handles the non-numeric keys and
/// returns false for a key it does not know.
fn apply_table(
    cfg: &mut DriveConfig,
    prefix: &str,
    table: &Table,
    reals: &[Real],
    words: &mut dyn FnMut(&mut DriveConfig, &str, &str, &Value) -> Result<bool>,
    allowed_extra: &[&str],
) -> Result<()> {
    // Words first so that a filter kind is set before its corner and q.
    for (k, v) in table {
        let key = format!("{prefix}.{k}");
        if reals.iter().any(|r| r.key == k) || matches!(v, Value::Table(_)) {
            continue;
        }
        if !words(cfg, &key, k, v)? {
            return Err(unknown(&key, reals, allowed_extra));
        }
    }
    for (k, v) in table {
        let key = format!("{prefix}.{k}");
        if let Some(r) = reals.iter().find(|r| r.key == k) {
            let x = number(&key, v, r.min, r.max)?;
            if r.whole && x.fract() != 0.0 {
                return Err(HarnessError::config(
                    &key,
                    format!("{x} must be a whole number in {}..={}", r.min, r.max),
                ));
            }
            (r.set)(cfg, x);
            if let Some(why) = ignored_filter_setting(cfg, &key) {
                return Err(HarnessError::config(&key, why));
            }
        }
    }
    Ok(())
}

/// A filter corner or q that the chosen filter kind does not read: an error, not a no-op.
fn ignored_filter_setting(cfg: &DriveConfig, key: &str) -> Option<String> {
    let (filter, kind_key) = match key {
        "drive.velocity_filter_corner_hz" | "drive.velocity_filter_q" => {
            (cfg.velocity_filter, "drive.velocity_filter")
        }
        "drive.accel_feedback.filter_corner_hz" | "drive.accel_feedback.filter_q" => {
            (cfg.accel_feedback.filter, "drive.accel_feedback.filter")
        }
        _ => return None,
    };
    let kind = match filter {
        FilterConfig::None => "none",
        FilterConfig::FirstOrder { .. } => "first_order",
        FilterConfig::SecondOrder { .. } => return None,
    };
    let reads = if key.ends_with("_q") {
        kind == "second_order"
    } else {
        kind != "none"
    };
    (!reads).then(|| {
        format!(
            "is set, but {kind_key} = \"{kind}\" does not read it (only {} filters do)",
            if key.ends_with("_q") {
                "\"second_order\""
            } else {
                "\"first_order\" and \"second_order\""
            }
        )
    })
}

fn unknown(key: &str, reals: &[Real], extra: &[&str]) -> HarnessError {
    let mut names: Vec<&str> = reals.iter().map(|r| r.key).collect();
    names.extend_from_slice(extra);
    HarnessError::config(
        key,
        format!("unknown key; allowed keys: {}", names.join(", ")),
    )
}

/// Builds the drive configuration: Table 1 defaults, then the machine's values, then the
/// `[drive]` table of `doc` (if any).
pub fn drive_config(doc: &Table, machine: &MachineDefaults) -> Result<DriveConfig> {
    // Base: the loop keys of configs/table1.toml's [drive] (what `DriveConfig::table1()`
    // gave), the design defaults, then the machine (interim, until the harness composes the
    // file tree itself).
    let base: Table = include_str!("../../configs/table1.toml")
        .parse::<Table>()
        .ok()
        .and_then(|t| t.get("drive").and_then(Value::as_table).cloned())
        .unwrap_or_default();
    let mut base = base;
    base.insert(
        "base_speed_rpm".into(),
        Value::Float(f64::from(machine.base_speed_rpm)),
    );
    base.insert(
        "encoder_cpr".into(),
        Value::Integer(i64::from(machine.encoder_cpr)),
    );
    for (k, v) in [
        ("motor_inertia_s", machine.motor_inertia_s),
        ("load_inertia_s", machine.load_inertia_s),
        ("winding_resistance_pu", machine.winding_resistance_pu),
        ("winding_inductance_pu_s", machine.winding_inductance_pu_s),
    ] {
        base.insert(k.into(), Value::Float(f64::from(v)));
    }
    let mut cfg: DriveConfig = base
        .try_into()
        .map_err(|e: toml::de::Error| HarnessError::config("drive", e.to_string()))?;
    cfg.base_speed_rpm = machine.base_speed_rpm;
    cfg.encoder_cpr = machine.encoder_cpr;
    cfg.motor_inertia_s = machine.motor_inertia_s;
    cfg.load_inertia_s = machine.load_inertia_s;
    cfg.winding_resistance_pu = machine.winding_resistance_pu;
    cfg.winding_inductance_pu_s = machine.winding_inductance_pu_s;
    let Some(drive) = doc.get("drive") else {
        return Ok(cfg);
    };
    let Value::Table(drive) = drive else {
        return Err(HarnessError::config("drive", "must be a table"));
    };
    apply_table(
        &mut cfg,
        "drive",
        drive,
        REALS,
        &mut |c, key, k, v| match k {
            "velocity_estimator" => {
                let w = word(key, v, &["differentiation", "observer"])?;
                c.velocity_estimator = estimator(w).unwrap_or(Estimator::Observer);
                Ok(true)
            }
            "velocity_filter" => {
                let w = word(key, v, &["none", "first_order", "second_order"])?;
                c.velocity_filter = filter_kind(c.velocity_filter, w).unwrap_or(FilterConfig::None);
                Ok(true)
            }
            // The inertia the velocity PI is sized for: J_total, or J_total + Ka.
            "velocity_pi_inertia" => {
                c.velocity_pi_inertia = match word(key, v, &["total", "total_plus_afb"])? {
                    "total_plus_afb" => PiInertia::TotalPlusAfb,
                    _ => PiInertia::Total,
                };
                Ok(true)
            }
            _ => Ok(false),
        },
        &[
            "velocity_estimator",
            "velocity_filter",
            "velocity_pi_inertia",
            "[accel_feedback]",
            "[observer]",
            "[faults]",
        ],
    )?;
    for (k, v) in drive {
        let Value::Table(sub) = v else { continue };
        let prefix = format!("drive.{k}");
        match k.as_str() {
            "accel_feedback" => apply_table(
                &mut cfg,
                &prefix,
                sub,
                AFB_REALS,
                &mut |c, key, k, v| match k {
                    "mode" => {
                        c.accel_feedback.mode = match word(key, v, &["off", "plain", "error"])? {
                            "plain" => AfbMode::Plain,
                            "error" => AfbMode::Error,
                            _ => AfbMode::Off,
                        };
                        Ok(true)
                    }
                    "filter" => {
                        let w = word(key, v, &["none", "first_order", "second_order"])?;
                        c.accel_feedback.filter =
                            filter_kind(c.accel_feedback.filter, w).unwrap_or(FilterConfig::None);
                        Ok(true)
                    }
                    "rate" => {
                        c.accel_feedback.rate = match word(key, v, &["current", "velocity"])? {
                            "velocity" => AfbRate::Velocity,
                            _ => AfbRate::Current,
                        };
                        Ok(true)
                    }
                    "source" => {
                        let w = word(key, v, &["differentiation", "observer"])?;
                        c.accel_feedback.source = estimator(w).unwrap_or(Estimator::Observer);
                        Ok(true)
                    }
                    _ => Ok(false),
                },
                &["mode", "filter", "rate", "source"],
            )?,
            "observer" => apply_table(
                &mut cfg,
                &prefix,
                sub,
                OBSERVER_REALS,
                &mut |c, key, k, v| match k {
                    "model_inertia" => {
                        c.observer.model_inertia = match word(key, v, &["total", "motor"])? {
                            "total" => ObserverInertia::Total,
                            _ => ObserverInertia::Motor,
                        };
                        Ok(true)
                    }
                    "torque_input" => {
                        c.observer.torque_input =
                            match word(key, v, &["command", "measured_current"])? {
                                "measured_current" => ObserverTorque::MeasuredCurrent,
                                _ => ObserverTorque::Command,
                            };
                        Ok(true)
                    }
                    _ => Ok(false),
                },
                &["model_inertia", "torque_input"],
            )?,
            "faults" => apply_table(
                &mut cfg,
                &prefix,
                sub,
                FAULT_REALS,
                &mut |_, _, _, _| Ok(false),
                &[],
            )?,
            _ => {
                return Err(HarnessError::config(
                    prefix,
                    "unknown table; allowed: drive.accel_feedback, drive.observer, drive.faults",
                ))
            }
        }
    }
    // The controller checks the combination (rates dividing, bandwidths below Nyquist).
    controller_core::design(&cfg)
        .map_err(|e| HarnessError::config(format!("drive.{}", e.param()), e.to_string()))?;
    Ok(cfg)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn machine() -> MachineDefaults {
        MachineDefaults {
            base_speed_rpm: 1000.0,
            encoder_cpr: 4096,
            motor_inertia_s: 0.117,
            load_inertia_s: 0.863,
            winding_resistance_pu: 0.05,
            winding_inductance_pu_s: 5e-4,
        }
    }

    fn parse(text: &str) -> Result<DriveConfig> {
        drive_config(&text.parse::<Table>().unwrap(), &machine())
    }

    #[test]
    fn machine_values_come_from_the_plant_and_keys_override_them() {
        let cfg = parse("[drive]\nvelocity_bandwidth_rad_s = 50\n").unwrap();
        assert_eq!(cfg.velocity_bandwidth_rad_s, 50.0);
        assert_eq!(cfg.winding_inductance_pu_s, 5e-4);
        assert_eq!(cfg.encoder_cpr, 4096);
        let cfg = parse("[drive]\nload_inertia_s = 0.5\n").unwrap();
        assert_eq!(cfg.load_inertia_s, 0.5);
    }

    #[test]
    fn nested_tables_and_words_map_onto_the_config() {
        let cfg = parse(
            "[drive.accel_feedback]\nfilter_corner_hz = 40\nfilter = \"second_order\"\nmode = \"plain\"\n\
             source = \"differentiation\"\n[drive.observer]\nmodel_inertia = \"total\"\n",
        )
        .unwrap();
        assert_eq!(cfg.accel_feedback.mode, AfbMode::Plain);
        assert_eq!(cfg.accel_feedback.source, Estimator::Differentiation);
        // The kind is applied before the corner, whatever the order in the file.
        assert!(matches!(
            cfg.accel_feedback.filter,
            FilterConfig::SecondOrder { corner_hz, .. } if corner_hz == 40.0
        ));
        assert_eq!(cfg.observer.model_inertia, ObserverInertia::Total);
        assert_eq!(cfg.observer.torque_input, ObserverTorque::Command);
        let cfg = parse("[drive.observer]\ntorque_input = \"measured_current\"\n").unwrap();
        assert_eq!(cfg.observer.torque_input, ObserverTorque::MeasuredCurrent);
        let e = parse("[drive.observer]\ntorque_input = \"current\"\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("drive.observer.torque_input") && e.contains("command, measured_current"),
            "{e}"
        );
    }

    #[test]
    fn velocity_pi_inertia_is_total_unless_set_and_sizes_the_pi() {
        assert_eq!(parse("").unwrap().velocity_pi_inertia, PiInertia::Total);
        let plus = parse("[drive]\nvelocity_pi_inertia = \"total_plus_afb\"\n").unwrap();
        assert_eq!(plus.velocity_pi_inertia, PiInertia::TotalPlusAfb);
        let total = parse("[drive]\nvelocity_pi_inertia = \"total\"\n").unwrap();
        let (gt, gp) = (
            controller_core::design(&total).unwrap(),
            controller_core::design(&plus).unwrap(),
        );
        assert_eq!(
            gt.kp_vel,
            total.velocity_bandwidth_rad_s * total.total_inertia_s()
        );
        assert!(gp.kp_vel > gt.kp_vel, "Ka adds to the PI's inertia");
        for bad in ["\"motor\"", "1", "\"Total\""] {
            let e = parse(&format!("[drive]\nvelocity_pi_inertia = {bad}\n"))
                .unwrap_err()
                .to_string();
            assert!(
                e.contains("drive.velocity_pi_inertia") && e.contains("total, total_plus_afb"),
                "{bad}: {e}"
            );
        }
    }

    #[test]
    fn counts_bits_and_rates_must_be_whole_numbers() {
        for text in [
            "[drive]\nencoder_cpr = 4096.5\n",
            "[drive]\ncounter_bits = 20.7\n",
            "[drive]\ncurrent_rate_hz = 4000.25\n",
            "[drive]\nvelocity_rate_hz = 1999.9\n",
        ] {
            let e = parse(text).unwrap_err().to_string();
            assert!(e.contains("must be a whole number"), "{text}: {e}");
        }
        assert_eq!(
            parse("[drive]\ncounter_bits = 24.0\n")
                .unwrap()
                .counter_bits,
            24
        );
    }

    #[test]
    fn errors_name_the_key_and_the_range_or_the_allowed_keys() {
        let e = parse("[drive]\nvelocity_bandwith_rad_s = 5\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("drive.velocity_bandwith_rad_s") && e.contains("velocity_bandwidth_rad_s"),
            "{e}"
        );
        let e = parse("[drive]\nvelocity_damping = 20\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("drive.velocity_damping") && e.contains("0.1..=10"),
            "{e}"
        );
        let e = parse("[drive.accel_feedback]\nmode = \"on\"\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("drive.accel_feedback.mode") && e.contains("off, plain, error"),
            "{e}"
        );
        let e = parse("[drive.nosuch]\nx = 1\n").unwrap_err().to_string();
        assert!(e.contains("drive.nosuch"), "{e}");
        // A combination only the controller's design can judge: above the loop's Nyquist.
        let e = parse("[drive]\nvelocity_bandwidth_rad_s = 9000\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("drive.velocity_bandwidth_rad_s"), "{e}");
    }
}
