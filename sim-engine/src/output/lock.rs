//! One command per output directory at a time: an advisory lock beside the target.
//!
//! `TargetLock::acquire` opens (or creates) `<parent>/.<name>.lock` and takes an exclusive
//! `flock` on it without waiting. If another process holds it, the command is refused at
//! once ([`HarnessError::OutputInTheWay`]), naming the folder and the holder: its pid and
//! command line, which the holder writes into the file when it takes the lock. The lock is
//! held from [`Staging::new`](super::Staging::new) until the commit is done (or the
//! staging dropped); then the file is removed, still under the lock, and the lock let go.
//!
//! A process that dies holding the lock lets go of it with its last file descriptor (the
//! kernel releases a `flock`), so a dead process's lock file is stale by itself: the next
//! command takes the lock on it, writes its own pid, and removes the file when it is done,
//! as [`Staging::new`](super::Staging::new) removes a dead process's staging directory.
//! Since the file may be removed between another process's open and its lock, the lock is
//! kept only if the path still names the file locked; otherwise the open is tried again.
//!
//! On a file system without `flock` the command goes on unlocked, as before locks.

use crate::error::{HarnessError, Result};
use std::ffi::{OsStr, OsString};
use std::fs::{File, OpenOptions, TryLockError};
use std::io::{ErrorKind, Seek, Write};
use std::os::unix::fs::MetadataExt;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// How often the open is tried again when the lock file is replaced under it.
const ATTEMPTS: usize = 20;
/// How long a refused command waits for the holder to write its pid (the holder writes it
/// right after taking the lock).
const HOLDER_WAIT: Duration = Duration::from_millis(200);

/// The held lock of one output target.
#[derive(Debug)]
pub(super) struct TargetLock {
    /// `None` on a file system without `flock`.
    file: Option<File>,
    path: PathBuf,
}

/// `<parent>/.<name>.lock`.
pub(super) fn lock_path(parent: &Path, name: &OsStr) -> PathBuf {
    let mut s = OsString::from(".");
    s.push(name);
    s.push(".lock");
    parent.join(s)
}

/// Whether `name` is a lock file's name (`.<name>.lock`).
pub(super) fn is_lock_name(name: &str) -> bool {
    name.strip_prefix('.')
        .and_then(|rest| rest.strip_suffix(".lock"))
        .is_some_and(|stem| !stem.is_empty())
}

/// This process's command line, its arguments joined by spaces (empty if unknown).
fn own_command() -> String {
    std::fs::read("/proc/self/cmdline")
        .map(|raw| {
            raw.split(|&b| b == 0)
                .filter(|a| !a.is_empty())
                .map(String::from_utf8_lossy)
                .collect::<Vec<_>>()
                .join(" ")
        })
        .unwrap_or_default()
}

/// Whether `file` is still what `path` names (same device and inode).
fn still_named(file: &File, path: &Path) -> std::io::Result<bool> {
    let held = file.metadata()?;
    match std::fs::symlink_metadata(path) {
        Ok(now) => Ok(now.dev() == held.dev() && now.ino() == held.ino()),
        Err(e) if e.kind() == ErrorKind::NotFound => Ok(false),
        Err(e) => Err(e),
    }
}

/// What the holder wrote into the lock file: "pid N (`command`)", or as much as is known.
fn holder(path: &Path) -> String {
    let start = Instant::now();
    loop {
        let text = std::fs::read_to_string(path).unwrap_or_default();
        let mut lines = text.lines();
        let pid = lines.next().and_then(|l| l.trim().parse::<u32>().ok());
        if let Some(pid) = pid {
            let command = lines.next().unwrap_or("").trim();
            return if command.is_empty() {
                format!("pid {pid}")
            } else {
                format!("pid {pid} (`{command}`)")
            };
        }
        if start.elapsed() >= HOLDER_WAIT {
            return "a process that has not yet written its pid".to_string();
        }
        std::thread::sleep(Duration::from_millis(5));
    }
}

impl TargetLock {
    /// Takes the lock of `target` (`parent` and `name` its parts; `parent` exists), or
    /// refuses naming the process that holds it.
    pub(super) fn acquire(target: &Path, parent: &Path, name: &OsStr) -> Result<Self> {
        let path = lock_path(parent, name);
        // Errors name the output directory the user gave, and the lock file.
        let io = |e: std::io::Error| {
            HarnessError::io(
                target,
                format!("cannot lock it with `{}`: {e}", path.display()),
            )
        };
        for _ in 0..ATTEMPTS {
            let mut file = OpenOptions::new()
                .read(true)
                .write(true)
                .create(true)
                .truncate(false)
                .open(&path)
                .map_err(io)?;
            match file.try_lock() {
                Ok(()) => {}
                Err(TryLockError::WouldBlock) => {
                    return Err(HarnessError::OutputInTheWay {
                        out: target.to_path_buf(),
                        reason: format!(
                            "it is in use by another stiffdrive command, {}, until it has \
                             written its output (lock `{}`); run this one when that one has \
                             finished, or give it another output directory",
                            holder(&path),
                            path.display()
                        ),
                    });
                }
                Err(TryLockError::Error(e)) if e.kind() == ErrorKind::Unsupported => {
                    drop(file);
                    let _ = std::fs::remove_file(&path);
                    return Ok(Self { file: None, path });
                }
                Err(TryLockError::Error(e)) => return Err(io(e)),
            }
            if !still_named(&file, &path).map_err(io)? {
                // Its holder removed it between our open and our lock: a new file now.
                continue;
            }
            file.set_len(0).map_err(io)?;
            file.rewind().map_err(io)?;
            let record = format!("{}\n{}\n", std::process::id(), own_command());
            file.write_all(record.as_bytes()).map_err(io)?;
            return Ok(Self {
                file: Some(file),
                path,
            });
        }
        Err(HarnessError::io(
            target,
            format!(
                "its lock `{}` kept being replaced while this command tried to take it",
                path.display()
            ),
        ))
    }

    /// Lets go of the lock as a process that dies does: the file stays (tests of a crash).
    pub(super) fn abandon(mut self) {
        self.file = None;
    }
}

impl Drop for TargetLock {
    fn drop(&mut self) {
        if let Some(file) = self.file.take() {
            // Removed while still locked, so the next command finds no file or a new one.
            // Errors here have nowhere to go; a file left behind is taken over by the next.
            let _ = std::fs::remove_file(&self.path);
            drop(file);
        }
    }
}
