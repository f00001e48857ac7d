//! pil-link's integration tests, built as one test binary: each module is one concern, on
//! the Table 1 drive (`common`).
//! `cargo test -p pil-link --features std --test it <module>::` runs one module.

/// The paper's Table 1 drive, composed from `configs/machines/table1.toml` by the one composer.
mod common {
    #[allow(clippy::expect_used)]
    pub fn table1() -> controller_core::DriveConfig {
        machine_file::table1()
            .expect("configs/machines/table1.toml composes")
            .drive
    }
}

mod board;
mod frames;
mod keys;
mod run_config;
// The socket pair needs the harness side of the link (`pil_link::host`).
#[cfg(feature = "std")]
mod session;
mod session_machine;
