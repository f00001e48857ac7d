//! `stiffdrive board`: a console session with the drive firmware, on a board's serial port
//! or in QEMU: the `board` image on mps2-an386 (UART0), or the STM32F4 image on
//! netduinoplus2 (USART2), its port on a pseudo-terminal opened as a serial device (the
//! board's code path). The actions run in order in one session; the first one
//! that fails or is refused ends the command with an error that names the key.

use crate::board_scope::{scope, Scope};
use crate::image::{build_board_console_image_for, build_stm32_image_for};
use fw_runner::defmt_log::{LineFormat, LogDecoder};
use fw_runner::provision;
use pil_link::board::client::{BoardClient, BoardError};
use pil_link::board::keys;
use pil_link::board::message::Request;
use pil_link::board::session::fault_name;
use pil_link::host::{open_serial, Stream};
pub use pil_link::qemu::Machine;
use pil_link::qemu::{LinkPort, Qemu, QemuOptions};
use sim_engine::error::{HarnessError, Result};
use std::path::PathBuf;
use std::time::Duration;

/// One console action.
#[derive(Clone, Debug, PartialEq)]
pub enum Action {
    /// Firmware version, drive, enabled, latched fault.
    Status,
    /// Print one setting.
    Get(String),
    /// Change one setting (drive disabled).
    Set(String, f64),
    /// Store the running settings on the board.
    Save,
    /// Reset the board and wait until it answers again.
    Reset,
    /// Print the fault history.
    Faults,
    /// Power stage on.
    Enable,
    /// Power stage off.
    Disable,
    /// Record the scope for `seconds` into `out/scope.csv` and a plot.
    Scope(Scope),
    /// Calibrate a PMSM drive's motor on the board and set and save the calibration (the
    /// estimation is the caller's: [`board_command`]'s `calibrate`).
    Calibrate,
}

/// What runs the `calibrate` action on a session: it calibrates, sets the calibration on
/// the board, saves it and returns the line to print (`stiffdrive board` passes
/// machine-workflows' own, whose estimation is `identify`'s).
pub type Calibrator<'a> = &'a mut dyn FnMut(&mut BoardClient<Stream>) -> Result<String>;

/// Where the board is.
#[derive(Clone, Debug)]
pub enum BoardTarget {
    /// A board console image in QEMU (`elf`, or built with cargo: the `board` image for
    /// mps2-an386, the STM32F4 image for netduinoplus2), run with `qemu`.
    Qemu {
        /// The QEMU machine.
        machine: Machine,
        /// Image to run instead of building it.
        elf: Option<PathBuf>,
        /// The machine file (absolute path) whose drive the built image carries; `None`:
        /// Table 1's.
        drive: Option<PathBuf>,
        /// The QEMU binary.
        qemu: PathBuf,
    },
    /// A serial device at a baud rate.
    Port {
        /// The device, e.g. /dev/ttyACM0.
        path: PathBuf,
        /// Baud rate.
        baud: u32,
    },
}

const USAGE: &str = "actions: status, get KEY, set KEY=VALUE, save, reset, faults, enable, \
                     disable, scope --seconds S --out DIR, calibrate";

fn bad(reason: impl Into<String>) -> HarnessError {
    HarnessError::config("board", format!("{}; {USAGE}", reason.into()))
}

/// Parses the action words of the command line, in order.
///
/// # Errors
/// A word that is not an action, or an action without its argument.
pub fn parse_actions(words: &[String]) -> Result<Vec<Action>> {
    let mut actions = Vec::new();
    let mut it = words.iter().peekable();
    while let Some(word) = it.next() {
        let action = match word.as_str() {
            "status" => Action::Status,
            "save" => Action::Save,
            "reset" => Action::Reset,
            "faults" => Action::Faults,
            "enable" => Action::Enable,
            "disable" => Action::Disable,
            "calibrate" => Action::Calibrate,
            "get" => Action::Get(it.next().ok_or_else(|| bad("get needs a KEY"))?.clone()),
            "set" => {
                let arg = it.next().ok_or_else(|| bad("set needs KEY=VALUE"))?;
                let (key, value) = arg
                    .split_once('=')
                    .ok_or_else(|| bad(format!("set {arg}: expected KEY=VALUE")))?;
                let (key, value) = (key.trim(), value.trim());
                let value = match keys::choice(key) {
                    // An enumerated setting by the name of its value, as the machine file
                    // spells it; the wire carries the name's index.
                    Some(c) => c.index(value).map(|i| i as f64).ok_or_else(|| {
                        bad(format!(
                            "set {key}: {value:?} is not one of {}",
                            c.names.join(", ")
                        ))
                    })?,
                    None => value
                        .parse()
                        .map_err(|_| bad(format!("set {key}: {value:?} is not a number")))?,
                };
                Action::Set(key.to_string(), value)
            }
            "scope" => {
                let (mut seconds, mut out) = (None, None);
                while let Some(opt) = it.next_if(|w| w.starts_with("--")) {
                    let val = it
                        .next()
                        .ok_or_else(|| bad(format!("scope {opt} needs a value")))?;
                    match opt.as_str() {
                        "--seconds" => seconds = val.parse::<f64>().ok(),
                        "--out" => out = Some(PathBuf::from(val)),
                        _ => return Err(bad(format!("scope: unknown option {opt}"))),
                    }
                }
                let seconds = seconds
                    .filter(|s| s.is_finite() && *s > 0.0 && *s <= 3600.0)
                    .ok_or_else(|| bad("scope needs --seconds S (0 < S <= 3600)"))?;
                let out = out.ok_or_else(|| bad("scope needs --out DIR"))?;
                Action::Scope(Scope { seconds, out })
            }
            other => return Err(bad(format!("unknown action {other:?}"))),
        };
        actions.push(action);
    }
    if actions.is_empty() {
        return Err(bad("no action given"));
    }
    Ok(actions)
}

/// `stiffdrive board`: runs `actions` on the board at `target`, printing a line for each;
/// each reply must come within `reply_timeout`; `calibrate` runs the `calibrate` action.
///
/// # Errors
/// The first action that fails or is refused (its message names the key and range), a
/// link that fails, an `--out` that is not stiffdrive's to write.
pub fn board_command(
    target: &BoardTarget,
    actions: &[Action],
    reply_timeout: Duration,
    calibrate: Calibrator<'_>,
) -> Result<String> {
    // A scope's --out is checked before anything runs (and again when it is written).
    for a in actions {
        if let Action::Scope(s) = a {
            sim_engine::output::check_dir_target(&s.out)?;
        }
    }
    with_board(target, reply_timeout, |client| {
        run_actions(client, actions, calibrate)
    })
}

/// Opens a console session with the board at `target` (for `--qemu`: builds the image if
/// need be and starts QEMU) and runs `f` on it; QEMU ends with it, and its log is printed
/// when `f` fails (or with `STIFFDRIVE_BOARD_LOG` set).
///
/// # Errors
/// QEMU not there or not starting, the port not opening, and `f`'s.
pub fn with_board<T>(
    target: &BoardTarget,
    reply_timeout: Duration,
    f: impl FnOnce(&mut BoardClient<Stream>) -> Result<T>,
) -> Result<T> {
    match target {
        BoardTarget::Port { path, baud } => {
            let stream = open_serial(path, *baud).map_err(|e| HarnessError::io(path, e))?;
            f(&mut BoardClient::new(stream, reply_timeout))
        }
        BoardTarget::Qemu {
            machine,
            elf,
            drive,
            qemu,
        } => {
            provision::ensure_qemu().map_err(|e| HarnessError::Backend(format!("board: {e}")))?;
            let elf = match (elf, machine) {
                (Some(e), _) => e.clone(),
                (None, Machine::Mps2An386) => build_board_console_image_for(drive.as_deref())?,
                (None, Machine::Netduinoplus2) => build_stm32_image_for(drive.as_deref())?,
            };
            let log =
                std::env::temp_dir().join(format!("stiffdrive-board-{}.defmt", std::process::id()));
            let (mut vm, stream) = Qemu::spawn(&QemuOptions {
                qemu: qemu.clone(),
                elf: elf.clone(),
                log: log.clone(),
                connect_timeout: Duration::from_secs(20),
                port: LinkPort::Pty,
                machine: *machine,
            })
            .map_err(|e| HarnessError::Backend(format!("board: {e}")))?;
            let result = f(&mut BoardClient::new(stream, reply_timeout));
            vm.finish(Duration::ZERO);
            let lines = match machine {
                Machine::Mps2An386 => firmware_log(&elf, &log),
                // The STM32F4 image logs over RTT, which QEMU does not carry.
                Machine::Netduinoplus2 => {
                    vec!["(the STM32F4 image logs over RTT: no log in QEMU)".into()]
                }
            };
            let _ = std::fs::remove_file(&log);
            if result.is_err() || std::env::var_os("STIFFDRIVE_BOARD_LOG").is_some() {
                for line in lines {
                    eprintln!("firmware: {line}");
                }
            }
            result
        }
    }
}

/// The decoded defmt log of the QEMU run.
fn firmware_log(elf: &std::path::Path, raw: &std::path::Path) -> Vec<String> {
    let Ok(bytes) = std::fs::read(raw) else {
        return Vec::new();
    };
    match LogDecoder::from_elf(elf) {
        Ok(d) => d.decode_all(pil_link::qemu::log_bytes(&bytes), LineFormat::Full),
        Err(e) => vec![format!("(defmt log not decoded: {e})")],
    }
}

fn link(e: BoardError) -> HarnessError {
    match e {
        BoardError::Refused { message, .. } => {
            HarnessError::Backend(format!("board refused: {message}"))
        }
        other => HarnessError::Backend(format!("board: {other}")),
    }
}

/// Runs the actions in order on one session; prints one line each.
///
/// # Errors
/// As [`board_command`].
pub fn run_actions(
    client: &mut BoardClient<Stream>,
    actions: &[Action],
    calibrate: Calibrator<'_>,
) -> Result<String> {
    // The board may still be booting (QEMU just started it).
    client
        .wait_ready(Duration::from_secs(10), Duration::from_millis(300))
        .map_err(link)?;
    for action in actions {
        let line = match action {
            Action::Calibrate => calibrate(client)?,
            other => run_action(client, other)?,
        };
        println!("{line}");
    }
    Ok(format!("board: {} action(s) done", actions.len()))
}

fn run_action(client: &mut BoardClient<Stream>, action: &Action) -> Result<String> {
    Ok(match action {
        Action::Status => client
            .status(|s| {
                format!(
                    "firmware {}.{}.{}; running settings crc {:08x} ({}); baked drive {}; {}; \
                     fault: {}",
                    s.firmware_version >> 16,
                    (s.firmware_version >> 8) & 0xFF,
                    s.firmware_version & 0xFF,
                    s.settings_crc,
                    s.origin.describe(),
                    s.baked_name,
                    if s.enabled { "enabled" } else { "disabled" },
                    fault_name(s.fault_code)
                )
            })
            .map_err(link)?,
        Action::Get(key) => format!(
            "{} = {}",
            shown(key),
            value_text(key, client.get(key).map_err(link)?)
        ),
        Action::Set(key, value) => {
            format!(
                "{} = {} (set)",
                shown(key),
                value_text(key, client.set(key, *value).map_err(link)?)
            )
        }
        Action::Save => {
            client.request(&Request::Save).map_err(link)?;
            "settings saved on the board".to_string()
        }
        Action::Reset => {
            client.request(&Request::Reset).map_err(link)?;
            client
                .wait_ready(Duration::from_secs(20), Duration::from_millis(300))
                .map_err(link)?;
            "board reset; it answers again".to_string()
        }
        Action::Faults => {
            let h = client.faults().map_err(link)?;
            let mut text = format!("faults since boot: {}", h.total());
            for e in h.entries() {
                text.push_str(&format!("\n  {:>10} ms  {}", e.ms, fault_name(e.code)));
            }
            text
        }
        Action::Enable => {
            client.request(&Request::Enable).map_err(link)?;
            "drive enabled".to_string()
        }
        Action::Disable => {
            client.request(&Request::Disable).map_err(link)?;
            "drive disabled".to_string()
        }
        Action::Scope(s) => scope(client, s)?,
        Action::Calibrate => {
            return Err(bad("calibrate runs only from `stiffdrive board`"));
        }
    })
}

/// A key as the machine file spells it (`drive.` prefixed).
/// `value` of `key` as the machine file writes it: the name of an enumerated setting's
/// value, the number otherwise.
fn value_text(key: &str, value: f64) -> String {
    keys::choice(key)
        .and_then(|c| c.name(value))
        .map_or_else(|| value.to_string(), str::to_string)
}

fn shown(key: &str) -> String {
    if key.starts_with(keys::PREFIX) {
        key.to_string()
    } else {
        format!("{}{key}", keys::PREFIX)
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn words(w: &[&str]) -> Vec<String> {
        w.iter().map(ToString::to_string).collect()
    }

    #[test]
    fn an_enumerated_setting_is_set_by_its_name_and_shown_by_it() {
        let a = parse_actions(&words(&["set", "drive.accel_feedback.mode=plain"])).unwrap();
        assert_eq!(
            a,
            vec![Action::Set("drive.accel_feedback.mode".into(), 1.0)]
        );
        assert_eq!(value_text("drive.accel_feedback.mode", 2.0), "error");
        assert_eq!(value_text("drive.velocity_bandwidth_rad_s", 50.0), "50");
        let e = parse_actions(&words(&["set", "drive.accel_feedback.mode=sideways"]))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("drive.accel_feedback.mode") && e.contains("off, plain, error"),
            "{e}"
        );
        // A number is not a name: the index is the wire's business, not the operator's.
        assert!(parse_actions(&words(&["set", "drive.accel_feedback.mode=1"])).is_err());
    }
}
