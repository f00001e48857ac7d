//! The workspace's end-to-end tests, built as one test binary: the command line and its bad
//! inputs, the closed loop against the paper's claims, the firmware image's symbols and the
//! shape of the source tree, and the processor-in-the-loop runs (`pil`, `pil_identify`), which
//! take one QEMU session at a time (`pil::one_at_a_time`) while the other tests run beside them.
//! `cargo test --test it <module>::` runs one module.

mod afb_claims;
mod bad_inputs;
mod cli;
mod closed_loop;
mod delay;
mod elf_symbols;
mod out_paths;
mod pil;
mod pil_identify;
mod same_gains;
mod structure;
