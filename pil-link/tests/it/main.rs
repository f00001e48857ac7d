//! pil-link's integration tests, built as one test binary: each module is one concern, on
//! the Table 1 drive of controller-core's test support (`common`).
//! `cargo test -p pil-link --features std --test it <module>::` runs one module.

#[path = "../../../controller-core/tests/common/mod.rs"]
mod common;

mod frames;
mod run_config;
// The socket pair needs the harness side of the link (`pil_link::host`).
#[cfg(feature = "std")]
mod session;
mod session_machine;
