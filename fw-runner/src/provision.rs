//! What running the firmware needs and a fresh machine lacks, installed on first use.
//!
//! * [`ensure_arm_target`]: the `thumbv7em-none-eabihf` standard library of the active
//!   toolchain. rustup installs the targets of `rust-toolchain.toml` only together with a
//!   toolchain it installs, never into one that is already there, so this checks the
//!   sysroot and runs `rustup target add` when the library is missing.
//! * [`ensure_qemu`]: `qemu-system-arm`, installed with `apt-get` when the process runs as
//!   root and `apt-get` exists; otherwise the error gives the exact command to run.
//!
//! Each install prints one line on the process's standard error (written directly, so
//! `cargo test`'s output capture does not hide it). Both checks hold a lock file while they
//! run, so parallel test binaries install once.

use std::fmt;
use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::sync::{Mutex, PoisonError};

/// The firmware's Rust target.
pub const ARM_TARGET: &str = "thumbv7em-none-eabihf";
/// The QEMU binary that runs the firmware (mps2-an386, Cortex-M4F).
pub const QEMU_BINARY: &str = "qemu-system-arm";
/// The Debian/Ubuntu package that holds [`QEMU_BINARY`].
pub const QEMU_PACKAGE: &str = "qemu-system-arm";

/// A dependency that is missing and could not be installed.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ProvisionError {
    /// What is missing.
    pub what: &'static str,
    /// Why it could not be installed.
    pub reason: String,
    /// The exact command that installs it.
    pub command: String,
}

impl fmt::Display for ProvisionError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} is missing and could not be installed ({}); run: {}",
            self.what, self.reason, self.command
        )
    }
}

impl std::error::Error for ProvisionError {}

/// One line on the real standard error, past `cargo test`'s capture of `eprintln!`.
fn announce(line: &str) {
    let _ = writeln!(std::io::stderr(), "stiffdrive: {line}");
}

/// Runs `f` holding a process-wide mutex and a lock file shared by every process.
fn locked<T>(f: impl FnOnce() -> T) -> T {
    static LOCK: Mutex<()> = Mutex::new(());
    let _guard = LOCK.lock().unwrap_or_else(PoisonError::into_inner);
    let file = File::create(std::env::temp_dir().join("stiffdrive-provision.lock")).ok();
    if let Some(file) = &file {
        // Without the lock two processes may both install; apt and rustup serialise
        // themselves, so that is slower, not wrong.
        let _ = file.lock();
    }
    f()
}

/// The first `name` on the PATH.
#[must_use]
pub fn which(name: &str) -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path)
        .map(|dir| dir.join(name))
        .find(|p| p.is_file())
}

/// Whether the process runs with effective user id 0.
#[must_use]
pub fn is_root() -> bool {
    // /proc/self/status: "Uid:\treal\teffective\tsaved\tfs".
    if let Ok(status) = std::fs::read_to_string("/proc/self/status") {
        if let Some(line) = status.lines().find(|l| l.starts_with("Uid:")) {
            return line.split_whitespace().nth(2) == Some("0");
        }
    }
    Command::new("id")
        .arg("-u")
        .output()
        .is_ok_and(|o| o.status.success() && o.stdout.trim_ascii() == b"0")
}

fn stderr_tail(o: &Output) -> String {
    let text = String::from_utf8_lossy(&o.stderr);
    let lines: Vec<&str> = text.lines().rev().take(4).collect();
    lines.into_iter().rev().collect::<Vec<_>>().join(" | ")
}

/// Whether `sysroot` holds the core library of [`ARM_TARGET`].
#[must_use]
pub fn sysroot_has_target(sysroot: &Path) -> bool {
    let lib = sysroot.join("lib/rustlib").join(ARM_TARGET).join("lib");
    std::fs::read_dir(lib).is_ok_and(|mut entries| {
        entries.any(|e| e.is_ok_and(|e| e.file_name().to_string_lossy().starts_with("libcore-")))
    })
}

/// The sysroot of the toolchain that builds in `dir` (its `rust-toolchain.toml` applies).
fn sysroot(dir: &Path) -> Result<PathBuf, String> {
    let rustc = std::env::var_os("RUSTC").unwrap_or_else(|| "rustc".into());
    let out = Command::new(&rustc)
        .current_dir(dir)
        .args(["--print", "sysroot"])
        .stdin(Stdio::null())
        .output()
        .map_err(|e| format!("cannot run rustc: {e}"))?;
    if !out.status.success() {
        return Err(format!(
            "rustc --print sysroot failed: {}",
            stderr_tail(&out)
        ));
    }
    Ok(PathBuf::from(
        String::from_utf8_lossy(&out.stdout).trim().to_owned(),
    ))
}

/// Makes sure the toolchain that builds in `workspace` has the [`ARM_TARGET`] standard
/// library, running `rustup target add` for that toolchain when it is missing.
pub fn ensure_arm_target(workspace: &Path) -> Result<(), ProvisionError> {
    let toolchain = std::env::var("RUSTUP_TOOLCHAIN").ok();
    let command = match &toolchain {
        Some(t) => format!("rustup target add --toolchain {t} {ARM_TARGET}"),
        None => format!("rustup target add {ARM_TARGET}"),
    };
    let fail = |reason: String| ProvisionError {
        what: "the thumbv7em-none-eabihf Rust target",
        reason,
        command: command.clone(),
    };
    locked(|| {
        let root = sysroot(workspace).map_err(fail)?;
        if sysroot_has_target(&root) {
            return Ok(());
        }
        announce(&format!("installing the {ARM_TARGET} target: {command}"));
        let mut cmd = Command::new("rustup");
        cmd.current_dir(workspace).args(["target", "add"]);
        if let Some(t) = &toolchain {
            cmd.args(["--toolchain", t]);
        }
        let out = cmd
            .arg(ARM_TARGET)
            .stdin(Stdio::null())
            .output()
            .map_err(|e| fail(format!("cannot run rustup: {e}")))?;
        if !out.status.success() {
            return Err(fail(format!("rustup failed: {}", stderr_tail(&out))));
        }
        if sysroot_has_target(&root) {
            Ok(())
        } else {
            Err(fail(format!(
                "rustup succeeded but {} still lacks the target",
                root.display()
            )))
        }
    })
}

/// Whether `qemu-system-arm --version` runs.
#[must_use]
pub fn qemu_installed() -> bool {
    Command::new(QEMU_BINARY)
        .arg("--version")
        .stdin(Stdio::null())
        .output()
        .is_ok_and(|o| o.status.success())
}

fn apt_get(args: &[&str]) -> Result<(), String> {
    let out = Command::new("apt-get")
        .args(args)
        .env("DEBIAN_FRONTEND", "noninteractive")
        .stdin(Stdio::null())
        .output()
        .map_err(|e| format!("cannot run apt-get: {e}"))?;
    if out.status.success() {
        Ok(())
    } else {
        Err(format!(
            "apt-get {} failed: {}",
            args.join(" "),
            stderr_tail(&out)
        ))
    }
}

/// Makes sure `qemu-system-arm` runs, installing it with `apt-get` as root.
pub fn ensure_qemu() -> Result<(), ProvisionError> {
    let fail = |reason: String, command: String| ProvisionError {
        what: QEMU_BINARY,
        reason,
        command,
    };
    locked(|| {
        if qemu_installed() {
            return Ok(());
        }
        let sudo_cmd = format!("sudo apt-get install -y {QEMU_PACKAGE}");
        if !is_root() {
            return Err(fail("this process is not root".into(), sudo_cmd));
        }
        if which("apt-get").is_none() {
            return Err(fail(
                "there is no apt-get on this machine".into(),
                format!("install QEMU's {QEMU_BINARY} (machine mps2-an386) with the system's package manager"),
            ));
        }
        let cmd = format!("apt-get update && apt-get install -y {QEMU_PACKAGE}");
        announce(&format!("installing {QEMU_PACKAGE}: {cmd}"));
        apt_get(&["update", "-qq"]).map_err(|r| fail(r, cmd.clone()))?;
        apt_get(&[
            "install",
            "-y",
            "-qq",
            "--no-install-recommends",
            QEMU_PACKAGE,
        ])
        .map_err(|r| fail(r, cmd.clone()))?;
        if qemu_installed() {
            Ok(())
        } else {
            Err(fail("apt-get succeeded but it does not run".into(), cmd))
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sysroot_without_the_core_library_lacks_the_target() {
        let dir = tempfile::tempdir().unwrap_or_else(|e| unreachable!("{e}"));
        assert!(!sysroot_has_target(dir.path()));
        let lib = dir.path().join("lib/rustlib").join(ARM_TARGET).join("lib");
        std::fs::create_dir_all(&lib).unwrap_or_else(|e| unreachable!("{e}"));
        assert!(!sysroot_has_target(dir.path()), "an empty lib folder");
        std::fs::write(lib.join("libcore-0123.rlib"), b"").unwrap_or_else(|e| unreachable!("{e}"));
        assert!(sysroot_has_target(dir.path()));
    }

    #[test]
    fn which_finds_a_shell_and_not_a_made_up_name() {
        assert!(which("sh").is_some());
        assert!(which("no-such-binary-stiffdrive").is_none());
    }

    #[test]
    fn the_error_names_the_command() {
        let e = ProvisionError {
            what: QEMU_BINARY,
            reason: "this process is not root".into(),
            command: "sudo apt-get install -y qemu-system-arm".into(),
        };
        let text = e.to_string();
        assert!(text.contains("qemu-system-arm is missing"), "{text}");
        assert!(
            text.ends_with("run: sudo apt-get install -y qemu-system-arm"),
            "{text}"
        );
    }
}
