//! `hil-harness` command line: run, sweep, stiffness, reproduce, replay.
use std::process::ExitCode;

fn main() -> ExitCode {
    hil_harness::main_with_default("reproduce")
}
