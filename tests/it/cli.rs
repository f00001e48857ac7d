//! The command line end to end: good runs write their files, bad input gives a clear
//! message, a non-zero exit and nothing half-written.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use std::path::Path;
use std::process::{Command, Output};

fn stiffdrive(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_stiffdrive"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("binary runs")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn empty_or_missing(dir: &Path) -> bool {
    !dir.exists() || std::fs::read_dir(dir).unwrap().next().is_none()
}

#[test]
fn run_writes_trace_summary_and_plots() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("fig6");
    let o = stiffdrive(&[
        "run",
        "--scenario",
        "fig6",
        "--set",
        "scenario.duration_s=0.5",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let csv = std::fs::read_to_string(out.join("trace.csv")).unwrap();
    let header = csv.lines().next().unwrap();
    for col in [
        "t_s",
        "pos_cmd_counts",
        "motor_pos_counts",
        "load_pos_counts",
        "vel_cmd_pu",
        "motor_vel_pu",
        "load_vel_pu",
        "torque_cmd_pu",
        "current_pu",
        "accel_fb_pu",
        "load_torque_pu",
    ] {
        assert!(header.split(',').any(|c| c == col), "missing column {col}");
    }
    // 0.5 s at 2 kHz.
    assert_eq!(csv.lines().count(), 1 + 1000);
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    for key in [
        "stable",
        "torque_ripple_rms_pu",
        "load_step_droop_pu",
        "overshoot_pu",
        "settling_s",
        "torque_saturated_s",
        "sim_time_s",
        "wall_time_s",
        "ticks",
    ] {
        assert!(summary.get(key).is_some(), "summary lacks {key}");
    }
    assert_eq!(summary["ticks"], 2000);
    for f in ["trace.png", "trace.svg"] {
        assert!(std::fs::metadata(out.join(f)).unwrap().len() > 1000, "{f}");
    }
}

#[test]
fn unknown_scenario_is_a_clear_error_and_writes_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("o");
    let o = stiffdrive(&["run", "--scenario", "fig99", "--out", out.to_str().unwrap()]);
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(
        e.contains("unknown scenario `fig99`") && e.contains("fig6"),
        "{e}"
    );
    assert!(empty_or_missing(&out));
}

#[test]
fn bad_set_key_or_value_names_the_key_and_writes_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("o");
    let cases = [
        (
            "drive.velocity_bandwith_rad_s=50",
            "drive.velocity_bandwith_rad_s",
        ),
        (
            "drive.velocity_bandwidth_rad_s=-3",
            "drive.velocity_bandwidth_rad_s",
        ),
        (
            "drive.accel_feedback.mode=sideways",
            "drive.accel_feedback.mode",
        ),
        ("plant.backlash_deg=90", "plant.backlash_deg"),
        ("plant.nosuch=1", "plant.nosuch"),
        ("motor.x=1", "motor.x"),
        ("drive.velocity_damping", "drive.velocity_damping"),
    ];
    for (set, key) in cases {
        let o = stiffdrive(&[
            "run",
            "--scenario",
            "fig6",
            "--set",
            set,
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(!o.status.success(), "{set} accepted");
        let e = stderr(&o);
        assert!(e.contains(key), "{set}: message does not name {key}: {e}");
        assert!(empty_or_missing(&out), "{set} wrote output");
    }
}

#[test]
fn unwritable_out_is_a_clear_error() {
    let tmp = tempfile::tempdir().unwrap();
    let file = tmp.path().join("a-file");
    std::fs::write(&file, "x").unwrap();
    let out = file.join("sub");
    let o = stiffdrive(&[
        "run",
        "--scenario",
        "fig6",
        "--set",
        "scenario.duration_s=0.1",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("a-file/sub"), "{}", stderr(&o));
    assert_eq!(std::fs::read_to_string(&file).unwrap(), "x");
}

#[test]
fn replay_runs_the_plant_on_a_generated_torque_csv() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("torque.csv");
    let mut text = String::from(plant_host::REPLAY_INPUT_HEADER);
    text.push('\n');
    let columns = plant_host::REPLAY_INPUT_HEADER.split(',').count();
    for k in 0..50 {
        let t = k as f64 * 1e-3;
        let mut row = vec![format!("{t}")];
        // Motor torque 1 pu, other inputs zero.
        row.push("1.0".into());
        while row.len() < columns {
            row.push("0.0".into());
        }
        text.push_str(&row.join(","));
        text.push('\n');
    }
    std::fs::write(&input, text).unwrap();
    let out = tmp.path().join("state.csv");
    let o = stiffdrive(&[
        "replay",
        "--config",
        "table1",
        "--torque",
        input.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let result = std::fs::read_to_string(&out).unwrap();
    let mut lines = result.lines();
    assert_eq!(lines.next().unwrap(), plant_host::REPLAY_OUTPUT_HEADER);
    assert_eq!(lines.count(), 50);

    // A bad config names the key and writes nothing.
    let bad = tmp.path().join("bad.toml");
    let good = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/machines/table1.toml"),
    )
    .unwrap();
    std::fs::write(
        &bad,
        good.replace("motor_inertia_s = 0.117", "motor_inertia_s = -1.0"),
    )
    .unwrap();
    let out2 = tmp.path().join("state2.csv");
    let o = stiffdrive(&[
        "replay",
        "--config",
        bad.to_str().unwrap(),
        "--torque",
        input.to_str().unwrap(),
        "--out",
        out2.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("plant.motor_inertia_s"),
        "{}",
        stderr(&o)
    );
    assert!(!out2.exists());
}

/// `flash` composes and designs the machine file's drive before it builds anything: a bad
/// key is refused, named with its range, with a non-zero exit and no image built.
#[test]
fn flash_refuses_a_bad_drive_before_building() {
    let tmp = tempfile::tempdir().unwrap();
    let file = tmp.path().join("bad.toml");
    let table1 = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/machines/table1.toml"),
    )
    .unwrap();
    let bad = table1.replace(
        "velocity_bandwidth_rad_s = 94.25",
        "velocity_bandwidth_rad_s = -5.0",
    );
    assert_ne!(bad, table1, "the edit applies");
    std::fs::write(&file, bad).unwrap();
    let o = stiffdrive(&["flash", "--config", file.to_str().unwrap(), "--build-only"]);
    let e = stderr(&o);
    assert!(!o.status.success(), "{e}");
    assert!(e.contains("drive.velocity_bandwidth_rad_s"), "{e}");
    assert!(!e.contains("firmware build"), "nothing was built: {e}");
    let o = stiffdrive(&["flash", "--config", "no/such/machine.toml"]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("no/such/machine.toml"),
        "{}",
        stderr(&o)
    );
}

/// `flash` builds the board of the file's motor: a PMSM drive goes to the three-phase board
/// (NUCLEO-F446RE, chip STM32F446RETx), whose image carries the PMSM current loop. That
/// board has no console to calibrate through, so a drive without its measured encoder offset
/// is refused, and so is a current loop that is not a whole number of PWM periods, each
/// naming its key, with nothing built.
#[test]
fn flash_builds_a_pmsm_drive_for_the_three_phase_board() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let pmsm = root.join("configs/machines/table1-pmsm.toml");
    let o = stiffdrive(&["flash", "--config", pmsm.to_str().unwrap(), "--build-only"]);
    let out = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(out.contains("probe-rs run --chip STM32F446RETx"), "{out}");
    let elf = out
        .lines()
        .find_map(|l| l.strip_prefix("flash it with: probe-rs run --chip STM32F446RETx "))
        .unwrap();
    let image = std::fs::read(elf).unwrap();
    let needle = b"pmsm_image";
    assert!(
        image.windows(needle.len()).any(|w| w == needle),
        "{elf} is the three-phase image"
    );

    let tmp = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(&pmsm).unwrap();
    let cases = [
        (
            text.replace(
                "encoder_offset_elec_deg = 23.0\nangle_advance",
                "angle_advance",
            ),
            "drive.pmsm.encoder_offset_elec_deg",
        ),
        (
            text.replace("current_rate_hz = 4000 ", "current_rate_hz = 8000 "),
            "drive.current_rate_hz",
        ),
    ];
    for (k, (bad, key)) in cases.into_iter().enumerate() {
        assert_ne!(bad, text, "the edit for {key} applies");
        let file = tmp.path().join(format!("bad{k}.toml"));
        std::fs::write(&file, bad).unwrap();
        let o = stiffdrive(&["flash", "--config", file.to_str().unwrap(), "--build-only"]);
        let e = stderr(&o);
        assert!(!o.status.success(), "{e}");
        assert!(e.contains(key), "{key}: {e}");
        assert!(!e.contains("firmware build"), "nothing was built: {e}");
        assert!(o.stdout.is_empty(), "{key}");
    }
}

/// `summary.json`'s load-step figures are the trace's: the peak shaft torque is the largest
/// |shaft_torque_pu| from the step on, and the peak droop the largest |e − e₀| there, with
/// e = command − motor speed and e₀ its mean over the two velocity-bandwidth half periods
/// before the step (the definition in `sim-engine/src/engine/metrics/response.rs`).
#[test]
fn the_summarys_peak_droop_and_peak_shaft_torque_are_the_traces() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("fig6");
    let o = stiffdrive(&["run", "--scenario", "fig6", "--out", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    let csv = std::fs::read_to_string(out.join("trace.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|c| *c == name).unwrap();
    let (t, cmd, vel, shaft) = (
        col("t_s"),
        col("vel_cmd_pu"),
        col("motor_vel_pu"),
        col("shaft_torque_pu"),
    );
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    // fig6's load step (configs/scenarios/fig6.toml).
    let step = rows.iter().position(|r| r[t] >= 1.5).unwrap();
    let dt = rows[1][t] - rows[0][t];
    let f_bw = summary["velocity_bandwidth_rad_s"].as_f64().unwrap() / std::f64::consts::TAU;
    let n = (1.0 / (2.0 * f_bw * dt)).round() as usize;
    let err = |r: &Vec<f64>| r[cmd] - r[vel];
    let e0 = rows[step - 2 * n..step].iter().map(err).sum::<f64>() / (2 * n) as f64;
    let droop = rows[step..]
        .iter()
        .map(|r| (err(r) - e0).abs())
        .fold(0.0, f64::max);
    let peak_shaft = rows[step..]
        .iter()
        .map(|r| r[shaft].abs())
        .fold(0.0, f64::max);
    let field = |k: &str| summary[k].as_f64().unwrap();
    // The trace holds each value as printed (shortest round trip), so they agree to round-off.
    assert!(
        (field("peak_droop_pu") - droop).abs() < 1e-12 && droop > 1e-3,
        "summary {} against trace {droop}",
        field("peak_droop_pu")
    );
    assert!(
        (field("peak_shaft_torque_pu") - peak_shaft).abs() < 1e-12 && peak_shaft > 0.1,
        "summary {} against trace {peak_shaft}",
        field("peak_shaft_torque_pu")
    );
}

#[test]
fn board_refuses_bad_actions_and_a_foreign_out_before_starting_the_board() {
    // Parsed before QEMU or an image is touched: each fails at once, naming what is wrong.
    let cases: [(&[&str], &str); 4] = [
        (
            &["board", "--qemu", "frobnicate"],
            "unknown action \"frobnicate\"",
        ),
        (
            &["board", "--qemu", "set", "drive.velocity_damping"],
            "expected KEY=VALUE",
        ),
        (
            &["board", "--qemu", "set", "drive.velocity_damping=x"],
            "is not a number",
        ),
        (
            &["board", "--qemu", "scope", "--seconds", "1"],
            "scope needs --out DIR",
        ),
    ];
    for (args, expected) in cases {
        let o = stiffdrive(args);
        assert!(!o.status.success(), "{args:?}");
        assert!(stderr(&o).contains(expected), "{args:?}: {}", stderr(&o));
    }
    // Neither --qemu nor --port: a usage error.
    let o = stiffdrive(&["board", "status"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    // A foreign file at a scope's --out is refused before the session starts (a missing
    // serial device would be the next error, and is not reached).
    let tmp = tempfile::tempdir().unwrap();
    let file = tmp.path().join("notes.txt");
    std::fs::write(&file, "mine").unwrap();
    let o = stiffdrive(&[
        "board",
        "--port",
        "/nonexistent/tty",
        "scope",
        "--seconds",
        "1",
        "--out",
        file.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("notes.txt"), "{}", stderr(&o));
    assert!(!stderr(&o).contains("/nonexistent/tty"), "{}", stderr(&o));
    assert_eq!(std::fs::read_to_string(&file).unwrap(), "mine");
    // A missing serial device is named.
    let o = stiffdrive(&["board", "--port", "/nonexistent/tty", "status"]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("/nonexistent/tty"), "{}", stderr(&o));
}

/// `tune` and `commission` need no bandwidth flag: without `--target-bandwidth` they search
/// every bandwidth of the grid; a bandwidth and `--max-bandwidth` together are refused.
#[test]
fn the_bandwidth_is_searched_unless_a_target_is_given() {
    use clap::Parser;
    use hil_harness::cli::{Cli, Command};
    for cmd in ["tune", "commission"] {
        let cli =
            Cli::try_parse_from(["stiffdrive", cmd, "--config", "table1", "--out", "d"]).unwrap();
        let design = match cli.command {
            Command::Tune { design, .. } | Command::Commission { design, .. } => design,
            other => panic!("{other:?}"),
        };
        assert_eq!(design.target_bandwidth, None);
        let both = [
            "stiffdrive",
            cmd,
            "--config",
            "table1",
            "--target-bandwidth",
            "60",
            "--max-bandwidth",
            "--out",
            "d",
        ];
        assert!(Cli::try_parse_from(both).is_err());
    }
}

/// `board --config` picks the drive the QEMU image carries: it goes with `--qemu` only.
#[test]
fn board_config_goes_with_qemu_only() {
    use clap::Parser;
    use hil_harness::cli::Cli;
    let parse = |args: &[&str]| Cli::try_parse_from([&["stiffdrive", "board"], args].concat());
    assert!(parse(&["--qemu", "--config", "table1", "status"]).is_ok());
    assert!(parse(&["--port", "/dev/ttyACM0", "--config", "table1", "status"]).is_err());
    assert!(parse(&["--qemu", "--elf", "x", "--config", "table1", "status"]).is_err());
    // `--elf` and `--machine` are QEMU's: refused with `--port`.
    assert!(parse(&["--qemu", "--elf", "x", "status"]).is_ok());
    assert!(parse(&["--port", "/dev/ttyACM0", "--elf", "x", "status"]).is_err());
    assert!(parse(&[
        "--port",
        "/dev/ttyACM0",
        "--machine",
        "netduinoplus2",
        "status"
    ])
    .is_err());
}

/// `identify --board`: where the board is must be said, once; `--set` may change only the
/// `identify.` keys (the board carries its own machine and drive), refused before any board
/// is opened; a port that is not there is named; nothing is written; without `--board`,
/// `--qemu` and `--port` are refused.
#[test]
fn identify_board_arguments_are_checked_before_any_board_is_opened() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("id");
    let out_s = out.to_str().unwrap();
    for (args, says) in [
        (vec!["identify", "--board", "--out", out_s], "--qemu|--port"),
        (
            vec![
                "identify",
                "--board",
                "--qemu",
                "--port",
                "/dev/null",
                "--out",
                out_s,
            ],
            "cannot be used with",
        ),
        (
            vec!["identify", "--qemu", "--config", "table1", "--out", out_s],
            "--board",
        ),
        (
            vec![
                "identify",
                "--board",
                "--port",
                "/nonexistent/tty",
                "--set",
                "plant.motor_inertia_s=1",
                "--out",
                out_s,
            ],
            "only identify.* keys",
        ),
        (
            vec![
                "identify",
                "--board",
                "--port",
                "/nonexistent/tty",
                "--out",
                out_s,
            ],
            "/nonexistent/tty",
        ),
    ] {
        let o = stiffdrive(&args);
        assert!(!o.status.success(), "{args:?} ran");
        assert!(stderr(&o).contains(says), "{args:?}: {}", stderr(&o));
        assert!(empty_or_missing(&out), "{args:?} wrote {}", out.display());
    }
}
