//! Processor in the loop: the same scenarios as `run`, with the controller replaced by the
//! firmware binary running in QEMU (mps2-an386, Cortex-M4F), one `pil-link` frame exchange
//! per controller tick in lock step, so QEMU's speed does not matter.
//!
//! Wiring into the CLI (owner of hil-harness: these are the exact lines):
//! ```text
//! lib.rs:           pub mod pil;
//! cli.rs, Command:  /// Run one scenario through the firmware in QEMU (processor in the loop).
//!                   Pil(crate::pil::PilArgs),
//! lib.rs, dispatch: Command::Pil(args) => pil::pil_command(&args),
//! report (optional): pil::report_section(&dir) returns the REPORT.md section for a run
//!                   directory written by `pil` (e.g. out/pil-fig6).
//! ```
//!
//! Files in `--out` DIR: `trace.csv`, `summary.json`, `trace.svg/png` (as `run`), plus
//! `pil.json` (link statistics, fault), `pil-comparison.json` and `pil-comparison.md` (the
//! bit-for-bit comparison with the host run of the same scenario), `firmware.defmt` (the
//! firmware's defmt log) and `firmware.log` (decoded in-process by `fw-runner`'s defmt decoder).
//!
//! On a link fault (lost, corrupted or late frame, seen by either side) the run stops
//! driving the firmware at that tick, waits for the firmware to show its latched safe state,
//! writes the trace up to the fault and returns an error naming both sides' view.

use crate::commands::write_run;
use crate::config::{resolve, RunConfig};
use crate::error::{HarnessError, Result};
use crate::metrics::compute;
use crate::output::Staging;
use crate::runner::{run_with_backend, ControlBackend, RunOutput};
use controller_core::{CurrentInputs, CurrentOutputs, Fault, VelocityInputs, VelocityOutputs};
use fw_runner::defmt_log::{LineFormat, LogDecoder};
use fw_runner::provision;
use pil_link::host::{FaultPlan, HostError, HostLink};
use pil_link::qemu::{Qemu, QemuOptions};
use pil_link::tick::{Commands, Sensors};
use pil_link::wire::Writer;
use pil_link::{FaultReport, HelloAck};
use serde::Serialize;
use std::collections::BTreeMap;
use std::os::unix::net::UnixStream;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// The harness's reply deadlines it accepts, in ms.
pub const REPLY_TIMEOUT_MS: std::ops::RangeInclusive<u64> = 1..=60_000;

/// `hil-harness pil` arguments.
#[derive(Clone, Debug, clap::Args)]
pub struct PilArgs {
    /// Scenario name (a file under configs/scenarios/).
    #[arg(long)]
    pub scenario: String,
    /// Configuration (path, or name under configs/); default: the scenario's.
    #[arg(long)]
    pub config: Option<String>,
    /// Override `section.key=value` (repeatable), as for `run`.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// Output directory.
    #[arg(long)]
    pub out: PathBuf,
    /// Firmware ELF to run; default: build the `pil` image with cargo
    /// (`cargo build -p firmware --release --target thumbv7em-none-eabihf --bin pil`).
    #[arg(long)]
    pub elf: Option<PathBuf>,
    /// QEMU binary.
    #[arg(long, default_value = "qemu-system-arm")]
    pub qemu: PathBuf,
    /// Inject a link fault, `KIND@TICK[:ARG]` with KIND one of drop, corrupt, delay (ARG =
    /// ms), skip-seq, corrupt-reply, drop-reply; TICK counts sensor frames from 0.
    #[arg(long, value_name = "KIND@TICK[:ARG]")]
    pub inject: Option<String>,
    /// Firmware link watchdog: no frame for this long latches its safe state (ms, 1 to
    /// 1000: the firmware refuses others).
    #[arg(long, default_value_t = 1000)]
    pub watchdog_ms: u32,
    /// Harness deadline for each reply (ms, 1 to 60000).
    #[arg(long, default_value_t = 5000)]
    pub reply_timeout_ms: u64,
    /// Skip the bit-for-bit comparison with the host run.
    #[arg(long)]
    pub no_compare: bool,
}

impl PilArgs {
    /// Arguments for `scenario` into `out` with every default.
    pub fn new(scenario: &str, out: &Path) -> Self {
        Self {
            scenario: scenario.to_string(),
            config: None,
            set: Vec::new(),
            out: out.to_path_buf(),
            elf: None,
            qemu: PathBuf::from("qemu-system-arm"),
            inject: None,
            watchdog_ms: 1000,
            reply_timeout_ms: 5000,
            no_compare: false,
        }
    }
}

/// The firmware's `Fault` report, as written to `pil.json`.
#[derive(Clone, Debug, Serialize, PartialEq, Eq)]
pub struct FirmwareFault {
    /// Why the firmware latched (`BadCrc`, `Timeout`, `OutOfSequence`, ...).
    pub code: String,
    /// Sequence number it expected next.
    pub expected_seq: u16,
    /// Sensor frames it had answered.
    pub ticks_done: u32,
    /// Whether the current-loop interrupt ran after the fault (else nothing is shown).
    pub current_tick_ran: bool,
    /// Torque (current) reference of that tick, Q16.16 bits (0 = safe).
    pub torque_cmd_bits: i32,
    /// Voltage the board layer wrote to the PWM, Q16.16 bits (0 = safe).
    pub pwm_voltage_bits: i32,
    /// Level the board layer wrote to the enable pin (false = low = safe).
    pub enable_pin: bool,
    /// The harness's verdict on those outputs: tick ran, zero torque, zero PWM voltage,
    /// enable pin low.
    pub outputs_safe: bool,
}

impl From<FaultReport> for FirmwareFault {
    fn from(r: FaultReport) -> Self {
        let o = r.outputs;
        Self {
            code: r.code.name().to_string(),
            expected_seq: r.expected_seq,
            ticks_done: r.ticks_done,
            current_tick_ran: o.current_tick_ran,
            torque_cmd_bits: o.torque_cmd_bits,
            pwm_voltage_bits: o.pwm_voltage_bits,
            enable_pin: o.enable_pin,
            outputs_safe: o.are_safe(),
        }
    }
}

/// A link fault and how each side saw it.
#[derive(Clone, Debug, Serialize)]
pub struct LinkFault {
    /// What the harness detected (its own check, or the firmware's report).
    pub harness_error: String,
    /// True when the firmware reported the fault first.
    pub detected_by_firmware: bool,
    /// Index of the current tick at which the run stopped.
    pub at_current_tick: u64,
    /// Simulated time of that tick (s); the trace ends before it.
    pub t_s: f64,
    /// The firmware's latched state, read back after the fault (`None`: it never showed one).
    pub firmware: Option<FirmwareFault>,
}

/// `pil.json`: the link side of a PIL run.
#[derive(Clone, Debug, Serialize)]
pub struct LinkReport {
    /// pil-link protocol version.
    pub protocol_version: u8,
    /// Firmware version (`major.minor.patch`).
    pub firmware_version: String,
    /// Firmware watchdog (ms).
    pub watchdog_ms: u32,
    /// Fault injected, if any.
    pub injected: Option<String>,
    /// Sensor frames exchanged.
    pub frames: u64,
    /// Wall time of the closed loop (s).
    pub wall_time_s: f64,
    /// Mean round trip per frame (µs), QEMU included.
    pub round_trip_us: f64,
    /// QEMU's exit code (0: clean stop, 1: stopped in the safe state), `None` if killed.
    pub qemu_exit_code: Option<i32>,
    /// The link fault that stopped the run.
    pub fault: Option<LinkFault>,
}

/// Every controller input and output of a run, in tick order (raw fixed-point values).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TickLog {
    /// Current ticks.
    pub current: Vec<(CurrentInputs, CurrentOutputs)>,
    /// Velocity ticks.
    pub velocity: Vec<(VelocityInputs, VelocityOutputs)>,
}

/// A backend that records every tick of another.
pub struct Recorder<B> {
    /// The backend recorded.
    pub inner: B,
    /// What it saw and answered.
    pub log: TickLog,
}

impl<B: ControlBackend> ControlBackend for Recorder<B> {
    fn halted(&self) -> bool {
        self.inner.halted()
    }

    fn current_tick(&mut self, inputs: CurrentInputs) -> CurrentOutputs {
        let out = self.inner.current_tick(inputs);
        self.log.current.push((inputs, out));
        out
    }

    fn velocity_tick(&mut self, inputs: VelocityInputs) -> VelocityOutputs {
        let out = self.inner.velocity_tick(inputs);
        self.log.velocity.push((inputs, out));
        out
    }
}

/// The firmware in QEMU as a [`ControlBackend`]. After a link fault it stops talking to the
/// firmware, answers with the safe state (zero commands, fault set) and reports itself
/// halted, so the runner stops at the next tick; [`run_pil`] then cuts the trace exactly at
/// the fault.
struct PilBackend {
    link: HostLink<UnixStream>,
    log: TickLog,
    current_ticks: u64,
    fault: Option<(HostError, u64)>,
}

impl PilBackend {
    fn exchange(&mut self, sensors: Sensors) -> Option<Commands> {
        if self.fault.is_some() {
            return None;
        }
        let mut w = Writer::new();
        let result = sensors
            .encode(&mut w)
            .map_err(HostError::Link)
            .and_then(|()| self.link.tick(w.as_slice()))
            .and_then(|frame| Commands::decode(frame.payload()).map_err(HostError::Link));
        match result {
            Ok(c) => Some(c),
            Err(e) => {
                self.fault = Some((e, self.current_ticks));
                None
            }
        }
    }
}

const SAFE_CURRENT: CurrentOutputs = CurrentOutputs {
    voltage_cmd_pu: controller_core::Pu::ZERO,
    current_ref_pu: controller_core::Pu::ZERO,
    accel_fb_pu: controller_core::Pu::ZERO,
    fault: Some(Fault::External),
};

impl ControlBackend for PilBackend {
    fn halted(&self) -> bool {
        self.fault.is_some()
    }

    fn current_tick(&mut self, inputs: CurrentInputs) -> CurrentOutputs {
        let out = match self.exchange(Sensors::Current(inputs)) {
            Some(Commands::Current(out, _applied)) => {
                self.log.current.push((inputs, out));
                out
            }
            Some(Commands::Velocity(_)) => {
                self.fault = Some((wrong_reply(), self.current_ticks));
                SAFE_CURRENT
            }
            None => SAFE_CURRENT,
        };
        self.current_ticks += 1;
        out
    }

    fn velocity_tick(&mut self, inputs: VelocityInputs) -> VelocityOutputs {
        let safe = VelocityOutputs {
            fault: Some(Fault::External),
            ..VelocityOutputs::default()
        };
        match self.exchange(Sensors::Velocity(inputs)) {
            Some(Commands::Velocity(out)) => {
                self.log.velocity.push((inputs, out));
                out
            }
            Some(Commands::Current(..)) => {
                self.fault = Some((wrong_reply(), self.current_ticks));
                safe
            }
            None => safe,
        }
    }
}

fn wrong_reply() -> HostError {
    HostError::Link(pil_link::LinkError::BadPayload {
        kind: pil_link::FrameKind::Commands as u8,
        len: 0,
    })
}

/// A PIL run's results.
pub struct PilOutcome {
    /// The run (trace cut at the fault, if any) and its metrics.
    pub run: RunOutput,
    /// The resolved configuration.
    pub cfg: RunConfig,
    /// Link statistics and fault.
    pub link: LinkReport,
    /// Bit-for-bit comparison with the host run (clean runs, unless `--no-compare`).
    pub comparison: Option<Comparison>,
    /// Where the files went.
    pub out: PathBuf,
}

/// `hil-harness pil`: runs, writes DIR, returns the line to print; a link fault is an error
/// (after the trace up to it has been written).
pub fn pil_command(args: &PilArgs) -> Result<String> {
    let o = run_pil(args)?;
    if let Some(f) = &o.link.fault {
        let fw =
            f.firmware.as_ref().map_or_else(
                || "the firmware never reported a latched safe state".to_string(),
                |r| {
                    format!(
                    "firmware latched {}; its outputs are {} (torque bits {}, PWM voltage bits \
                     {}, enable pin {}, tick after the fault {})",
                    r.code,
                    if r.outputs_safe { "safe" } else { "NOT SAFE" },
                    r.torque_cmd_bits,
                    r.pwm_voltage_bits,
                    if r.enable_pin { "high" } else { "low" },
                    if r.current_tick_ran { "ran" } else { "did not run" }
                )
                },
            );
        return Err(HarnessError::Backend(format!(
            "PIL link fault at t = {:.4} s (current tick {}): {}; {fw}; trace up to the fault \
             written to {}",
            f.t_s,
            f.at_current_tick,
            f.harness_error,
            o.out.display()
        )));
    }
    let cmp = o.comparison.as_ref().map_or_else(
        || "not compared".to_string(),
        |c| {
            if c.bit_identical {
                format!(
                    "bit-identical to the host run ({} current + {} velocity ticks)",
                    c.current_ticks, c.velocity_ticks
                )
            } else {
                format!(
                    "DIFFERS from the host run: {} mismatched values",
                    c.mismatches
                )
            }
        },
    );
    let message = format!(
        "{} (PIL, firmware in QEMU): {} frames, {:.0} µs per round trip, {:.2} s simulated in \
         {:.1} s; {cmp} -> {}",
        o.cfg.name,
        o.link.frames,
        o.link.round_trip_us,
        o.run.sim_time_s,
        o.link.wall_time_s,
        o.out.display()
    );
    match &o.comparison {
        Some(c) if !c.bit_identical => Err(HarnessError::Backend(message)),
        _ => Ok(message),
    }
}

/// Runs a scenario through the firmware in QEMU and writes its files (see the module docs).
/// A link fault is not an `Err` here: it is in `link.fault`, with the trace cut before it.
pub fn run_pil(args: &PilArgs) -> Result<PilOutcome> {
    let wd = &pil_link::WATCHDOG_MS_RANGE;
    if !wd.contains(&args.watchdog_ms) {
        return Err(HarnessError::config(
            "--watchdog-ms",
            format!(
                "{} ms is outside the PIL protocol's watchdog range [{}, {}] ms (the firmware \
                 refuses such a Hello with a Protocol fault)",
                args.watchdog_ms,
                wd.start(),
                wd.end()
            ),
        ));
    }
    if !REPLY_TIMEOUT_MS.contains(&args.reply_timeout_ms) {
        return Err(HarnessError::config(
            "--reply-timeout-ms",
            format!(
                "{} ms is outside [{}, {}] ms",
                args.reply_timeout_ms,
                REPLY_TIMEOUT_MS.start(),
                REPLY_TIMEOUT_MS.end()
            ),
        ));
    }
    let cfg = resolve(&args.scenario, args.config.as_deref(), &args.set)?;
    // The link carries drive settings, not gains: the firmware designs its own. A
    // comparison run whose borrowed gains differ from its own design cannot run there.
    let own = controller_core::design(&cfg.drive)
        .map_err(|e| HarnessError::config(format!("drive.{}", e.param()), e.to_string()))?;
    if crate::runner::regulator_gains(&cfg)? != own {
        return Err(HarnessError::config(
            "scenario.comparison.gains_of",
            format!(
                "{} borrows gains that differ from its own design; the firmware designs its \
                 gains from the drive settings, so this run cannot go through PIL",
                cfg.name
            ),
        ));
    }
    let plan: Option<FaultPlan> = args
        .inject
        .as_deref()
        .map(str::parse)
        .transpose()
        .map_err(|e: String| HarnessError::config("--inject", e))?;
    let elf = match &args.elf {
        Some(p) => p.clone(),
        None => build_pil_image()?,
    };
    if args.qemu == Path::new(provision::QEMU_BINARY) {
        provision::ensure_qemu().map_err(|e| HarnessError::Backend(format!("PIL: {e}")))?;
    }
    let staging = Staging::new(&args.out)?;
    let log_path = staging.path("firmware.defmt")?;
    let (mut qemu, stream) = Qemu::spawn(&QemuOptions {
        qemu: args.qemu.clone(),
        elf: elf.clone(),
        log: log_path.clone(),
        connect_timeout: Duration::from_secs(20),
    })
    .map_err(|e| HarnessError::Backend(format!("PIL: {e}")))?;

    let mut link = HostLink::new(stream, Duration::from_millis(args.reply_timeout_ms));
    let backend_err = |stage: &str, e: HostError| {
        let stderr = qemu.stderr();
        let stderr = stderr.trim();
        HarnessError::Backend(format!(
            "PIL {stage}: {e} (QEMU stderr: {})",
            if stderr.is_empty() { "empty" } else { stderr }
        ))
    };
    let ack: HelloAck = link
        .hello(args.watchdog_ms)
        .map_err(|e| backend_err("hello", e))?;
    let mut w = Writer::new();
    pil_link::settings::encode(&cfg.drive, &mut w)
        .map_err(|e| backend_err("config", HostError::Link(e)))?;
    link.configure(w.as_slice())
        .map_err(|e| backend_err("config", e))?;
    if let Some(p) = plan {
        link.inject(p);
    }

    let mut backend = PilBackend {
        link,
        log: TickLog::default(),
        current_ticks: 0,
        fault: None,
    };
    let start = Instant::now();
    let mut run = run_with_backend(&cfg, &mut backend)?;
    let wall_time_s = start.elapsed().as_secs_f64();
    let frames = backend.link.sensors_sent();

    let tc_s = 1.0 / f64::from(cfg.drive.current_rate_hz.max(1));
    let fault = match backend.fault.take() {
        None => {
            backend.link.stop().map_err(|e| backend_err("stop", e))?;
            None
        }
        Some((error, at)) => {
            let already = match &error {
                HostError::FirmwareFault(r) => Some(*r),
                _ => None,
            };
            // Silence long enough for the firmware's watchdog, then read its latched state.
            let wait = Duration::from_millis(u64::from(args.watchdog_ms) * 2 + 500);
            let report = backend.link.confirm_safe_state(already, wait);
            let t_s = at as f64 * tc_s;
            cut_at(&mut run, &cfg, t_s);
            Some(LinkFault {
                harness_error: error.to_string(),
                detected_by_firmware: already.is_some(),
                at_current_tick: at,
                t_s,
                firmware: report.map(FirmwareFault::from),
            })
        }
    };
    let exit = qemu.finish(Duration::from_secs(5));
    drop(qemu);
    if let Some(p) = plan {
        if fault.is_none() && p.at_tick >= frames {
            return Err(HarnessError::config(
                "--inject",
                format!(
                    "sensor frame {} is past the end of the run ({frames} sensor frames): \
                     nothing was injected",
                    p.at_tick
                ),
            ));
        }
    }

    let link_report = LinkReport {
        protocol_version: ack.protocol_version,
        firmware_version: format!(
            "{}.{}.{}",
            ack.firmware_version >> 16,
            (ack.firmware_version >> 8) & 0xFF,
            ack.firmware_version & 0xFF
        ),
        watchdog_ms: ack.watchdog_ms,
        injected: args.inject.clone(),
        frames,
        wall_time_s,
        round_trip_us: if frames > 0 {
            wall_time_s * 1e6 / frames as f64
        } else {
            0.0
        },
        qemu_exit_code: exit.and_then(|s| s.code()),
        fault,
    };
    run.wall_time_s = wall_time_s;

    let comparison = if link_report.fault.is_none() && !args.no_compare {
        let mut host = Recorder {
            inner: crate::runner::controller(&cfg)?,
            log: TickLog::default(),
        };
        let host_run = run_with_backend(&cfg, &mut host)?;
        Some(compare(&cfg.name, &host.log, &backend.log, &host_run, &run))
    } else {
        None
    };

    write_run(staging.dir(), &cfg, &run)?;
    write_json(&staging, "pil.json", &link_report)?;
    if let Some(c) = &comparison {
        write_json(&staging, "pil-comparison.json", c)?;
        staging.write("pil-comparison.md", &section_text(c, &link_report))?;
    }
    decode_log(&elf, &log_path, &staging)?;
    // The commit replaces the whole directory: no comparison of an earlier run survives.
    staging.commit()?;
    Ok(PilOutcome {
        run,
        cfg,
        link: link_report,
        comparison,
        out: args.out.clone(),
    })
}

/// Drops trace rows at or after `t_s` and recomputes the metrics on what is left.
fn cut_at(run: &mut RunOutput, cfg: &RunConfig, t_s: f64) {
    run.trace.rows.retain(|r| r.t_s < t_s - 1e-12);
    run.sim_time_s = t_s;
    run.ticks = (t_s * f64::from(cfg.drive.current_rate_hz)).round() as u64;
    let windows = cfg
        .scenario
        .metric_windows(f64::from(cfg.drive.torque_limit_pu));
    run.metrics = compute(&run.trace, &windows);
}

fn write_json<T: Serialize>(staging: &Staging, name: &str, value: &T) -> Result<()> {
    let text = serde_json::to_string_pretty(value)
        .map_err(|e| HarnessError::io(staging.dir().join(name), e))?;
    staging.write(name, &(text + "\n")).map(|_| ())
}

/// Decodes the firmware's defmt log in-process into `firmware.log` (the raw log stays in
/// `firmware.defmt`). A log that cannot be decoded says why in `firmware.log`.
fn decode_log(elf: &Path, raw: &Path, staging: &Staging) -> Result<()> {
    let bytes = std::fs::read(raw).map_err(|e| HarnessError::io(raw, e))?;
    let lines = match LogDecoder::from_elf(elf) {
        Ok(d) => d.decode_all(&bytes, LineFormat::Full),
        Err(e) => vec![format!("(defmt log not decoded: {e})")],
    };
    let mut text = lines.join("\n");
    text.push('\n');
    staging.write("firmware.log", &text).map(|_| ())
}

/// Builds the firmware's `pil` image for thumbv7em-none-eabihf and returns the ELF path.
/// Uses its own target directory (`<target>/pil-firmware`) so it never waits on the lock of
/// a host build that is running it (e.g. `cargo test`). Adds the ARM target to the
/// toolchain first if it lacks it.
pub fn build_pil_image() -> Result<PathBuf> {
    build_pil_image_with(&[])
}

/// [`build_pil_image`] with extra firmware features (each feature set in a target
/// directory of its own, `<target>/pil-firmware-<features>`).
pub fn build_pil_image_with(features: &[&str]) -> Result<PathBuf> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_else(|| PathBuf::from("."));
    provision::ensure_arm_target(&root).map_err(|e| HarnessError::Backend(format!("PIL: {e}")))?;
    let dir_name = if features.is_empty() {
        "pil-firmware".to_string()
    } else {
        format!("pil-firmware-{}", features.join("-"))
    };
    let target_dir = std::env::var_os("CARGO_TARGET_DIR")
        .map_or_else(|| root.join("target"), PathBuf::from)
        .join(dir_name);
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let mut cmd = Command::new(&cargo);
    cmd.current_dir(&root)
        .args(["build", "-p", "firmware", "--release"])
        .args(["--target", provision::ARM_TARGET, "--bin", "pil"]);
    if !features.is_empty() {
        cmd.arg("--features").arg(features.join(","));
    }
    let output = cmd
        .arg("--message-format=json-render-diagnostics")
        .env("CARGO_TARGET_DIR", &target_dir)
        .stderr(Stdio::inherit())
        .output()
        .map_err(|e| {
            HarnessError::Backend(format!("PIL: cannot run cargo to build the image: {e}"))
        })?;
    if !output.status.success() {
        return Err(HarnessError::Backend(format!(
            "PIL: building the firmware image failed ({}): cargo build -p firmware --release \
             --target thumbv7em-none-eabihf --bin pil",
            output.status
        )));
    }
    let stdout = String::from_utf8_lossy(&output.stdout);
    let from_json = stdout.lines().find_map(|line| {
        let v: serde_json::Value = serde_json::from_str(line).ok()?;
        (v.get("reason")?.as_str()? == "compiler-artifact"
            && v.get("target")?.get("name")?.as_str()? == "pil")
            .then(|| v.get("executable")?.as_str().map(PathBuf::from))
            .flatten()
    });
    let elf = from_json.unwrap_or_else(|| target_dir.join("thumbv7em-none-eabihf/release/pil"));
    if elf.is_file() {
        Ok(elf)
    } else {
        Err(HarnessError::Backend(format!(
            "PIL: the firmware image {} was not produced",
            elf.display()
        )))
    }
}

/// `pil-comparison.json`: the PIL run against the host run, bit for bit.
#[derive(Clone, Debug, Serialize)]
pub struct Comparison {
    /// Scenario.
    pub scenario: String,
    /// Current ticks compared (both runs).
    pub current_ticks: usize,
    /// Velocity ticks compared (both runs).
    pub velocity_ticks: usize,
    /// Tick counts of the host run (current, velocity), to show nothing is missing.
    pub host_ticks: (usize, usize),
    /// Output values compared.
    pub values_compared: usize,
    /// Output values whose raw bits differ.
    pub mismatches: usize,
    /// Mismatches per output field.
    pub per_field: BTreeMap<String, usize>,
    /// The first differing value.
    pub first_mismatch: Option<Mismatch>,
    /// The controller inputs (encoder, current, setpoint) were identical at every tick.
    pub inputs_identical: bool,
    /// Every trace value (plant states included) identical to the last bit.
    pub trace_identical: bool,
    /// All of the above: the firmware binary controls the machine as the host build does.
    pub bit_identical: bool,
}

/// One differing output value.
#[derive(Clone, Debug, Serialize)]
pub struct Mismatch {
    /// `current` or `velocity` loop.
    pub tick_loop: String,
    /// Tick index within that loop.
    pub index: usize,
    /// Field name.
    pub field: String,
    /// Raw bits on the host.
    pub host_bits: i64,
    /// Raw bits from the firmware.
    pub pil_bits: i64,
}

fn fault_bits(f: Option<Fault>) -> i64 {
    i64::from(pil_link::tick::fault_to_byte(f))
}

fn current_fields(o: &CurrentOutputs) -> [(&'static str, i64); 4] {
    [
        ("voltage_cmd_pu", i64::from(o.voltage_cmd_pu.to_bits())),
        ("current_ref_pu", i64::from(o.current_ref_pu.to_bits())),
        ("accel_fb_pu", i64::from(o.accel_fb_pu.to_bits())),
        ("fault", fault_bits(o.fault)),
    ]
}

fn velocity_fields(o: &VelocityOutputs) -> [(&'static str, i64); 8] {
    [
        ("current_ref_pu", i64::from(o.current_ref_pu.to_bits())),
        ("accel_fb_pu", i64::from(o.accel_fb_pu.to_bits())),
        ("velocity_cmd_pu", i64::from(o.velocity_cmd_pu.to_bits())),
        ("velocity_est_pu", i64::from(o.velocity_est_pu.to_bits())),
        (
            "acceleration_est_pu_s",
            i64::from(o.acceleration_est_pu_s.to_bits()),
        ),
        (
            "position_error_counts",
            i64::from(o.position_error_counts.to_bits()),
        ),
        (
            "disturbance_est_pu",
            i64::from(o.disturbance_est_pu.to_bits()),
        ),
        ("fault", fault_bits(o.fault)),
    ]
}

/// Compares every controller output of two runs bit for bit.
pub fn compare(
    scenario: &str,
    host: &TickLog,
    pil: &TickLog,
    host_run: &RunOutput,
    pil_run: &RunOutput,
) -> Comparison {
    let mut per_field = BTreeMap::new();
    let mut first = None;
    let mut compared = 0;
    let mut mismatches = 0;
    let mut note = |tick_loop: &str,
                    index: usize,
                    host: &[(&'static str, i64)],
                    pil: &[(&'static str, i64)]| {
        for (&(name, h), &(_, p)) in host.iter().zip(pil) {
            compared += 1;
            if h != p {
                mismatches += 1;
                *per_field
                    .entry(format!("{tick_loop}.{name}"))
                    .or_insert(0_usize) += 1;
                if first.is_none() {
                    first = Some(Mismatch {
                        tick_loop: tick_loop.to_string(),
                        index,
                        field: name.to_string(),
                        host_bits: h,
                        pil_bits: p,
                    });
                }
            }
        }
    };
    for (i, ((_, h), (_, p))) in host.current.iter().zip(&pil.current).enumerate() {
        note("current", i, &current_fields(h), &current_fields(p));
    }
    for (i, ((_, h), (_, p))) in host.velocity.iter().zip(&pil.velocity).enumerate() {
        note("velocity", i, &velocity_fields(h), &velocity_fields(p));
    }
    let inputs_identical = host.current.len() == pil.current.len()
        && host.velocity.len() == pil.velocity.len()
        && host
            .current
            .iter()
            .zip(&pil.current)
            .all(|((a, _), (b, _))| a == b)
        && host
            .velocity
            .iter()
            .zip(&pil.velocity)
            .all(|((a, _), (b, _))| a == b);
    let trace_identical = host_run.trace.rows.len() == pil_run.trace.rows.len()
        && host_run
            .trace
            .rows
            .iter()
            .zip(&pil_run.trace.rows)
            .all(|(a, b)| {
                a.values()
                    .iter()
                    .zip(b.values().iter())
                    .all(|(x, y)| x.to_bits() == y.to_bits())
            });
    let complete = host.current.len() == pil.current.len()
        && host.velocity.len() == pil.velocity.len()
        && !pil.current.is_empty();
    Comparison {
        scenario: scenario.to_string(),
        current_ticks: host.current.len().min(pil.current.len()),
        velocity_ticks: host.velocity.len().min(pil.velocity.len()),
        host_ticks: (host.current.len(), host.velocity.len()),
        values_compared: compared,
        mismatches,
        per_field,
        first_mismatch: first,
        inputs_identical,
        trace_identical,
        bit_identical: complete && mismatches == 0 && inputs_identical && trace_identical,
    }
}

/// The REPORT.md section for a PIL run directory (reads `pil-comparison.json` and
/// `pil.json` written by `pil`).
pub fn report_section(dir: &Path) -> Result<String> {
    let read = |name: &str| -> Result<serde_json::Value> {
        let p = dir.join(name);
        let text = std::fs::read_to_string(&p).map_err(|e| HarnessError::io(&p, e))?;
        serde_json::from_str(&text).map_err(|e| HarnessError::io(&p, e))
    };
    let c = read("pil-comparison.json")?;
    let l = read("pil.json")?;
    let n = |v: &serde_json::Value, k: &str| {
        v.get(k)
            .and_then(serde_json::Value::as_f64)
            .unwrap_or(f64::NAN)
    };
    let b = |v: &serde_json::Value, k: &str| {
        v.get(k)
            .and_then(serde_json::Value::as_bool)
            .unwrap_or(false)
    };
    let s = |v: &serde_json::Value, k: &str| {
        v.get(k)
            .and_then(serde_json::Value::as_str)
            .unwrap_or("?")
            .to_string()
    };
    Ok(format_section(
        &s(&c, "scenario"),
        n(&c, "current_ticks"),
        n(&c, "velocity_ticks"),
        n(&c, "values_compared"),
        n(&c, "mismatches"),
        b(&c, "inputs_identical"),
        b(&c, "trace_identical"),
        b(&c, "bit_identical"),
        &s(&l, "firmware_version"),
        n(&l, "frames"),
        n(&l, "round_trip_us"),
        n(&l, "wall_time_s"),
        &c.get("first_mismatch")
            .map(ToString::to_string)
            .unwrap_or_default(),
    ))
}

fn section_text(c: &Comparison, l: &LinkReport) -> String {
    format_section(
        &c.scenario,
        c.current_ticks as f64,
        c.velocity_ticks as f64,
        c.values_compared as f64,
        c.mismatches as f64,
        c.inputs_identical,
        c.trace_identical,
        c.bit_identical,
        &l.firmware_version,
        l.frames as f64,
        l.round_trip_us,
        l.wall_time_s,
        &c.first_mismatch
            .as_ref()
            .map(|m| format!("{m:?}"))
            .unwrap_or_default(),
    )
}

#[allow(clippy::too_many_arguments)]
fn format_section(
    scenario: &str,
    current_ticks: f64,
    velocity_ticks: f64,
    values: f64,
    mismatches: f64,
    inputs_identical: bool,
    trace_identical: bool,
    bit_identical: bool,
    firmware_version: &str,
    frames: f64,
    round_trip_us: f64,
    wall_time_s: f64,
    first_mismatch: &str,
) -> String {
    let verdict = if bit_identical {
        "**bit-identical**: the firmware binary on the Cortex-M4F controls the simulated \
         machine exactly as the host build of controller-core does"
    } else {
        "**NOT bit-identical**"
    };
    let mut text = format!(
        "## Processor in the loop: `{scenario}` through the firmware in QEMU\n\n\
         Command: `cargo run --release -- pil --scenario {scenario} --out DIR`.\n\
         The firmware's `pil` image (version {firmware_version}) runs in QEMU mps2-an386 \
         (Cortex-M4F); every controller tick the harness sends the sampled encoder count and \
         current (or the velocity setpoint) in a CRC-32 framed `pil-link` frame over UART0, the \
         firmware pends its TIMER0/TIMER1 interrupt, whose handler runs the drive's interrupt \
         body, and returns the commands; the harness then advances the plant. Lock step, so \
         QEMU's speed does not matter.\n\n\
         | quantity | value |\n|---|---|\n\
         | current ticks compared | {current_ticks:.0} |\n\
         | velocity ticks compared | {velocity_ticks:.0} |\n\
         | output values compared (raw fixed-point bits) | {values:.0} |\n\
         | mismatches | {mismatches:.0} |\n\
         | controller inputs identical | {inputs_identical} |\n\
         | trace (plant states included) identical | {trace_identical} |\n\
         | link frames | {frames:.0} |\n\
         | mean wall time per frame (QEMU round trip + plant step) | {round_trip_us:.0} µs |\n\
         | wall time of the closed loop | {wall_time_s:.1} s |\n\n\
         Verdict: {verdict}.\n"
    );
    if !first_mismatch.is_empty() && first_mismatch != "null" {
        text.push_str(&format!("\nFirst mismatch: `{first_mismatch}`\n"));
    }
    text
}

/// The REPORT.md section for the PIL run in `dir`, or, if there is none, a paragraph
/// saying how to produce it (the PIL run needs QEMU and the ARM image, which `reproduce`
/// may not have).
pub fn report_section_or_hint(dir: &Path) -> String {
    report_section(dir).unwrap_or_else(|_| {
        format!(
            "## Processor in the loop\n\nNo PIL run in `{}`. Produce it with \
             `cargo run --release -- pil --scenario fig6 --out {}` \
             (needs qemu-system-arm and the thumbv7em-none-eabihf target); it compares \
             every controller output of the firmware in QEMU with the host run, bit for bit.\n",
            dir.display(),
            dir.display()
        )
    })
}

/// For `reproduce`: runs `fig6` through the firmware into `dir` (building the image) and
/// returns the REPORT.md section; if that is impossible here (no QEMU, no ARM target, a
/// link fault), returns a section that says why and how to run it.
pub fn run_for_report(dir: &Path) -> String {
    let args = PilArgs::new("fig6", dir);
    match pil_command(&args) {
        Ok(_) => report_section_or_hint(dir),
        Err(e) => format!(
            "## Processor in the loop\n\nThe PIL run of `fig6` did not complete here: {e}.\n\n{}",
            report_section_or_hint(dir)
        ),
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;
    use crate::trace::{Trace, TraceRow};
    use controller_core::Pu;

    fn log(n: usize) -> TickLog {
        let mut l = TickLog::default();
        for k in 0..n {
            let i = CurrentInputs {
                encoder_count: k as u32,
                current_pu: Pu::from_bits(k as i32),
            };
            let o = CurrentOutputs {
                voltage_cmd_pu: Pu::from_bits(3 * k as i32),
                ..CurrentOutputs::default()
            };
            l.current.push((i, o));
            if k % 2 == 0 {
                l.velocity
                    .push((VelocityInputs::default(), VelocityOutputs::default()));
            }
        }
        l
    }

    fn run_of(rows: usize) -> RunOutput {
        let trace = Trace {
            rows: (0..rows)
                .map(|k| TraceRow {
                    t_s: k as f64 * 5e-4,
                    ..TraceRow::default()
                })
                .collect(),
        };
        let windows = resolve("fig6", None, &[])
            .unwrap()
            .scenario
            .metric_windows(2.0);
        let metrics = compute(&trace, &windows);
        RunOutput {
            trace,
            metrics,
            sim_time_s: 0.0,
            wall_time_s: 0.0,
            ticks: 0,
        }
    }

    #[test]
    fn identical_logs_compare_bit_identical() {
        let c = compare("t", &log(10), &log(10), &run_of(5), &run_of(5));
        assert!(c.bit_identical, "{c:?}");
        assert_eq!(c.values_compared, 10 * 4 + 5 * 8);
    }

    #[test]
    fn one_lsb_anywhere_is_a_mismatch() {
        let host = log(10);
        let mut pil = log(10);
        pil.current[7].1.voltage_cmd_pu =
            Pu::from_bits(pil.current[7].1.voltage_cmd_pu.to_bits() + 1);
        pil.velocity[3].1.fault = Some(Fault::External);
        let c = compare("t", &host, &pil, &run_of(5), &run_of(5));
        assert!(!c.bit_identical);
        assert_eq!(c.mismatches, 2);
        assert_eq!(c.per_field.get("current.voltage_cmd_pu"), Some(&1));
        assert_eq!(c.per_field.get("velocity.fault"), Some(&1));
        let m = c.first_mismatch.unwrap();
        assert_eq!((m.tick_loop.as_str(), m.index), ("current", 7));
    }

    #[test]
    fn missing_ticks_or_trace_rows_are_not_identical() {
        let c = compare("t", &log(10), &log(9), &run_of(5), &run_of(5));
        assert!(!c.bit_identical && !c.inputs_identical);
        let mut other = run_of(5);
        other.trace.rows[2].motor_vel_pu = 1e-300;
        let c = compare("t", &log(10), &log(10), &run_of(5), &other);
        assert!(!c.bit_identical && !c.trace_identical);
    }

    #[test]
    fn the_trace_is_cut_before_the_fault() {
        let cfg = resolve("fig6", None, &[]).unwrap();
        let mut run = run_of(100);
        cut_at(&mut run, &cfg, 0.01);
        assert_eq!(run.trace.rows.len(), 20);
        assert!(run.trace.rows.iter().all(|r| r.t_s < 0.01));
    }
}
