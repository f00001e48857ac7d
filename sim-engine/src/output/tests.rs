//! The staging, commit, recovery and ownership rules of output directories.
#![allow(clippy::unwrap_used)]
use super::*;
use std::collections::BTreeMap;

/// Every file below `dir` with its content, the manifests left out.
fn snapshot(dir: &Path) -> BTreeMap<String, String> {
    fn walk(root: &Path, dir: &Path, out: &mut BTreeMap<String, String>) {
        for e in std::fs::read_dir(dir).unwrap().flatten() {
            let p = e.path();
            if p.is_dir() {
                walk(root, &p, out);
            } else if e.file_name() != MANIFEST {
                let rel = p.strip_prefix(root).unwrap().display().to_string();
                out.insert(rel, std::fs::read_to_string(&p).unwrap());
            }
        }
    }
    let mut out = BTreeMap::new();
    if dir.is_dir() {
        walk(dir, dir, &mut out);
    }
    out
}

fn write_set(out: &Path, files: &[(&str, &str)]) {
    let s = Staging::new(out).unwrap();
    for (name, text) in files {
        s.write(name, text).unwrap();
    }
    s.commit().unwrap();
}

/// The hidden entries of `parent` (a manifest aside): staging and old sets.
fn siblings(parent: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(parent)
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with('.') && n != MANIFEST)
        .collect();
    v.sort();
    v
}

#[test]
fn dropped_staging_leaves_nothing_and_commit_replaces_the_set() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("o");
    {
        let s = Staging::new(&out).unwrap();
        s.write("a.txt", "x").unwrap();
    }
    assert!(!out.exists() && siblings(tmp.path()).is_empty());
    write_set(&out, &[("sub/b.txt", "y"), ("trace.svg", "fig6")]);
    write_set(&out, &[("sub/b.txt", "z")]);
    // Exactly the second run's files: no trace.svg of the first run beside them.
    let expect: BTreeMap<String, String> = [("sub/b.txt".into(), "z".into())].into();
    assert_eq!(snapshot(&out), expect);
    assert!(siblings(tmp.path()).is_empty());
}

#[test]
fn keeping_others_carries_over_what_the_new_set_lacks() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    write_set(&out, &[("pil-fig6/pil.json", "pil"), ("REPORT.md", "old")]);
    let s = Staging::keeping_others(&out).unwrap();
    s.write("REPORT.md", "new").unwrap();
    s.commit().unwrap();
    let snap = snapshot(&out);
    assert_eq!(snap.get("REPORT.md").map(String::as_str), Some("new"));
    assert_eq!(
        snap.get("pil-fig6/pil.json").map(String::as_str),
        Some("pil")
    );
    // The new manifest covers the carried-over entry.
    assert_eq!(
        manifest(&out),
        ["REPORT.md", "pil-fig6/pil.json"].map(String::from)
    );
}

#[test]
fn a_crash_at_any_commit_step_leaves_the_old_set_or_the_new_one() {
    let old: &[(&str, &str)] = &[
        ("summary.json", "fig4"),
        ("trace.csv", "fig4"),
        ("trace.png", "fig4"),
    ];
    let new: &[(&str, &str)] = &[("summary.json", "fig6"), ("trace.svg", "fig6")];
    let set = |files: &[(&str, &str)]| -> BTreeMap<String, String> {
        files
            .iter()
            .map(|(a, b)| ((*a).to_string(), (*b).to_string()))
            .collect()
    };
    for (step, expect_new) in [
        (CommitStep::CarriedOver, false),
        (CommitStep::OldMovedAside, false),
        (CommitStep::NewInPlace, true),
    ] {
        let tmp = tempfile::tempdir().unwrap();
        let out = tmp.path().join("run");
        write_set(&out, old);
        let s = Staging::new(&out).unwrap();
        for (name, text) in new {
            s.write(name, text).unwrap();
        }
        s.commit_until(Some(step)).unwrap();
        // The next command (here: the next staging of the same target) recovers.
        drop(Staging::new(&out).unwrap());
        let want = if expect_new { set(new) } else { set(old) };
        assert_eq!(snapshot(&out), want, "crash after {step:?}");
        assert!(
            siblings(tmp.path()).is_empty(),
            "crash after {step:?}: left {:?}",
            siblings(tmp.path())
        );
    }
}

#[test]
fn a_stale_staging_directory_of_a_dead_process_is_removed() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("o");
    // No process has pid u32::MAX - 1 (Linux pids stay below 2^22).
    let stale = sibling(tmp.path(), &OsString::from("o"), "staging", u32::MAX - 1);
    std::fs::create_dir_all(stale.join("big")).unwrap();
    drop(Staging::new(&out).unwrap());
    assert!(!stale.exists());
}

#[test]
fn unwritable_target_is_an_error_naming_it() {
    let tmp = tempfile::tempdir().unwrap();
    let file = tmp.path().join("f");
    std::fs::write(&file, "").unwrap();
    let e = Staging::new(&file.join("x")).unwrap_err();
    assert!(e.to_string().contains("f/x"), "{e}");
}

/// The paths the manifest of `dir` lists.
fn manifest(dir: &Path) -> Vec<String> {
    let text = std::fs::read_to_string(dir.join(MANIFEST)).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some(owner::MANIFEST_HEADER));
    lines.map(String::from).collect()
}

/// The error `check_dir_target` gives for `out`, as text.
fn refusal(out: &Path) -> String {
    check_dir_target(out).unwrap_err().to_string()
}

#[test]
fn absent_empty_own_and_nested_own_directories_are_accepted() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    check_dir_target(&out).unwrap();
    check_dir_target(&out.join("a/b")).unwrap();
    std::fs::create_dir_all(out.join("empty/sub")).unwrap();
    check_dir_target(&out).unwrap();
    std::fs::remove_dir_all(&out).unwrap();
    write_set(&out, &[("REPORT.md", "r"), ("fig6/trace.csv", "t")]);
    assert_eq!(
        manifest(&out),
        ["REPORT.md", "fig6/trace.csv"].map(String::from)
    );
    check_dir_target(&out).unwrap();
    // A stiffdrive directory inside one, written after it (`pil` into out/pil-fig6), and a
    // listed file the user removed.
    write_set(&out.join("pil-fig6"), &[("pil.json", "p")]);
    std::fs::remove_file(out.join("REPORT.md")).unwrap();
    check_dir_target(&out).unwrap();
    // A staging leftover of a nested target belongs to stiffdrive.
    std::fs::create_dir(out.join(".pil-fig6.old-12345")).unwrap();
    std::fs::write(out.join(".pil-fig6.old-12345/pil.json"), "p").unwrap();
    check_dir_target(&out).unwrap();
}

#[test]
fn foreign_files_anywhere_below_are_refused_and_nothing_is_touched() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("results");
    std::fs::create_dir(&out).unwrap();
    std::fs::write(out.join("notes.txt"), "mine").unwrap();
    let e = refusal(&out);
    assert!(
        e.contains("results/notes.txt` was not written by stiffdrive"),
        "{e}"
    );
    assert!(Staging::new(&out).is_err());
    assert_eq!(
        std::fs::read_to_string(out.join("notes.txt")).unwrap(),
        "mine"
    );
    assert!(siblings(tmp.path()).is_empty());
    // In a subdirectory of a stiffdrive directory, and in a nested stiffdrive directory.
    std::fs::remove_dir_all(&out).unwrap();
    write_set(&out, &[("fig6/trace.csv", "t")]);
    std::fs::write(out.join("fig6/notes.txt"), "mine").unwrap();
    assert!(refusal(&out).contains("results/fig6/notes.txt`"));
    std::fs::remove_file(out.join("fig6/notes.txt")).unwrap();
    write_set(&out.join("pil-fig6"), &[("pil.json", "p")]);
    std::fs::write(out.join("pil-fig6/notes.txt"), "mine").unwrap();
    assert!(refusal(&out).contains("results/pil-fig6/notes.txt`"));
    // A manifest without its header is a foreign file like any other.
    let bare = tmp.path().join("bare");
    std::fs::create_dir(&bare).unwrap();
    std::fs::write(bare.join(MANIFEST), "notes.txt\n").unwrap();
    std::fs::write(bare.join("notes.txt"), "mine").unwrap();
    assert!(refusal(&bare).contains("was not written by stiffdrive"));
}

#[test]
fn a_listed_file_replaced_by_a_directory_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("o");
    write_set(&out, &[("summary.json", "s")]);
    std::fs::remove_file(out.join("summary.json")).unwrap();
    std::fs::create_dir(out.join("summary.json")).unwrap();
    let e = refusal(&out);
    assert!(
        e.contains("o/summary.json` is a directory where stiffdrive wrote a file"),
        "{e}"
    );
}

#[test]
fn a_file_a_symlink_or_a_path_through_a_file_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let file = tmp.path().join("notes.txt");
    std::fs::write(&file, "mine").unwrap();
    assert!(refusal(&file).contains("notes.txt` is a file, not an output directory"));
    let e = refusal(&file.join("x/y"));
    assert!(e.contains("notes.txt` is a file, not a directory"), "{e}");
    // A link to a directory stiffdrive wrote is refused too: the commit would replace it.
    let own = tmp.path().join("own");
    write_set(&own, &[("a.txt", "a")]);
    let link = tmp.path().join("link");
    std::os::unix::fs::symlink(&own, &link).unwrap();
    assert!(refusal(&link).contains("link` is a symbolic link"));
    assert!(Staging::new(&link).is_err());
    assert_eq!(std::fs::read_to_string(&file).unwrap(), "mine");
    assert!(link.is_symlink() && own.join("a.txt").is_file());
}

#[test]
fn a_foreign_file_that_appears_during_the_command_stops_the_commit() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("o");
    write_set(&out, &[("a.txt", "old")]);
    let s = Staging::new(&out).unwrap();
    s.write("a.txt", "new").unwrap();
    std::fs::write(out.join("notes.txt"), "mine").unwrap();
    assert!(s.commit().is_err());
    assert_eq!(std::fs::read_to_string(out.join("a.txt")).unwrap(), "old");
    assert_eq!(
        std::fs::read_to_string(out.join("notes.txt")).unwrap(),
        "mine"
    );
    assert!(siblings(tmp.path()).is_empty());
}

#[test]
fn pil_then_reproduce_then_both_again_into_the_same_out() {
    // `.ci/run`'s order: `pil --out out/pil-fig6` creates out/, then `reproduce` (keeping
    // others) into out/; then the same again.
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let pil = out.join("pil-fig6");
    let reproduce = |report: &str| {
        let s = Staging::keeping_others(&out).unwrap();
        s.write("REPORT.md", report).unwrap();
        s.write("fig6/trace.csv", report).unwrap();
        s.commit().unwrap();
    };
    for round in ["1", "2"] {
        write_set(&pil, &[("pil.json", round), ("firmware.defmt", round)]);
        reproduce(round);
        let snap = snapshot(&out);
        let want: BTreeMap<String, String> = [
            "REPORT.md",
            "fig6/trace.csv",
            "pil-fig6/firmware.defmt",
            "pil-fig6/pil.json",
        ]
        .into_iter()
        .map(|k| (k.to_string(), round.to_string()))
        .collect();
        assert_eq!(snap, want, "round {round}");
        assert!(siblings(tmp.path()).is_empty() && siblings(&out).is_empty());
    }
}

#[test]
fn a_subdirectory_of_a_stiffdrive_directory_is_its_own() {
    // `reproduce` writes out/sweep/ without a manifest of its own; `sweep --out out/sweep`
    // may then replace it, while a foreign file in it is still refused.
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    write_set(&out, &[("REPORT.md", "r"), ("sweep/sweep.csv", "s")]);
    check_dir_target(&out.join("sweep")).unwrap();
    write_set(&out.join("sweep"), &[("sweep.csv", "s2")]);
    check_dir_target(&out).unwrap();
    std::fs::write(out.join("sweep/notes.txt"), "mine").unwrap();
    assert!(refusal(&out.join("sweep")).contains("sweep/notes.txt` was not written"));
}

#[test]
fn a_second_staging_of_a_target_in_use_is_refused_naming_it_and_the_holder() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("o");
    write_set(&out, &[("a.txt", "first")]);
    let first = Staging::new(&out).unwrap();
    first.write("a.txt", "second").unwrap();
    // The lock is per open file: a second staging in this process is a second command.
    let e = Staging::new(&out).unwrap_err().to_string();
    assert!(
        e.contains("/o`: it is in use by another stiffdrive command"),
        "{e}"
    );
    assert!(
        e.contains(&format!("pid {}", std::process::id())),
        "no pid: {e}"
    );
    assert!(e.contains(".o.lock"), "{e}");
    // The refusal touched nothing: the old set, the first command's staging, its lock.
    assert_eq!(std::fs::read_to_string(out.join("a.txt")).unwrap(), "first");
    assert_eq!(
        siblings(tmp.path()),
        [
            ".o.lock".to_string(),
            format!(".o.staging-{}", std::process::id())
        ]
    );
    first.commit().unwrap();
    assert_eq!(
        std::fs::read_to_string(out.join("a.txt")).unwrap(),
        "second"
    );
    // Let go with the commit: the next command goes ahead, and nothing is left beside.
    assert!(siblings(tmp.path()).is_empty());
    write_set(&out, &[("a.txt", "third")]);
    assert!(siblings(tmp.path()).is_empty());
}

#[test]
fn a_failed_command_lets_go_of_the_target() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("o");
    drop(Staging::new(&out).unwrap());
    assert!(siblings(tmp.path()).is_empty());
    drop(Staging::new(&out).unwrap());
}

#[test]
fn the_lock_file_of_a_dead_process_is_taken_over_and_removed() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("o");
    // What a killed command leaves: the file, with its pid, and no lock on it.
    std::fs::write(
        tmp.path().join(".o.lock"),
        format!("{}\nstiffdrive run\n", u32::MAX - 1),
    )
    .unwrap();
    write_set(&out, &[("a.txt", "x")]);
    assert!(siblings(tmp.path()).is_empty());
    // A killed command's lock file inside a directory is stiffdrive's, not a foreign file.
    std::fs::write(out.join(".nested.lock"), "1\n").unwrap();
    check_dir_target(&out).unwrap();
}
