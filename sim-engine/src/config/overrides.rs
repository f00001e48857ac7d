//! `--set section.key=value` overrides applied to a configuration's TOML tree before it
//! is parsed, so a bad key or value is reported by the same typed parsing as a file.

use crate::error::{HarnessError, Result};
use toml::{Table, Value};

/// Top-level tables a `--set` may address.
pub const SECTIONS: [&str; 7] = [
    "plant",
    "electrics",
    "sensors",
    "lost_motion",
    "drive",
    "scenario",
    "identify",
];

/// Parses the right-hand side of `key=value` as a TOML value; a bare word that is not
/// valid TOML (e.g. `error`) is taken as a string.
pub fn parse_value(text: &str) -> Value {
    let text = text.trim();
    match toml::from_str::<Table>(&format!("v = {text}")) {
        Ok(mut t) => t
            .remove("v")
            .unwrap_or_else(|| Value::String(text.to_string())),
        Err(_) => Value::String(text.to_string()),
    }
}

/// Splits `a.b.c=value` into the key path and the value text.
pub fn split_assignment(assignment: &str) -> Result<(String, String)> {
    let Some((key, value)) = assignment.split_once('=') else {
        return Err(HarnessError::config(
            assignment,
            "expected `section.key=value`, e.g. `drive.velocity_bandwidth_rad_s=50`",
        ));
    };
    let key = key.trim();
    let value = value.trim();
    if value.is_empty() {
        return Err(HarnessError::config(key, "empty value"));
    }
    // One assignment is one line: the value text is parsed as `v = TEXT`, where a newline
    // would end it and the lines after it would be read as other keys (or dropped).
    if let Some(c) = value.chars().find(|c| c.is_control()) {
        return Err(HarnessError::config(
            key,
            format!(
                "the value must be one line (it holds {:?}); give each key its own --set",
                c
            ),
        ));
    }
    Ok((key.to_string(), value.to_string()))
}

/// Sets `key` (dotted path, first part one of [`SECTIONS`]) to `value` in `root`.
pub fn set(root: &mut Table, key: &str, value: Value) -> Result<()> {
    let parts: Vec<&str> = key.split('.').collect();
    let (Some(first), Some((last, middle))) = (parts.first(), parts.split_last()) else {
        return Err(HarnessError::config(key, "empty key"));
    };
    if parts.len() < 2 || !SECTIONS.contains(first) || parts.iter().any(|p| p.is_empty()) {
        return Err(HarnessError::config(
            key,
            format!(
                "keys are `section.name` with section one of {}",
                SECTIONS.join(", ")
            ),
        ));
    }
    let mut table = root;
    for part in middle {
        let entry = table
            .entry((*part).to_string())
            .or_insert_with(|| Value::Table(Table::new()));
        table = match entry {
            Value::Table(t) => t,
            _ => {
                return Err(HarnessError::config(
                    key,
                    format!("`{part}` is not a table"),
                ))
            }
        };
    }
    table.insert((*last).to_string(), value);
    Ok(())
}

/// Applies `key=value` assignments in order.
pub fn apply_all(root: &mut Table, assignments: &[String]) -> Result<()> {
    for a in assignments {
        let (key, value) = split_assignment(a)?;
        set(root, &key, parse_value(&value))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn values_are_typed_and_nested_keys_create_tables() {
        let mut t = Table::new();
        apply_all(
            &mut t,
            &[
                "drive.velocity_bandwidth_rad_s=50".into(),
                "drive.accel_feedback.mode=error".into(),
                "plant.backlash_deg = 0.0".into(),
            ],
        )
        .unwrap();
        assert_eq!(
            t["drive"]["velocity_bandwidth_rad_s"].as_integer(),
            Some(50)
        );
        assert_eq!(t["drive"]["accel_feedback"]["mode"].as_str(), Some("error"));
        assert_eq!(t["plant"]["backlash_deg"].as_float(), Some(0.0));
    }

    #[test]
    fn bad_assignments_name_the_key() {
        let mut t = Table::new();
        let e = apply_all(&mut t, &["nosuch.x=1".into()]).unwrap_err();
        assert!(e.to_string().contains("nosuch.x"), "{e}");
        let e = apply_all(&mut t, &["drive.kp".into()]).unwrap_err();
        assert!(e.to_string().contains("drive.kp"), "{e}");
        let e = apply_all(&mut t, &["drive=3".into()]).unwrap_err();
        assert!(e.to_string().contains("drive"), "{e}");
        // A value over two lines is refused, naming the key, not cut at the first line.
        for bad in ["50\ndrive.velocity_damping = 3", "50\r\nx", "1\t2"] {
            let e =
                apply_all(&mut t, &[format!("drive.velocity_bandwidth_rad_s={bad}")]).unwrap_err();
            assert!(
                e.to_string().contains("drive.velocity_bandwidth_rad_s"),
                "{e}"
            );
            assert!(e.to_string().contains("one line"), "{e}");
        }
    }
}
