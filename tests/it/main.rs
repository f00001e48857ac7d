//! The workspace's end-to-end tests, built as one test binary: the command line and its bad
//! inputs, the closed loop against the paper's claims, the machine workflows (`workflows`:
//! tune, identify, commission), the firmware image's symbols and the shape of the source tree,
//! and the processor-in-the-loop runs (`pil`, `pil_identify`), which run one QEMU session at a
//! time in one test (`pil::processor_in_the_loop`) while the other tests run beside it.
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
mod workflows;
