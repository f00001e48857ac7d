//! hil-harness: stiffdrive's command line. [`cli`] parses it and [`dispatch`] hands each
//! command to the crate that does it: `run`, `replay` and `schema` to `sim-engine`, `pil` and `board` to
//! `pil-host`, `linear`, `tune`, `identify`, `commission`, `sweep`, `stiffness` and `flash`
//! to `machine-workflows`, `reproduce` and `sec2-map` to `paper-repro`.

pub mod board;
pub mod cli;
pub mod pil;

use clap::Parser;
use sim_engine::Result;
use std::process::ExitCode;

/// Entry point of the one command-line binary, the root `stiffdrive` (`cargo run --release
/// -- ...`; the harness has no binary of its own, so the fat-LTO release link runs once).
/// `default_command` is used when no subcommand is given (the root binary passes
/// `"reproduce"`).
pub fn main_with_default(default_command: &str) -> ExitCode {
    let mut args: Vec<String> = std::env::args().collect();
    if args.len() <= 1 {
        args.push(default_command.to_string());
    }
    let cli = match cli::Cli::try_parse_from(&args) {
        Ok(cli) => cli,
        Err(e) => {
            // Help and version are not errors.
            let code = if e.use_stderr() { 2 } else { 0 };
            let _ = e.print();
            return ExitCode::from(code);
        }
    };
    match dispatch(cli.command) {
        Ok(message) => {
            println!("{message}");
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(e.exit_code())
        }
    }
}

/// Runs one parsed command; returns the text to print.
pub fn dispatch(command: cli::Command) -> Result<String> {
    use cli::Command;
    use machine_workflows::{commission, identify, linear, stiffness, sweep, tune};
    match command {
        Command::Run(a) => sim_engine::run::run(&a.scenario, a.config.as_deref(), &a.set, &a.out),
        Command::Linear(a) => {
            linear::analyze::linear(&a.scenario, a.config.as_deref(), &a.set, &a.out)
        }
        Command::Tune {
            config,
            design,
            out,
        } => tune::tune(
            &config,
            design.target_bandwidth,
            &design.constraints(),
            &out,
        ),
        Command::Identify {
            config,
            board,
            set,
            out,
        } => {
            let config = config.unwrap_or_else(|| "configs/machines/table1.toml".into());
            match board.target() {
                Some(target) => identify::board::identify_board(&config, &set, &out, &target),
                None => identify::identify(&config, &set, &out),
            }
        }
        Command::Commission {
            config,
            set,
            design,
            out,
        } => commission::commission(
            &config,
            &set,
            design.target_bandwidth,
            &design.constraints(),
            &out,
        ),

        Command::Sweep { out } => sweep::sweep(&out),
        Command::Stiffness { config, set, out } => match config {
            Some(c) => stiffness::machine::stiffness_machine(&out, &c, &set),
            None => stiffness::stiffness(&out),
        },
        Command::Sec2Map { out } => paper_repro::sec2::sec2(&out),
        Command::Reproduce { out } => paper_repro::report::reproduce(&out),
        Command::Replay {
            config,
            torque,
            out,
        } => sim_engine::replay::replay(&config, &torque, &out),
        Command::Pil(args) => pil_host::pil_command(&args.to_run()),
        Command::Board(args) => args.run(),
        Command::Schema { grids, out } => {
            use sim_engine::config::schema::{write_schema, SchemaOf};
            let of = if grids {
                SchemaOf::Grids
            } else {
                SchemaOf::Machine
            };
            write_schema(of, &out.unwrap_or_else(|| of.default_out().into()))
        }
        Command::Flash { config, build_only } => {
            machine_workflows::flash::flash(&config, build_only)
        }
    }
}
