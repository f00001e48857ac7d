//! The firmware session and the harness client over a real socket pair, with the firmware
//! side in a thread driving a stand-in target. Every injected fault must be seen by the
//! harness and must leave the firmware latched in its safe state (zero commands).
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use pil_link::host::{FaultPlan, HostError, HostLink};
use pil_link::wire::{Reader, Writer};
use pil_link::{
    FaultCode, FirmwareSession, FrameKind, LinkError, SafeOutputs, SessionState, Target,
};
use std::io::{Read, Write};
use std::os::unix::net::UnixStream;
use std::thread;
use std::time::{Duration, Instant};

/// Stand-in controller: commands = 2 × sensor word + offset from the config.
#[derive(Default)]
struct Doubler {
    offset: i32,
    output: i32,
}

impl Target for Doubler {
    fn configure(&mut self, payload: &[u8]) -> Result<(), FaultCode> {
        let mut r = Reader::new(FrameKind::Config, payload);
        self.offset = r.i32().map_err(|_| FaultCode::Config)?;
        Ok(())
    }
    fn tick(&mut self, sensors: &[u8], commands: &mut Writer) -> Result<(), FaultCode> {
        let mut r = Reader::new(FrameKind::Sensors, sensors);
        let x = r.i32().map_err(|_| FaultCode::BadPayload)?;
        self.output = 2 * x + self.offset;
        commands
            .i32(self.output)
            .map(|_| ())
            .map_err(|_| FaultCode::BadPayload)
    }
    fn enter_safe_state(&mut self) -> SafeOutputs {
        self.output = 0;
        SafeOutputs {
            current_tick_ran: true,
            torque_cmd_bits: self.output,
            ..SafeOutputs::default()
        }
    }
}

/// Generous, so a loaded CI machine does not trip it by starving the firmware thread.
const WATCHDOG_MS: u32 = 250;

/// Runs the firmware side on `stream` until the session stops; returns its final state and
/// the target's last output.
fn firmware(mut stream: UnixStream) -> (SessionState, i32) {
    let t0 = Instant::now();
    let mut session = FirmwareSession::new(0x00_01_00);
    let mut target = Doubler::default();
    stream
        .set_read_timeout(Some(Duration::from_millis(5)))
        .unwrap();
    let mut buf = [0_u8; 64];
    loop {
        let now_ms = t0.elapsed().as_millis() as u32;
        if let Some(f) = session.poll_watchdog(now_ms, &mut target) {
            let mut wire = [0_u8; pil_link::MAX_FRAME];
            let n = f.encode(&mut wire).unwrap();
            let _ = stream.write_all(&wire[..n]);
        }
        let n = match stream.read(&mut buf) {
            Ok(0) => break,
            Ok(n) => n,
            Err(_) => continue,
        };
        for &b in &buf[..n] {
            let now_ms = t0.elapsed().as_millis() as u32;
            if let Some(f) = session.on_byte(b, now_ms, &mut target) {
                let mut wire = [0_u8; pil_link::MAX_FRAME];
                let n = f.encode(&mut wire).unwrap();
                let _ = stream.write_all(&wire[..n]);
            }
        }
        if matches!(session.state(), SessionState::Stopped { .. }) {
            break;
        }
    }
    (session.state(), target.output)
}

/// Opens a session, runs `ticks` ticks with an optional fault; returns what the harness saw
/// and the firmware's final state.
fn run(
    ticks: i32,
    plan: Option<FaultPlan>,
) -> (
    Vec<i32>,
    Option<HostError>,
    Option<pil_link::FaultReport>,
    SessionState,
    i32,
) {
    let (h, f) = UnixStream::pair().unwrap();
    let fw = thread::spawn(move || firmware(f));
    let mut link = HostLink::new(h, Duration::from_millis(4 * u64::from(WATCHDOG_MS)));
    if let Some(p) = plan {
        link.inject(p);
    }
    let ack = link.hello(WATCHDOG_MS).unwrap();
    assert_eq!(ack.watchdog_ms, WATCHDOG_MS);
    assert_eq!(ack.protocol_version, pil_link::PROTOCOL_VERSION);
    link.configure(&7_i32.to_le_bytes()).unwrap();
    let mut outputs = Vec::new();
    let mut error = None;
    for x in 0..ticks {
        match link.tick(&x.to_le_bytes()) {
            Ok(frame) => {
                let mut r = Reader::new(FrameKind::Commands, frame.payload());
                outputs.push(r.i32().unwrap());
            }
            Err(e) => {
                error = Some(e);
                break;
            }
        }
    }
    let confirmed = if let Some(e) = &error {
        let already = match e {
            HostError::FirmwareFault(r) => Some(*r),
            _ => None,
        };
        link.confirm_safe_state(already, Duration::from_millis(4 * u64::from(WATCHDOG_MS)))
    } else {
        link.stop().unwrap();
        None
    };
    drop(link);
    let (state, last_output) = fw.join().unwrap();
    (outputs, error, confirmed, state, last_output)
}

#[test]
fn clean_session_runs_lock_step_and_stops() {
    let (out, err, _, state, _) = run(50, None);
    assert!(err.is_none(), "{err:?}");
    assert_eq!(out, (0..50).map(|x| 2 * x + 7).collect::<Vec<_>>());
    assert_eq!(state, SessionState::Stopped { faulted: false });
}

#[test]
fn corrupted_request_is_caught_by_the_firmware() {
    let plan = "corrupt@10".parse().unwrap();
    let (out, err, confirmed, state, last) = run(50, Some(plan));
    assert_eq!(out.len(), 10, "the trace stops at the corrupted tick");
    match err {
        Some(HostError::FirmwareFault(r)) => {
            assert_eq!(r.code, FaultCode::BadCrc);
            assert_eq!(r.ticks_done, 10);
            assert!(r.outputs.are_safe(), "{:?}", r.outputs);
        }
        other => panic!("harness did not report the firmware fault: {other:?}"),
    }
    assert_eq!(confirmed.map(|r| r.code), Some(FaultCode::BadCrc));
    assert_eq!(state, SessionState::Stopped { faulted: true });
    assert_eq!(last, 0);
}

#[test]
fn dropped_request_times_out_on_the_firmware_watchdog() {
    let (out, err, _, state, last) = run(50, Some("drop@5".parse().unwrap()));
    assert_eq!(out.len(), 5);
    match err {
        Some(HostError::FirmwareFault(r)) => assert_eq!(r.code, FaultCode::Timeout),
        other => panic!("expected the firmware's Timeout fault, got {other:?}"),
    }
    assert_eq!(state, SessionState::Stopped { faulted: true });
    assert_eq!(last, 0);
}

#[test]
fn late_request_is_a_timeout_fault() {
    let (out, err, _, state, last) = run(
        50,
        Some(format!("delay@7:{}", 2 * WATCHDOG_MS).parse().unwrap()),
    );
    assert_eq!(out.len(), 7);
    match err {
        Some(HostError::FirmwareFault(r)) => assert_eq!(r.code, FaultCode::Timeout),
        other => panic!("expected the firmware's Timeout fault, got {other:?}"),
    }
    assert_eq!(state, SessionState::Stopped { faulted: true });
    assert_eq!(last, 0);
}

#[test]
fn sequence_gap_is_caught_at_once() {
    let t = Instant::now();
    let (out, err, _, state, _) = run(50, Some("skip-seq@3".parse().unwrap()));
    assert_eq!(out.len(), 3);
    match err {
        Some(HostError::FirmwareFault(r)) => assert_eq!(r.code, FaultCode::OutOfSequence),
        other => panic!("expected OutOfSequence, got {other:?}"),
    }
    assert!(t.elapsed() < Duration::from_millis(u64::from(WATCHDOG_MS) * 3));
    assert_eq!(state, SessionState::Stopped { faulted: true });
}

#[test]
fn corrupted_reply_is_caught_by_the_harness_and_firmware_times_out() {
    let (out, err, confirmed, state, last) = run(50, Some("corrupt-reply@4:8".parse().unwrap()));
    assert_eq!(out.len(), 4);
    assert!(
        matches!(err, Some(HostError::Link(LinkError::BadCrc { .. }))),
        "{err:?}"
    );
    // The harness stops sending; the firmware's watchdog latches the safe state.
    assert_eq!(confirmed.map(|r| r.code), Some(FaultCode::Timeout));
    assert_eq!(state, SessionState::Stopped { faulted: true });
    assert_eq!(last, 0);
}

#[test]
fn dropped_reply_is_a_harness_timeout() {
    let (out, err, confirmed, state, last) = run(50, Some("drop-reply@2".parse().unwrap()));
    assert_eq!(out.len(), 2);
    // The firmware's watchdog (250 ms) fires before the harness deadline (1 s), and its
    // Fault frame is what the harness reads next: either way the loss is detected.
    assert!(
        matches!(
            err,
            Some(HostError::FirmwareFault(_)) | Some(HostError::Link(LinkError::Timeout { .. }))
        ),
        "{err:?}"
    );
    assert_eq!(confirmed.map(|r| r.code), Some(FaultCode::Timeout));
    assert_eq!(state, SessionState::Stopped { faulted: true });
    assert_eq!(last, 0);
}

#[test]
fn fault_plan_parsing_names_the_problem() {
    assert!(
        "bogus@1"
            .parse::<FaultPlan>()
            .unwrap_err()
            .contains("bogus")
    );
    assert!(
        "delay@1"
            .parse::<FaultPlan>()
            .unwrap_err()
            .contains("needs")
    );
    assert!("drop@x".parse::<FaultPlan>().unwrap_err().contains("TICK"));
}
