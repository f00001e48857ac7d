//! fw-runner: the host side of running stiffdrive's firmware in QEMU.
//!
//! * [`provision`]: what a fresh machine lacks for it, installed on first use with one line
//!   printed per install: the `thumbv7em-none-eabihf` standard library (`rustup target
//!   add`) and `qemu-system-arm` (`apt-get`, as root). Without root, or without rustup or
//!   apt-get, the error names the exact command to run. Nothing is ever skipped.
//! * [`defmt_log`]: decodes the firmware's defmt log in-process with the `defmt-decoder`
//!   crate, from the ELF's own table, so no external `defmt-print` is needed.
//! * [`runner`]: the cargo runner of the embedded target (`.cargo/config.toml`): boots an
//!   ELF on QEMU's mps2-an386 (Cortex-M4F), decodes its log as it arrives, and exits with
//!   the firmware's semihosting exit status.
//! * [`cycles`]: the cycle estimate of `cargo fw-bench`: the executed instruction stream of
//!   the firmware's measured windows priced by the Cortex-M4 TRM's timings.
//! * [`plugin`]: the QEMU TCG plugin that feeds it (this library, built as
//!   `libfw_runner.so`).
//!
//! The `hil-harness pil` command and the PIL tests use the first two; the `fw-*` cargo
//! aliases go through the runner binary.

pub mod cycles;
pub mod defmt_log;
pub mod plugin;
pub mod provision;
pub mod runner;
