//! The shape of the source tree, checked on every `cargo test`:
//!
//! * small modules: no source file over 600 lines and no function over 100 lines (outside
//!   `#[cfg(test)]` modules). A cap is a smell detector: a file or function that grows past
//!   it is usually two ideas;
//! * one source of truth: the Table 1 numbers live only in `configs/machines/table1.toml` (no `.rs`
//!   file outside `tests/` holds them);
//! * the tree explains itself: no tracked file (outside `target/`, `.git/` and `out/`) refers
//!   to a work-tracker item by number, because a reader of the tree cannot open one. Say
//!   what the code does and why instead; design reasons go in `docs/design.md`;
//! * short READMEs about the product: the root README.md at most 200 lines, each crate's at
//!   most 150, and history in CHANGELOG.md;
//! * shared code is a crate, not a file borrowed by path: no `#[path]` attribute anywhere
//!   reaches into a `tests/` folder (the machine file's composer is the `machine-file`
//!   crate, not a test helper that a build script or another crate's tests include).

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use std::path::{Path, PathBuf};

const MAX_FILE_LINES: usize = 600;
const MAX_FN_LINES: usize = 100;
/// Table 1's motor and load inertias (s) and anti-resonance (Hz).
const TABLE1_VALUES: [&str; 3] = ["0.117", "0.863", "22.5"];

/// Every `.rs` file of the workspace outside `tests/` folders and `target/`.
fn sources() -> Vec<PathBuf> {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        let Ok(entries) = std::fs::read_dir(dir) else {
            return;
        };
        for e in entries.flatten() {
            let p = e.path();
            let name = e.file_name().to_string_lossy().to_string();
            if p.is_dir() {
                if !matches!(name.as_str(), "target" | "tests" | "out" | ".git") {
                    walk(&p, out);
                }
            } else if name.ends_with(".rs") {
                out.push(p);
            }
        }
    }
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut out = Vec::new();
    for dir in [
        "src",
        "controller-core",
        "plant-host",
        "loop-model",
        "machine-file",
        "sim-engine",
        "pil-host",
        "machine-workflows",
        "paper-repro",
        "hil-harness",
        "firmware",
        "pil-link",
        "fw-runner",
    ] {
        walk(&root.join(dir), &mut out);
    }
    out.sort();
    out
}

/// (name, first line, length) of each function outside `#[cfg(test)]` modules: from its
/// `fn` line to the closing brace at the same indentation.
fn long_functions(text: &str) -> Vec<(String, usize, usize)> {
    let lines: Vec<&str> = text.lines().collect();
    let mut found = Vec::new();
    let mut i = 0;
    while i < lines.len() {
        let line = lines[i];
        if line.trim_start().starts_with("#[cfg(test)]") {
            break;
        }
        let indent = line.len() - line.trim_start().len();
        let code = line.trim_start();
        let is_fn = [
            "fn ",
            "pub fn ",
            "pub(crate) fn ",
            "pub(super) fn ",
            "const fn ",
            "pub const fn ",
        ]
        .iter()
        .any(|p| code.starts_with(p));
        if is_fn && !code.ends_with(';') {
            let close = format!("{}}}", " ".repeat(indent));
            let end = (i..lines.len())
                .find(|&j| lines[j].starts_with(&close) && lines[j].trim() == "}")
                .unwrap_or(i);
            let name = code
                .split("fn ")
                .nth(1)
                .unwrap_or("")
                .split(['(', '<'])
                .next()
                .unwrap_or("");
            let len = end + 1 - i;
            if len > MAX_FN_LINES {
                found.push((name.to_string(), i + 1, len));
            }
        }
        i += 1;
    }
    found
}

#[test]
fn no_source_file_over_600_lines_and_no_function_over_100() {
    let mut bad = Vec::new();
    for p in sources() {
        let text = std::fs::read_to_string(&p).unwrap();
        let n = text.lines().count();
        if n > MAX_FILE_LINES {
            bad.push(format!("{}: {n} lines", p.display()));
        }
        for (name, at, len) in long_functions(&text) {
            bad.push(format!("{}:{at}: fn {name} is {len} lines", p.display()));
        }
    }
    assert!(bad.is_empty(), "over the limits:\n{}", bad.join("\n"));
}

#[test]
fn the_table1_numbers_live_only_in_the_config_file() {
    let mut bad = Vec::new();
    for p in sources() {
        let text = std::fs::read_to_string(&p).unwrap();
        for (k, line) in text.lines().enumerate() {
            for v in TABLE1_VALUES {
                let hit = line.match_indices(v).any(|(at, _)| {
                    let before = line[..at].chars().next_back();
                    let after = line[at + v.len()..].chars().next();
                    !before.is_some_and(|c| c.is_ascii_digit() || c == '.')
                        && !after.is_some_and(|c| c.is_ascii_digit())
                });
                if hit {
                    bad.push(format!("{}:{}: {}", p.display(), k + 1, line.trim()));
                }
            }
        }
    }
    let table1 = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/machines/table1.toml"),
    )
    .unwrap();
    for v in TABLE1_VALUES {
        assert!(table1.contains(v), "configs/machines/table1.toml lost {v}");
    }
    assert!(
        bad.is_empty(),
        "Table 1 values in source files:\n{}",
        bad.join("\n")
    );
}

#[test]
fn the_function_scanner_sees_a_long_function_and_skips_tests() {
    let body = "    let x = 1;\n".repeat(MAX_FN_LINES);
    let text = format!("pub fn long() {{\n{body}}}\nfn short() {{\n}}\n#[cfg(test)]\nmod tests {{\n    fn long_test() {{\n{body}    }}\n}}\n");
    let found = long_functions(&text);
    assert_eq!(found.len(), 1, "{found:?}");
    assert_eq!(found[0].0, "long");
}

/// Every tracked file of the repository (`git ls-files`), or, without git, every file below
/// the workspace root; `target/`, `.git/` and `out/` left out either way.
fn tracked_files() -> Vec<PathBuf> {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        let Ok(entries) = std::fs::read_dir(dir) else {
            return;
        };
        for e in entries.flatten() {
            let p = e.path();
            let name = e.file_name().to_string_lossy().to_string();
            if p.is_dir() {
                if !matches!(name.as_str(), "target" | ".git" | "out") {
                    walk(&p, out);
                }
            } else {
                out.push(p);
            }
        }
    }
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let listed = std::process::Command::new("git")
        .args(["ls-files", "-z"])
        .current_dir(root)
        .output()
        .ok()
        .filter(|o| o.status.success());
    let mut out = Vec::new();
    match listed {
        Some(o) => {
            for name in o.stdout.split(|&b| b == 0).filter(|n| !n.is_empty()) {
                let rel = String::from_utf8_lossy(name).to_string();
                let first = rel.split('/').next().unwrap_or("");
                if !matches!(first, "target" | ".git" | "out") {
                    out.push(root.join(rel));
                }
            }
        }
        None => walk(root, &mut out),
    }
    out.sort();
    out
}

/// Whether `line` refers to a tracker item by number: "issue" or "Issue", then a space, a
/// hyphen, `#` or ` #`, then a digit (the regular expression `[Ii]ssue[ -]?#?[0-9]`).
fn names_a_tracker_item(line: &str) -> bool {
    let b = line.as_bytes();
    line.match_indices("ssue").any(|(at, _)| {
        if at == 0 || !matches!(b[at - 1], b'I' | b'i') {
            return false;
        }
        let mut k = at + 4;
        if matches!(b.get(k), Some(b' ' | b'-')) {
            k += 1;
        }
        if b.get(k) == Some(&b'#') {
            k += 1;
        }
        b.get(k).is_some_and(u8::is_ascii_digit)
    })
}

#[test]
fn no_tracked_file_refers_to_a_tracker_item_by_number() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut bad = Vec::new();
    for p in tracked_files() {
        let Ok(bytes) = std::fs::read(&p) else {
            continue;
        };
        let text = String::from_utf8_lossy(&bytes);
        for (k, line) in text.lines().enumerate() {
            if names_a_tracker_item(line) {
                let rel = p.strip_prefix(root).unwrap_or(&p);
                bad.push(format!("{}:{}: {}", rel.display(), k + 1, line.trim()));
            }
        }
    }
    assert!(
        bad.is_empty(),
        "tracker references (say what the code does instead):\n{}",
        bad.join("\n")
    );
}

#[test]
fn the_tracker_scanner_sees_a_reference_and_passes_prose() {
    // Built at run time, so this file does not hold what it looks for.
    let word = format!("{}ssue", 'I');
    for hit in [
        format!("see {word} 12"),
        format!("({} 3)", word.to_lowercase()),
        format!("the {}-14 note", word.to_lowercase()),
        format!("{word} #{}", 7),
    ] {
        assert!(names_a_tracker_item(&hit), "{hit}");
    }
    for prose in [
        format!("an {} with 3 parts", word.to_lowercase()),
        "a tissue, 3 layers".to_string(),
        "ssue 1 at the start".to_string(),
    ] {
        assert!(!names_a_tracker_item(&prose), "{prose}");
    }
}

/// The `#[path = "…"]` attributes of a Rust text that reach into a `tests/` folder from outside
/// it, as (line number, attribute).
fn paths_into_tests(text: &str) -> Vec<(usize, String)> {
    text.lines()
        .enumerate()
        .filter_map(|(i, line)| {
            let t = line.trim_start();
            let rest = t.strip_prefix("#[path")?;
            let target = rest.split('"').nth(1)?;
            let reaches = target.starts_with("..") && target.contains("tests/");
            reaches.then(|| (i + 1, t.to_string()))
        })
        .collect()
}

#[test]
fn no_file_includes_a_test_helper_by_path() {
    let mut found = Vec::new();
    for path in tracked_files() {
        if path.extension().is_some_and(|e| e == "rs") {
            let text = std::fs::read_to_string(&path).unwrap_or_default();
            for (line, attr) in paths_into_tests(&text) {
                found.push(format!("{}:{line}: {attr}", path.display()));
            }
        }
    }
    assert!(
        found.is_empty(),
        "test helpers included by path (make them a crate or a module of the same test \
         binary):\n{}",
        found.join("\n")
    );
}

#[test]
fn the_path_scanner_sees_an_include_into_tests_and_passes_a_local_module() {
    let text = "#[path = \"../../controller-core/tests/common/mod.rs\"]\nmod common;\n\
                #[path = \"fw_bench/blocks.rs\"]\nmod blocks;\n";
    let found = paths_into_tests(text);
    assert_eq!(found.len(), 1, "{found:?}");
    assert_eq!(found[0].0, 1);
}

#[test]
fn readmes_are_short_and_history_is_in_the_changelog() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let lines = |p: &Path| std::fs::read_to_string(p).map_or(0, |t| t.lines().count());
    let mut bad = Vec::new();
    let top = lines(&root.join("README.md"));
    if top == 0 || top > 200 {
        bad.push(format!("README.md: {top} lines (1..=200)"));
    }
    let mut crates = 0;
    for entry in std::fs::read_dir(root).unwrap().flatten() {
        let dir = entry.path();
        if dir.join("Cargo.toml").is_file() && dir.join("README.md").is_file() {
            crates += 1;
            let n = lines(&dir.join("README.md"));
            if n > 150 {
                bad.push(format!(
                    "{}: {n} lines (at most 150)",
                    dir.join("README.md").display()
                ));
            }
        }
    }
    assert!(crates >= 8, "{crates} crate READMEs found");
    assert!(
        root.join("CHANGELOG.md").is_file(),
        "CHANGELOG.md is missing"
    );
    assert!(bad.is_empty(), "{}", bad.join("\n"));
}
