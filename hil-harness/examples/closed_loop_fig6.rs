//! fig6's closed loop, run once, writing no files: the deterministic benchmark figure.
//!
//! ```text
//! cargo build --release -p hil-harness --example closed_loop_fig6
//! valgrind --tool=callgrind --callgrind-out-file=/dev/null \
//!     target/release/examples/closed_loop_fig6
//! ```
//! Instructions per current tick = callgrind's "Collected" count / the ticks printed here
//! (process start-up and the scenario's resolution included, a fixed few hundred
//! thousand of the total).
#![allow(missing_docs)]

use sim_engine::{resolve, run_scenario};
use std::process::ExitCode;

fn main() -> ExitCode {
    let run = resolve("fig6", None, &[]).and_then(|cfg| run_scenario(&cfg));
    match run {
        Ok(out) => {
            println!(
                "fig6: {} current ticks, {} trace rows, {:.1} s simulated",
                out.ticks,
                out.trace.rows.len(),
                out.sim_time_s
            );
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
