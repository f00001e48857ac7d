//! One PIL session: QEMU started on the firmware image, Hello and drive settings over the
//! link, the scenario run in lock step, and on a link fault the firmware's latched safe
//! state read back; then the files of the run directory.

use crate::backend::{PilBackend, Recorder, TickLog};
use crate::compare::{compare, Comparison};
use crate::image::build_pil_image;
use crate::settings::PilRun;
use controller_core::excitation::ExcitationConfig;
use fw_runner::defmt_log::{LineFormat, LogDecoder};
use fw_runner::provision;
use pil_link::host::{FaultPlan, HostError, HostLink, Stream};
use pil_link::qemu::{Machine, Qemu, QemuOptions};
use pil_link::wire::Writer;
use pil_link::{FaultReport, HelloAck};
use serde::{Deserialize, Serialize};
use sim_engine::config::{resolve, RunConfig};
use sim_engine::engine::metrics::compute;
use sim_engine::engine::runner::{run_with_backend, RunOutput};
use sim_engine::error::{HarnessError, Result};
use sim_engine::output::Staging;
use sim_engine::run::write_run;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// The firmware's `Fault` report, as written to `pil.json`.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq, Eq)]
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
#[derive(Clone, Debug, Serialize, Deserialize)]
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
#[derive(Clone, Debug, Serialize, Deserialize)]
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

/// The scenario as the firmware can run it. The link carries drive settings, not gains:
/// the firmware designs its own, so a comparison run whose borrowed gains differ from its
/// own design cannot run there.
fn resolve_for_firmware(args: &PilRun) -> Result<RunConfig> {
    let cfg = resolve(&args.scenario, args.config.as_deref(), &args.set)?;
    // One design for a run of its own gains (the firmware designs the same from the same
    // settings); a comparison run is checked against its own design as well.
    own_design(&cfg, cfg.gains_of.is_some())?;
    Ok(cfg)
}

/// Whether the firmware, designing its gains from the drive settings, runs `cfg`'s gains:
/// checked for a comparison run (`borrowed`) or always (`with_firmware`).
fn own_design(cfg: &RunConfig, check: bool) -> Result<()> {
    let gains = sim_engine::engine::runner::regulator_gains(cfg)?;
    if check && Ok(gains) != controller_core::design(&cfg.drive) {
        return Err(HarnessError::config(
            "scenario.comparison.gains_of",
            format!(
                "{} borrows gains that differ from its own design; the firmware designs its \
                 gains from the drive settings, so this run cannot go through PIL",
                cfg.name
            ),
        ));
    }
    Ok(())
}

/// QEMU running the image, with the link through Hello and the drive settings.
struct Session {
    qemu: Qemu,
    link: HostLink<Stream>,
    ack: HelloAck,
}

impl Session {
    fn open(
        args: &PilRun,
        cfg: &RunConfig,
        excitation: Option<&ExcitationConfig>,
        elf: &Path,
        log: &Path,
    ) -> Result<Self> {
        let (qemu, stream) = Qemu::spawn(&QemuOptions {
            qemu: args.qemu.clone(),
            elf: elf.to_path_buf(),
            log: log.to_path_buf(),
            connect_timeout: Duration::from_secs(20),
            port: args.port,
            machine: Machine::default(),
        })
        .map_err(|e| HarnessError::Backend(format!("PIL: {e}")))?;
        let mut link = HostLink::new(stream, Duration::from_millis(args.reply_timeout_ms));
        let ack = match link.hello(args.watchdog_ms) {
            Ok(ack) => ack,
            Err(e) => return Err(qemu_error(&qemu, "hello", e)),
        };
        let mut w = Writer::new();
        let sent = pil_link::run_config::encode(&cfg.drive, excitation, &mut w)
            .map_err(HostError::Link)
            .and_then(|()| link.configure(w.as_slice()));
        match sent {
            Ok(()) => Ok(Self { qemu, link, ack }),
            Err(e) => Err(qemu_error(&qemu, "config", e)),
        }
    }
}

/// A link error at `stage`, with what QEMU printed.
fn qemu_error(qemu: &Qemu, stage: &str, e: HostError) -> HarnessError {
    let stderr = qemu.stderr();
    let stderr = stderr.trim();
    HarnessError::Backend(format!(
        "PIL {stage}: {e} (QEMU stderr: {})",
        if stderr.is_empty() { "empty" } else { stderr }
    ))
}

/// After the run: a clean stop, or the fault with the firmware's latched state read back
/// (silence long enough for its watchdog first) and the trace cut before it.
fn settle(
    backend: &mut PilBackend,
    qemu: &Qemu,
    args: &PilRun,
    cfg: &RunConfig,
    run: &mut RunOutput,
) -> Result<Option<LinkFault>> {
    let Some((error, at)) = backend.fault.take() else {
        return match backend.stop() {
            Ok(()) => Ok(None),
            Err(e) => Err(qemu_error(qemu, "stop", e)),
        };
    };
    let already = match &error {
        HostError::FirmwareFault(r) => Some(*r),
        _ => None,
    };
    let wait = Duration::from_millis(u64::from(args.watchdog_ms) * 2 + 500);
    let report = backend.link.confirm_safe_state(already, wait);
    let tc_s = 1.0 / f64::from(cfg.drive.current_rate_hz.max(1));
    let t_s = at as f64 * tc_s;
    cut_at(run, cfg, t_s);
    Ok(Some(LinkFault {
        harness_error: error.to_string(),
        detected_by_firmware: already.is_some(),
        at_current_tick: at,
        t_s,
        firmware: report.map(FirmwareFault::from),
    }))
}

fn link_report(
    ack: &HelloAck,
    args: &PilRun,
    frames: u64,
    wall_time_s: f64,
    qemu_exit_code: Option<i32>,
    fault: Option<LinkFault>,
) -> LinkReport {
    let v = ack.firmware_version;
    LinkReport {
        protocol_version: ack.protocol_version,
        firmware_version: format!("{}.{}.{}", v >> 16, (v >> 8) & 0xFF, v & 0xFF),
        watchdog_ms: ack.watchdog_ms,
        injected: args.inject.clone(),
        frames,
        wall_time_s,
        round_trip_us: if frames > 0 {
            wall_time_s * 1e6 / frames as f64
        } else {
            0.0
        },
        qemu_exit_code,
        fault,
    }
}

/// The fault to inject, the firmware image (built if not given) and QEMU (installed if it
/// is the default binary and missing).
fn prepare(args: &PilRun) -> Result<(Option<FaultPlan>, PathBuf)> {
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
    Ok((plan, elf))
}

/// Runs a scenario through the firmware in QEMU and writes its files (see the module docs).
/// A link fault is not an `Err` here: it is in `link.fault`, with the trace cut before it.
pub fn run_pil(args: &PilRun) -> Result<PilOutcome> {
    args.check()?;
    let cfg = resolve_for_firmware(args)?;
    // The output directory is checked before the image is built and QEMU provisioned.
    let staging = Staging::new(&args.out)?;
    let (plan, elf) = prepare(args)?;
    let log_path = staging.path("firmware.defmt")?;
    let Session {
        mut qemu,
        mut link,
        ack,
    } = Session::open(args, &cfg, None, &elf, &log_path)?;
    if let Some(p) = plan {
        link.inject(p);
    }
    let mut backend = PilBackend::new(link);
    let start = Instant::now();
    let mut run = run_with_backend(&cfg, &mut backend)?;
    let wall_time_s = start.elapsed().as_secs_f64();
    let frames = backend.link.sensors_sent();
    let fault = settle(&mut backend, &qemu, args, &cfg, &mut run)?;
    let exit = qemu.finish(Duration::from_secs(5));
    drop(qemu);
    if let Some(p) = plan.filter(|p| fault.is_none() && p.at_tick >= frames) {
        return Err(HarnessError::config(
            "--inject",
            format!(
                "sensor frame {} is past the end of the run ({frames} sensor frames): \
                 nothing was injected",
                p.at_tick
            ),
        ));
    }
    let link = link_report(
        &ack,
        args,
        frames,
        wall_time_s,
        exit.and_then(|s| s.code()),
        fault,
    );
    run.wall_time_s = wall_time_s;
    let comparison = if link.fault.is_none() && !args.no_compare {
        Some(compare_with_host(&cfg, &backend.log, &run)?)
    } else {
        None
    };
    if link.fault.is_none() {
        // The oscillation rule's step 5: a limit cycle is rerun with the encoder
        // interpolated, on the host build of controller-core (the firmware image counts the
        // encoder of the run); a run cut at a link fault keeps its verdict unconfirmed.
        sim_engine::engine::runner::confirm_limit_cycle(&cfg, &mut run);
    }
    write_files(
        &staging,
        &cfg,
        &run,
        &link,
        comparison.as_ref(),
        &elf,
        &log_path,
    )?;
    // The commit replaces the whole directory: no comparison of an earlier run survives.
    staging.commit()?;
    Ok(PilOutcome {
        run,
        cfg,
        link,
        comparison,
        out: args.out.clone(),
    })
}

/// Runs `f` with the firmware in QEMU as its control backend, configured with `cfg`'s drive
/// settings and `excitation`, if any: how a run that drives its backend itself (the
/// identification's records, `machine_workflows::identify::measure::record`) goes through the
/// firmware. The firmware's defmt log goes to `firmware.defmt` in `args.out`; `args`'
/// scenario is not used. A link fault, seen by either side, is an error.
pub fn with_firmware<T>(
    args: &PilRun,
    cfg: &RunConfig,
    excitation: Option<&ExcitationConfig>,
    f: impl FnOnce(&mut PilBackend) -> Result<T>,
) -> Result<T> {
    args.check()?;
    own_design(cfg, true)?;
    let (plan, elf) = prepare(args)?;
    std::fs::create_dir_all(&args.out).map_err(|e| HarnessError::io(&args.out, e))?;
    let Session {
        mut qemu, mut link, ..
    } = Session::open(
        args,
        cfg,
        excitation,
        &elf,
        &args.out.join("firmware.defmt"),
    )?;
    if let Some(p) = plan {
        link.inject(p);
    }
    let mut backend = PilBackend::new(link);
    let out = f(&mut backend);
    let end = match backend.fault.take() {
        Some((e, at)) => Err(HarnessError::Backend(format!(
            "PIL link fault at current tick {at}: {e}"
        ))),
        None => backend.stop().map_err(|e| qemu_error(&qemu, "stop", e)),
    };
    let _ = qemu.finish(Duration::from_secs(5));
    end.and(out)
}

/// The same scenario on the host build of controller-core, compared bit for bit.
fn compare_with_host(cfg: &RunConfig, pil: &TickLog, pil_run: &RunOutput) -> Result<Comparison> {
    let mut host = Recorder {
        inner: sim_engine::engine::runner::controller(cfg)?,
        log: TickLog::default(),
    };
    let host_run = run_with_backend(cfg, &mut host)?;
    Ok(compare(&cfg.name, &host.log, pil, &host_run, pil_run))
}

fn write_files(
    staging: &Staging,
    cfg: &RunConfig,
    run: &RunOutput,
    link: &LinkReport,
    comparison: Option<&Comparison>,
    elf: &Path,
    log_path: &Path,
) -> Result<()> {
    write_run(staging.dir(), cfg, run)?;
    write_json(staging, "pil.json", link)?;
    if let Some(c) = comparison {
        write_json(staging, "pil-comparison.json", c)?;
        staging.write("pil-comparison.md", &crate::comparison_markdown(c, link))?;
    }
    decode_log(elf, log_path, staging)
}

/// Drops trace rows at or after `t_s` and recomputes the metrics on what is left.
pub(super) fn cut_at(run: &mut RunOutput, cfg: &RunConfig, t_s: f64) {
    run.trace.rows.retain(|r| r.t_s < t_s - 1e-12);
    run.sim_time_s = t_s;
    run.ticks = (t_s * f64::from(cfg.drive.current_rate_hz)).round() as u64;
    let windows = cfg.metric_windows();
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
    let bytes = pil_link::qemu::log_bytes(&bytes);
    let lines = match LogDecoder::from_elf(elf) {
        Ok(d) => d.decode_all(bytes, LineFormat::Full),
        Err(e) => vec![format!("(defmt log not decoded: {e})")],
    };
    let mut text = lines.join("\n");
    text.push('\n');
    staging.write("firmware.log", &text).map(|_| ())
}
