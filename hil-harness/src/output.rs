//! Output directories that are never half-written: files go to a hidden staging directory
//! beside the target and are moved in only when the whole command succeeded.

use crate::error::{HarnessError, Result};
use std::path::{Path, PathBuf};

/// A staging directory for one command's output.
#[derive(Debug)]
pub struct Staging {
    target: PathBuf,
    dir: PathBuf,
    committed: bool,
}

impl Staging {
    /// Creates `target` (and parents) and a staging directory inside it. Fails with the
    /// path named if `target` cannot be created or written.
    pub fn new(target: &Path) -> Result<Self> {
        std::fs::create_dir_all(target).map_err(|e| HarnessError::io(target, e))?;
        let dir = target.join(format!(".staging-{}", std::process::id()));
        if dir.exists() {
            std::fs::remove_dir_all(&dir).map_err(|e| HarnessError::io(&dir, e))?;
        }
        std::fs::create_dir(&dir).map_err(|e| HarnessError::io(target, e))?;
        Ok(Self {
            target: target.to_path_buf(),
            dir,
            committed: false,
        })
    }

    /// Path of `name` inside the staging directory (subdirectories are created).
    pub fn path(&self, name: &str) -> Result<PathBuf> {
        let p = self.dir.join(name);
        if let Some(parent) = p.parent() {
            std::fs::create_dir_all(parent).map_err(|e| HarnessError::io(parent, e))?;
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
        std::fs::write(&p, text).map_err(|e| HarnessError::io(&p, e))?;
        Ok(p)
    }

    /// Moves every staged entry into the target, replacing entries of the same name.
    pub fn commit(mut self) -> Result<()> {
        let entries = std::fs::read_dir(&self.dir).map_err(|e| HarnessError::io(&self.dir, e))?;
        for entry in entries {
            let entry = entry.map_err(|e| HarnessError::io(&self.dir, e))?;
            let dest = self.target.join(entry.file_name());
            if dest.is_dir() {
                std::fs::remove_dir_all(&dest).map_err(|e| HarnessError::io(&dest, e))?;
            }
            std::fs::rename(entry.path(), &dest).map_err(|e| HarnessError::io(&dest, e))?;
        }
        self.committed = true;
        std::fs::remove_dir_all(&self.dir).map_err(|e| HarnessError::io(&self.dir, e))
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
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn dropped_staging_leaves_nothing_and_commit_moves_files() {
        let tmp = tempfile::tempdir().unwrap();
        let out = tmp.path().join("o");
        {
            let s = Staging::new(&out).unwrap();
            s.write("a.txt", "x").unwrap();
        }
        assert_eq!(std::fs::read_dir(&out).unwrap().count(), 0);
        let s = Staging::new(&out).unwrap();
        s.write("sub/b.txt", "y").unwrap();
        s.commit().unwrap();
        assert_eq!(std::fs::read_to_string(out.join("sub/b.txt")).unwrap(), "y");
        assert_eq!(std::fs::read_dir(&out).unwrap().count(), 1);
    }

    #[test]
    fn unwritable_target_is_an_error_naming_it() {
        let tmp = tempfile::tempdir().unwrap();
        let file = tmp.path().join("f");
        std::fs::write(&file, "").unwrap();
        let e = Staging::new(&file.join("x")).unwrap_err();
        assert!(e.to_string().contains("f/x"), "{e}");
    }
}
