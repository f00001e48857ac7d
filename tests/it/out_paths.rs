//! `--out` never destroys what stiffdrive did not write. Every writing command, through the
//! real binary, is pointed at an existing file, a directory holding a foreign file, a
//! read-only location, a path through a file and a symbolic link to a foreign directory.
//! Each must exit non-zero, name the path, and leave every byte in place (no staging
//! directory or temporary file beside it either). A directory stiffdrive wrote is replaced.
//!
//! The refusals happen before any simulation, so the suite runs each command on its
//! ordinary arguments and stays fast. Read-only as root: permission bits do not stop root,
//! so when the suite runs as root the binary runs as user `nobody` (uid 65534) for that
//! case, in a 0o555 directory.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::collections::BTreeMap;
use std::os::unix::fs::{MetadataExt, PermissionsExt};
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// What an output path must be for a command.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Kind {
    Dir,
    File,
}

/// Every writing command: its arguments before `--out`, and what `--out` is.
fn commands(torque: &Path) -> Vec<(&'static str, Vec<String>, Kind)> {
    let s = |v: &[&str]| v.iter().map(|x| (*x).to_string()).collect::<Vec<_>>();
    let torque = torque.to_str().unwrap();
    vec![
        ("run", s(&["run", "--scenario", "fig6"]), Kind::Dir),
        ("linear", s(&["linear", "--scenario", "fig6"]), Kind::Dir),
        (
            "tune",
            s(&["tune", "--config", "table1", "--target-bandwidth", "60"]),
            Kind::Dir,
        ),
        (
            "identify",
            s(&["identify", "--config", "table1"]),
            Kind::Dir,
        ),
        (
            "commission",
            s(&[
                "commission",
                "--config",
                "table1",
                "--target-bandwidth",
                "60",
            ]),
            Kind::Dir,
        ),
        ("sweep", s(&["sweep"]), Kind::Dir),
        ("stiffness", s(&["stiffness"]), Kind::Dir),
        ("sec2-map", s(&["sec2-map"]), Kind::Dir),
        ("reproduce", s(&["reproduce"]), Kind::Dir),
        ("pil", s(&["pil", "--scenario", "fig6"]), Kind::Dir),
        ("schema", s(&["schema"]), Kind::File),
        (
            "replay",
            s(&["replay", "--config", "table1", "--torque", torque]),
            Kind::File,
        ),
    ]
}

fn configs() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("configs")
}

fn running_as_root() -> bool {
    std::fs::metadata("/proc/self").is_ok_and(|m| m.uid() == 0)
}

fn stiffdrive(args: &[String], cwd: &Path, as_nobody: bool) -> Output {
    let mut c = Command::new(env!("CARGO_BIN_EXE_stiffdrive"));
    c.args(args)
        .env("STIFFDRIVE_CONFIGS", configs())
        .current_dir(cwd);
    if as_nobody {
        c.uid(65534).gid(65534);
    }
    c.output().unwrap()
}

/// Every entry below `dir` (not following links): files with their bytes, links with
/// their targets, directories.
fn snapshot(dir: &Path) -> BTreeMap<PathBuf, String> {
    fn walk(root: &Path, dir: &Path, out: &mut BTreeMap<PathBuf, String>) {
        for e in std::fs::read_dir(dir).unwrap().flatten() {
            let p = e.path();
            let rel = p.strip_prefix(root).unwrap().to_path_buf();
            let t = e.file_type().unwrap();
            if t.is_symlink() {
                out.insert(
                    rel,
                    format!("-> {}", std::fs::read_link(&p).unwrap().display()),
                );
            } else if t.is_dir() {
                out.insert(rel, "dir".into());
                walk(root, &p, out);
            } else {
                let bytes = std::fs::read(&p).unwrap();
                out.insert(rel, format!("file {bytes:?}"));
            }
        }
    }
    let mut out = BTreeMap::new();
    walk(dir, dir, &mut out);
    out
}

/// One way `--out` can be in the way: sets it up in `root`, returns the `--out` path and
/// whether the binary runs as `nobody`.
type Setup = fn(&Path, Kind) -> (PathBuf, bool);

fn foreign_dir(root: &Path, name: &str) -> PathBuf {
    let d = root.join(name);
    std::fs::create_dir(&d).unwrap();
    std::fs::write(d.join("notes.txt"), "the user's own notes\n").unwrap();
    d
}

fn existing_file(root: &Path, kind: Kind) -> (PathBuf, bool) {
    let f = root.join(if kind == Kind::Dir {
        "notes.txt"
    } else {
        "out.csv"
    });
    std::fs::write(&f, "the user's own notes\n").unwrap();
    (f, false)
}

fn dir_with_a_foreign_file(root: &Path, _: Kind) -> (PathBuf, bool) {
    // For a file command: a directory where the file goes.
    (foreign_dir(root, "results"), false)
}

fn read_only_location(root: &Path, _: Kind) -> (PathBuf, bool) {
    let locked = foreign_dir(root, "locked");
    std::fs::set_permissions(&locked, std::fs::Permissions::from_mode(0o555)).unwrap();
    let as_nobody = running_as_root();
    if as_nobody {
        // `nobody` must reach `locked/` (a tempdir is 0o700).
        std::fs::set_permissions(root, std::fs::Permissions::from_mode(0o755)).unwrap();
    }
    (locked.join("out"), as_nobody)
}

fn path_through_a_file(root: &Path, _: Kind) -> (PathBuf, bool) {
    let f = root.join("notes.txt");
    std::fs::write(&f, "the user's own notes\n").unwrap();
    (f.join("out"), false)
}

fn symlink_to_a_foreign_dir(root: &Path, _: Kind) -> (PathBuf, bool) {
    let d = foreign_dir(root, "elsewhere");
    let link = root.join("link");
    std::os::unix::fs::symlink(&d, &link).unwrap();
    (link, false)
}

const CASES: [(&str, Setup); 5] = [
    ("an existing file", existing_file),
    ("a directory with a foreign file", dir_with_a_foreign_file),
    ("a read-only location", read_only_location),
    ("a path through a file", path_through_a_file),
    ("a symlink to a foreign directory", symlink_to_a_foreign_dir),
];

#[test]
fn every_writing_command_refuses_an_out_in_the_way_and_touches_nothing() {
    let torque_dir = tempfile::tempdir().unwrap();
    let torque = torque_dir.path().join("torque.csv");
    std::fs::write(
        &torque,
        "t_s,motor_torque_pu,load_torque_pu\n0,0,0\n0.01,0.1,0\n",
    )
    .unwrap();
    std::fs::set_permissions(torque_dir.path(), std::fs::Permissions::from_mode(0o755)).unwrap();
    let mut faults = Vec::new();
    for (name, args, kind) in commands(&torque) {
        for (case, setup) in CASES {
            let tmp = tempfile::tempdir().unwrap();
            let (out, as_nobody) = setup(tmp.path(), kind);
            let before = snapshot(tmp.path());
            let mut argv = args.clone();
            argv.extend(["--out".to_string(), out.to_str().unwrap().to_string()]);
            let o = stiffdrive(&argv, tmp.path(), as_nobody);
            let stderr = String::from_utf8_lossy(&o.stderr);
            let mut bad = Vec::new();
            if o.status.success() {
                bad.push("exit 0".to_string());
            }
            if !stderr.contains(out.to_str().unwrap()) {
                bad.push("the path is not named".to_string());
            }
            if stderr.contains("panicked") {
                bad.push("panicked".to_string());
            }
            let after = snapshot(tmp.path());
            if after != before {
                bad.push(format!("changed: {before:?} -> {after:?}"));
            }
            if !bad.is_empty() {
                faults.push(format!(
                    "{name} into {case}: {} ({})",
                    bad.join(", "),
                    stderr.trim()
                ));
            }
        }
    }
    assert!(faults.is_empty(), "{}", faults.join("\n"));
}

#[test]
fn the_errors_say_what_is_in_the_way() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    let run = |out: &Path, args: &[&str]| {
        let mut argv: Vec<String> = args.iter().map(|s| (*s).to_string()).collect();
        argv.extend(["--out".to_string(), out.to_str().unwrap().to_string()]);
        String::from_utf8_lossy(&stiffdrive(&argv, root, false).stderr).into_owned()
    };
    let (file, _) = existing_file(root, Kind::Dir);
    let results = foreign_dir(root, "results");
    let sweep = ["sweep"];
    for (out, args, says) in [
        (
            &file,
            &sweep[..],
            "notes.txt` is a file, not an output directory",
        ),
        (
            &results,
            &sweep[..],
            "results/notes.txt` was not written by stiffdrive",
        ),
        (
            &file.join("x"),
            &sweep[..],
            "notes.txt` is a file, not a directory",
        ),
        (
            &results,
            &["schema"][..],
            "results` is a directory, not an output file",
        ),
        (
            &file,
            &["schema"][..],
            "notes.txt` was not written by stiffdrive",
        ),
    ] {
        let e = run(out, args);
        assert!(e.contains(says), "{args:?} --out {}: {e}", out.display());
    }
}

#[test]
fn a_second_run_replaces_what_stiffdrive_wrote() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let argv: Vec<String> = [
        "run",
        "--scenario",
        "fig6",
        "--set",
        "scenario.duration_s=0.2",
        "--out",
        out.to_str().unwrap(),
    ]
    .iter()
    .map(|s| (*s).to_string())
    .collect();
    let first = stiffdrive(&argv, tmp.path(), false);
    assert!(
        first.status.success(),
        "{}",
        String::from_utf8_lossy(&first.stderr)
    );
    let trace = std::fs::read(out.join("trace.csv")).unwrap();
    std::fs::write(out.join("trace.csv"), "stale\n").unwrap();
    let second = stiffdrive(&argv, tmp.path(), false);
    assert!(
        second.status.success(),
        "{}",
        String::from_utf8_lossy(&second.stderr)
    );
    // The same run again: the same trace, bit for bit, in place of the edited one.
    assert_eq!(std::fs::read(out.join("trace.csv")).unwrap(), trace);
    let manifest = std::fs::read_to_string(out.join(".stiffdrive-manifest")).unwrap();
    assert!(manifest.lines().any(|l| l == "trace.csv"), "{manifest}");
    let hidden: Vec<_> = std::fs::read_dir(tmp.path())
        .unwrap()
        .flatten()
        .filter(|e| e.file_name().to_string_lossy().starts_with('.'))
        .collect();
    assert!(hidden.is_empty(), "{hidden:?}");

    // The file commands replace their own output, and refuse it once it is edited away.
    let schema = tmp.path().join("machine.schema.json");
    for _ in 0..2 {
        let o = stiffdrive(
            &[
                "schema".into(),
                "--out".into(),
                schema.to_str().unwrap().into(),
            ],
            tmp.path(),
            false,
        );
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let committed = std::fs::read(configs().join("machine.schema.json")).unwrap();
    assert_eq!(std::fs::read(&schema).unwrap(), committed);
    // The grids file's schema likewise; it does not replace the machine file's.
    let grids = |out: &Path| {
        stiffdrive(
            &[
                "schema".into(),
                "--grids".into(),
                "--out".into(),
                out.to_str().unwrap().into(),
            ],
            tmp.path(),
            false,
        )
    };
    let grids_schema = tmp.path().join("grids.schema.json");
    for _ in 0..2 {
        let o = grids(&grids_schema);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let committed = std::fs::read(configs().join("grids.schema.json")).unwrap();
    assert_eq!(std::fs::read(&grids_schema).unwrap(), committed);
    let o = grids(&schema);
    assert!(!o.status.success());
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("was not written by stiffdrive"),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let torque = tmp.path().join("torque.csv");
    std::fs::write(
        &torque,
        "t_s,motor_torque_pu,load_torque_pu\n0,0,0\n0.01,0.1,0\n",
    )
    .unwrap();
    let csv = tmp.path().join("replay.csv");
    let replay: Vec<String> = [
        "replay",
        "--config",
        "table1",
        "--torque",
        torque.to_str().unwrap(),
        "--out",
        csv.to_str().unwrap(),
    ]
    .iter()
    .map(|s| (*s).to_string())
    .collect();
    for _ in 0..2 {
        let o = stiffdrive(&replay, tmp.path(), false);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    assert!(std::fs::read_to_string(&csv)
        .unwrap()
        .starts_with(plant_host::REPLAY_OUTPUT_HEADER));
}
