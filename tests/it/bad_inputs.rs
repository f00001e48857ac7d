//! The bad-input suite: malformed values for every key of every shipped config and scenario
//! file, misspelt keys and tables, and malformed torque CSVs for `replay`, each run through
//! the real command line. Every one must be handled cleanly: a non-zero exit, an error
//! naming the key (or column) it is about, and nothing written.
//!
//! The inputs are generated from the files themselves (every leaf value, every table), so a
//! key added to a shipped file is covered without touching this test. Each mutation is made
//! in a private copy of `configs/` that the binary reads through `STIFFDRIVE_CONFIGS`.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Mutex;
use toml::{Table, Value};

/// One malformed input.
#[derive(Clone, Debug)]
struct Case {
    /// What it is, for the failure list.
    label: String,
    /// The file under `configs/` it replaces (relative), and its new text.
    file: String,
    text: String,
    /// The command's arguments.
    args: Vec<String>,
    /// A word the error must contain (the key, table or column).
    must_name: String,
}

fn configs() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("configs")
}

fn read(rel: &str) -> Table {
    let text = std::fs::read_to_string(configs().join(rel)).unwrap();
    text.parse::<Table>().unwrap()
}

/// Values no key of its type accepts: not finite, absurdly large, of the wrong type.
fn bad_values(v: &Value, key: &str) -> Vec<Value> {
    let wrong_type = [Value::String("text".into()), Value::Boolean(true)];
    let huge = [
        Value::Float(f64::NAN),
        Value::Float(f64::INFINITY),
        Value::Float(f64::NEG_INFINITY),
        Value::Float(1e300),
        Value::Float(-1e300),
    ];
    match v {
        Value::Float(_) => huge.into_iter().chain(wrong_type).collect(),
        Value::Integer(_) => huge
            .into_iter()
            .chain(wrong_type)
            .chain([Value::Float(2.5), Value::Integer(i64::MIN)])
            .collect(),
        // Free text takes any string; everything else of string type is a name from a
        // closed list (a config, a model, an estimator).
        Value::String(_) if matches!(key, "description" | "paper") => {
            vec![Value::Float(1.5), Value::Boolean(true)]
        }
        Value::String(_) => vec![
            Value::String("no_such_value".into()),
            Value::Float(1.5),
            Value::Boolean(true),
        ],
        Value::Boolean(_) => vec![Value::String("yes".into()), Value::Integer(1)],
        Value::Array(a) if a.iter().all(|x| x.is_float() || x.is_integer()) => {
            let num = |x: f64| Value::Float(x);
            let mut out = vec![
                Value::String("text".into()),
                Value::Array(vec![num(f64::NAN), num(1.0)]),
                Value::Array(vec![num(1.0)]),
                Value::Array(vec![num(0.1), num(1e9)]),
            ];
            if a.len() == 2 {
                let mut rev = a.clone();
                rev.reverse();
                out.push(Value::Array(rev));
            }
            out
        }
        _ => Vec::new(),
    }
}

/// Sets the value at `path` (table keys and array indices) in `root`.
fn set_at(root: &mut Value, path: &[String], new: Value) {
    let mut cur = root;
    for p in path {
        cur = match cur {
            Value::Table(t) => t.get_mut(p).unwrap(),
            Value::Array(a) => &mut a[p.parse::<usize>().unwrap()],
            _ => unreachable!(),
        };
    }
    *cur = new;
}

/// Renames the last element of `path` (a table key) to `new_name`.
fn rename_at(root: &mut Value, path: &[String], new_name: &str) {
    let (last, parent) = path.split_last().unwrap();
    let mut cur = root;
    for p in parent {
        cur = match cur {
            Value::Table(t) => t.get_mut(p).unwrap(),
            Value::Array(a) => &mut a[p.parse::<usize>().unwrap()],
            _ => unreachable!(),
        };
    }
    if let Value::Table(t) = cur {
        let v = t.remove(last).unwrap();
        t.insert(new_name.to_string(), v);
    }
}

/// Every (path, value) below `v`: leaves, and tables (for renaming).
fn walk(v: &Value, path: &mut Vec<String>, out: &mut Vec<(Vec<String>, Value)>) {
    match v {
        Value::Table(t) => {
            for (k, x) in t {
                path.push(k.clone());
                out.push((path.clone(), x.clone()));
                walk(x, path, out);
                path.pop();
            }
        }
        Value::Array(a) if a.iter().all(Value::is_table) => {
            for (i, x) in a.iter().enumerate() {
                path.push(i.to_string());
                walk(x, path, out);
                path.pop();
            }
        }
        _ => {}
    }
}

/// The cases for one file: each leaf with each bad value, each key and table misspelt.
fn file_cases(rel: &str, args: &[String], skip_top: &[&str]) -> Vec<Case> {
    let doc = Value::Table(read(rel));
    let mut entries = Vec::new();
    walk(&doc, &mut Vec::new(), &mut entries);
    let mut cases = Vec::new();
    for (path, value) in entries {
        if path.first().is_some_and(|p| skip_top.contains(&p.as_str())) {
            continue;
        }
        let key = path.last().unwrap().clone();
        let dotted = path.join(".");
        let mut push = |label: String, new_doc: Value, must_name: String| {
            cases.push(Case {
                label: format!("{rel}: {label}"),
                file: rel.to_string(),
                text: toml::to_string(&new_doc).unwrap(),
                args: args.to_vec(),
                must_name,
            });
        };
        // `[scenario.set]` keys are dotted config keys: the error names them by the
        // part after the table, e.g. `velocity_bandwidth_rad_s`.
        let named = key.rsplit('.').next().unwrap_or(&key).to_string();
        for bad in bad_values(&value, &key) {
            let mut d = doc.clone();
            set_at(&mut d, &path, bad.clone());
            push(format!("{dotted} = {bad}"), d, named.clone());
        }
        // A misspelt key or table: nothing reads it, so it is an error naming it.
        if !key.chars().all(|c| c.is_ascii_digit()) {
            let misspelt = format!("{key}x");
            let mut d = doc.clone();
            rename_at(&mut d, &path, &misspelt);
            push(format!("{dotted} misspelt as {misspelt}"), d, misspelt);
        }
    }
    cases
}

fn csv_cases() -> Vec<Case> {
    let header = "t_s,motor_torque_pu,load_torque_pu";
    let good = ["0,0.1,0", "0.001,0.2,0.1", "0.002,0.2,0.1"];
    let columns: Vec<&str> = header.split(',').collect();
    let mut cases = Vec::new();
    let mut push = |label: String, body: String, must_name: &str| {
        cases.push(Case {
            label: format!("torque.csv: {label}"),
            file: "torque.csv".into(),
            text: body,
            args: Vec::new(),
            must_name: must_name.to_string(),
        });
    };
    for (c, name) in columns.iter().enumerate() {
        for bad in [
            "nan", "inf", "-inf", "1e308", "-1e308", "abc", "", "0x10", "1,5", "1e400",
        ] {
            for row in 0..good.len() {
                let mut rows: Vec<String> = good.iter().map(|r| (*r).to_string()).collect();
                let mut fields: Vec<String> = rows[row].split(',').map(String::from).collect();
                fields[c] = bad.to_string();
                rows[row] = fields.join(",");
                push(
                    format!("row {row} {name} = `{bad}`"),
                    format!("{header}\n{}\n", rows.join("\n")),
                    if bad == "1,5" { "fields" } else { name },
                );
            }
        }
        let mut misspelt: Vec<String> = columns.iter().map(|s| (*s).to_string()).collect();
        misspelt[c] = format!("{name}x");
        push(
            format!("header {name} misspelt"),
            format!("{}\n{}\n", misspelt.join(","), good.join("\n")),
            "header",
        );
    }
    for (label, body, must) in [
        (
            "time not increasing",
            format!("{header}\n0,0,0\n0,0,0\n"),
            "t_s",
        ),
        (
            "time going back",
            format!("{header}\n1,0,0\n0.5,0,0\n"),
            "t_s",
        ),
        (
            "span too long",
            format!("{header}\n0,0,0\n1000,0,0\n"),
            "t_s",
        ),
        ("no rows", format!("{header}\n"), "rows"),
        ("empty file", String::new(), "header"),
        ("two fields", format!("{header}\n0,0\n"), "fields"),
        ("four fields", format!("{header}\n0,0,0,0\n"), "fields"),
    ] {
        push(label.to_string(), body, must);
    }
    cases
}

/// Runs one case in the private `configs/` copy `dir`; `Err` says what went wrong.
fn run_case(case: &Case, dir: &Path, bin: &Path) -> Result<(), String> {
    let configs = dir.join("configs");
    let out = dir.join("out");
    let target = configs.join(&case.file);
    let original = std::fs::read(&target).ok();
    let mut args = case.args.clone();
    if case.file == "torque.csv" {
        std::fs::write(dir.join("torque.csv"), &case.text).unwrap();
        args = [
            "replay",
            "--config",
            configs
                .join("machines")
                .join("table1.toml")
                .to_str()
                .unwrap(),
            "--torque",
            dir.join("torque.csv").to_str().unwrap(),
            "--out",
            out.join("replay.csv").to_str().unwrap(),
        ]
        .iter()
        .map(|s| (*s).to_string())
        .collect();
        std::fs::create_dir_all(&out).unwrap();
    } else {
        std::fs::write(&target, &case.text).unwrap();
        args.extend(["--out".to_string(), out.to_str().unwrap().to_string()]);
    }
    let o = Command::new(bin)
        .args(&args)
        .env("STIFFDRIVE_CONFIGS", &configs)
        .current_dir(dir)
        .output()
        .unwrap();
    if let Some(bytes) = original {
        std::fs::write(&target, bytes).unwrap();
    }
    let stderr = String::from_utf8_lossy(&o.stderr).into_owned();
    let written = out.exists() && std::fs::read_dir(&out).unwrap().next().is_some();
    let _ = std::fs::remove_dir_all(&out);
    let mut faults = Vec::new();
    if o.status.success() {
        faults.push("exit 0".to_string());
    }
    if !stderr.contains(&case.must_name) {
        faults.push(format!("error does not name `{}`", case.must_name));
    }
    if written {
        faults.push("output written".to_string());
    }
    if stderr.contains("panicked") {
        faults.push("panicked".to_string());
    }
    if faults.is_empty() {
        Ok(())
    } else {
        Err(format!(
            "{}: {} (stderr: {})",
            case.label,
            faults.join(", "),
            stderr.trim().lines().next().unwrap_or("")
        ))
    }
}

fn copy_tree(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap().flatten() {
        let p = e.path();
        if p.is_dir() {
            copy_tree(&p, &to.join(e.file_name()));
        } else {
            std::fs::copy(&p, to.join(e.file_name())).unwrap();
        }
    }
}

#[test]
fn every_malformed_input_is_refused_cleanly() {
    let s = |v: &[&str]| v.iter().map(|x| (*x).to_string()).collect::<Vec<_>>();
    let mut cases = Vec::new();
    // Machine configs, each under a scenario that reads it.
    cases.extend(file_cases(
        "machines/table1.toml",
        &s(&["run", "--scenario", "fig6"]),
        &[],
    ));
    cases.extend(file_cases(
        "machines/printing-press.toml",
        &s(&["run", "--scenario", "fig6", "--config", "printing-press"]),
        &[],
    ));
    cases.extend(file_cases(
        "machines/dyno.toml",
        &s(&["run", "--scenario", "shock"]),
        &[],
    ));
    // Every scenario file's keys.
    let mut names: Vec<String> = std::fs::read_dir(configs().join("scenarios"))
        .unwrap()
        .flatten()
        .filter_map(|e| {
            let n = e.file_name().to_string_lossy().into_owned();
            n.strip_suffix(".toml").map(str::to_string)
        })
        .collect();
    names.sort();
    for name in &names {
        cases.extend(file_cases(
            &format!("scenarios/{name}.toml"),
            &s(&["run", "--scenario", name]),
            &[],
        ));
    }
    // Settings the chosen filter kind does not read: an error that names them, not a no-op.
    let table1 = std::fs::read_to_string(configs().join("machines").join("table1.toml")).unwrap();
    for (extra, key) in [
        (
            "[drive.velocity_filter]\nkind = \"none\"\ncorner_hz = 50.0\n",
            "corner_hz",
        ),
        (
            "[drive.velocity_filter]\nkind = \"first_order\"\ncorner_hz = 50.0\nq = 0.7\n",
            "q",
        ),
        (
            "[drive.accel_feedback.filter]\nkind = \"first_order\"\ncorner_hz = 100.0\nq = 0.7\n",
            "q",
        ),
        // A filter table without its kind.
        ("[drive.accel_feedback.filter]\ncorner_hz = 100.0\n", "kind"),
    ] {
        cases.push(Case {
            label: format!("table1.toml: {}", extra.replace('\n', " ")),
            file: "machines/table1.toml".into(),
            text: format!("{table1}\n{extra}"),
            args: s(&["run", "--scenario", "fig6"]),
            must_name: key.into(),
        });
    }
    cases.extend(csv_cases());

    let bin = PathBuf::from(env!("CARGO_BIN_EXE_stiffdrive"));
    let failures = Mutex::new(Vec::new());
    let next = Mutex::new(cases.iter());
    let workers = 3;
    std::thread::scope(|scope| {
        for _ in 0..workers {
            scope.spawn(|| {
                let tmp = tempfile::tempdir().unwrap();
                copy_tree(&configs(), &tmp.path().join("configs"));
                loop {
                    let Some(case) = next.lock().unwrap().next() else {
                        break;
                    };
                    if let Err(e) = run_case(case, tmp.path(), &bin) {
                        failures.lock().unwrap().push(e);
                    }
                }
            });
        }
    });
    let failures = failures.into_inner().unwrap();
    let tried = cases.len();
    // Straight to stderr, past the test harness's capture, so `cargo test` shows it.
    let _ = writeln!(
        std::io::stderr(),
        "bad-input suite: {tried} inputs tried, {} handled cleanly, {} not",
        tried - failures.len(),
        failures.len()
    );
    assert!(tried >= 1000, "only {tried} inputs generated");
    assert!(
        failures.is_empty(),
        "{} of {tried} bad inputs were not handled cleanly:\n{}",
        failures.len(),
        failures.join("\n")
    );
}
