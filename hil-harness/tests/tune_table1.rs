//! `tune --config configs/table1.toml --max-bandwidth` against the Must-show: the
//! written config runs `fig6` stably, the figures are written and linked, and the model's
//! smallest damping is within 0.05 of the damping fitted to the nonlinear loop's step
//! response (gears engaged throughout, torque below its limit).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use hil_harness::experiments::tune::{tune, Constraints, DAMPING_TOLERANCE};
use std::time::Instant;

#[test]
fn tune_table1_max_bandwidth() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("tune");
    let config = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../configs/table1.toml");
    let config = config.display().to_string();
    let t0 = Instant::now();
    let text = tune(&config, None, &Constraints::default(), &out).unwrap();
    eprintln!("{text} ({:.1} s)", t0.elapsed().as_secs_f64());

    // `run --scenario fig6 --config DIR/config.toml` is stable, with the tuned drive.
    let cfg = hil_harness::resolve(
        "fig6",
        Some(&out.join("config.toml").display().to_string()),
        &[],
    )
    .unwrap();
    let m = hil_harness::run_scenario(&cfg).unwrap().metrics;
    assert!(m.stable && !m.faulted, "{m:?}");
    // drive.toml is the whole [drive] table of that drive.
    let drive: toml::Table = std::fs::read_to_string(out.join("drive.toml"))
        .unwrap()
        .parse()
        .unwrap();
    let drive: controller_core::DriveConfig = drive["drive"].clone().try_into().unwrap();
    assert_eq!(drive, cfg.drive);

    let md = std::fs::read_to_string(out.join("tune.md")).unwrap();
    for img in ["tune-bode.png", "tune-poles.png"] {
        assert!(out.join(img).is_file(), "{img}");
        assert!(md.contains(&format!("]({img})")), "{img} not linked");
    }

    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("tune.json")).unwrap()).unwrap();
    let step = &json["step"];
    let f = |k: &str| step[k].as_f64().unwrap();
    eprintln!(
        "predicted smallest damping {:.3}; fitted {:.3} at {:.2} Hz; nearest pole {:.3} at {:.2} Hz; \
         shaft torque >= {:.3} pu, |torque| <= {:.3} pu",
        f("smallest_damping"),
        f("fitted_damping"),
        f("fitted_hz"),
        f("nearest_pole_damping"),
        f("nearest_pole_hz"),
        f("min_shaft_torque_pu"),
        f("max_torque_pu")
    );
    assert!(f("min_shaft_torque_pu") > 0.0, "the gears separated");
    assert!(f("max_torque_pu") < f64::from(cfg.drive.torque_limit_pu));
    assert!(
        (f("fitted_damping") - f("smallest_damping")).abs() <= DAMPING_TOLERANCE,
        "{step}"
    );
}
