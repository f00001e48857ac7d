//! The firmware's modules depend one way: the board layer (`board.rs`, `boards/`) on
//! nothing of the app layer (the console, the rig, the app, the interrupt glue), and no
//! two modules on each other in a circle. A source scan: every `crate::module` and
//! `$crate::module` path outside comments is an edge from the file's top-level module.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The board layer's modules, and the only modules they may name (the virtual machines
/// behind QEMU's board are hardware models: they name nothing of the app layer either).
const BOARD_LAYER: [&str; 2] = ["board", "boards"];
const BOARD_LAYER_MAY_USE: [&str; 5] =
    ["board", "boards", "drive", "virtual_motor", "virtual_pmsm"];

fn src() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The top-level modules of the library: `src/x.rs` and `src/x/` (not the binaries).
fn top_modules() -> BTreeSet<String> {
    let mut names = BTreeSet::new();
    for entry in std::fs::read_dir(src()).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_stem().unwrap().to_string_lossy().into_owned();
        if !matches!(name.as_str(), "bin" | "lib" | "main") {
            names.insert(name);
        }
    }
    names
}

/// Module names after `crate::` in `code` (comments stripped line by line).
fn named_modules(code: &str, modules: &BTreeSet<String>) -> BTreeSet<String> {
    let mut found = BTreeSet::new();
    for line in code.lines() {
        let line = line.split("//").next().unwrap_or("");
        let mut rest = line;
        while let Some(at) = rest.find("crate::") {
            let before = rest[..at].chars().last();
            let tail = &rest[at + "crate::".len()..];
            let name: String = tail
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_')
                .collect();
            // `crate::x`, `$crate::x`, not `foo_crate::x`.
            if before.is_none_or(|c| !(c.is_alphanumeric() || c == '_')) && modules.contains(&name)
            {
                found.insert(name);
            }
            rest = tail;
        }
    }
    found
}

/// Each top-level module and the top-level modules its files name.
fn graph() -> BTreeMap<String, BTreeSet<String>> {
    let modules = top_modules();
    let mut files = Vec::new();
    rust_files(&src(), &mut files);
    let mut edges: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for file in files {
        let rel = file.strip_prefix(src()).unwrap();
        let first = rel
            .components()
            .next()
            .unwrap()
            .as_os_str()
            .to_string_lossy();
        let top = first.trim_end_matches(".rs").to_string();
        if !modules.contains(&top) {
            continue; // bin/, lib.rs, main.rs
        }
        let code = std::fs::read_to_string(&file).unwrap();
        let mut named = named_modules(&code, &modules);
        named.remove(&top);
        edges.entry(top).or_default().extend(named);
    }
    edges
}

#[test]
fn the_board_layer_names_nothing_of_the_app_layer() {
    let g = graph();
    // The virtual machines it may name obey the same rule.
    for layer in BOARD_LAYER.iter().chain(&["virtual_motor", "virtual_pmsm"]) {
        let uses = g.get(*layer).expect("board layer module present");
        let bad: Vec<_> = uses
            .iter()
            .filter(|m| !BOARD_LAYER_MAY_USE.contains(&m.as_str()))
            .collect();
        assert!(
            bad.is_empty(),
            "`{layer}` names {bad:?}: the board layer must not"
        );
    }
}

#[test]
fn no_two_modules_depend_on_each_other_in_a_circle() {
    let g = graph();
    // Depth-first search with the path on a stack: a back edge is a circle.
    fn visit(
        g: &BTreeMap<String, BTreeSet<String>>,
        node: &str,
        path: &mut Vec<String>,
        done: &mut BTreeSet<String>,
    ) -> Option<Vec<String>> {
        if let Some(at) = path.iter().position(|n| n == node) {
            let mut circle = path[at..].to_vec();
            circle.push(node.to_string());
            return Some(circle);
        }
        if done.contains(node) {
            return None;
        }
        path.push(node.to_string());
        for next in g.get(node).into_iter().flatten() {
            if let Some(c) = visit(g, next, path, done) {
                return Some(c);
            }
        }
        path.pop();
        done.insert(node.to_string());
        None
    }
    let mut done = BTreeSet::new();
    for node in g.keys() {
        let circle = visit(&g, node, &mut Vec::new(), &mut done);
        assert!(
            circle.is_none(),
            "module circle: {}",
            circle.unwrap().join(" → ")
        );
    }
}

#[test]
fn the_scan_sees_a_circle_and_a_board_module_that_names_the_console() {
    // The scanner itself: a planted `use` is found, a comment is not.
    let modules: BTreeSet<String> = ["board_console", "rig", "boards"].map(String::from).into();
    let code = "// crate::rig in a comment\nuse crate::board_console::LOOPS;\n\
                $crate::boards::x(); my_crate::rig::y();";
    let found = named_modules(code, &modules);
    assert_eq!(
        found,
        ["board_console", "boards"].map(String::from).into(),
        "comments and other crates' paths are not edges"
    );
}
