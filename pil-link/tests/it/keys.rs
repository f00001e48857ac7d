//! The console's enumerated keys (`pil_link::board::keys::CHOICES`): every enumerated
//! setting of the machine file's `[drive]` is one (filter kinds aside), each value's name is
//! the machine file's spelling, and an index that names no value is refused with the key.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use crate::common::table1;
use controller_core::{ConfigError, DriveConfig};
use pil_link::board::keys::{self, CHOICES, KeyError};

/// The machine-file value at the dotted `key` of `cfg`'s `[drive]` table.
fn file_value(cfg: &DriveConfig, key: &str) -> toml::Value {
    let tree = toml::Value::try_from(cfg).unwrap();
    key.split('.')
        .try_fold(&tree, |t, part| t.get(part))
        .unwrap_or_else(|| panic!("{key} is not in the serialized drive"))
        .clone()
}

/// The dotted keys of every string-valued setting in `t`, below `path`.
fn string_keys(t: &toml::Value, path: &str, out: &mut Vec<String>) {
    match t {
        toml::Value::Table(map) => {
            for (k, v) in map {
                let p = if path.is_empty() {
                    k.clone()
                } else {
                    format!("{path}.{k}")
                };
                string_keys(v, &p, out);
            }
        }
        toml::Value::String(_) => out.push(path.to_string()),
        _ => {}
    }
}

#[test]
fn every_value_of_every_choice_reads_back_with_the_machine_files_spelling() {
    for c in &CHOICES {
        for (i, name) in c.names.iter().enumerate() {
            let mut cfg = table1();
            keys::set(&mut cfg, &format!("drive.{}", c.key), i as f64).unwrap();
            assert_eq!(keys::get(&cfg, c.key).unwrap(), i as f64, "{}", c.key);
            assert_eq!(
                file_value(&cfg, c.key).as_str(),
                Some(*name),
                "{} = {i} is not written `{name}` in a machine file",
                c.key
            );
            assert_eq!(c.index(name), Some(i));
            assert_eq!(c.name(i as f64), Some(*name));
        }
    }
}

#[test]
fn every_enumerated_drive_setting_but_a_filter_kind_is_a_console_key() {
    let mut found = Vec::new();
    string_keys(&toml::Value::try_from(table1()).unwrap(), "", &mut found);
    let enumerated: Vec<_> = found.iter().filter(|k| !k.ends_with(".kind")).collect();
    assert!(enumerated.len() >= 6, "found only {enumerated:?}");
    for k in enumerated {
        assert!(keys::choice(k).is_some(), "drive.{k} has no console key");
    }
}

#[test]
fn an_index_that_names_no_value_is_refused_with_the_key_and_changes_nothing() {
    let c = keys::choice("drive.accel_feedback.mode").unwrap();
    for bad in [c.names.len() as f64, -1.0, 0.5, f64::NAN, 1e12] {
        let mut cfg = table1();
        let before = cfg;
        let e = keys::set(&mut cfg, "drive.accel_feedback.mode", bad).unwrap_err();
        let KeyError::Invalid(ConfigError::OutOfRange { param, max, .. }) = e else {
            panic!("{bad}: {e:?}");
        };
        assert_eq!(param, "accel_feedback.mode");
        assert_eq!(max, (c.names.len() - 1) as f32);
        assert_eq!(cfg, before, "{bad} changed the drive");
        assert_eq!(c.name(bad), None);
    }
}
