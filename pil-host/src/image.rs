//! Building the firmware's images for the Cortex-M4F from the host.
//!
//! Every host-side build of the firmware (the `pil` image, its test-feature variants, the
//! symbol check of all images) goes to one target directory, `<target>/firmware`:
//! - its own, so a build started from a running host process (e.g. a test of `cargo test`)
//!   never waits on the lock of the build that runs it;
//! - one for all, so the ARM dependencies are compiled once and a feature variant rebuilds
//!   only the firmware crate. CI points its `cargo fw-*` steps at it as well.
//!
//! The builds are serialized by a lock file, and each image is copied out (atomically, by
//! rename) to a name of its own feature set before the lock is released. So a concurrent
//! build of another feature set, which replaces cargo's `release/pil`, never changes an
//! image a caller is running.

use fw_runner::provision;
use sim_engine::error::{HarnessError, Result};

/// The three-phase board's table and arithmetic, the firmware's own source: what its image
/// checks a drive against, checked here before a build.
#[path = "../../firmware/src/board/three_phase.rs"]
#[allow(dead_code)]
mod three_phase;

use std::fs::File;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
pub use three_phase::{drive_periods_per_tick, DriveError as ThreePhaseDriveError, TIM1_CLOCK_HZ};

/// The workspace root (this crate's parent).
fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map_or_else(|| PathBuf::from("."), Path::to_path_buf)
}

/// The target directory of the host-side firmware builds: `<target>/firmware`, where
/// `<target>` is `CARGO_TARGET_DIR` or the workspace's `target/`.
pub fn firmware_target_dir() -> PathBuf {
    std::env::var_os("CARGO_TARGET_DIR")
        .map_or_else(|| workspace_root().join("target"), PathBuf::from)
        .join("firmware")
}

fn backend(what: &str, e: impl std::fmt::Display) -> HarnessError {
    HarnessError::Backend(format!("firmware build: {what}: {e}"))
}

/// Runs `cargo build -p firmware --release --target thumbv7em-none-eabihf` with `args`
/// into [`firmware_target_dir`], holding its lock file while `then` runs on the release
/// directory. Adds the ARM target to the toolchain first if it lacks it. The image carries
/// the drive of the machine file `drive` (`STIFFDRIVE_DRIVE`, an absolute path), or
/// `configs/machines/table1.toml` for `None`, whatever the caller's environment says.
fn build_locked<T>(
    args: &[&str],
    drive: Option<&Path>,
    then: impl FnOnce(&Path) -> Result<T>,
) -> Result<T> {
    let root = workspace_root();
    provision::ensure_arm_target(&root).map_err(|e| backend("ARM target", e))?;
    let target_dir = firmware_target_dir();
    std::fs::create_dir_all(&target_dir).map_err(|e| backend("target directory", e))?;
    let lock = File::create(target_dir.join("stiffdrive-images.lock"))
        .map_err(|e| backend("lock file", e))?;
    lock.lock().map_err(|e| backend("lock", e))?;
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let mut cmd = Command::new(&cargo);
    cmd.current_dir(&root)
        .args(["build", "-p", "firmware", "--release"])
        .args(["--target", provision::ARM_TARGET])
        .args(args)
        .env("CARGO_TARGET_DIR", &target_dir);
    // The default file named by its path is the default: the build script reruns when
    // STIFFDRIVE_DRIVE changes, so spelling Table 1 two ways would rebuild the firmware at
    // every switch between them.
    let default = root.join(machine_file::TABLE1_PATH).canonicalize().ok();
    match drive.filter(|f| f.canonicalize().ok() != default) {
        Some(file) => cmd.env("STIFFDRIVE_DRIVE", file),
        None => cmd.env_remove("STIFFDRIVE_DRIVE"),
    };
    let status = cmd
        .stdout(Stdio::null())
        .stderr(Stdio::inherit())
        .status()
        .map_err(|e| backend("cannot run cargo", e))?;
    if !status.success() {
        return Err(HarnessError::Backend(format!(
            "firmware build failed ({status}): cargo build -p firmware --release --target {} {}",
            provision::ARM_TARGET,
            args.join(" ")
        )));
    }
    // The lock is released when `lock` drops, after `then`.
    then(&target_dir.join(provision::ARM_TARGET).join("release"))
}

/// Builds the firmware's `pil` image and returns the ELF path.
pub fn build_pil_image() -> Result<PathBuf> {
    build_pil_image_with(&[])
}

/// [`build_pil_image`] with extra firmware features. The image is returned as a copy named
/// after its feature set (`images/pil` or `images/pil-<features>`), which no later build
/// of another feature set replaces.
pub fn build_pil_image_with(features: &[&str]) -> Result<PathBuf> {
    let joined = features.join(",");
    let mut args = vec!["--bin", "pil"];
    if !features.is_empty() {
        args.extend(["--features", joined.as_str()]);
    }
    let name = if features.is_empty() {
        "pil".to_string()
    } else {
        format!("pil-{}", features.join("-"))
    };
    build_locked(&args, None, |release| copy_out(release, "pil", &name))
}

/// Builds the firmware's `board` image (the board console in QEMU) and returns the ELF
/// path, `images/board`.
pub fn build_board_console_image() -> Result<PathBuf> {
    build_board_console_image_for(None)
}

/// Builds the `board` image carrying the drive of the machine file `drive` (an absolute
/// path; `None`: Table 1's) and returns the ELF path, `images/board` or
/// `images/board-<file stem>`.
pub fn build_board_console_image_for(drive: Option<&Path>) -> Result<PathBuf> {
    let name = drive.and_then(Path::file_stem).map_or_else(
        || "board".to_string(),
        |s| format!("board-{}", s.to_string_lossy()),
    );
    build_locked(&["--bin", "board"], drive, |release| {
        copy_out(release, "board", &name)
    })
}

/// Copies the built binary `bin` of `release` to `release/images/name` (atomically, by
/// rename) and returns that path.
fn copy_out(release: &Path, bin: &str, name: &str) -> Result<PathBuf> {
    let built = release.join(bin);
    if !built.is_file() {
        return Err(HarnessError::Backend(format!(
            "the firmware image {} was not produced",
            built.display()
        )));
    }
    let images = release.join("images");
    std::fs::create_dir_all(&images).map_err(|e| backend("images directory", e))?;
    let elf = images.join(name);
    let tmp = images.join(format!("{name}.tmp"));
    std::fs::copy(&built, &tmp).map_err(|e| backend("copy of the image", e))?;
    std::fs::rename(&tmp, &elf).map_err(|e| backend("rename of the image", e))?;
    Ok(elf)
}

/// Builds the STM32F4 board's image (`--no-default-features --features board-stm32f4`)
/// carrying the drive of the machine file `drive` and returns the ELF path,
/// `images/stm32f4-<file stem>`.
pub fn build_board_image(drive: &Path) -> Result<PathBuf> {
    build_stm32_image_for(Some(drive))
}

/// Builds the STM32F4 board's image carrying the drive of the machine file `drive` (an
/// absolute path; `None`: Table 1's) and returns the ELF path, `images/stm32f4` or
/// `images/stm32f4-<file stem>`.
pub fn build_stm32_image_for(drive: Option<&Path>) -> Result<PathBuf> {
    let name = drive.and_then(Path::file_stem).map_or_else(
        || "stm32f4".to_string(),
        |s| format!("stm32f4-{}", s.to_string_lossy()),
    );
    let args = [
        "--bin",
        "firmware",
        "--no-default-features",
        "--features",
        "board-stm32f4",
    ];
    build_locked(&args, drive, |release| copy_out(release, "firmware", &name))
}

/// Builds the three-phase board's image (NUCLEO-F446RE with X-NUCLEO-IHM08M1,
/// `--no-default-features --features board-stm32f4-3ph`) carrying the PMSM drive `cfg` of
/// the machine file `drive` (an absolute path) and returns the ELF path,
/// `images/stm32f4-3ph-<file stem>`. The drive is checked against the board first
/// ([`drive_periods_per_tick`]), so a drive the board cannot run builds nothing.
///
/// # Errors
/// The drive's key that the board refuses; a failed build.
pub fn build_three_phase_image(
    drive: &Path,
    cfg: &controller_core::DriveConfig,
) -> Result<PathBuf> {
    drive_periods_per_tick(cfg).map_err(|e| match e {
        ThreePhaseDriveError::NotPmsm => HarnessError::config("electrics.motor", e.to_string()),
        ThreePhaseDriveError::TickRatio(_) => {
            HarnessError::config("drive.current_rate_hz", e.to_string())
        }
    })?;
    let name = drive.file_stem().map_or_else(
        || "stm32f4-3ph".to_string(),
        |s| format!("stm32f4-3ph-{}", s.to_string_lossy()),
    );
    let args = [
        "--bin",
        "firmware",
        "--no-default-features",
        "--features",
        "board-stm32f4-3ph",
    ];
    build_locked(&args, Some(drive), |release| {
        copy_out(release, "firmware", &name)
    })
}

/// Builds every firmware binary for the QEMU board (default features) and calls `check`
/// on the release directory that holds them, with the build lock held (so no concurrent
/// feature build replaces an image while it is read).
pub fn with_all_images<T>(check: impl FnOnce(&Path) -> Result<T>) -> Result<T> {
    build_locked(&["--bins"], None, check)
}
