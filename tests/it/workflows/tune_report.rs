//! `reproduce`'s tune section on real runs, cheaply: the dyno tuned at its own velocity
//! bandwidth (a few seconds; `reproduce` tunes every machine at the highest bandwidth that
//! meets the constraints). The files are written as `tune` writes them, and the section's
//! figures are the runs' figures.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use machine_workflows::tune::machines::{tune_into, Bandwidth};
use machine_workflows::tune::pair::afb_passes;
use machine_workflows::tune::Constraints;
use paper_repro::report::tune::section;
use std::time::Instant;

#[test]
fn the_tune_section_is_built_from_the_dyno_runs() {
    let dir = tempfile::tempdir().unwrap();
    let k = Constraints::default();
    let t0 = Instant::now();
    let tunes = tune_into(dir.path(), &["dyno"], Bandwidth::FromConfig, &k).unwrap();
    eprintln!("tuned in {:.1} s", t0.elapsed().as_secs_f64());
    let t = &tunes[0];
    let cfg = sim_engine::resolve("fig6", Some("dyno"), &[]).unwrap();
    let own = f64::from(cfg.drive.velocity_bandwidth_rad_s);
    assert_eq!(t.target_bandwidth_rad_s, Some(own));
    assert_eq!(t.with.candidate.bandwidth_rad_s, own);
    assert!(t.without.candidate.bandwidth_rad_s <= own);
    assert_eq!(
        t.without.candidate.afb.mode,
        controller_core::AfbMode::Off,
        "{t:?}"
    );
    assert_eq!(t.passed, afb_passes(&t.runs[0], &t.runs[1]));
    for f in ["tune.md", "tune.json", "drive.toml"] {
        assert!(dir.path().join("dyno").join(f).is_file(), "{f}");
        assert!(
            dir.path().join("dyno/no-afb").join(f).is_file(),
            "no-afb/{f}"
        );
    }
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("machines.json")).unwrap())
            .unwrap();
    assert_eq!(
        json[0]["runs"][0]["shaft_torque_ripple_rms_pu"].as_f64(),
        Some(t.runs[0].shaft_torque_ripple_rms_pu)
    );
    let tune_json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("dyno/tune.json")).unwrap())
            .unwrap();
    assert_eq!(
        tune_json["design"]["candidate"]["bandwidth_rad_s"].as_f64(),
        Some(own)
    );
    let md = section(&tunes, &k).unwrap().markdown();
    eprintln!("{md}");
    for r in &t.runs {
        let row = format!(
            "| dyno | {} | {} | {} | {} | {} at {:.1} Hz | {} | {:.4} |",
            r.design,
            r.bandwidth_rad_s,
            r.afb,
            r.stable,
            r.oscillation.word(),
            r.oscillation_freq_hz,
            r.faulted,
            r.shaft_torque_ripple_rms_pu
        );
        assert!(md.contains(&row), "missing {row}");
    }
    let verdict = if t.passed {
        "**agrees**"
    } else {
        "**does not agree**"
    };
    assert!(md.contains(verdict), "{md}");
}
