//! The workspace's end-to-end tests, built as one test binary: the command line and its bad
//! inputs, the closed loop against the paper's claims, the machine workflows (`workflows`:
//! tune, identify, commission), the firmware image's symbols and the shape of the source tree.
//! The processor-in-the-loop runs are a binary of their own (`tests/pil/`): cargo runs test
//! binaries one after another, so QEMU never shares the two cores with the parallel `tune`
//! runs here (under that load the firmware's 1 s link watchdog could expire).
//! `cargo test --test it <module>::` runs one module.

mod afb_claims;
mod bad_inputs;
mod cli;
mod closed_loop;
mod delay;
mod elf_symbols;
mod one_run_per_out;
mod out_paths;
mod plots;
mod pmsm;
mod same_gains;
mod structure;
mod trips;
mod user_keys;
mod workflows;
