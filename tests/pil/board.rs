//! `stiffdrive board --qemu`: the board console against the `board` image in QEMU, through
//! the real binary (set, save, reset, get; refusals; the scope) and through the client
//! library where a test must look at the drive between refusals; and against the STM32F4
//! image on QEMU's netduinoplus2 (`--machine netduinoplus2`).

use pil_host::image::{build_board_console_image, build_stm32_image_for};
use pil_link::board::client::{BoardClient, BoardError};
use pil_link::board::message::{Refusal, Request};
use pil_link::host::Stream;
use pil_link::qemu::{LinkPort, Machine, Qemu, QemuOptions};
use pil_link::{Frame, FrameKind, MAX_FRAME};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::OnceLock;
use std::time::Duration;

const KEY: &str = "drive.velocity_bandwidth_rad_s";

/// The `board` ELF, built once per test binary.
fn board_elf() -> PathBuf {
    static ELF: OnceLock<PathBuf> = OnceLock::new();
    ELF.get_or_init(|| {
        fw_runner::provision::ensure_qemu().unwrap();
        build_board_console_image().unwrap_or_else(|e| panic!("cannot build the board image: {e}"))
    })
    .clone()
}

/// The STM32F4 image (Table 1's drive), built once per test binary.
fn stm32_elf() -> PathBuf {
    static ELF: OnceLock<PathBuf> = OnceLock::new();
    ELF.get_or_init(|| {
        fw_runner::provision::ensure_qemu().unwrap();
        build_stm32_image_for(None).unwrap_or_else(|e| panic!("cannot build the STM32 image: {e}"))
    })
    .clone()
}

/// `stiffdrive board --qemu --elf <board image> ARGS...`
fn board(args: &[&str]) -> Output {
    board_on("mps2-an386", &board_elf(), args)
}

/// `stiffdrive board --qemu --machine MACHINE --elf ELF ARGS...`
fn board_on(machine: &str, elf: &Path, args: &[&str]) -> Output {
    let out = Command::new(env!("CARGO_BIN_EXE_stiffdrive"))
        .args(["board", "--qemu", "--machine", machine, "--elf"])
        .arg(elf)
        .args(args)
        .env("STIFFDRIVE_BOARD_LOG", "1")
        .output()
        .unwrap();
    eprintln!(
        "board {args:?}: {}\n{}{}",
        out.status,
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

pub fn set_save_reset_get_prints_the_saved_value() {
    // An enumerated setting goes by the name of its value, and is saved with the rest.
    let mode = "drive.accel_feedback.mode";
    let out = board(&[
        "set",
        &format!("{KEY}=50"),
        "set",
        &format!("{mode}=plain"),
        "save",
        "reset",
        "get",
        KEY,
        "get",
        mode,
    ]);
    assert!(out.status.success());
    let stdout = String::from_utf8_lossy(&out.stdout);
    let lines: Vec<&str> = stdout.lines().collect();
    let reset = lines
        .iter()
        .position(|l| l.starts_with("board reset"))
        .unwrap();
    assert_eq!(lines[reset + 1], format!("{KEY} = 50"), "{stdout}");
    assert_eq!(lines[reset + 2], format!("{mode} = plain"), "{stdout}");
    // The boot after the reset ran the saved settings and said so.
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("drive: saved on the board (settings crc"),
        "{stderr}"
    );
}

pub fn a_set_while_enabled_or_out_of_range_is_refused_naming_the_key() {
    let out = board(&["enable", "set", &format!("{KEY}=50")]);
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains(&format!("{KEY}: refused while the drive is enabled")),
        "{stderr}"
    );
    let out = board(&["set", "drive.velocity_damping=50"]);
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("drive.velocity_damping = 50: allowed range is [0.1, 10]"),
        "{stderr}"
    );
}

fn session(log: &Path) -> (Qemu, BoardClient<Stream>) {
    let (qemu, stream) = Qemu::spawn(&QemuOptions {
        qemu: PathBuf::from("qemu-system-arm"),
        elf: board_elf(),
        log: log.to_path_buf(),
        connect_timeout: Duration::from_secs(20),
        port: LinkPort::Pty,
        machine: Machine::default(),
    })
    .unwrap();
    let mut client = BoardClient::new(stream, Duration::from_secs(3));
    client
        .wait_ready(Duration::from_secs(10), Duration::from_millis(300))
        .unwrap();
    (qemu, client)
}

fn refusal<T: std::fmt::Debug>(r: Result<T, BoardError>) -> (Refusal, String) {
    match r {
        Err(BoardError::Refused { refusal, message }) => (refusal, message),
        other => panic!("expected a refusal, got {other:?}"),
    }
}

pub fn refused_sets_leave_the_drive_unchanged_and_a_corrupt_frame_disables_it() {
    let dir = tempfile::tempdir().unwrap();
    let (_qemu, mut c) = session(&dir.path().join("board.defmt"));
    let crc = |c: &mut BoardClient<Stream>| c.status(|s| s.settings_crc).unwrap();
    let (bw, damping, crc0) = (
        c.get(KEY).unwrap(),
        c.get("drive.velocity_damping").unwrap(),
        crc(&mut c),
    );
    c.request(&Request::Enable).unwrap();
    let (code, msg) = refusal(c.set(KEY, 50.0));
    assert_eq!(code, Refusal::Enabled);
    assert!(msg.contains(KEY), "{msg}");
    c.request(&Request::Disable).unwrap();
    let (code, msg) = refusal(c.set("drive.velocity_damping", 50.0));
    assert_eq!(code, Refusal::Invalid);
    assert!(
        msg.contains("drive.velocity_damping") && msg.contains("[0.1, 10]"),
        "{msg}"
    );
    assert_eq!(c.get(KEY).unwrap(), bw);
    assert_eq!(c.get("drive.velocity_damping").unwrap(), damping);
    assert_eq!(crc(&mut c), crc0);
    // A Set frame with a bit flipped, sent while enabled: the drive turns off, the history
    // names the link, and the setting is what it was.
    c.request(&Request::Enable).unwrap();
    assert!(c.status(|s| s.enabled).unwrap());
    let mut w = pil_link::wire::Writer::new();
    Request::Set(KEY, 50.0).encode(&mut w).unwrap();
    let mut wire = [0_u8; MAX_FRAME];
    let n = Frame::new(FrameKind::BoardRequest, 999, w.as_slice())
        .unwrap()
        .encode(&mut wire)
        .unwrap();
    wire[12] ^= 0x04;
    c.write_raw(&wire[..n]).unwrap();
    assert!(
        !c.status(|s| s.enabled).unwrap(),
        "a corrupt frame left the drive enabled"
    );
    let history = c.faults().unwrap();
    assert_eq!(history.total(), 1);
    assert_eq!(
        history.entries().next().map(|e| e.code),
        Some(pil_link::board::faults::LINK_FAULT_CODE)
    );
    assert_eq!(c.get(KEY).unwrap(), bw);
}

pub fn scope_writes_a_second_of_samples_at_the_trace_rate_without_gaps() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("D");
    let out = board(&[
        "scope",
        "--seconds",
        "1",
        "--out",
        out_dir.to_str().unwrap(),
    ]);
    assert!(out.status.success());
    let csv = std::fs::read_to_string(out_dir.join("scope.csv")).unwrap();
    let rows: Vec<Vec<i64>> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').filter_map(|v| v.parse().ok()).collect())
        .collect();
    assert!(rows.len() >= 1000, "{} rows", rows.len());
    for pair in rows.windows(2) {
        // sample counter: +1; current-loop tick: +4 (the trace's decimation, 1 kHz at 4 kHz).
        assert_eq!(pair[1][0], pair[0][0] + 1, "gap in the sample counter");
        assert_eq!(pair[1][1] - pair[0][1], 4, "not at the trace rate");
    }
    assert!(std::fs::metadata(out_dir.join("scope.png")).unwrap().len() > 1000);
    // --out never deletes what is there: a directory with a foreign file is refused.
    let foreign = dir.path().join("F");
    std::fs::create_dir(&foreign).unwrap();
    std::fs::write(foreign.join("notes.txt"), "mine").unwrap();
    let out = board(&[
        "scope",
        "--seconds",
        "1",
        "--out",
        foreign.to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    assert_eq!(
        std::fs::read_to_string(foreign.join("notes.txt")).unwrap(),
        "mine"
    );
    assert_eq!(std::fs::read_dir(&foreign).unwrap().count(), 1);
}

/// The STM32F4 image on netduinoplus2: the console on USART2 answers status, set, get and
/// faults; an out-of-range set is refused naming the key; and `save` says it failed, since
/// QEMU 7.2 models no flash controller (its registers read 0, flash ignores writes).
pub fn netduinoplus2_serves_the_console_and_save_reports_the_missing_flash_controller() {
    let elf = stm32_elf();
    let on_stm32 = |args: &[&str]| board_on("netduinoplus2", &elf, args);
    let out = on_stm32(&[
        "status",
        "set",
        &format!("{KEY}=50"),
        "get",
        KEY,
        "faults",
        "save",
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    let lines: Vec<&str> = stdout.lines().collect();
    assert!(
        lines[0].contains("(the baked drive); baked drive configs/machines/table1.toml")
            && lines[0].ends_with("disabled; fault: none"),
        "{stdout}"
    );
    assert_eq!(lines[1], format!("{KEY} = 50 (set)"));
    assert_eq!(lines[2], format!("{KEY} = 50"));
    assert_eq!(lines[3], "faults since boot: 0");
    assert_eq!(lines.len(), 4, "save must not claim success: {stdout}");
    assert!(!out.status.success());
    assert!(
        stderr.contains("board refused: save failed: erase: the sector is not blank at byte 0"),
        "{stderr}"
    );
    let out = on_stm32(&["set", "drive.velocity_damping=50"]);
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("drive.velocity_damping = 50: allowed range is [0.1, 10]"),
        "{stderr}"
    );
}
