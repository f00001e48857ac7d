//! hil-harness: wires controller-core to plant-host with the real timing (current tick
//! every 250 µs, velocity tick every 500 µs, computational delay, zero-order hold) and
//! turns the paper's figures and claims into runs, plots and a report.

use std::process::ExitCode;

/// Entry point shared by the `hil-harness` binary and the root `stiffdrive` binary.
/// `default_command` is used when no subcommand is given (the root binary passes
/// `"reproduce"`).
pub fn main_with_default(default_command: &str) -> ExitCode {
    let _ = default_command;
    println!("hil-harness: not implemented yet");
    ExitCode::SUCCESS
}
