//! stiffdrive: `cargo run --release` reproduces the paper's figures and claims into `out/`.
//! Any arguments are passed to the harness (`cargo run --release -- run --scenario fig6 ...`).
use std::process::ExitCode;

fn main() -> ExitCode {
    hil_harness::main_with_default("reproduce")
}
