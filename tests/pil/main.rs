//! Processor in the loop, end to end: the firmware's `pil` image, built for
//! the Cortex-M4F, runs in QEMU and controls the simulated machine through `pil-link`.
//!
//! * `fig6` through the firmware matches the host build bit for bit (every controller
//!   output of every tick, and the whole trace);
//! * corrupted, dropped, late and out-of-sequence frames, in either direction, are detected;
//!   the firmware latches its safe state (zero torque and voltage, fault latched, QEMU exits
//!   with status 1) and the harness reports the fault, stops, and writes the trace up to it.
//!
//! These tests build the ARM image themselves (cargo, thumbv7em-none-eabihf) and run it in
//! `qemu-system-arm`. On a fresh machine they install what is missing first (`rustup target
//! add`, and `apt-get install qemu-system-arm` as root, one line printed for each); where
//! that is impossible they FAIL with the command to run. They are never skipped.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use pil_host::{build_pil_image, build_pil_image_with, pil_command, run_pil, PilRun};
use pil_link::host::{HostError, HostLink, Stream};
use pil_link::qemu::{LinkPort, Machine, Qemu, QemuOptions};
use pil_link::FaultCode;
use std::path::PathBuf;
use std::sync::OnceLock;
use std::time::{Duration, Instant};

mod board;
mod board_calibrate;
mod board_identify;
mod pil_identify;

/// Every QEMU case of this binary, in one test that sets its own concurrency, in three
/// phases:
///
/// 1. the two long bit-for-bit runs side by side (each a QEMU and a host thread in lock
///    step: about one core each, with the default 1 s link watchdog);
/// 2. the other processor-in-the-loop cases one after another, alone on the machine (the
///    fault cases use a 500 ms link watchdog);
/// 3. beside `identify --board` (which records from the board's own tick source, the same
///    record however loaded the host is), one after another: the two serial-device cases
///    (lock step with the default 1 s watchdog, as in phase 1), the board console's
///    cases (the console waits for replies) and the PMSM board's calibration and
///    `identify --board` (from the board's tick source too).
///
/// So at most two QEMU sessions run at once, and no other test binary runs meanwhile (cargo
/// runs test binaries one after another). A failing case is named in the test's output.
#[test]
fn qemu_sessions() {
    let pil_cases: [(&str, fn()); 9] = [
        (
            "fig6_through_the_firmware_is_bit_identical_to_the_host_run",
            fig6_through_the_firmware_is_bit_identical_to_the_host_run,
        ),
        (
            "link_faults_latch_the_safe_state_on_both_sides",
            link_faults_latch_the_safe_state_on_both_sides,
        ),
        (
            "the_command_fails_loudly_on_a_link_fault",
            the_command_fails_loudly_on_a_link_fault,
        ),
        (
            "a_firmware_that_keeps_its_outputs_on_fails_the_safe_state_check",
            a_firmware_that_keeps_its_outputs_on_fails_the_safe_state_check,
        ),
        (
            "the_firmware_refuses_an_unbounded_watchdog_with_a_protocol_fault",
            the_firmware_refuses_an_unbounded_watchdog_with_a_protocol_fault,
        ),
        (
            "a_second_config_while_running_is_a_protocol_fault",
            a_second_config_while_running_is_a_protocol_fault,
        ),
        (
            "qemu_ends_by_itself_when_the_harness_goes_silent",
            qemu_ends_by_itself_when_the_harness_goes_silent,
        ),
        (
            "pil_identify: the_frequency_response_record_through_the_firmware_is_the_host_record_bit_for_bit",
            crate::pil_identify::the_frequency_response_record_through_the_firmware_is_the_host_record_bit_for_bit,
        ),
        (
            "pil_identify: the_firmware_refuses_a_bad_excitation_with_a_config_fault",
            crate::pil_identify::the_firmware_refuses_a_bad_excitation_with_a_config_fault,
        ),
    ];
    let beside_identify: [(&str, fn()); 9] = [
        (
            "the_link_over_a_serial_device_is_bit_identical_too",
            the_link_over_a_serial_device_is_bit_identical_too,
        ),
        (
            "a_late_reader_on_a_serial_device_still_gets_the_stop_reply",
            a_late_reader_on_a_serial_device_still_gets_the_stop_reply,
        ),
        (
            "board: set_save_reset_get_prints_the_saved_value",
            crate::board::set_save_reset_get_prints_the_saved_value,
        ),
        (
            "board: a_set_while_enabled_or_out_of_range_is_refused_naming_the_key",
            crate::board::a_set_while_enabled_or_out_of_range_is_refused_naming_the_key,
        ),
        (
            "board: refused_sets_leave_the_drive_unchanged_and_a_corrupt_frame_disables_it",
            crate::board::refused_sets_leave_the_drive_unchanged_and_a_corrupt_frame_disables_it,
        ),
        (
            "board: scope_writes_a_second_of_samples_at_the_trace_rate_without_gaps",
            crate::board::scope_writes_a_second_of_samples_at_the_trace_rate_without_gaps,
        ),
        (
            "board: netduinoplus2_serves_the_console_and_save_reports_the_missing_flash_controller",
            crate::board::netduinoplus2_serves_the_console_and_save_reports_the_missing_flash_controller,
        ),
        (
            "board: a_pmsm_board_refuses_to_enable_until_calibrated_and_keeps_its_calibration",
            crate::board_calibrate::a_pmsm_board_refuses_to_enable_until_calibrated_and_keeps_its_calibration,
        ),
        (
            "board: identify_on_the_board_calibrates_a_pmsm_no_config_describes",
            crate::board_calibrate::identify_on_the_board_calibrates_a_pmsm_no_config_describes,
        ),
    ];
    let long = [
        "fig6_through_the_firmware_is_bit_identical_to_the_host_run",
        "pil_identify: the_frequency_response_record_through_the_firmware_is_the_host_record_bit_for_bit",
    ];
    let (side_by_side, one_by_one): (Vec<_>, Vec<_>) = pil_cases
        .into_iter()
        .partition(|(name, _)| long.contains(name));
    assert_eq!(side_by_side.len(), long.len());
    std::thread::scope(|s| {
        for (name, case) in side_by_side {
            s.spawn(move || run_case(name, case));
        }
    });
    for (name, case) in one_by_one {
        run_case(name, case);
    }
    std::thread::scope(|s| {
        s.spawn(move || {
            beside_identify
                .into_iter()
                .for_each(|(n, c)| run_case(n, c))
        });
        s.spawn(|| {
            run_case(
                "board: identify_on_the_board_with_its_defaults_recovers_the_qemu_machine",
                crate::board_identify::identify_on_the_board_with_its_defaults_recovers_the_qemu_machine,
            );
        });
    });
}

fn run_case(name: &str, case: fn()) {
    let t0 = Instant::now();
    eprintln!("processor in the loop: {name}");
    case();
    eprintln!(
        "processor in the loop: {name} passed in {:.1} s",
        t0.elapsed().as_secs_f64()
    );
}

/// The `pil` ELF, built once per test binary.
fn elf() -> PathBuf {
    static ELF: OnceLock<PathBuf> = OnceLock::new();
    ELF.get_or_init(|| {
        fw_runner::provision::ensure_qemu()
            .unwrap_or_else(|e| panic!("the processor-in-the-loop tests need QEMU: {e}"));
        build_pil_image().unwrap_or_else(|e| panic!("cannot build the PIL firmware image: {e}"))
    })
    .clone()
}

fn csv_rows(dir: &std::path::Path) -> usize {
    let text = std::fs::read_to_string(dir.join("trace.csv")).expect("trace.csv written");
    text.lines().count() - 1
}

fn fig6_through_the_firmware_is_bit_identical_to_the_host_run() {
    let dir = tempfile::tempdir().unwrap();
    let mut args = PilRun::new("fig6", dir.path());
    args.elf = Some(elf());
    let o = run_pil(&args).unwrap();
    assert!(o.link.fault.is_none(), "link fault: {:?}", o.link.fault);
    assert_eq!(
        o.link.qemu_exit_code,
        Some(0),
        "the firmware exits cleanly on Stop"
    );
    let c = o.comparison.expect("compared with the host run");
    // fig6: 2.5 s at 4 kHz / 2 kHz.
    assert_eq!((c.current_ticks, c.velocity_ticks), (10_000, 5_000));
    assert_eq!(c.host_ticks, (10_000, 5_000));
    assert_eq!(c.values_compared, 10_000 * 4 + 5_000 * 8);
    assert_eq!(c.mismatches, 0, "first mismatch: {:?}", c.first_mismatch);
    assert!(c.inputs_identical && c.trace_identical && c.bit_identical);
    assert_eq!(o.link.frames, 15_000);
    // The same files as `run`, plus the comparison.
    for f in [
        "trace.csv",
        "summary.json",
        "pil.json",
        "pil-comparison.json",
        "pil-comparison.md",
        "firmware.defmt",
    ] {
        assert!(dir.path().join(f).is_file(), "{f} missing");
    }
    assert_eq!(csv_rows(dir.path()), 5_000);
    // The defmt log, decoded in-process: the boot line, the configuration, the clean stop.
    let log = std::fs::read_to_string(dir.path().join("firmware.log")).unwrap();
    for line in [
        "waiting for Hello on UART0",
        "pil: configured, current loop 4000 Hz, velocity loop 2000 Hz",
        "pil: stopped after 15000 ticks, faulted false",
    ] {
        assert!(log.contains(line), "firmware.log lacks {line:?}:\n{log}");
    }
    assert!(!log.contains("damaged frame"), "{log}");
    let section = paper_repro::report::pil::report_section(dir.path()).unwrap();
    assert!(section.contains("| mismatches | 0 |"), "{section}");
}

/// One injected fault: what the harness must report and what the firmware must latch.
struct Case {
    inject: &'static str,
    /// Fault code the firmware must report.
    firmware_code: &'static str,
    /// True when the firmware, not the harness, must see it first.
    firmware_first: bool,
    /// Text the harness's error must contain.
    harness_says: &'static str,
    /// Harness reply deadline (ms); the firmware watchdog is 500 ms.
    reply_timeout_ms: u64,
}

/// The first half second of `fig6` with QEMU's UART on a pseudo-terminal that the harness
/// opens as a serial device (termios raw mode, read timeouts): the code path a board's
/// `/dev/ttyACM0` takes. The run is the host's bit for bit, and the firmware's log (on the
/// same QEMU stdout as the pseudo-terminal's notice) decodes.
fn the_link_over_a_serial_device_is_bit_identical_too() {
    let dir = tempfile::tempdir().unwrap();
    let mut args = PilRun::new("fig6", dir.path());
    args.elf = Some(elf());
    args.port = pil_host::LinkPort::Pty;
    args.set = vec!["scenario.duration_s=0.5".into()];
    let o = run_pil(&args).unwrap();
    assert!(o.link.fault.is_none(), "link fault: {:?}", o.link.fault);
    let c = o.comparison.expect("compared with the host run");
    assert_eq!((c.current_ticks, c.velocity_ticks), (2_000, 1_000));
    assert_eq!(c.mismatches, 0, "first mismatch: {:?}", c.first_mismatch);
    assert!(c.bit_identical);
    let log = std::fs::read_to_string(dir.path().join("firmware.log")).unwrap();
    assert!(log.contains("waiting for Hello on UART0"), "{log}");
    assert!(log.contains("stopped after 3000 ticks"), "{log}");
}

fn link_faults_latch_the_safe_state_on_both_sides() {
    let elf = elf();
    let cases = [
        // A bit flipped in a sensor frame: the firmware's CRC check.
        Case {
            inject: "corrupt@301:12",
            firmware_code: "BadCrc",
            firmware_first: true,
            harness_says: "BadCrc",
            reply_timeout_ms: 3000,
        },
        // A sensor frame lost: the firmware's watchdog (nothing arrives).
        Case {
            inject: "drop@450",
            firmware_code: "Timeout",
            firmware_first: true,
            harness_says: "Timeout",
            reply_timeout_ms: 3000,
        },
        // A sensor frame late by twice the watchdog.
        Case {
            inject: "delay@600:1000",
            firmware_code: "Timeout",
            firmware_first: true,
            harness_says: "Timeout",
            reply_timeout_ms: 3000,
        },
        // A frame lost in a stream: the sequence gap.
        Case {
            inject: "skip-seq@200",
            firmware_code: "OutOfSequence",
            firmware_first: true,
            harness_says: "OutOfSequence",
            reply_timeout_ms: 3000,
        },
        // A bit flipped in the firmware's reply: the harness's CRC check; then the
        // firmware, hearing nothing more, must latch on its watchdog.
        Case {
            inject: "corrupt-reply@500:9",
            firmware_code: "Timeout",
            firmware_first: false,
            harness_says: "bad CRC",
            reply_timeout_ms: 3000,
        },
        // A reply lost, with the harness's deadline shorter than the firmware's watchdog:
        // the harness sees the loss first (its own timeout), then the firmware latches.
        Case {
            inject: "drop-reply@700",
            firmware_code: "Timeout",
            firmware_first: false,
            harness_says: "no frame within 250 ms",
            reply_timeout_ms: 250,
        },
    ];
    for case in cases {
        let dir = tempfile::tempdir().unwrap();
        let mut args = PilRun::new("fig6", dir.path());
        args.elf = Some(elf.clone());
        args.inject = Some(case.inject.to_string());
        args.watchdog_ms = 500;
        args.reply_timeout_ms = case.reply_timeout_ms;
        let o = run_pil(&args).unwrap();
        let fault = o
            .link
            .fault
            .as_ref()
            .unwrap_or_else(|| panic!("{}: no fault reported", case.inject));
        assert!(
            fault.harness_error.contains(case.harness_says),
            "{}: harness said {:?}",
            case.inject,
            fault.harness_error
        );
        assert_eq!(
            fault.detected_by_firmware, case.firmware_first,
            "{}",
            case.inject
        );
        // The safe state, from the board's outputs as the fault frame carries them: the
        // current tick ran, zero torque, zero PWM voltage, enable pin low.
        let fw = fault
            .firmware
            .as_ref()
            .unwrap_or_else(|| panic!("{}: firmware never showed its safe state", case.inject));
        assert_eq!(fw.code, case.firmware_code, "{}", case.inject);
        assert!(
            fw.current_tick_ran
                && fw.torque_cmd_bits == 0
                && fw.pwm_voltage_bits == 0
                && !fw.enable_pin,
            "{}: {fw:?}",
            case.inject
        );
        assert!(fw.outputs_safe, "{}", case.inject);
        assert_eq!(
            o.link.qemu_exit_code,
            Some(1),
            "{}: firmware must end faulted",
            case.inject
        );
        // Sensor frame k is the k-th of the pattern [velocity, current, current] repeated
        // (fig6: 2 current ticks per velocity tick), so the run stopped at current tick
        // floor(2k/3) or just after it, and the trace holds only the rows before that.
        let frame: u64 = case.inject[case.inject.find('@').unwrap() + 1..]
            .split(':')
            .next()
            .unwrap()
            .parse()
            .unwrap();
        let at = fault.at_current_tick;
        assert!(
            at == frame * 2 / 3 || at == frame * 2 / 3 + 1,
            "{}: stopped at current tick {at}",
            case.inject
        );
        let rows = csv_rows(dir.path());
        assert_eq!(
            rows as u64,
            at.div_ceil(2),
            "{}: trace cut at the fault",
            case.inject
        );
        assert!(o.run.trace.rows.iter().all(|r| r.t_s < fault.t_s));
        assert!(o.comparison.is_none());
    }
}

fn the_command_fails_loudly_on_a_link_fault() {
    let dir = tempfile::tempdir().unwrap();
    let mut args = PilRun::new("fig6", dir.path());
    args.elf = Some(elf());
    args.inject = Some("corrupt@40".to_string());
    let err = pil_command(&args).unwrap_err().to_string();
    assert!(
        err.contains("PIL link fault") && err.contains("BadCrc"),
        "{err}"
    );
    // The trace up to the fault is still there.
    assert!(csv_rows(dir.path()) > 0);
}

/// QEMU with the `pil` image and the raw link to it, for tests that speak the protocol
/// themselves (below the harness's own argument checks).
fn raw_session(elf: &std::path::Path, log: &std::path::Path) -> (Qemu, HostLink<Stream>) {
    raw_session_on(elf, log, LinkPort::Socket)
}

fn raw_session_on(
    elf: &std::path::Path,
    log: &std::path::Path,
    port: LinkPort,
) -> (Qemu, HostLink<Stream>) {
    let (qemu, stream) = Qemu::spawn(&QemuOptions {
        qemu: PathBuf::from("qemu-system-arm"),
        elf: elf.to_path_buf(),
        log: log.to_path_buf(),
        connect_timeout: Duration::from_secs(20),
        port,
        machine: Machine::default(),
    })
    .unwrap();
    (qemu, HostLink::new(stream, Duration::from_secs(3)))
}

fn a_firmware_that_keeps_its_outputs_on_fails_the_safe_state_check() {
    fw_runner::provision::ensure_qemu().unwrap();
    // The same image with the safe-state entry sabotaged (enable stays on, controller runs).
    let bad = build_pil_image_with(&["test-unsafe-keep-outputs-on"]).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let mut args = PilRun::new("fig6", dir.path());
    args.elf = Some(bad);
    args.inject = Some("drop@450".to_string());
    args.watchdog_ms = 500;
    args.reply_timeout_ms = 3000;
    let o = run_pil(&args).unwrap();
    let fw = o
        .link
        .fault
        .as_ref()
        .and_then(|f| f.firmware.clone())
        .expect("fault report");
    assert_eq!(fw.code, "Timeout");
    assert!(
        !fw.outputs_safe,
        "a firmware with its outputs on passed: {fw:?}"
    );
    assert!(fw.enable_pin, "{fw:?}");
    // And the command says so.
    let dir2 = tempfile::tempdir().unwrap();
    args.out = dir2.path().to_path_buf();
    let err = pil_command(&args).unwrap_err().to_string();
    assert!(err.contains("NOT SAFE"), "{err}");
}

fn the_firmware_refuses_an_unbounded_watchdog_with_a_protocol_fault() {
    let elf = elf();
    let dir = tempfile::tempdir().unwrap();
    let start = Instant::now();
    let (mut qemu, mut link) = raw_session(&elf, &dir.path().join("fw.defmt"));
    match link.hello(u32::MAX) {
        Err(HostError::FirmwareFault(r)) => {
            assert_eq!(r.code, FaultCode::Protocol);
            // Refused before any Config: no controller runs, the stage stays off.
            assert!(!r.outputs.current_tick_ran, "{:?}", r.outputs);
            assert!(r.outputs.are_safe(), "{:?}", r.outputs);
        }
        other => panic!("a Hello with a 49-day watchdog was not refused: {other:?}"),
    }
    drop(link);
    qemu.finish(Duration::from_secs(1));
    assert!(
        start.elapsed() < Duration::from_secs(5),
        "{:?}",
        start.elapsed()
    );

    // The harness refuses it before it starts anything, naming the flag and the range.
    let out = dir.path().join("out");
    let mut args = PilRun::new("fig6", &out);
    args.elf = Some(elf);
    args.watchdog_ms = u32::MAX;
    args.inject = Some("drop@100".to_string());
    let start = Instant::now();
    let Err(err) = run_pil(&args) else {
        panic!("a 49-day watchdog was accepted by the harness")
    };
    let err = err.to_string();
    assert!(
        err.contains("--watchdog-ms") && err.contains("[1, 1000]") && err.contains("Protocol"),
        "{err}"
    );
    assert!(start.elapsed() < Duration::from_secs(5));
    assert!(!out.exists(), "nothing is written");
}

fn a_second_config_while_running_is_a_protocol_fault() {
    let dir = tempfile::tempdir().unwrap();
    let (mut qemu, mut link) = raw_session(&elf(), &dir.path().join("fw.defmt"));
    link.hello(500).unwrap();
    let mut w = pil_link::wire::Writer::new();
    pil_link::run_config::encode(&table1_drive(), None, &mut w).unwrap();
    link.configure(w.as_slice()).unwrap();
    match link.configure(w.as_slice()) {
        Err(HostError::FirmwareFault(r)) => assert_eq!(r.code, FaultCode::Protocol),
        other => panic!("a second Config was accepted: {other:?}"),
    }
    drop(link);
    qemu.finish(Duration::from_secs(1));
}

/// On a serial device QEMU's exit hangs the line up, and a hang-up discards what the
/// harness has not read yet. A harness that reads the `Stop` reply 100 ms late still gets
/// it: the image stays up after its last reply before it ends QEMU.
fn a_late_reader_on_a_serial_device_still_gets_the_stop_reply() {
    let dir = tempfile::tempdir().unwrap();
    let (mut qemu, mut link) = raw_session_on(&elf(), &dir.path().join("fw.defmt"), LinkPort::Pty);
    link.hello(500).unwrap();
    let mut w = pil_link::wire::Writer::new();
    pil_link::run_config::encode(&table1_drive(), None, &mut w).unwrap();
    link.configure(w.as_slice()).unwrap();
    let seq = link.send_next(pil_link::FrameKind::Stop, &[]).unwrap();
    std::thread::sleep(Duration::from_millis(100));
    let reply = link
        .receive(Instant::now() + Duration::from_secs(3))
        .unwrap_or_else(|e| panic!("no Stop reply read 100 ms late: {e}"));
    assert_eq!((reply.kind, reply.seq), (pil_link::FrameKind::Stop, seq));
    drop(link);
    let status = qemu.finish(Duration::from_secs(5));
    assert_eq!(status.and_then(|s| s.code()), Some(0), "a clean stop");
}

fn qemu_ends_by_itself_when_the_harness_goes_silent() {
    let dir = tempfile::tempdir().unwrap();
    let (mut qemu, mut link) = raw_session(&elf(), &dir.path().join("fw.defmt"));
    link.hello(200).unwrap();
    // The harness "dies": it says nothing more. Watchdog (200 ms), then 2·200 ms + 2 s.
    let start = Instant::now();
    let status = qemu.finish(Duration::from_secs(10));
    assert_eq!(
        status.and_then(|s| s.code()),
        Some(1),
        "QEMU did not exit by itself (waited {:?})",
        start.elapsed()
    );
    drop(link);
}

/// The paper's Table 1 drive, composed from `configs/machines/table1.toml` by the one composer.
fn table1_drive() -> controller_core::DriveConfig {
    machine_file::table1()
        .expect("configs/machines/table1.toml composes")
        .drive
}
