//! Building the firmware's `pil` image for the Cortex-M4F.

use crate::error::{HarnessError, Result};
use fw_runner::provision;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

/// Builds the firmware's `pil` image for thumbv7em-none-eabihf and returns the ELF path.
/// Uses its own target directory (`<target>/pil-firmware`) so it never waits on the lock of
/// a host build that is running it (e.g. `cargo test`). Adds the ARM target to the
/// toolchain first if it lacks it.
pub fn build_pil_image() -> Result<PathBuf> {
    build_pil_image_with(&[])
}

/// [`build_pil_image`] with extra firmware features (each feature set in a target
/// directory of its own, `<target>/pil-firmware-<features>`).
pub fn build_pil_image_with(features: &[&str]) -> Result<PathBuf> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_else(|| PathBuf::from("."));
    provision::ensure_arm_target(&root).map_err(|e| HarnessError::Backend(format!("PIL: {e}")))?;
    let dir_name = if features.is_empty() {
        "pil-firmware".to_string()
    } else {
        format!("pil-firmware-{}", features.join("-"))
    };
    let target_dir = std::env::var_os("CARGO_TARGET_DIR")
        .map_or_else(|| root.join("target"), PathBuf::from)
        .join(dir_name);
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let mut cmd = Command::new(&cargo);
    cmd.current_dir(&root)
        .args(["build", "-p", "firmware", "--release"])
        .args(["--target", provision::ARM_TARGET, "--bin", "pil"]);
    if !features.is_empty() {
        cmd.arg("--features").arg(features.join(","));
    }
    let output = cmd
        .arg("--message-format=json-render-diagnostics")
        .env("CARGO_TARGET_DIR", &target_dir)
        .stderr(Stdio::inherit())
        .output()
        .map_err(|e| {
            HarnessError::Backend(format!("PIL: cannot run cargo to build the image: {e}"))
        })?;
    if !output.status.success() {
        return Err(HarnessError::Backend(format!(
            "PIL: building the firmware image failed ({}): cargo build -p firmware --release \
             --target thumbv7em-none-eabihf --bin pil",
            output.status
        )));
    }
    let stdout = String::from_utf8_lossy(&output.stdout);
    let from_json = stdout.lines().find_map(|line| {
        let v: serde_json::Value = serde_json::from_str(line).ok()?;
        (v.get("reason")?.as_str()? == "compiler-artifact"
            && v.get("target")?.get("name")?.as_str()? == "pil")
            .then(|| v.get("executable")?.as_str().map(PathBuf::from))
            .flatten()
    });
    let elf = from_json.unwrap_or_else(|| target_dir.join("thumbv7em-none-eabihf/release/pil"));
    if elf.is_file() {
        Ok(elf)
    } else {
        Err(HarnessError::Backend(format!(
            "PIL: the firmware image {} was not produced",
            elf.display()
        )))
    }
}
