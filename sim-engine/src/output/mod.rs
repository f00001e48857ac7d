//! Output directories that are never half-written, never mix two runs, and never replace
//! what stiffdrive did not write.
//!
//! A command writes into a staging directory beside its target
//! (`<parent>/.<name>.staging-<pid>`). [`Staging::commit`] writes the set's manifest
//! ([`MANIFEST`], see [`owner`]) into it, then swaps it in with two renames: the old
//! directory to `<parent>/.<name>.old-<pid>`, the staging directory to the target; then
//! the old set is removed. A crash between the two renames leaves the target absent and the
//! old set beside it; the next [`Staging::new`] for that target puts the old set back, so a
//! reader sees the old set or the new one, never a mix. Staging directories of processes
//! that no longer run are removed at the same time.
//!
//! [`Staging::new`] first checks the target ([`check_dir_target`]): it must be absent, or
//! a directory every file of which a stiffdrive manifest lists. Anything else (a file, a
//! symbolic link, a directory holding other files, a path through a file) is refused
//! before anything is touched, and the commit checks again before it moves the old set.
//!
//! After the commit, a target made with [`Staging::new`] holds exactly what the command
//! wrote. [`Staging::keeping_others`] is for a directory that collects the products of
//! several commands (`out/` holds `pil-fig6/` from `pil` beside the report): entries of
//! the old set that the new one lacks are carried over (hard links, so the old set stays
//! intact until the swap), and the new manifest lists them too.
//!
//! One command writes a target at a time: [`Staging::new`] takes an advisory lock beside it
//! (`<parent>/.<name>.lock`, see [`lock`]) and holds it until the commit is done, so a second
//! command on the same target is refused at once, naming the folder and the process that
//! has it, before it runs or touches anything; the recovery above runs under the lock too.
//!
//! Output files (`schema`, `replay`) go through [`write_file`] and [`check_file_target`].

mod file;
pub mod lock;
pub mod owner;

pub use file::{check_file_target, write_file, FileMark};
pub use owner::{check_dir_target, MANIFEST};

use crate::error::{HarnessError, Result};
use std::ffi::OsString;
use std::path::{Path, PathBuf};

/// A staging directory for one command's output.
#[derive(Debug)]
pub struct Staging {
    target: PathBuf,
    dir: PathBuf,
    keep_others: bool,
    committed: bool,
    /// Held until this value is dropped (after the commit, or on failure after the staging
    /// directory is removed: fields drop after [`Drop::drop`]).
    lock: Option<lock::TargetLock>,
}

/// The steps of a commit, in order (a crash test stops after one of them).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum CommitStep {
    /// Old entries carried over into the staging directory (keeping mode) and the
    /// manifest written.
    CarriedOver,
    /// The old set moved aside.
    OldMovedAside,
    /// The new set renamed into place.
    NewInPlace,
}

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> HarnessError + '_ {
    move |e| HarnessError::io(path, e)
}

/// `<parent>` and `<name>` of a target directory.
fn split(target: &Path) -> Result<(PathBuf, OsString)> {
    let name = target.file_name().ok_or_else(|| {
        HarnessError::io(
            target,
            std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                "an output directory needs a name (not `/`, `.` or `..`)",
            ),
        )
    })?;
    let parent = match target.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    Ok((parent, name.to_os_string()))
}

fn sibling(parent: &Path, name: &OsString, kind: &str, pid: u32) -> PathBuf {
    let mut s = OsString::from(".");
    s.push(name);
    s.push(format!(".{kind}-{pid}"));
    parent.join(s)
}

/// The pid in `.<name>.<kind>-<pid>`, if `file` is such an entry.
fn sibling_pid(file: &OsString, name: &OsString, kind: &str) -> Option<u32> {
    let mut prefix = OsString::from(".");
    prefix.push(name);
    prefix.push(format!(".{kind}-"));
    let file = file.to_str()?;
    file.strip_prefix(prefix.to_str()?)?.parse().ok()
}

fn process_alive(pid: u32) -> bool {
    pid == std::process::id() || Path::new("/proc").join(pid.to_string()).exists()
}

/// Puts back an old set a crashed commit left beside an absent target, and removes stale
/// staging and old sets.
fn recover(target: &Path, parent: &Path, name: &OsString) -> Result<()> {
    let Ok(entries) = std::fs::read_dir(parent) else {
        return Ok(());
    };
    for entry in entries.flatten() {
        let file = entry.file_name();
        let path = entry.path();
        if sibling_pid(&file, name, "old").is_some() {
            if target.exists() {
                std::fs::remove_dir_all(&path).map_err(io(&path))?;
            } else {
                std::fs::rename(&path, target).map_err(io(target))?;
            }
        } else if let Some(pid) = sibling_pid(&file, name, "staging") {
            if pid == std::process::id() || !process_alive(pid) {
                std::fs::remove_dir_all(&path).map_err(io(&path))?;
            }
        }
    }
    Ok(())
}

/// Copies `from` into `to` as hard links (directories recreated).
fn link_tree(from: &Path, to: &Path) -> Result<()> {
    let meta = std::fs::symlink_metadata(from).map_err(io(from))?;
    if meta.is_dir() {
        std::fs::create_dir(to).map_err(io(to))?;
        for entry in std::fs::read_dir(from).map_err(io(from))? {
            let entry = entry.map_err(io(from))?;
            link_tree(&entry.path(), &to.join(entry.file_name()))?;
        }
        Ok(())
    } else if meta.file_type().is_symlink() {
        let dest = std::fs::read_link(from).map_err(io(from))?;
        std::os::unix::fs::symlink(dest, to).map_err(io(to))
    } else {
        std::fs::hard_link(from, to).map_err(io(to))
    }
}

/// Runs `write` on a staging directory for `target` and commits it: the whole directory
/// appears at once, or (on an error) the old one stays.
pub fn staged<T>(target: &Path, write: impl FnOnce(&Path) -> Result<T>) -> Result<T> {
    let staging = Staging::new(target)?;
    let value = write(staging.dir())?;
    staging.commit()?;
    Ok(value)
}

impl Staging {
    /// A staging directory whose commit replaces `target` as a whole. Checks the target
    /// ([`check_dir_target`]) before anything else, then creates the parent, takes the
    /// target's lock (refusing if another command holds it, see [`lock`]), checks the
    /// target again under it, recovers from a crashed earlier commit, and fails with the
    /// path named if the location cannot be written.
    pub fn new(target: &Path) -> Result<Self> {
        let (parent, name) = split(target)?;
        check_dir_target(target)?;
        std::fs::create_dir_all(&parent).map_err(io(target))?;
        let lock = lock::TargetLock::acquire(target, &parent, &name)?;
        check_dir_target(target)?;
        recover(target, &parent, &name)?;
        let dir = sibling(&parent, &name, "staging", std::process::id());
        std::fs::create_dir(&dir).map_err(io(target))?;
        Ok(Self {
            target: target.to_path_buf(),
            dir,
            keep_others: false,
            committed: false,
            lock: Some(lock),
        })
    }

    /// Like [`Staging::new`], but the commit keeps the old entries the new set lacks.
    pub fn keeping_others(target: &Path) -> Result<Self> {
        let mut s = Self::new(target)?;
        s.keep_others = true;
        Ok(s)
    }

    /// Path of `name` inside the staging directory (subdirectories are created).
    pub fn path(&self, name: &str) -> Result<PathBuf> {
        let p = self.dir.join(name);
        if let Some(parent) = p.parent() {
            std::fs::create_dir_all(parent).map_err(io(parent))?;
        }
        Ok(p)
    }

    /// The staging directory itself.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Writes a text file into the staging directory.
    pub fn write(&self, name: &str, text: &str) -> Result<PathBuf> {
        let p = self.path(name)?;
        std::fs::write(&p, text).map_err(io(&p))?;
        Ok(p)
    }

    /// Swaps the staged set in (see the module docs).
    pub fn commit(self) -> Result<()> {
        self.commit_until(None)
    }

    /// The commit, stopped after `crash_after` as if the process had died there (tests).
    #[doc(hidden)]
    pub fn commit_until(mut self, crash_after: Option<CommitStep>) -> Result<()> {
        let stop = |step: CommitStep| crash_after == Some(step);
        let (parent, name) = split(&self.target)?;
        // The command ran for a while: what is at the target now must still be ours.
        check_dir_target(&self.target)?;
        let had_old = std::fs::symlink_metadata(&self.target).is_ok_and(|m| m.is_dir());
        if self.keep_others && had_old {
            for entry in std::fs::read_dir(&self.target).map_err(io(&self.target))? {
                let entry = entry.map_err(io(&self.target))?;
                let dest = self.dir.join(entry.file_name());
                // A nested target's lock belongs to the command that holds it, not the set.
                let a_lock = entry.file_name().to_str().is_some_and(lock::is_lock_name);
                if !dest.exists() && !a_lock {
                    link_tree(&entry.path(), &dest)?;
                }
            }
        }
        owner::write_manifest(&self.dir)?;
        if stop(CommitStep::CarriedOver) {
            return self.die();
        }
        let old = sibling(&parent, &name, "old", std::process::id());
        if had_old {
            std::fs::rename(&self.target, &old).map_err(io(&self.target))?;
        }
        if stop(CommitStep::OldMovedAside) {
            return self.die();
        }
        std::fs::rename(&self.dir, &self.target).map_err(io(&self.target))?;
        self.committed = true;
        if stop(CommitStep::NewInPlace) {
            return self.die();
        }
        if had_old {
            std::fs::remove_dir_all(&old).map_err(io(&old))?;
        }
        Ok(())
    }

    /// Ends here as a killed process would: nothing cleaned up, and the lock let go of (as
    /// the kernel does for a dead process) with its file left behind.
    fn die(mut self) -> Result<()> {
        if let Some(l) = self.lock.take() {
            l.abandon();
        }
        std::mem::forget(self);
        Ok(())
    }
}

impl Drop for Staging {
    fn drop(&mut self) {
        if !self.committed {
            // Failure path: leave nothing behind. Errors here have nowhere to go.
            let _ = std::fs::remove_dir_all(&self.dir);
        }
    }
}

#[cfg(test)]
mod tests;
