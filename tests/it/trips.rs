//! A trip is named everywhere a run reports: the one-line output of `run`, `summary.json`
//! (`fault` with its cause and time; the oscillation verdict `tripped`, naming it) and the
//! trace plot (a labelled vertical line at the trip). The shipped `overcurrent` and
//! `locked-rotor` scenarios trip; `fig6` does not, and says nothing of a trip.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use serde_json::Value;
use std::path::Path;
use std::process::Command;

/// `stiffdrive run --scenario NAME --out OUT` plus `extra`: its one line and summary.json.
fn run(name: &str, out: &Path, extra: &[&str]) -> (String, Value) {
    let o = Command::new(env!("CARGO_BIN_EXE_stiffdrive"))
        .args(["run", "--scenario", name, "--out", out.to_str().unwrap()])
        .args(extra)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{name}: {stderr}");
    let line = String::from_utf8(o.stdout).unwrap();
    let summary =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    (line, summary)
}

#[test]
fn the_shipped_trips_are_named_in_the_line_the_summary_and_the_plot() {
    let tmp = tempfile::tempdir().unwrap();
    // The scenario, the fault it trips on, and the window its time must fall in (s): the
    // overcurrent within a few current ticks of the start, the I²t trip near the 25 s its
    // model gives at 2 pu (the scenario's comment).
    for (scenario, cause, (from, to)) in [
        ("overcurrent", "overcurrent", (0.0, 0.01)),
        ("locked-rotor", "overload", (20.0, 30.0)),
    ] {
        let out = tmp.path().join(scenario);
        let (line, s) = run(scenario, &out, &[]);
        eprintln!("{line}");
        let fault = &s["fault"];
        assert_eq!(fault["cause"], cause, "{scenario}: {fault}");
        let t = fault["t_s"].as_f64().unwrap();
        assert!((from..to).contains(&t), "{scenario}: trip at {t} s");
        let at = format!("{t:.4} s");
        assert!(
            line.contains(&format!("TRIPPED: {cause} at {at}")),
            "{scenario}: {line}"
        );
        assert!(
            line.contains(&format!("verdict=tripped ({cause})")),
            "{line}"
        );
        assert!(line.contains("stable=false"), "{line}");
        // The verdict names the trip, not an oscillation of a loop that was switched off.
        assert_eq!(s["oscillation"]["kind"], "tripped", "{scenario}");
        assert_eq!(s["oscillation"]["fault"], cause, "{scenario}");
        assert_eq!(s["stable"], false);
        // The plot: the line's label on each of the four panels, and the heading.
        let svg = std::fs::read_to_string(out.join("trace.svg")).unwrap();
        let label = format!("tripped: {cause} at {at}");
        assert_eq!(
            svg.matches(&format!("fill=\"#3C3C3C\">\n{label}\n</text>"))
                .count(),
            4,
            "{scenario}: the trip's label on every panel"
        );
        assert!(
            svg.contains("stroke=\"#3C3C3C\""),
            "{scenario}: no trip line"
        );
        assert!(svg.contains(&format!("tripped: {cause} at {at}\n")));
        assert!(out.join("trace.png").is_file());
    }
}

#[test]
fn a_run_without_a_trip_names_none() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("fig6");
    let (line, s) = run("fig6", &out, &["--set", "scenario.duration_s=0.5"]);
    assert!(!line.contains("TRIPPED"), "{line}");
    assert!(s["fault"].is_null(), "{}", s["fault"]);
    assert_ne!(s["oscillation"]["kind"], "tripped");
    assert!(s["oscillation"].get("fault").is_none());
    let svg = std::fs::read_to_string(out.join("trace.svg")).unwrap();
    assert!(!svg.contains("tripped"));
}
