//! `fw-runner ELF [--plain-log] [--expect-crash] [QEMU ARGS...]`: the cargo runner of the
//! embedded target (see [`fw_runner::runner`]). Exits with the firmware's exit status;
//! 127 when QEMU cannot be provided or started.

fn main() {
    let code = fw_runner::runner::parse_args(std::env::args_os().skip(1))
        .and_then(|args| fw_runner::runner::run(&args))
        .unwrap_or_else(|e| {
            eprintln!("fw-runner: {e}");
            127
        });
    std::process::exit(code);
}
