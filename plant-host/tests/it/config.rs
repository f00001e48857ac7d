//! Every configuration error names the key and its allowed range; the range table is the
//! struct's keys; replay writes nothing on error.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic,
    missing_docs
)]

use crate::common;

use plant_host::{
    Allowed, BacklashModel, ConfigError, ElectricsConfig, PlantConfig, PlantError, RANGES, Reading,
    SensorsConfig, replay,
};
use std::path::PathBuf;
use toml::{Table, Value};

/// The plant tables of `configs/machines/table1.toml` as a value tree (its `[drive]` removed, as the
/// harness does).
fn table1_doc() -> Table {
    let mut doc: Table = common::config_text("table1.toml").parse().unwrap();
    doc.remove("drive");
    doc
}

/// `doc` with `table.key` set to `value` (the table created if absent).
fn with(mut doc: Table, key: &str, value: Value) -> Table {
    let (table, name) = key.split_once('.').unwrap();
    let t = doc
        .entry(table)
        .or_insert_with(|| Value::Table(Table::new()));
    t.as_table_mut().unwrap().insert(name.to_string(), value);
    doc
}

/// `doc` without `table.key`.
fn without(mut doc: Table, key: &str) -> Table {
    let (table, name) = key.split_once('.').unwrap();
    doc.get_mut(table)
        .unwrap()
        .as_table_mut()
        .unwrap()
        .remove(name);
    doc
}

fn err(doc: Table) -> ConfigError {
    match PlantConfig::from_table(doc.clone()) {
        Err(e) => e,
        Ok(c) => panic!("expected an error for\n{doc}\ngot {c:?}"),
    }
}

/// The error names `key` through [`ConfigError::key`] and in its message, with `allowed`.
fn assert_names(e: &ConfigError, key: &str, allowed: &str) {
    assert_eq!(e.key(), key, "{e}");
    let msg = e.to_string();
    assert!(msg.contains(key) && msg.contains(allowed), "{msg}");
}

#[test]
fn shipped_configs_parse_and_round_trip() {
    let t1 = PlantConfig::from_table(table1_doc()).unwrap();
    assert_eq!(t1, common::table1());
    // A config written out and read back is the same config (the struct is the format).
    let text = toml::to_string(&t1).unwrap();
    assert_eq!(PlantConfig::from_machine_toml(&text).unwrap(), t1);
    let pp = common::config("printing-press.toml");
    assert_eq!(pp.mechanics.encoder_cpr, 1_000_000);
    // 150 counts of lost motion at 1e6 counts/rev.
    let counts = pp.mechanics.backlash_deg / 360.0 * 1e6;
    assert!((counts - 150.0).abs() < 1e-6, "{counts}");
    assert!((pp.mechanics.load_inertia_s / pp.mechanics.motor_inertia_s - 8.0).abs() < 1e-12);
    let dyno = common::config("dyno.toml");
    assert_eq!(dyno.mechanics.backlash_deg, 0.0);
}

#[test]
fn optional_keys_and_tables_default() {
    let mut doc = table1_doc();
    doc.remove("sensors");
    doc.remove("lost_motion");
    let delay = Value::Float(1e-4);
    doc.insert("electrics".into(), Value::Table(Table::new()));
    let doc = with(doc, "electrics.computational_delay_s", delay);
    let c = PlantConfig::from_table(doc).unwrap();
    assert_eq!(c.electrics, ElectricsConfig::with_delay(1e-4));
    assert_eq!(c.sensors, SensorsConfig::default());
    assert_eq!(c.lost_motion.model, BacklashModel::DeadZone);
    assert_eq!(c.sensors.load_encoder(), None);
    let clamped = with(
        table1_doc(),
        "lost_motion.model",
        Value::String("clamped".into()),
    );
    assert_eq!(
        PlantConfig::from_table(clamped).unwrap().lost_motion.model,
        BacklashModel::Clamped
    );
}

#[test]
fn every_required_key_is_named_when_missing_and_the_others_default() {
    for r in RANGES {
        let doc = without(table1_doc(), r.key);
        if r.required {
            let e = err(doc);
            assert!(matches!(e, ConfigError::Missing { .. }), "{e}");
            assert_names(&e, r.key, &r.describe());
            assert!(e.to_string().contains("..="), "{e}");
        } else {
            assert!(
                PlantConfig::from_table(doc).is_ok(),
                "{} has a default",
                r.key
            );
        }
    }
    for table in ["plant", "electrics"] {
        let mut doc = table1_doc();
        doc.remove(table);
        let e = err(doc);
        assert!(matches!(e, ConfigError::MissingTable { .. }), "{e}");
        assert_eq!(e.key(), table);
    }
    let mut doc = table1_doc();
    doc.insert("plant".into(), Value::Integer(3));
    assert_eq!(err(doc), ConfigError::NotATable { table: "plant" });
    let e = PlantConfig::from_machine_toml("[plant\n").unwrap_err();
    assert!(matches!(e, ConfigError::Syntax { .. }), "{e}");
}

/// Values each key refuses: out of range, not finite, of the wrong type.
fn refused(allowed: Allowed) -> Vec<(Value, &'static str)> {
    let mut out = Vec::new();
    if !matches!(allowed, Allowed::Bool) {
        out.push((Value::Boolean(true), "wrong"));
    }
    if !matches!(allowed, Allowed::Words(_)) {
        out.push((Value::String("fast".into()), "wrong"));
    }
    match allowed {
        Allowed::Real { min, max } => {
            out.push((Value::Float(min - 1.0), "range"));
            out.push((Value::Float(max * 10.0 + 1.0), "range"));
            for x in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
                out.push((Value::Float(x), "finite"));
            }
        }
        Allowed::Integer { min, max } => {
            out.push((Value::Integer(min - 1), "range"));
            if max < i64::MAX {
                out.push((Value::Integer(max + 1), "range"));
            }
            out.push((Value::Integer(i64::MIN), "range"));
            out.push((Value::Float(f64::NAN), "finite"));
            out.push((Value::Float(16.5), "wrong"));
        }
        Allowed::Words(_) => {
            out.push((Value::String("hysteresis".into()), "range"));
            out.push((Value::Integer(1), "wrong"));
        }
        Allowed::Bool => out.push((Value::Integer(1), "wrong")),
    }
    out
}

#[test]
fn every_key_refuses_out_of_range_non_finite_and_wrong_type_naming_its_range() {
    for r in RANGES {
        for (value, kind) in refused(r.allowed) {
            let e = err(with(table1_doc(), r.key, value.clone()));
            let ok = match kind {
                "range" => matches!(e, ConfigError::OutOfRange { .. }),
                "finite" => matches!(e, ConfigError::NotFinite { .. }),
                _ => matches!(e, ConfigError::WrongType { .. }),
            };
            assert!(ok, "{} = {value}: expected {kind}, got {e}", r.key);
            assert_names(&e, r.key, &r.describe());
        }
    }
}

#[test]
fn a_config_built_in_code_is_checked_by_the_same_table() {
    let mut c = common::table1();
    assert_eq!(c.validate(), Ok(()));
    c.mechanics.motor_inertia_s = -1.0;
    let e = c.validate().unwrap_err();
    assert!(matches!(e, ConfigError::OutOfRange { .. }), "{e}");
    assert_eq!(e.key(), "plant.motor_inertia_s");
    c.mechanics.motor_inertia_s = f64::NAN;
    assert!(matches!(c.validate(), Err(ConfigError::NotFinite { .. })));
    let mut c = common::table1();
    c.sensors.noise_seed = u64::MAX;
    assert_eq!(c.validate().unwrap_err().key(), "sensors.noise_seed");
}

#[test]
fn unknown_keys_and_tables_are_rejected_by_name() {
    for table in PlantConfig::TABLES {
        let key = format!("{table}.no_such_key");
        let e = err(with(table1_doc(), &key, Value::Float(1.0)));
        assert!(matches!(e, ConfigError::Unknown { .. }), "{table}: {e}");
        assert_eq!(e.key(), key);
        // The message lists the keys the table has.
        let first = RANGES.iter().find(|r| r.table() == table).unwrap();
        assert!(e.to_string().contains(first.name()), "{e}");
    }
    let mut doc = table1_doc();
    doc.insert("plantx".into(), Value::Table(Table::new()));
    let e = err(doc);
    assert_eq!(
        e,
        ConfigError::UnknownTable {
            table: "plantx".into()
        }
    );
    assert!(e.to_string().contains("[plantx]"), "{e}");
    // [drive] is the caller's to remove; a machine file's own is ignored.
    let mut doc = table1_doc();
    doc.insert("drive".into(), Value::Table(Table::new()));
    assert_eq!(err(doc).key(), "drive");
    assert!(PlantConfig::from_machine_toml(&common::config_text("table1.toml")).is_ok());
}

#[test]
fn the_special_rules_of_the_sensors() {
    let e = err(with(
        table1_doc(),
        "sensors.load_encoder_cpr",
        Value::Integer(2),
    ));
    assert_names(&e, "sensors.load_encoder_cpr", "0 (no load encoder)");
    let plain = PlantConfig::from_table(table1_doc()).unwrap();
    assert_eq!(plain.sensors.encoder_interpolation, 1);
    assert_eq!(plain.counts_per_rev(), plain.mechanics.encoder_cpr);
    let c = PlantConfig::from_table(with(
        table1_doc(),
        "sensors.encoder_interpolation",
        Value::Integer(16),
    ))
    .unwrap();
    assert_eq!(c.counts_per_rev(), 16 * plain.mechanics.encoder_cpr);
    // 1e6 counts x 4096 exceeds the 2^30 counts a revolution may have (the drive's range).
    let big = with(table1_doc(), "plant.encoder_cpr", Value::Integer(1_000_000));
    let e = err(with(
        big,
        "sensors.encoder_interpolation",
        Value::Integer(4096),
    ));
    assert_names(&e, "sensors.encoder_interpolation", "1073741824");
}

/// The range table and the structs agree: every key written out has its entry, every
/// entry is written out (but the PMSM's keys and the default motor kind, which a DC
/// config leaves out; `pmsm::the_range_table_reads_the_pmsm_keys` has them all), and each
/// entry reads the value written.
#[test]
fn the_range_table_is_the_structs_keys() {
    let c = common::config("printing-press.toml");
    let doc = Value::try_from(c).unwrap();
    let mut leaves = Vec::new();
    for (table, t) in doc.as_table().unwrap() {
        for (key, v) in t.as_table().unwrap() {
            leaves.push((format!("{table}.{key}"), v.clone()));
        }
    }
    let unwritten = RANGES
        .iter()
        .filter(|r| r.key == "electrics.motor" || (r.get)(&c) == Reading::Unset)
        .count();
    assert_eq!(unwritten, 9);
    assert_eq!(leaves.len() + unwritten, RANGES.len());
    for (key, v) in leaves {
        let r = plant_host::range_of(&key).unwrap_or_else(|| panic!("{key} has no range"));
        let same = match ((r.get)(&c), v) {
            (Reading::Real(a), Value::Float(b)) => a == b,
            (Reading::Integer(a), Value::Integer(b)) => a == i128::from(b),
            (Reading::Word(a), Value::String(b)) => a == b,
            _ => false,
        };
        assert!(same, "{key}");
    }
}

#[cfg(feature = "schema")]
#[test]
fn the_schema_has_the_four_tables() {
    let schema = schemars::schema_for!(PlantConfig);
    let props = schema.get("properties").unwrap();
    for t in PlantConfig::TABLES {
        assert!(props.get(t).is_some(), "{t}: {schema:?}");
    }
}

#[test]
fn replay_writes_nothing_on_any_error() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("c.toml");
    let bad_cfg = dir.path().join("bad.toml");
    std::fs::write(&cfg, common::config_text("table1.toml")).unwrap();
    let bad = with(table1_doc(), "plant.motor_inertia_s", Value::Float(-1.0));
    std::fs::write(&bad_cfg, toml::to_string(&bad).unwrap()).unwrap();
    let out = dir.path().join("out.csv");
    let good = "t_s,motor_torque_pu,load_torque_pu\n0,1,0\n0.001,0,0\n";
    let cases: [(&PathBuf, &str, &str); 7] = [
        (&bad_cfg, good, "motor_inertia_s"),
        (&cfg, "t,motor,load\n0,1,0\n", "header"),
        (&cfg, "t_s,motor_torque_pu,load_torque_pu\n0,1\n", "fields"),
        (
            &cfg,
            "t_s,motor_torque_pu,load_torque_pu\n0,1,0\n0,1,0\n",
            "greater",
        ),
        (
            &cfg,
            "t_s,motor_torque_pu,load_torque_pu\n0,nan,0\n",
            "motor_torque_pu",
        ),
        (&cfg, "t_s,motor_torque_pu,load_torque_pu\n", "no data rows"),
        (&cfg, "", "empty"),
    ];
    for (c, input, needle) in cases {
        let inp = dir.path().join("in.csv");
        std::fs::write(&inp, input).unwrap();
        let e = replay(c, &inp, &out).unwrap_err();
        assert!(e.to_string().contains(needle), "{needle}: {e}");
        assert!(!out.exists(), "nothing written on error ({needle})");
    }
    let e = replay(&cfg, &dir.path().join("missing.csv"), &out).unwrap_err();
    assert!(matches!(e, PlantError::Io { .. }));
    assert!(!out.exists());
    // Only the output remains after a good run (the temporary file was renamed).
    let inp = dir.path().join("in.csv");
    std::fs::write(&inp, good).unwrap();
    let s = replay(&cfg, &inp, &out).unwrap();
    assert_eq!(s.rows, 2);
    let names: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert!(
        names.iter().all(|n| !n.to_string_lossy().contains(".tmp")),
        "{names:?}"
    );
    let text = std::fs::read_to_string(&out).unwrap();
    // Row 0: at rest; row 1: after 1 ms of 1 pu torque on the free motor (inside the gap):
    // ωm = T·t/Jm, θm = ω_b·T·t²/(2·Jm).
    let row1: Vec<f64> = text
        .lines()
        .nth(2)
        .unwrap()
        .split(',')
        .map(|x| x.parse().unwrap())
        .collect();
    let m = common::table1().mechanics;
    let (jm, wb) = (m.motor_inertia_s, m.derived().base_speed_rad_s);
    assert!((row1[3] - 1e-3 / jm).abs() < 1e-12);
    assert!((row1[1] - wb * 1e-6 / (2.0 * jm)).abs() < 1e-12);
    assert_eq!(row1[5], 0.0);
}

#[test]
fn absurdly_stiff_combinations_are_rejected_naming_the_keys() {
    // Each key in range, the combination far too stiff: Jm = 1e-5 s under a 5 kHz shaft.
    let doc = with(table1_doc(), "plant.motor_inertia_s", Value::Float(1e-5));
    let e = err(with(doc, "plant.anti_resonance_hz", Value::Float(5000.0)));
    assert!(matches!(e, ConfigError::Inconsistent { .. }), "{e}");
    assert_eq!(e.key(), "plant.motor_inertia_s");
    assert!(e.to_string().contains("1e6"), "{e}");
    // A very small winding inductance alone also trips it, and is named first.
    let key = "electrics.winding_inductance_pu_s";
    let e = err(with(table1_doc(), key, Value::Float(1e-6)));
    assert_eq!(e.key(), key, "{e}");
}
