//! Which directories stiffdrive may replace: the ones it wrote, known by their manifest.
//!
//! A commit writes [`MANIFEST`] into the staging directory before the swap: its first line
//! is [`MANIFEST_HEADER`], then every file of the set, one relative path (`/`-separated) a
//! line. [`check_dir_target`] accepts an `--out` directory only if nothing in it would be
//! lost that stiffdrive did not write:
//!
//! - a path that does not exist (its first existing ancestor must be a directory), or
//! - a real directory (not a symbolic link) in which every entry that is not a directory
//!   (files, symbolic links, anything else) is listed in the manifest of the directory or
//!   of a directory above it (`out/pil-fig6/` has its own, beside the report's; `out/`'s
//!   lists `out/sweep/`'s files, so `sweep --out out/sweep` may follow `reproduce`), and no
//!   listed path is now a directory. Empty directories hold nothing and are accepted, so
//!   an empty or absent target needs no manifest. Directories named like stiffdrive's own
//!   staging leftovers (`.<name>.staging-<pid>`, `.<name>.old-<pid>`) and files named like
//!   its lock files (`.<name>.lock`) are stiffdrive's.
//!
//! A symbolic link at the target is refused whatever it points to: the commit renames the
//! target, so it would replace the link with a directory rather than write where it points.

use crate::error::{HarnessError, Result};
use std::collections::BTreeSet;
use std::io::ErrorKind;
use std::path::{Path, PathBuf};

/// The file that marks a directory as written by stiffdrive, and lists what it wrote.
pub const MANIFEST: &str = ".stiffdrive-manifest";
/// The manifest's first line.
pub const MANIFEST_HEADER: &str =
    "# stiffdrive output manifest: the files stiffdrive wrote here, one relative path a line";

fn refuse(target: &Path, reason: String) -> HarnessError {
    HarnessError::OutputInTheWay {
        out: target.to_path_buf(),
        reason,
    }
}

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> HarnessError + '_ {
    move |e| HarnessError::io(path, e)
}

/// Whether `name` is a staging or old-set directory name a commit uses.
pub(super) fn is_leftover_name(name: &str) -> bool {
    let Some(rest) = name.strip_prefix('.') else {
        return false;
    };
    ["staging", "old"].iter().any(|kind| {
        rest.rsplit_once(&format!(".{kind}-"))
            .is_some_and(|(stem, pid)| {
                !stem.is_empty() && !pid.is_empty() && pid.bytes().all(|b| b.is_ascii_digit())
            })
    })
}

/// Refuses `target` as an output directory unless it is absent or stiffdrive's own (see the
/// module docs). Reads only; the error names the path and what is in the way.
pub fn check_dir_target(target: &Path) -> Result<()> {
    let meta = match std::fs::symlink_metadata(target) {
        Ok(m) => m,
        Err(e) if matches!(e.kind(), ErrorKind::NotFound | ErrorKind::NotADirectory) => {
            return check_parents(target);
        }
        Err(e) => return Err(HarnessError::io(target, e)),
    };
    let shown = target.display();
    if meta.file_type().is_symlink() {
        return Err(refuse(
            target,
            format!(
                "`{shown}` is a symbolic link; stiffdrive writes only into a real directory \
                 it wrote (or a new one), never through a link"
            ),
        ));
    }
    if !meta.is_dir() {
        return Err(refuse(
            target,
            format!("`{shown}` is a file, not an output directory"),
        ));
    }
    let mut listed = ancestor_listings(target);
    check_tree(target, target, &mut listed)
}

/// What the manifests of the directories above `target` list below it, re-rooted at
/// `target`: `reproduce` lists `out/sweep/sweep.csv` in `out/`'s manifest, so a later
/// `sweep --out out/sweep` may replace it. An ancestor that cannot be read lists nothing.
fn ancestor_listings(target: &Path) -> Vec<(PathBuf, BTreeSet<String>)> {
    let Ok(abs) = std::fs::canonicalize(target) else {
        return Vec::new();
    };
    let mut listed = Vec::new();
    for anc in abs.ancestors().skip(1) {
        let Some(set) = read_manifest(anc).ok().flatten() else {
            continue;
        };
        let Some(rel) = abs.strip_prefix(anc).ok().and_then(Path::to_str) else {
            continue;
        };
        let prefix = format!("{rel}/");
        let below: BTreeSet<String> = set
            .iter()
            .filter_map(|p| p.strip_prefix(&prefix).map(str::to_string))
            .collect();
        listed.push((target.to_path_buf(), below));
    }
    listed
}

/// The first existing ancestor of an absent `target` must be a directory.
pub(super) fn check_parents(target: &Path) -> Result<()> {
    for a in target.ancestors().skip(1) {
        let a = if a.as_os_str().is_empty() {
            Path::new(".")
        } else {
            a
        };
        match std::fs::metadata(a) {
            Ok(m) if m.is_dir() => return Ok(()),
            Ok(_) => {
                return Err(refuse(
                    target,
                    format!(
                        "`{}` is a file, not a directory, so `{}` cannot be created",
                        a.display(),
                        target.display()
                    ),
                ))
            }
            Err(e) if matches!(e.kind(), ErrorKind::NotFound | ErrorKind::NotADirectory) => {}
            Err(e) => return Err(HarnessError::io(a, e)),
        }
    }
    Ok(())
}

/// The paths a manifest lists, or `None` if `dir` has no valid manifest.
fn read_manifest(dir: &Path) -> Result<Option<BTreeSet<String>>> {
    let path = dir.join(MANIFEST);
    match std::fs::symlink_metadata(&path) {
        Ok(m) if m.is_file() => {}
        Ok(_) => return Ok(None),
        Err(e) if e.kind() == ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(HarnessError::io(&path, e)),
    }
    let text = std::fs::read_to_string(&path).map_err(io(&path))?;
    let mut lines = text.lines();
    if lines.next() != Some(MANIFEST_HEADER) {
        return Ok(None);
    }
    Ok(Some(lines.map(str::to_string).collect()))
}

/// Checks `dir` (below `target`); `listed` holds the manifests of the directories above,
/// each with its directory.
fn check_tree(
    target: &Path,
    dir: &Path,
    listed: &mut Vec<(PathBuf, BTreeSet<String>)>,
) -> Result<()> {
    let own = read_manifest(dir)?;
    let pushed = own.is_some();
    if let Some(set) = own {
        listed.push((dir.to_path_buf(), set));
    }
    let is_listed = |p: &Path, listed: &[(PathBuf, BTreeSet<String>)]| {
        listed.iter().any(|(root, set)| {
            p.strip_prefix(root)
                .ok()
                .and_then(Path::to_str)
                .is_some_and(|rel| set.contains(rel))
        })
    };
    let mut entries: Vec<_> = std::fs::read_dir(dir)
        .map_err(io(dir))?
        .collect::<std::io::Result<_>>()
        .map_err(io(dir))?;
    entries.sort_by_key(std::fs::DirEntry::file_name);
    for entry in entries {
        let path = entry.path();
        let name = entry.file_name();
        let kind = entry.file_type().map_err(io(&path))?;
        if kind.is_dir() {
            if is_listed(&path, listed) {
                return Err(refuse(
                    target,
                    format!(
                        "`{}` is a directory where stiffdrive wrote a file",
                        path.display()
                    ),
                ));
            }
            if !name.to_str().is_some_and(is_leftover_name) {
                check_tree(target, &path, listed)?;
            }
        } else {
            let own_manifest = pushed && name == MANIFEST;
            // A nested target's lock file (`.<name>.lock`) is stiffdrive's.
            let a_lock = name.to_str().is_some_and(super::lock::is_lock_name);
            if own_manifest || a_lock || is_listed(&path, listed) {
                continue;
            }
            return Err(refuse(
                target,
                format!("`{}` was not written by stiffdrive", path.display()),
            ));
        }
    }
    if pushed {
        listed.pop();
    }
    Ok(())
}

/// Writes the manifest of `dir`: every entry below it that is not a directory.
pub(super) fn write_manifest(dir: &Path) -> Result<()> {
    fn walk(root: &Path, dir: &Path, out: &mut Vec<String>) -> Result<()> {
        for entry in std::fs::read_dir(dir).map_err(io(dir))? {
            let entry = entry.map_err(io(dir))?;
            let path = entry.path();
            if entry.file_type().map_err(io(&path))?.is_dir() {
                walk(root, &path, out)?;
            } else if path != root.join(MANIFEST) {
                let rel = path.strip_prefix(root).ok().and_then(Path::to_str);
                match rel {
                    Some(rel) if !rel.contains('\n') => out.push(rel.to_string()),
                    _ => {
                        return Err(HarnessError::io(
                            &path,
                            "a file name a manifest cannot list (not UTF-8, or a newline)",
                        ))
                    }
                }
            }
        }
        Ok(())
    }
    let mut files = Vec::new();
    walk(dir, dir, &mut files)?;
    files.sort();
    let mut text = String::from(MANIFEST_HEADER);
    text.push('\n');
    for f in files {
        text.push_str(&f);
        text.push('\n');
    }
    let path = dir.join(MANIFEST);
    std::fs::write(&path, text).map_err(io(&path))
}
