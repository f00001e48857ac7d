//! The workspace's end-to-end tests, built as one test binary: the command line and its bad
//! inputs, the closed loop against the paper's claims, the firmware image's symbols and the
//! shape of the source tree. The processor-in-the-loop tests (`tests/pil.rs`,
//! `tests/pil_identify.rs`) are binaries of their own, so their QEMU sessions never overlap.
//! `cargo test --test it <module>::` runs one module.

mod afb_claims;
mod bad_inputs;
mod cli;
mod closed_loop;
mod delay;
mod elf_symbols;
mod out_paths;
mod same_gains;
mod structure;
