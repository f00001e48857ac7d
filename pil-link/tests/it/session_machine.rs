//! The firmware-side session state machine on its own (no sockets, no QEMU): what it
//! accepts in each state, when its watchdog fires, and that a latched fault stays latched.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use pil_link::session::{ABANDON_GRACE_MS, HELLO_WAIT_MS};
use pil_link::wire::Writer;
use pil_link::{
    FaultCode, FaultReport, FirmwareSession, Frame, FrameKind, Hello, MAX_FRAME, SafeOutputs,
    SessionState, Target, WATCHDOG_MS_RANGE,
};

/// Stand-in target: counts calls, refuses an empty config, outputs 5 until made safe.
#[derive(Default)]
struct Probe {
    ticks: u32,
    configs: u32,
    safe: bool,
}

impl Target for Probe {
    fn configure(&mut self, payload: &[u8]) -> Result<(), FaultCode> {
        if payload.is_empty() {
            Err(FaultCode::Config)
        } else {
            self.configs += 1;
            Ok(())
        }
    }
    fn tick(&mut self, _: &[u8], out: &mut Writer) -> Result<(), FaultCode> {
        self.ticks += 1;
        out.i32(5).map(|_| ()).map_err(|_| FaultCode::BadPayload)
    }
    fn enter_safe_state(&mut self) -> SafeOutputs {
        self.safe = true;
        SafeOutputs {
            current_tick_ran: true,
            ..SafeOutputs::default()
        }
    }
}

fn bytes(kind: FrameKind, seq: u16, payload: &[u8]) -> Vec<u8> {
    let mut wire = [0_u8; MAX_FRAME];
    let n = Frame::new(kind, seq, payload)
        .unwrap()
        .encode(&mut wire)
        .unwrap();
    wire[..n].to_vec()
}

/// Feeds bytes at time `now`; returns the replies.
fn feed(s: &mut FirmwareSession, t: &mut Probe, wire: &[u8], now: u32) -> Vec<Frame> {
    wire.iter().filter_map(|&b| s.on_byte(b, now, t)).collect()
}

fn hello(watchdog_ms: u32) -> Vec<u8> {
    let mut w = Writer::new();
    Hello { watchdog_ms }.encode(&mut w).unwrap();
    bytes(FrameKind::Hello, 10, w.as_slice())
}

fn open(watchdog_ms: u32) -> (FirmwareSession, Probe) {
    let mut s = FirmwareSession::new(1);
    let mut t = Probe::default();
    let r = feed(&mut s, &mut t, &hello(watchdog_ms), 0);
    assert_eq!(r.len(), 1);
    assert_eq!((r[0].kind, r[0].seq), (FrameKind::HelloAck, 10));
    assert_eq!(s.state(), SessionState::Open);
    (s, t)
}

fn report(f: &Frame) -> FaultReport {
    assert_eq!(f.kind, FrameKind::Fault);
    FaultReport::decode(f.payload()).unwrap()
}

#[test]
fn before_hello_noise_and_other_frames_are_ignored_and_no_watchdog_runs() {
    let mut s = FirmwareSession::new(1);
    let mut t = Probe::default();
    let mut junk = vec![0x00, 0xA5, 0x13, 0xFF];
    junk.extend(bytes(FrameKind::Sensors, 0, &[1]));
    junk.extend(bytes(FrameKind::Stop, 1, &[]));
    assert!(feed(&mut s, &mut t, &junk, 0).is_empty());
    assert!(s.poll_watchdog(1_000_000, &mut t).is_none());
    assert_eq!(s.state(), SessionState::AwaitHello);
    assert!(!t.safe);
}

#[test]
fn sensors_before_config_is_a_protocol_fault() {
    let (mut s, mut t) = open(100);
    let r = feed(&mut s, &mut t, &bytes(FrameKind::Sensors, 11, &[1]), 1);
    assert_eq!(report(&r[0]).code, FaultCode::Protocol);
    assert!(t.safe && t.ticks == 0);
}

#[test]
fn a_refused_config_is_a_config_fault() {
    let (mut s, mut t) = open(100);
    let r = feed(&mut s, &mut t, &bytes(FrameKind::Config, 11, &[]), 1);
    assert_eq!(report(&r[0]).code, FaultCode::Config);
}

#[test]
fn a_frame_of_the_wrong_direction_is_a_protocol_fault() {
    let (mut s, mut t) = open(100);
    let r = feed(&mut s, &mut t, &bytes(FrameKind::Commands, 11, &[]), 1);
    assert_eq!(report(&r[0]).code, FaultCode::Protocol);
}

#[test]
fn watchdog_fires_just_after_its_period_and_across_the_ms_wrap() {
    let mut s = FirmwareSession::new(1);
    let mut t = Probe::default();
    // Open at t = u32::MAX - 5 ms: the deadline lies past the wrap of the ms counter.
    let start = u32::MAX - 5;
    assert_eq!(feed(&mut s, &mut t, &hello(50), start).len(), 1);
    assert!(s.poll_watchdog(start.wrapping_add(50), &mut t).is_none());
    let f = s.poll_watchdog(start.wrapping_add(51), &mut t).unwrap();
    assert_eq!(report(&f).code, FaultCode::Timeout);
    assert!(t.safe);
    // Latched: fires once, then answers frames.
    assert!(s.poll_watchdog(start.wrapping_add(500), &mut t).is_none());
}

#[test]
fn every_frame_resets_the_watchdog() {
    let (mut s, mut t) = open(50);
    assert_eq!(
        feed(&mut s, &mut t, &bytes(FrameKind::Config, 11, &[1]), 40).len(),
        1
    );
    assert!(s.poll_watchdog(90, &mut t).is_none());
    assert_eq!(
        feed(&mut s, &mut t, &bytes(FrameKind::Sensors, 12, &[1]), 80).len(),
        1
    );
    assert!(s.poll_watchdog(130, &mut t).is_none());
    assert!(s.poll_watchdog(131, &mut t).is_some());
}

#[test]
fn a_latched_fault_answers_every_frame_and_ends_on_stop() {
    let (mut s, mut t) = open(100);
    feed(&mut s, &mut t, &bytes(FrameKind::Config, 11, &[1]), 1);
    feed(&mut s, &mut t, &bytes(FrameKind::Sensors, 12, &[1]), 1);
    // Corrupt frame 13.
    let mut bad = bytes(FrameKind::Sensors, 13, &[1]);
    bad[8] ^= 1;
    let r = feed(&mut s, &mut t, &bad, 2);
    let first = report(&r[0]);
    assert_eq!(first.code, FaultCode::BadCrc);
    assert_eq!((first.expected_seq, first.ticks_done), (13, 1));
    // A good frame afterwards still gets the same fault report, and no tick runs.
    let r = feed(&mut s, &mut t, &bytes(FrameKind::Sensors, 13, &[1]), 3);
    assert_eq!(report(&r[0]), first);
    assert_eq!(t.ticks, 1);
    let r = feed(&mut s, &mut t, &bytes(FrameKind::Stop, 14, &[]), 4);
    assert_eq!(report(&r[0]), first);
    assert_eq!(s.state(), SessionState::Stopped { faulted: true });
}

#[test]
fn a_clean_stop_is_acknowledged() {
    let (mut s, mut t) = open(100);
    let r = feed(&mut s, &mut t, &bytes(FrameKind::Stop, 11, &[]), 1);
    assert_eq!((r[0].kind, r[0].seq), (FrameKind::Stop, 11));
    assert_eq!(s.state(), SessionState::Stopped { faulted: false });
    assert!(!t.safe);
}

#[test]
fn a_hello_with_a_watchdog_outside_the_range_is_refused_with_a_protocol_fault() {
    assert_eq!(WATCHDOG_MS_RANGE, 1..=1000);
    for bad in [0, 1001, 86_400_000, u32::MAX] {
        let mut s = FirmwareSession::new(1);
        let mut t = Probe::default();
        let r = feed(&mut s, &mut t, &hello(bad), 0);
        assert_eq!(r.len(), 1, "watchdog {bad}");
        assert_eq!(report(&r[0]).code, FaultCode::Protocol, "watchdog {bad}");
        assert!(t.safe, "watchdog {bad}: safe state entered");
        assert!(matches!(s.state(), SessionState::Faulted(_)));
        // No Config and no tick is taken afterwards.
        feed(&mut s, &mut t, &bytes(FrameKind::Config, 11, &[1]), 1);
        assert!(t.configs == 0 && t.ticks == 0, "watchdog {bad}");
    }
    for good in [1, 1000] {
        let (s, _) = open(good);
        assert_eq!(s.state(), SessionState::Open);
    }
}

#[test]
fn a_second_config_while_running_is_a_protocol_fault() {
    let (mut s, mut t) = open(100);
    let r = feed(&mut s, &mut t, &bytes(FrameKind::Config, 11, &[1]), 1);
    assert_eq!(r[0].kind, FrameKind::ConfigAck);
    feed(&mut s, &mut t, &bytes(FrameKind::Sensors, 12, &[1]), 2);
    let configs = t.configs;
    let r = feed(&mut s, &mut t, &bytes(FrameKind::Config, 13, &[1]), 3);
    assert_eq!(report(&r[0]).code, FaultCode::Protocol);
    assert_eq!(
        t.configs, configs,
        "the controller was not configured again"
    );
    assert!(t.safe);
}

#[test]
fn a_session_nobody_drives_is_abandoned() {
    // No Hello: abandoned only after HELLO_WAIT_MS from boot.
    let s = FirmwareSession::new(1);
    assert!(!s.abandoned(HELLO_WAIT_MS));
    assert!(s.abandoned(HELLO_WAIT_MS + 1));
    // Open: never abandoned (the watchdog latches first).
    let (mut s, mut t) = open(100);
    assert!(!s.abandoned(1_000_000));
    // Faulted by the watchdog at 101 ms: abandoned after 2·100 + grace of silence.
    let f = s.poll_watchdog(101, &mut t).unwrap();
    assert_eq!(report(&f).code, FaultCode::Timeout);
    let limit = 200 + ABANDON_GRACE_MS;
    assert!(!s.abandoned(limit));
    assert!(s.abandoned(limit + 1));
    // A frame after the fault (the harness asking) restarts the count.
    feed(&mut s, &mut t, &bytes(FrameKind::Sensors, 11, &[1]), limit);
    assert!(!s.abandoned(2 * limit));
    assert!(s.abandoned(2 * limit + 1));
    // Stopped: the firmware exits anyway.
    feed(&mut s, &mut t, &bytes(FrameKind::Stop, 12, &[]), 2 * limit);
    assert!(!s.abandoned(u32::MAX));
}

#[test]
fn before_hello_a_hello_payload_in_another_kind_of_frame_is_ignored() {
    // Intact frames whose payload would be a valid Hello (a watchdog in range): only the
    // frame kind Hello opens the session.
    let mut w = Writer::new();
    Hello { watchdog_ms: 100 }.encode(&mut w).unwrap();
    for kind in [
        FrameKind::HelloAck,
        FrameKind::Config,
        FrameKind::ConfigAck,
        FrameKind::Sensors,
        FrameKind::Commands,
        FrameKind::Fault,
        FrameKind::Stop,
    ] {
        let mut s = FirmwareSession::new(1);
        let mut t = Probe::default();
        assert!(feed(&mut s, &mut t, &bytes(kind, 10, w.as_slice()), 0).is_empty());
        assert_eq!(s.state(), SessionState::AwaitHello, "{kind:?}");
        assert!(!t.safe, "{kind:?}");
    }
}

#[test]
fn ticks_done_counts_the_sensor_frames_answered() {
    let (mut s, mut t) = open(1000);
    assert_eq!(s.ticks_done(), 0);
    let r = feed(&mut s, &mut t, &bytes(FrameKind::Config, 11, &[1]), 1);
    assert_eq!(r[0].kind, FrameKind::ConfigAck);
    assert_eq!(s.ticks_done(), 0);
    for k in 0..5_u16 {
        let r = feed(&mut s, &mut t, &bytes(FrameKind::Sensors, 12 + k, &[1]), 2);
        assert_eq!(r[0].kind, FrameKind::Commands);
        assert_eq!(s.ticks_done(), u32::from(k) + 1);
    }
    assert_eq!(t.ticks, 5);
}

#[test]
fn out_of_sequence_a_stop_ends_the_run_latched_and_any_other_frame_latches() {
    for (kind, stopped) in [(FrameKind::Stop, true), (FrameKind::Sensors, false)] {
        let (mut s, mut t) = open(1000);
        feed(&mut s, &mut t, &bytes(FrameKind::Config, 11, &[1]), 1);
        // 13 where 12 is expected.
        let r = feed(&mut s, &mut t, &bytes(kind, 13, &[1]), 2);
        assert_eq!(report(&r[0]).code, FaultCode::OutOfSequence, "{kind:?}");
        assert!(t.safe, "{kind:?}");
        if stopped {
            assert_eq!(s.state(), SessionState::Stopped { faulted: true });
        } else {
            assert!(matches!(s.state(), SessionState::Faulted(_)), "{kind:?}");
        }
    }
}
