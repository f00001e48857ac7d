//! The cargo runner of `thumbv7em-none-eabihf`: boots an ELF on QEMU's mps2-an386
//! (Cortex-M4F) and exits with the firmware's semihosting exit status (0 = pass; a panic
//! or HardFault exits 1).
//!
//! * `-icount shift=0,sleep=off`: one instruction is one virtual ns, and idle time (WFI)
//!   jumps straight to the next timer deadline, so timer periods, SysTick readings and the
//!   instruction counts of `cargo fw-bench` are exact and repeatable.
//! * Semihosting output (QEMU's standard output) is the binary defmt stream; it is decoded
//!   as it arrives and printed one line per frame on standard output.
//! * UART0, the board's console (trace dumps), goes to standard error through a Unix
//!   socket. `UART_INPUT=<file>` feeds that file to UART0's receiver (a `d` asks the
//!   firmware for a trace dump): `UART_INPUT=<(printf d) cargo fw-run`.
//! * `QEMU_EXTRA` adds QEMU arguments; `QEMU_TIMEOUT` (s, default 120) bounds the run.
//! * `CYCLE_TRACE=<file>` (with `--cycles`) keeps the plugin's window-by-window trace there.
//!
//! Runner options, first after the ELF: `--plain-log` prints messages without level or
//! timestamp (`cargo fw-bench`); `--expect-crash` passes only on exit status 1 with a
//! `HardFault` or `panic` line in the log (`cargo fw-crash-check`); `--cycles` loads this
//! crate's QEMU plugin ([`crate::plugin`]) on the image's window marks, prints the cycle
//! estimate ([`crate::cycles`]) after the firmware's log, and fails when the worst period
//! exceeds the `period_cycle_budget` the firmware logged (`cargo fw-bench`). Further
//! arguments go to QEMU.

use crate::cycles::{log_values, BenchFigures, Marks, Trace};
use crate::defmt_log::{LineFormat, LogDecoder};
use crate::provision::{ensure_qemu, QEMU_BINARY};
use std::ffi::OsString;
use std::io::{Read, Write};
use std::os::unix::net::UnixListener;
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdout, Command, Stdio};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

/// What the runner was asked to do.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RunnerArgs {
    /// The firmware image.
    pub elf: PathBuf,
    /// How log lines are printed.
    pub format: LineFormat,
    /// Pass only on a logged crash with exit status 1.
    pub expect_crash: bool,
    /// Trace the image's marked windows and report (and gate) their cycle estimate.
    pub cycles: bool,
    /// Extra QEMU arguments after the runner options.
    pub qemu_args: Vec<OsString>,
}

/// Parses the runner's arguments (without the program name).
pub fn parse_args(args: impl IntoIterator<Item = OsString>) -> Result<RunnerArgs, String> {
    let mut args = args.into_iter();
    let elf = args
        .next()
        .map(PathBuf::from)
        .ok_or("usage: fw-runner ELF [--plain-log] [--expect-crash] [--cycles] [QEMU ARGS...]")?;
    let mut out = RunnerArgs {
        elf,
        format: LineFormat::Full,
        expect_crash: false,
        cycles: false,
        qemu_args: Vec::new(),
    };
    let mut options = true;
    for a in args {
        match a.to_str() {
            Some("--plain-log") if options => out.format = LineFormat::Plain,
            Some("--expect-crash") if options => out.expect_crash = true,
            Some("--cycles") if options => out.cycles = true,
            _ => {
                options = false;
                out.qemu_args.push(a);
            }
        }
    }
    Ok(out)
}

/// Whether a decoded log line reports a crash.
#[must_use]
pub fn is_crash_line(line: &str) -> bool {
    line.contains("HardFault") || line.contains("panic")
}

/// The exit status the runner returns for `--expect-crash`, given QEMU's status and
/// whether a crash line was logged.
#[must_use]
pub fn expected_crash_status(qemu_status: Option<i32>, crash_logged: bool) -> i32 {
    if qemu_status == Some(1) && crash_logged {
        0
    } else {
        1
    }
}

/// Copies UART0 to standard error once QEMU connects, after sending `UART_INPUT`.
fn serve_uart(listener: UnixListener, input: Option<PathBuf>) {
    let deadline = Instant::now() + Duration::from_secs(20);
    let mut stream = loop {
        match listener.accept() {
            Ok((s, _)) => break s,
            Err(_) if Instant::now() < deadline => std::thread::sleep(Duration::from_millis(5)),
            Err(_) => return,
        }
    };
    let _ = stream.set_nonblocking(false);
    if let Some(path) = input {
        match std::fs::read(&path) {
            Ok(bytes) => {
                let _ = stream.write_all(&bytes);
            }
            Err(e) => eprintln!("fw-runner: cannot read UART_INPUT {}: {e}", path.display()),
        }
    }
    let _ = std::io::copy(&mut stream, &mut std::io::stderr());
}

/// Kills QEMU when the run takes longer than `limit`.
fn watchdog(child: Arc<Mutex<Child>>, limit: Duration, fired: Arc<Mutex<bool>>) {
    let start = Instant::now();
    loop {
        std::thread::sleep(Duration::from_millis(20));
        let mut c = child.lock().unwrap_or_else(PoisonError::into_inner);
        if !matches!(c.try_wait(), Ok(None)) {
            return;
        }
        if start.elapsed() > limit {
            *fired.lock().unwrap_or_else(PoisonError::into_inner) = true;
            let _ = c.kill();
            return;
        }
    }
}

/// The QEMU plugin: this crate's library built as a shared object, next to the running
/// executable (`target/<profile>/`) or one folder up (a test in `target/<profile>/deps/`).
pub fn plugin_path() -> Result<PathBuf, String> {
    let exe = std::env::current_exe().map_err(|e| format!("cannot locate fw-runner: {e}"))?;
    let dir = exe.parent().unwrap_or_else(|| Path::new("."));
    let name = "libfw_runner.so";
    let candidates = [
        dir.join(name),
        dir.join("deps").join(name),
        dir.parent().unwrap_or(dir).join(name),
    ];
    candidates
        .iter()
        .find(|p| p.is_file())
        .cloned()
        .ok_or_else(|| {
            format!(
                "the cycle plugin {} is missing (it is built with fw-runner: cargo build -p fw-runner)",
                dir.join(name).display()
            )
        })
}

/// The window marks of the image at `elf` (its symbols `cycle_window_arm_current`,
/// required, `cycle_window_arm_velocity`, `cycle_window_preempt` and
/// `cycle_window_next_group`).
pub fn elf_marks(elf: &Path) -> Result<Marks, String> {
    use object::{Object, ObjectSymbol};
    let bytes = std::fs::read(elf).map_err(|e| format!("{}: {e}", elf.display()))?;
    let file = object::File::parse(bytes.as_slice())
        .map_err(|e| format!("{}: not an ELF image: {e}", elf.display()))?;
    let find = |name: &str| {
        file.symbols()
            .find(|s| s.name() == Ok(name))
            // A Thumb function's symbol has bit 0 set; the instruction is at the even address.
            .map(|s| s.address() & !1)
    };
    let marks = Marks {
        arm_current: find("cycle_window_arm_current"),
        arm_velocity: find("cycle_window_arm_velocity"),
        preempt: find("cycle_window_preempt"),
        next_group: find("cycle_window_next_group"),
    };
    if marks.arm_current.is_none() {
        return Err(format!(
            "{} has no cycle_window_arm_current: --cycles needs an image with window marks (fw-bench)",
            elf.display()
        ));
    }
    Ok(marks)
}

/// The `-plugin` argument that traces `marks` into `out`.
#[must_use]
pub fn plugin_arg(plugin: &Path, out: &Path, marks: &Marks) -> String {
    let mut arg = format!("file={},out={}", plugin.display(), out.display());
    for (name, addr) in [
        ("arm_current", marks.arm_current),
        ("arm_velocity", marks.arm_velocity),
        ("preempt", marks.preempt),
        ("next_group", marks.next_group),
    ] {
        if let Some(a) = addr {
            arg.push_str(&format!(",{name}={a:#x}"));
        }
    }
    arg
}

/// The cycle report of a traced run and its verdict: the lines to print, and whether the
/// worst period of every group of windows is within its `period_cycle_budget` (true for a
/// group the firmware logged none for). The firmware logs, per group (per drive of the
/// bench) in order, `period_velocity_share` (current ticks per velocity tick of a period,
/// 2 if not logged), `period_cycle_budget`, `period_cycle_target` (reported as met or
/// missed, not gated) and its SysTick `current_tick_instructions` and
/// `velocity_tick_instructions`.
#[must_use]
pub fn cycle_report(groups: &[Trace], log: &[String]) -> (Vec<String>, bool) {
    let budgets = log_values(log, "period_cycle_budget");
    let targets = log_values(log, "period_cycle_target");
    let shares = log_values(log, "period_velocity_share");
    let currents = log_values(log, "current_tick_instructions");
    let velocities = log_values(log, "velocity_tick_instructions");
    let mut lines = Vec::new();
    let mut pass = true;
    for (g, trace) in groups.iter().enumerate() {
        let figures = BenchFigures::of(trace, shares.get(g).copied().unwrap_or(2));
        if groups.len() > 1 {
            lines.push(format!(
                "cycle estimate of the bench's drive {} of {}:",
                g + 1,
                groups.len()
            ));
        }
        lines.extend(figures.lines());
        if let (Some(c), Some(v)) = (currents.get(g), velocities.get(g)) {
            lines.push(format!(
                "trace check: the traced mean ticks are {:.1} (current) and {:.1} (velocity) instructions, the SysTick figures {c} and {v}",
                figures.current.instructions.mean, figures.velocity.instructions.mean
            ));
        }
        if let Some(&target) = targets.get(g).filter(|_| figures.current.cycles.n > 0) {
            lines.push(format!(
                "target: worst period {} cycles against the target of {target}: {} (reported; the gate is the budget)",
                figures.period_worst,
                if figures.period_worst <= target {
                    "met"
                } else {
                    "MISSED"
                }
            ));
        }
        let Some(&budget) = budgets.get(g) else {
            continue;
        };
        let ok = figures.current.cycles.n > 0 && figures.period_worst <= budget;
        pass &= ok;
        lines.push(if figures.current.cycles.n == 0 {
            "FAIL: the cycle trace holds no current tick".to_string()
        } else if ok {
            format!(
                "PASS: worst period {} cycles within the budget of {budget}",
                figures.period_worst
            )
        } else {
            format!(
                "FAIL: worst period {} cycles exceeds the budget of {budget}",
                figures.period_worst
            )
        });
    }
    (lines, pass)
}

fn spawn_qemu(args: &RunnerArgs, socket: &Path, plugin: Option<&str>) -> Result<Child, String> {
    let mut cmd = Command::new(QEMU_BINARY);
    cmd.args(["-machine", "mps2-an386", "-cpu", "cortex-m4"])
        .args(["-nographic", "-monitor", "none"])
        .arg("-chardev")
        .arg(format!("socket,id=uart0,path={}", socket.display()))
        .args(["-serial", "chardev:uart0"])
        .args(["-semihosting-config", "enable=on,target=native"])
        .args(["-icount", "shift=0,sleep=off"]);
    if let Some(plugin) = plugin {
        cmd.args(["-plugin", plugin]);
    }
    if let Ok(extra) = std::env::var("QEMU_EXTRA") {
        cmd.args(extra.split_whitespace());
    }
    cmd.arg("-kernel")
        .arg(&args.elf)
        .args(&args.qemu_args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .map_err(|e| format!("cannot start {QEMU_BINARY}: {e}"))
}

/// Runs the image and returns the runner's exit status.
pub fn run(args: &RunnerArgs) -> Result<i32, String> {
    ensure_qemu().map_err(|e| e.to_string())?;
    let decoder = LogDecoder::from_elf(&args.elf).map_err(|e| e.to_string())?;
    let limit_s = qemu_timeout_s()?;
    let dir = tempfile_dir()?;
    let socket = dir.join("uart0.sock");
    let uart = start_uart(&socket)?;

    let trace_file = dir.join("cycles.txt");
    let plugin = if args.cycles {
        let marks = elf_marks(&args.elf)?;
        Some(plugin_arg(&plugin_path()?, &trace_file, &marks))
    } else {
        None
    };
    let mut child = spawn_qemu(args, &socket, plugin.as_deref())?;
    let stdout = child.stdout.take();
    let child = Arc::new(Mutex::new(child));
    let fired = Arc::new(Mutex::new(false));
    {
        let (child, fired) = (Arc::clone(&child), Arc::clone(&fired));
        std::thread::spawn(move || watchdog(child, Duration::from_secs(limit_s), fired));
    }

    let mut out = std::io::stdout();
    let (crash_logged, log) = print_log(&decoder, args, stdout, &mut out);
    let status = child
        .lock()
        .unwrap_or_else(PoisonError::into_inner)
        .wait()
        .map_err(|e| format!("waiting for QEMU: {e}"))?;
    let _ = uart.join();
    let traced = args.cycles.then(|| read_trace(&trace_file));
    let _ = std::fs::remove_dir_all(&dir);
    if *fired.lock().unwrap_or_else(PoisonError::into_inner) {
        return Err(format!(
            "QEMU ran past QEMU_TIMEOUT = {limit_s} s and was stopped"
        ));
    }
    Ok(verdict(
        args,
        status.code(),
        crash_logged,
        traced,
        &log,
        &mut out,
    ))
}

/// `QEMU_TIMEOUT` [s], 120 when unset.
fn qemu_timeout_s() -> Result<u64, String> {
    match std::env::var("QEMU_TIMEOUT") {
        Ok(v) => v
            .parse()
            .map_err(|_| format!("QEMU_TIMEOUT must be whole seconds, got {v:?}")),
        Err(_) => Ok(120),
    }
}

/// Binds UART0's socket at `socket` and serves it (with `UART_INPUT`) on a thread.
fn start_uart(socket: &Path) -> Result<std::thread::JoinHandle<()>, String> {
    let listener = UnixListener::bind(socket).map_err(|e| format!("UART socket: {e}"))?;
    listener
        .set_nonblocking(true)
        .map_err(|e| format!("UART socket: {e}"))?;
    let input = std::env::var_os("UART_INPUT").map(PathBuf::from);
    Ok(std::thread::spawn(move || serve_uart(listener, input)))
}

/// Decodes QEMU's semihosting output (the defmt stream) and prints it line by line until
/// QEMU closes it. Returns whether a crash was logged and, with `--cycles`, the lines.
fn print_log(
    decoder: &LogDecoder,
    args: &RunnerArgs,
    pipe: Option<ChildStdout>,
    out: &mut impl Write,
) -> (bool, Vec<String>) {
    let mut crash_logged = false;
    let mut log = Vec::new();
    let mut stream = decoder.stream(args.format);
    if let Some(mut pipe) = pipe {
        let mut buf = [0u8; 4096];
        loop {
            let n = match pipe.read(&mut buf) {
                Ok(0) | Err(_) => break,
                Ok(n) => n,
            };
            stream.push(buf.get(..n).unwrap_or_default(), |line| {
                crash_logged |= is_crash_line(&line);
                let _ = writeln!(out, "{line}");
                if args.cycles {
                    log.push(line);
                }
            });
            let _ = out.flush();
        }
    }
    if let Some(note) = stream.finish().note() {
        let _ = writeln!(out, "{note}");
    }
    (crash_logged, log)
}

/// The plugin's trace of the run, kept in `CYCLE_TRACE` when that is set.
fn read_trace(trace_file: &Path) -> Result<Vec<Trace>, String> {
    if let Some(keep) = std::env::var_os("CYCLE_TRACE") {
        if let Err(e) = std::fs::copy(trace_file, &keep) {
            eprintln!("fw-runner: cannot keep the cycle trace in {keep:?}: {e}");
        }
    }
    std::fs::read_to_string(trace_file)
        .map_err(|e| {
            format!(
                "the cycle trace {} was not written: {e}",
                trace_file.display()
            )
        })
        .and_then(|t| Trace::parse_groups(&t))
}

/// The runner's exit status from QEMU's `code`: the crash check with `--expect-crash`, else
/// QEMU's status, failed by a missing trace or a worst period over the budget (the cycle
/// report is printed to `out`).
fn verdict(
    args: &RunnerArgs,
    code: Option<i32>,
    crash_logged: bool,
    traced: Option<Result<Vec<Trace>, String>>,
    log: &[String],
    out: &mut impl Write,
) -> i32 {
    if args.expect_crash {
        let verdict = expected_crash_status(code, crash_logged);
        if verdict == 0 {
            let _ = writeln!(out, "expected crash: exit status 1 with the fault logged");
        } else {
            eprintln!(
                "fw-runner: expected a logged crash with exit status 1, got status {code:?}, \
                 crash logged: {crash_logged}"
            );
        }
        return verdict;
    }
    let code = code.unwrap_or(1);
    match traced {
        None => code,
        Some(Err(e)) => {
            eprintln!("fw-runner: {e}");
            1
        }
        Some(Ok(trace)) => {
            let (lines, pass) = cycle_report(&trace, log);
            for l in lines {
                let _ = writeln!(out, "{l}");
            }
            if pass {
                code
            } else {
                1
            }
        }
    }
}

/// A fresh private directory for the UART socket.
fn tempfile_dir() -> Result<PathBuf, String> {
    static N: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);
    let n = N.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let dir = std::env::temp_dir().join(format!("stiffdrive-fw-runner-{}-{n}", std::process::id()));
    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    Ok(dir)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn os(v: &[&str]) -> Vec<OsString> {
        v.iter().map(OsString::from).collect()
    }

    #[test]
    fn runner_options_come_first_and_the_rest_goes_to_qemu() {
        let a = parse_args(os(&["fw.elf", "--plain-log", "-d", "int", "--plain-log"]))
            .unwrap_or_else(|e| unreachable!("{e}"));
        assert_eq!(a.elf, PathBuf::from("fw.elf"));
        assert_eq!(a.format, LineFormat::Plain);
        assert!(!a.expect_crash);
        assert_eq!(a.qemu_args, os(&["-d", "int", "--plain-log"]));
        let b =
            parse_args(os(&["fw.elf", "--expect-crash"])).unwrap_or_else(|e| unreachable!("{e}"));
        assert!(b.expect_crash && b.format == LineFormat::Full && b.qemu_args.is_empty());
        assert!(!b.cycles);
        let c = parse_args(os(&["fw.elf", "--plain-log", "--cycles"]))
            .unwrap_or_else(|e| unreachable!("{e}"));
        assert!(c.cycles && c.qemu_args.is_empty());
        assert!(parse_args(os(&[])).is_err());
    }

    #[test]
    fn a_crash_passes_only_with_status_one_and_a_logged_fault() {
        assert_eq!(expected_crash_status(Some(1), true), 0);
        assert_eq!(expected_crash_status(Some(1), false), 1);
        assert_eq!(expected_crash_status(Some(0), true), 1);
        assert_eq!(expected_crash_status(None, true), 1);
        assert!(is_crash_line("ERROR HardFault at 0x0000_1234"));
        assert!(is_crash_line("panicked: index"));
        assert!(!is_crash_line("current_tick_instructions: 542"));
    }
}
