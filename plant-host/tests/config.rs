//! Every configuration error names the key and its allowed range; replay writes nothing on error.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic,
    missing_docs
)]

use plant_host::{replay, BacklashModel, ConfigError, PlantConfig, PlantError};
use std::path::PathBuf;

fn shipped(name: &str) -> String {
    std::fs::read_to_string(
        PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("../configs")
            .join(name),
    )
    .unwrap()
}

const PLANT_KEYS: [(&str, &str); 9] = [
    ("base_speed_rpm", "1000.0"),
    ("motor_inertia_s", "0.117"),
    ("load_inertia_s", "0.863"),
    ("anti_resonance_hz", "22.5"),
    ("shaft_damping_ratio", "0.05"),
    ("backlash_deg", "0.5"),
    ("motor_viscous_pu", "0.0"),
    ("load_viscous_pu", "0.0"),
    ("encoder_cpr", "4096"),
];

fn plant_table(skip: Option<&str>, replace: Option<(&str, &str)>) -> String {
    let mut s = String::from("[plant]\n");
    for (k, v) in PLANT_KEYS {
        if Some(k) == skip {
            continue;
        }
        let v = match replace {
            Some((rk, rv)) if rk == k => rv,
            _ => v,
        };
        s.push_str(&format!("{k} = {v}\n"));
    }
    s
}

fn err(text: &str) -> ConfigError {
    match PlantConfig::from_toml_str(text) {
        Err(e) => e,
        Ok(c) => panic!("expected an error for\n{text}\ngot {c:?}"),
    }
}

#[test]
fn shipped_configs_parse_and_table1_matches_the_builtin() {
    let t1 = PlantConfig::from_toml_str(&shipped("table1.toml")).unwrap();
    assert_eq!(t1, PlantConfig::table1());
    let pp = PlantConfig::from_toml_str(&shipped("printing-press.toml")).unwrap();
    assert_eq!(pp.sensors.encoder_cpr, 1_000_000);
    // 150 counts of lost motion at 1e6 counts/rev.
    let counts = pp.mechanics.backlash_deg / 360.0 * 1e6;
    assert!((counts - 150.0).abs() < 1e-6, "{counts}");
    assert!((pp.mechanics.load_inertia_s / pp.mechanics.motor_inertia_s - 8.0).abs() < 1e-12);
}

#[test]
fn other_tables_are_ignored_and_optional_tables_default() {
    let text = format!(
        "{}\n[drive]\nvelocity_bandwidth_hz = 15\nanything = \"x\"\n[scenario.fig6]\nt = 1\n",
        plant_table(None, None)
    );
    let c = PlantConfig::from_toml_str(&text).unwrap();
    assert_eq!(c.electrics, plant_host::ElectricsConfig::default());
    assert_eq!(c.backlash, BacklashModel::DeadZone);
    assert_eq!(c.sensors.load_encoder_cpr, None);
    let clamped = format!(
        "{}[lost_motion]\nmodel = \"clamped\"\n",
        plant_table(None, None)
    );
    assert_eq!(
        PlantConfig::from_toml_str(&clamped).unwrap().backlash,
        BacklashModel::Clamped
    );
}

#[test]
fn every_missing_plant_key_is_named_with_its_range() {
    for (k, _) in PLANT_KEYS {
        let e = err(&plant_table(Some(k), None));
        let msg = e.to_string();
        assert!(matches!(e, ConfigError::Missing { .. }), "{msg}");
        assert!(
            msg.contains(&format!("plant.{k}")) && msg.contains("..="),
            "{msg}"
        );
    }
    assert!(matches!(
        err("[drive]\nx = 1\n"),
        ConfigError::MissingTable { table: "plant" }
    ));
    assert!(matches!(
        err("plant = 3\n"),
        ConfigError::NotATable { table: "plant" }
    ));
    assert!(matches!(err("[plant\n"), ConfigError::Syntax { .. }));
}

#[test]
fn every_plant_key_rejects_out_of_range_non_finite_and_wrong_type() {
    let bad_low = [
        ("base_speed_rpm", "0.0"),
        ("motor_inertia_s", "0.0"),
        ("load_inertia_s", "-1.0"),
        ("anti_resonance_hz", "0.0"),
        ("shaft_damping_ratio", "-0.1"),
        ("backlash_deg", "-0.5"),
        ("motor_viscous_pu", "-1.0"),
        ("load_viscous_pu", "-1.0"),
        ("encoder_cpr", "0"),
    ];
    let bad_high = [
        ("base_speed_rpm", "1e6"),
        ("motor_inertia_s", "1e5"),
        ("load_inertia_s", "1e5"),
        ("anti_resonance_hz", "1e4"),
        ("shaft_damping_ratio", "3.0"),
        ("backlash_deg", "90.0"),
        ("motor_viscous_pu", "1e3"),
        ("load_viscous_pu", "1e3"),
        ("encoder_cpr", "9999999999"),
    ];
    for (k, v) in bad_low.into_iter().chain(bad_high) {
        let e = err(&plant_table(None, Some((k, v))));
        let msg = e.to_string();
        assert!(
            matches!(e, ConfigError::OutOfRange { .. }),
            "{k}={v}: {msg}"
        );
        assert!(
            msg.contains(&format!("plant.{k}")) && msg.contains("..="),
            "{msg}"
        );
    }
    for (k, _) in PLANT_KEYS {
        for v in ["nan", "inf", "-inf"] {
            let e = err(&plant_table(None, Some((k, v))));
            assert!(matches!(e, ConfigError::NotFinite { .. }), "{k}={v}: {e}");
            assert!(e.to_string().contains(&format!("plant.{k}")), "{e}");
        }
        let e = err(&plant_table(None, Some((k, "\"fast\""))));
        assert!(matches!(e, ConfigError::WrongType { .. }), "{k}: {e}");
        assert!(e.to_string().contains(&format!("plant.{k}")) && e.to_string().contains("..="));
    }
    // The counts are an integer.
    let e = err(&plant_table(None, Some(("encoder_cpr", "4096.5"))));
    assert!(matches!(e, ConfigError::WrongType { .. }), "{e}");
}

#[test]
fn unknown_keys_in_owned_tables_are_rejected() {
    let base = plant_table(None, None);
    for (table, extra) in [
        ("plant", "gear_ratio = 3.0\n"),
        ("electrics", "resistance = 0.1\n"),
        ("sensors", "cpr = 4096\n"),
        ("lost_motion", "kind = \"x\"\n"),
    ] {
        let text = if table == "plant" {
            format!("{base}{extra}")
        } else {
            format!("{base}[{table}]\n{extra}")
        };
        let e = err(&text);
        assert!(matches!(e, ConfigError::Unknown { .. }), "{table}: {e}");
        assert!(e.to_string().contains(&format!("{table}.")), "{e}");
    }
}

#[test]
fn electrics_sensors_and_lost_motion_ranges() {
    let base = plant_table(None, None);
    for (table, kv, key) in [
        (
            "electrics",
            "winding_resistance_pu = 0.0",
            "electrics.winding_resistance_pu",
        ),
        (
            "electrics",
            "winding_inductance_pu_s = 2.0",
            "electrics.winding_inductance_pu_s",
        ),
        (
            "electrics",
            "computational_delay_s = -1e-4",
            "electrics.computational_delay_s",
        ),
        (
            "electrics",
            "current_adc_bits = 40",
            "electrics.current_adc_bits",
        ),
        (
            "electrics",
            "current_full_scale_pu = 0.0",
            "electrics.current_full_scale_pu",
        ),
        (
            "sensors",
            "load_encoder_cpr = 2",
            "sensors.load_encoder_cpr",
        ),
        ("sensors", "gear_ratio = 0.0", "sensors.gear_ratio"),
        (
            "sensors",
            "encoder_noise_counts = -1.0",
            "sensors.encoder_noise_counts",
        ),
        (
            "sensors",
            "current_noise_pu = nan",
            "sensors.current_noise_pu",
        ),
        ("sensors", "noise_seed = -1", "sensors.noise_seed"),
        (
            "sensors",
            "encoder_interpolation = 0",
            "sensors.encoder_interpolation",
        ),
        (
            "sensors",
            "encoder_interpolation = 8192",
            "sensors.encoder_interpolation",
        ),
        (
            "sensors",
            "encoder_interpolation = 16.5",
            "sensors.encoder_interpolation",
        ),
        ("lost_motion", "model = \"hysteresis\"", "lost_motion.model"),
        ("lost_motion", "model = 1", "lost_motion.model"),
    ] {
        let e = err(&format!("{base}[{table}]\n{kv}\n"));
        assert!(e.to_string().contains(key), "{kv}: {e}");
    }
}

#[test]
fn encoder_interpolation_defaults_to_plain_counts_and_bounds_the_product() {
    let base = plant_table(None, None);
    let plain = PlantConfig::from_toml_str(&base).unwrap();
    assert_eq!(plain.sensors.encoder_interpolation, 1);
    assert_eq!(plain.sensors.counts_per_rev(), 4096);
    let c = PlantConfig::from_toml_str(&format!("{base}[sensors]\nencoder_interpolation = 16\n"))
        .unwrap();
    assert_eq!(c.sensors.counts_per_rev(), 65_536);
    // 1e6 counts x 4096 exceeds the 2^30 counts a revolution may have (the drive's range).
    let big = plant_table(None, Some(("encoder_cpr", "1000000")));
    let e = err(&format!("{big}[sensors]\nencoder_interpolation = 4096\n"));
    let text = e.to_string();
    assert!(
        text.contains("sensors.encoder_interpolation") && text.contains("1073741824"),
        "{text}"
    );
}

#[test]
fn replay_writes_nothing_on_any_error() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("c.toml");
    let bad_cfg = dir.path().join("bad.toml");
    std::fs::write(&cfg, shipped("table1.toml")).unwrap();
    std::fs::write(&bad_cfg, plant_table(None, Some(("motor_inertia_s", "-1")))).unwrap();
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
    let wb = 2.0 * std::f64::consts::PI * 1000.0 / 60.0;
    assert!((row1[3] - 1e-3 / 0.117).abs() < 1e-12);
    assert!((row1[1] - wb * 1e-6 / (2.0 * 0.117)).abs() < 1e-12);
    assert_eq!(row1[5], 0.0);
}

#[test]
fn absurdly_stiff_combinations_are_rejected_naming_the_keys() {
    // Each key in range, the combination far too stiff: Jm = 1e-5 s under a 5 kHz shaft.
    let text = plant_table(None, Some(("motor_inertia_s", "1e-5")))
        .replace("anti_resonance_hz = 22.5", "anti_resonance_hz = 5000.0");
    let e = err(&text);
    assert!(matches!(e, ConfigError::Inconsistent { .. }), "{e}");
    let msg = e.to_string();
    assert!(
        msg.contains("plant.motor_inertia_s") && msg.contains("1e6"),
        "{msg}"
    );
    // A very small winding inductance alone also trips it.
    let e = err(&format!(
        "{}[electrics]\nwinding_inductance_pu_s = 1e-6\n",
        plant_table(None, None)
    ));
    assert!(
        e.to_string().contains("electrics.winding_inductance_pu_s"),
        "{e}"
    );
}
