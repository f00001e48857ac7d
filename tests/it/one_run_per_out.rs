//! One command per output directory at a time: two commands started at once on one `--out`
//! give one complete set and one refusal that names the folder and the other process; never
//! a half-written folder, an "os error 2" (ENOENT), or a mix of the two runs' files.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use std::collections::BTreeSet;
use std::path::Path;
use std::process::{Child, Command, Output, Stdio};

const PAIRS: usize = 100;
/// What the refused command says (`sim_engine::output::lock`).
const IN_USE: &str = "is in use by another stiffdrive command";

fn spawn(args: &[&str]) -> Child {
    Command::new(env!("CARGO_BIN_EXE_stiffdrive"))
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

/// The entries of `dir`, names only.
fn names(dir: &Path) -> BTreeSet<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect()
}

/// Of two commands run at once, the one that completed and the one refused (with the
/// other's pid): exactly one of each, and neither failed otherwise.
fn one_ran_one_refused<'a>(
    out: &Path,
    a: (&'a str, u32, &'a Output),
    b: (&'a str, u32, &'a Output),
) -> (&'a str, &'a Output) {
    let refused = |o: &Output| !o.status.success() && text(&o.stderr).contains(IN_USE);
    for (_, _, o) in [a, b] {
        let err = text(&o.stderr);
        assert!(
            !err.contains("os error 2") && !err.contains("No such file"),
            "ENOENT: {err}"
        );
    }
    let (won, lost) = match (refused(a.2), refused(b.2)) {
        (false, true) => (a, b),
        (true, false) => (b, a),
        _ => panic!(
            "not one run and one refusal: {}: {:?} {}; {}: {:?} {}",
            a.0,
            a.2.status,
            text(&a.2.stderr),
            b.0,
            b.2.status,
            text(&b.2.stderr)
        ),
    };
    let err = text(&lost.2.stderr);
    // The refusal names the folder and the other process, and exits 1 at once.
    assert_eq!(lost.2.status.code(), Some(1), "{err}");
    assert!(err.contains(&format!("`{}`", out.display())), "{err}");
    assert!(err.contains(&format!("pid {}", won.1)), "{err}");
    assert!(err.contains("nothing was changed"), "{err}");
    (won.0, won.2)
}

#[test]
fn of_two_runs_at_once_on_one_out_one_completes_and_the_other_refuses() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("run");
    let out_s = out.to_str().unwrap();
    // Two runs that differ by one velocity tick (0.5 ms), so the folder tells whose it is.
    let durations = ["1.0", "1.0005"];
    let mut wins = [0; 2];
    for pair in 0..PAIRS {
        let mut children: Vec<(&str, Child)> = durations
            .iter()
            .map(|d| {
                let set = format!("scenario.duration_s={d}");
                (
                    *d,
                    spawn(&["run", "--scenario", "fig6", "--set", &set, "--out", out_s]),
                )
            })
            .collect();
        let ids: Vec<u32> = children.iter().map(|(_, c)| c.id()).collect();
        let outputs: Vec<Output> = children
            .drain(..)
            .map(|(_, c)| c.wait_with_output().unwrap())
            .collect();
        let (won, o) = one_ran_one_refused(
            &out,
            (durations[0], ids[0], &outputs[0]),
            (durations[1], ids[1], &outputs[1]),
        );
        wins[usize::from(won == durations[1])] += 1;
        // The folder is the winner's, whole: its summary and its trace's length.
        let summary: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap())
                .unwrap();
        let won_s: f64 = won.parse().unwrap();
        let sim = summary["sim_time_s"].as_f64().unwrap();
        assert!(
            (sim - won_s).abs() < 1e-9,
            "pair {pair}: {sim} s from the {won} s run"
        );
        let rows = std::fs::read_to_string(out.join("trace.csv"))
            .unwrap()
            .lines()
            .count()
            - 1;
        assert_eq!(rows, (won_s / 5e-4).round() as usize, "pair {pair}");
        assert!(
            text(&o.stdout).contains(&format!("-> {out_s}")),
            "{}",
            text(&o.stdout)
        );
        let files = names(&out);
        let want: BTreeSet<String> = [
            ".stiffdrive-manifest",
            "summary.json",
            "trace.csv",
            "trace.png",
            "trace.svg",
        ]
        .map(String::from)
        .into();
        assert_eq!(files, want, "pair {pair}");
        // Nothing left beside it: no lock, no staging directory.
        assert_eq!(names(tmp.path()), ["run".to_string()].into(), "pair {pair}");
    }
    eprintln!(
        "{PAIRS} pairs: the {} s run won {} times, the {} s run {}",
        durations[0], wins[0], durations[1], wins[1]
    );
}

#[test]
fn of_two_commissions_at_once_on_one_out_one_completes_and_the_other_refuses() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("commission");
    let out_s = out.to_str().unwrap();
    let args = [
        "commission",
        "--config",
        "configs/machines/table1.toml",
        "--target-bandwidth",
        "94.25",
        "--out",
        out_s,
    ];
    let (a, b) = (spawn(&args), spawn(&args));
    let ids = (a.id(), b.id());
    let (oa, ob) = (a.wait_with_output().unwrap(), b.wait_with_output().unwrap());
    let (_, won) = one_ran_one_refused(&out, ("a", ids.0, &oa), ("b", ids.1, &ob));
    // The one that ran wrote its folder (table1's own drive is not beaten: exit 3, with
    // every file of the identification and the designs tried written).
    let said = format!("{}{}", text(&won.stdout), text(&won.stderr));
    assert!(said.contains(out_s), "{said}");
    assert!(out.join("commission.md").is_file(), "{said}");
    assert!(out.join("identify/plant.toml").is_file(), "{said}");
    assert_eq!(names(tmp.path()), ["commission".to_string()].into());
}
