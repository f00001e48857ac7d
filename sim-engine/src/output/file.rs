//! Output files (`schema --out FILE`, `replay --out FILE`): written atomically, and an
//! existing file is replaced only if stiffdrive wrote it.
//!
//! A file command names its mark: a test on the existing file's first bytes that only its
//! own output passes (the schema's two titles, the replay CSV's exact header line). Anything
//! else at the path (a foreign file, a directory, a symbolic link) is refused.

use crate::error::{HarnessError, Result};
use std::io::{ErrorKind, Read};
use std::path::{Path, PathBuf};

/// How much of an existing file a mark reads.
const MARK_BYTES: u64 = 1 << 20;

/// What identifies a command's own output file.
#[derive(Clone, Copy, Debug)]
pub struct FileMark {
    /// What the file is, for the error (`a machine-file schema`).
    pub what: &'static str,
    /// Whether the first bytes of an existing file (up to 1 MiB) are this command's output.
    pub is_ours: fn(&[u8]) -> bool,
}

fn refuse(out: &Path, reason: String) -> HarnessError {
    HarnessError::OutputInTheWay {
        out: out.to_path_buf(),
        reason,
    }
}

/// Refuses `out` as an output file unless it is absent (under a directory, or a path that
/// can be created) or a regular file `mark` recognises. Reads only.
pub fn check_file_target(out: &Path, mark: &FileMark) -> Result<()> {
    if out.file_name().is_none() {
        return Err(refuse(
            out,
            format!("`{}` is not a file name", out.display()),
        ));
    }
    let meta = match std::fs::symlink_metadata(out) {
        Ok(m) => m,
        Err(e) if matches!(e.kind(), ErrorKind::NotFound | ErrorKind::NotADirectory) => {
            return super::owner::check_parents(out);
        }
        Err(e) => return Err(HarnessError::io(out, e)),
    };
    let shown = out.display();
    if meta.file_type().is_symlink() {
        return Err(refuse(
            out,
            format!("`{shown}` is a symbolic link; stiffdrive replaces only a file it wrote"),
        ));
    }
    if meta.is_dir() {
        return Err(refuse(
            out,
            format!("`{shown}` is a directory, not an output file"),
        ));
    }
    let mut head = Vec::new();
    std::fs::File::open(out)
        .and_then(|f| f.take(MARK_BYTES).read_to_end(&mut head))
        .map_err(|e| HarnessError::io(out, e))?;
    if meta.is_file() && (mark.is_ours)(&head) {
        Ok(())
    } else {
        Err(refuse(
            out,
            format!(
                "`{shown}` was not written by stiffdrive (it is not {})",
                mark.what
            ),
        ))
    }
}

/// The directory `out` is in.
fn parent(out: &Path) -> PathBuf {
    out.parent()
        .filter(|p| !p.as_os_str().is_empty())
        .map_or_else(|| PathBuf::from("."), Path::to_path_buf)
}

/// Writes `bytes` to `out` after [`check_file_target`]: into `.<name>.tmp-<pid>` beside it,
/// then renamed over it, so a reader sees the old file or the new one. Creates the parent.
pub fn write_file(out: &Path, bytes: &[u8], mark: &FileMark) -> Result<()> {
    check_file_target(out, mark)?;
    let dir = parent(out);
    std::fs::create_dir_all(&dir).map_err(|e| HarnessError::io(out, e))?;
    let mut name = std::ffi::OsString::from(".");
    name.push(out.file_name().unwrap_or_default());
    name.push(format!(".tmp-{}", std::process::id()));
    let tmp = dir.join(name);
    let written = std::fs::write(&tmp, bytes).and_then(|()| std::fs::rename(&tmp, out));
    written.map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        HarnessError::io(out, e)
    })
}
