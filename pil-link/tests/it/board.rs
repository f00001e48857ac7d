//! The board console's firmware side (`pil_link::board::session`) on a mock drive: `Set`
//! validation and refusals, `Save` records, the fault history; and the fuzz test: a million
//! random and corrupted bytes never panic, never change a setting, and turn an enabled
//! drive off.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use crate::common::table1;
use controller_core::foc::calibration::{Calibration, CalibrationSettings};
use controller_core::{ConfigError, DriveConfig};
use pil_link::board::calibrate::{self, CalibrateError};
use pil_link::board::faults::{FaultEntry, FaultHistory, LINK_FAULT_CODE};
use pil_link::board::identify::{CHANNELS, IdentifyError, IdentifyRun, is_cut_end};
use pil_link::board::message::{Origin, Refusal, Reply, Request, get_f64};
use pil_link::board::scope::{ScopeChunk, ScopeInfo, ScopeSample};
use pil_link::board::session::{BoardSession, Drive};
use pil_link::board::store::{self, RECORD_LEN, SaveError, StoreError};
use pil_link::wire::Writer;
use pil_link::{Frame, FrameKind, MAX_FRAME, MAX_PAYLOAD};

/// A drive that records what the session asked of it.
#[derive(Default)]
struct MockDrive {
    enabled: bool,
    fault: u8,
    applied: Option<DriveConfig>,
    saved: Option<[u8; RECORD_LEN]>,
    history: FaultHistory,
    scope_on: bool,
    identified: Option<(DriveConfig, IdentifyRun)>,
    calibrated: Option<(DriveConfig, Calibration)>,
    /// What `save` answers instead of storing the record.
    save_error: Option<SaveError>,
}

impl Drive for MockDrive {
    fn apply(&mut self, cfg: &DriveConfig) -> Result<(), ConfigError> {
        self.applied = Some(*cfg);
        Ok(())
    }
    fn enabled(&self) -> bool {
        self.enabled
    }
    fn set_enabled(&mut self, on: bool) {
        self.enabled = on;
    }
    fn fault_code(&self) -> u8 {
        self.fault
    }
    fn save(&mut self, record: &[u8; RECORD_LEN]) -> Result<(), SaveError> {
        if let Some(e) = self.save_error {
            return Err(e);
        }
        self.saved = Some(*record);
        Ok(())
    }
    fn fault_history(&self) -> FaultHistory {
        self.history
    }
    fn scope(&mut self, on: bool) -> ScopeInfo<'_> {
        self.scope_on = on;
        ScopeInfo {
            rate_hz: 1000,
            channels: "a,b,c,d",
        }
    }
    fn identify(
        &mut self,
        cfg: &DriveConfig,
        _running: &DriveConfig,
        run: &IdentifyRun,
    ) -> Result<ScopeInfo<'_>, IdentifyError> {
        self.identified = Some((*cfg, *run));
        self.enabled = true;
        Ok(ScopeInfo {
            rate_hz: cfg.current_rate_hz,
            channels: CHANNELS,
        })
    }
    fn calibrate(
        &mut self,
        cfg: &DriveConfig,
        seq: &Calibration,
    ) -> Result<ScopeInfo<'_>, CalibrateError> {
        self.calibrated = Some((*cfg, *seq));
        self.enabled = true;
        Ok(ScopeInfo {
            rate_hz: cfg.current_rate_hz,
            channels: calibrate::CHANNELS,
        })
    }
    fn enter_safe_state(&mut self) {
        self.enabled = false;
        self.history.push(FaultEntry {
            ms: 0,
            code: LINK_FAULT_CODE,
        });
    }
}

fn session() -> BoardSession {
    BoardSession::new(
        table1(),
        Origin::Baked,
        0x0001_0000,
        "configs/machines/table1.toml",
    )
}

fn wire(request: &Request<'_>, seq: u16) -> Vec<u8> {
    let mut w = Writer::new();
    request.encode(&mut w).unwrap();
    let frame = Frame::new(FrameKind::BoardRequest, seq, w.as_slice()).unwrap();
    let mut buf = [0_u8; MAX_FRAME];
    let n = frame.encode(&mut buf).unwrap();
    buf[..n].to_vec()
}

/// Feeds `bytes`; the replies' payloads.
fn feed(s: &mut BoardSession, d: &mut MockDrive, bytes: &[u8]) -> Vec<Vec<u8>> {
    bytes
        .iter()
        .filter_map(|&b| s.on_byte(b, d))
        .map(|f| f.payload().to_vec())
        .collect()
}

fn ask(
    s: &mut BoardSession,
    d: &mut MockDrive,
    r: &Request<'_>,
) -> Result<Vec<u8>, (Refusal, String)> {
    let replies = feed(s, d, &wire(r, 7));
    assert_eq!(replies.len(), 1, "one reply per request");
    let reply = Reply::decode(&replies[0]).unwrap();
    assert_eq!(reply.op, r.op() as u8);
    reply
        .result
        .map(<[u8]>::to_vec)
        .map_err(|(c, m)| (c, m.to_string()))
}

const KEY: &str = "drive.velocity_bandwidth_rad_s";

#[test]
fn a_set_in_range_changes_the_setting_and_rebuilds_the_drive() {
    let (mut s, mut d) = (session(), MockDrive::default());
    let body = ask(&mut s, &mut d, &Request::Set(KEY, 50.0)).unwrap();
    assert_eq!(get_f64(&body).unwrap(), 50.0);
    assert_eq!(s.settings().velocity_bandwidth_rad_s, 50.0);
    assert_eq!(d.applied.unwrap().velocity_bandwidth_rad_s, 50.0);
    assert_eq!(s.origin(), Origin::Changed);
    let got = ask(&mut s, &mut d, &Request::Get(KEY)).unwrap();
    assert_eq!(get_f64(&got).unwrap(), 50.0);
}

#[test]
fn a_set_while_enabled_is_refused_naming_the_key_and_changes_nothing() {
    let (mut s, mut d) = (session(), MockDrive::default());
    ask(&mut s, &mut d, &Request::Enable).unwrap();
    let before = *s.settings();
    let (code, msg) = ask(&mut s, &mut d, &Request::Set(KEY, 50.0)).unwrap_err();
    assert_eq!(code, Refusal::Enabled);
    assert!(msg.contains(KEY), "{msg}");
    assert_eq!(*s.settings(), before);
    assert!(d.applied.is_none());
}

#[test]
fn an_out_of_range_set_is_refused_naming_the_key_and_its_range() {
    let (mut s, mut d) = (session(), MockDrive::default());
    let before = *s.settings();
    let (code, msg) = ask(
        &mut s,
        &mut d,
        &Request::Set("drive.velocity_damping", 50.0),
    )
    .unwrap_err();
    assert_eq!(code, Refusal::Invalid);
    assert!(
        msg.contains("drive.velocity_damping") && msg.contains("0.1, 10]"),
        "{msg}"
    );
    // In its own range, but above the velocity loop's Nyquist limit: design() refuses it.
    let (code, msg) = ask(&mut s, &mut d, &Request::Set(KEY, 1.0e6)).unwrap_err();
    assert_eq!(code, Refusal::Invalid);
    assert!(msg.contains(KEY), "{msg}");
    let (code, _) = ask(&mut s, &mut d, &Request::Set("drive.no_such_key", 1.0)).unwrap_err();
    assert_eq!(code, Refusal::UnknownKey);
    let (code, _) = ask(&mut s, &mut d, &Request::Set("drive.encoder_cpr", 4096.5)).unwrap_err();
    assert_eq!(code, Refusal::Invalid);
    assert_eq!(*s.settings(), before);
    assert!(d.applied.is_none());
}

#[test]
fn save_writes_a_record_the_boot_reads_back_and_a_damaged_one_is_refused() {
    let (mut s, mut d) = (session(), MockDrive::default());
    ask(&mut s, &mut d, &Request::Set(KEY, 50.0)).unwrap();
    ask(&mut s, &mut d, &Request::Save).unwrap();
    assert_eq!(s.origin(), Origin::Saved);
    let record = d.saved.unwrap();
    assert_eq!(
        store::decode(&record).unwrap().velocity_bandwidth_rad_s,
        50.0
    );
    let mut torn = record;
    torn[20] ^= 1;
    assert!(matches!(
        store::decode(&torn),
        Err(StoreError::BadCrc { .. })
    ));
    assert_eq!(store::decode(&[0; RECORD_LEN]), Err(StoreError::Empty));
    // Another record version with a valid CRC.
    let mut other = record;
    other[4] = 9;
    let crc = pil_link::crc32(&other[..RECORD_LEN - 4]);
    other[RECORD_LEN - 4..].copy_from_slice(&crc.to_le_bytes());
    assert_eq!(
        store::decode(&other),
        Err(StoreError::BadVersion { found: 9 })
    );
}

#[test]
fn a_failed_save_is_refused_with_the_boards_reason_and_the_settings_stay_unsaved() {
    let (mut s, mut d) = (session(), MockDrive::default());
    ask(&mut s, &mut d, &Request::Set(KEY, 50.0)).unwrap();
    d.save_error = Some(SaveError::Verify { offset: 0 });
    let (code, msg) = ask(&mut s, &mut d, &Request::Save).unwrap_err();
    assert_eq!(code, Refusal::Storage);
    assert_eq!(
        msg,
        "save failed: the settings sector does not read back what was written (byte 0)"
    );
    assert_eq!(
        s.origin(),
        Origin::Changed,
        "a failed save is not a saved drive"
    );
    d.save_error = Some(SaveError::Flash {
        step: "erase",
        status: 0x10,
    });
    let (_, msg) = ask(&mut s, &mut d, &Request::Save).unwrap_err();
    assert!(msg.contains("erase") && msg.contains("0x00000010"), "{msg}");
}

#[test]
fn enable_is_refused_while_a_fault_is_latched_and_faults_returns_the_history() {
    let (mut s, mut d) = (session(), MockDrive::default());
    d.fault = 1;
    for ms in 0..20 {
        d.history.push(FaultEntry { ms, code: 1 });
    }
    let (code, msg) = ask(&mut s, &mut d, &Request::Enable).unwrap_err();
    assert_eq!(code, Refusal::Faulted);
    assert!(msg.contains("fault latched"), "{msg}");
    assert!(!d.enabled);
    let h = FaultHistory::decode(&ask(&mut s, &mut d, &Request::Faults).unwrap()).unwrap();
    assert_eq!(h.total(), 20);
    let ms: Vec<u32> = h.entries().map(|e| e.ms).collect();
    assert_eq!(ms, (4..20).collect::<Vec<_>>());
}

#[test]
fn a_request_of_another_board_version_is_refused() {
    let (mut s, mut d) = (session(), MockDrive::default());
    let mut bytes = wire(&Request::Status, 1);
    // Payload byte 0 is the board version; fix the CRC so only the version is wrong.
    bytes[7] = 99;
    let n = bytes.len();
    let crc = pil_link::crc32(&bytes[2..n - 4]);
    bytes[n - 4..].copy_from_slice(&crc.to_le_bytes());
    let replies = feed(&mut s, &mut d, &bytes);
    let reply = Reply::decode(&replies[0]).unwrap();
    assert!(matches!(reply.result, Err((Refusal::Version, _))));
}

/// xorshift64*: a deterministic byte source for the fuzz test.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

/// One damaged stream: noise, a valid `Set` with a bit flipped, truncated, or of another
/// protocol version.
fn damaged(rng: &mut Rng) -> Vec<u8> {
    let set = wire(
        &Request::Set(KEY, 20.0 + rng.below(100) as f64),
        rng.next() as u16,
    );
    match rng.below(4) {
        0 => (0..1 + rng.below(64)).map(|_| rng.next() as u8).collect(),
        1 => {
            let mut b = set;
            let i = rng.below(b.len() - 2) + 2;
            b[i] ^= 1 << rng.below(8);
            b
        }
        2 => set[..rng.below(set.len() - 1) + 1].to_vec(),
        _ => {
            let mut b = set;
            b[2] = b[2].wrapping_add(1 + rng.below(255) as u8);
            b
        }
    }
}

#[test]
fn a_million_damaged_bytes_never_change_a_setting_and_turn_an_enabled_drive_off() {
    let mut rng = Rng(0x5EED_B0A4_D000_0001);
    let (mut s, mut d) = (session(), MockDrive::default());
    let before = *s.settings();
    let (mut bytes, mut trips, mut enabled_hits) = (0_usize, 0_u32, 0_u32);
    while bytes < 1_000_000 {
        let enabled = rng.below(2) == 0;
        d.enabled = enabled;
        let errors_before = s.link_errors();
        let stream = damaged(&mut rng);
        bytes += stream.len();
        for b in stream {
            if let Some(frame) = s.on_byte(b, &mut d) {
                // Only an intact frame is answered; a corrupt Set never is a done Set.
                let reply = Reply::decode(frame.payload()).unwrap();
                assert!(reply.result.is_err() || reply.op != 3, "{reply:?}");
            }
        }
        // A truncated frame completes only with the next stream's bytes: hunt again.
        let closing = [0_u8; MAX_FRAME];
        for b in closing {
            let _ = s.on_byte(b, &mut d);
        }
        assert_eq!(
            *s.settings(),
            before,
            "a damaged frame changed the settings"
        );
        assert!(d.applied.is_none());
        if s.link_errors() > errors_before && enabled {
            enabled_hits += 1;
            assert!(!d.enabled, "a corrupt frame left the drive enabled");
            trips += 1;
        }
    }
    assert!(
        enabled_hits > 1000,
        "the damage reached an enabled drive {enabled_hits} times"
    );
    assert_eq!(d.history.total(), trips);
    // After all that, an intact request is still served.
    d.enabled = false;
    let body = ask(&mut s, &mut d, &Request::Set(KEY, 50.0)).unwrap();
    assert_eq!(get_f64(&body).unwrap(), 50.0);
}

/// Every key of controller-core's range table reaches its own setting: on a drive with
/// every optional part (a notch, second-order filters), `set` writes a value from inside
/// the key's range, `get` reads that value back and no other key's value changed. A key added to the table without its
/// line in `pil-link/src/board/keys.rs` fails here.
#[test]
fn every_key_of_the_range_table_reaches_its_setting() {
    use controller_core::{FilterConfig, NotchConfig};
    use pil_link::board::keys;
    let mut cfg = table1();
    cfg.notch = Some(NotchConfig {
        centre_hz: 300.0,
        width_hz: 50.0,
        depth_db: 20.0,
    });
    let second = FilterConfig::SecondOrder {
        corner_hz: 500.0,
        q: 0.7,
    };
    cfg.velocity_filter = second;
    cfg.accel_feedback.filter = second;
    for r in controller_core::RANGES {
        let key = format!("{}{}", keys::PREFIX, r.key);
        let before = keys::get(&cfg, &key)
            .unwrap_or_else(|e| panic!("{key} reaches no setting ({e:?}): add it to keys.rs"));
        let inside = if r.max.is_finite() {
            f64::from(r.min) / 2.0 + f64::from(r.max) / 2.0
        } else {
            f64::from(r.min) + 1.5
        };
        let inside = if r.whole {
            inside.round()
        } else {
            f64::from(inside as f32)
        };
        assert_ne!(inside, before, "{key}: pick another test value");
        let mut changed = cfg;
        keys::set(&mut changed, &key, inside).unwrap_or_else(|e| panic!("{key}: {e:?}"));
        assert_eq!(keys::get(&changed, &key).unwrap(), inside, "{key}");
        assert_ne!(changed, cfg, "{key}");
        // ... and no other key's: each key has a setting of its own.
        for other in controller_core::RANGES.iter().filter(|o| o.key != r.key) {
            assert_eq!(
                keys::get(&changed, other.key).unwrap(),
                keys::get(&cfg, other.key).unwrap(),
                "setting {key} changed {}",
                other.key
            );
        }
        // Without the prefix too, as the range table spells it.
        assert_eq!(keys::get(&changed, r.key).unwrap(), inside, "{key}");
    }
    // A key of a part the drive lacks: not present, and named.
    let mut plain = table1();
    plain.notch = None;
    assert!(matches!(
        keys::get(&plain, "drive.notch.centre_hz"),
        Err(keys::KeyError::NotPresent(r)) if r.key == "notch.centre_hz"
    ));
}

/// `Reset` is answered first and only then asked of the firmware: the session says so
/// after the reply, never before.
#[test]
fn reset_is_requested_only_once_it_was_answered() {
    let (mut s, mut d) = (session(), MockDrive::default());
    assert!(!s.reset_requested());
    ask(&mut s, &mut d, &Request::Status).unwrap();
    assert!(!s.reset_requested());
    ask(&mut s, &mut d, &Request::Reset).unwrap();
    assert!(s.reset_requested());
}

/// A well-formed board request in a frame of another kind (here the board's own reply
/// kind, and a PIL `Config`) is not for the console: no reply, no setting changed.
#[test]
fn a_request_in_a_frame_of_another_kind_is_not_served() {
    let (mut s, mut d) = (session(), MockDrive::default());
    let before = *s.settings();
    let mut w = Writer::new();
    Request::Set(KEY, 50.0).encode(&mut w).unwrap();
    for kind in [FrameKind::BoardReply, FrameKind::Config] {
        let frame = Frame::new(kind, 3, w.as_slice()).unwrap();
        let mut buf = [0_u8; MAX_FRAME];
        let n = frame.encode(&mut buf).unwrap();
        assert!(feed(&mut s, &mut d, &buf[..n]).is_empty(), "{kind:?}");
    }
    assert_eq!(*s.settings(), before);
    assert!(d.applied.is_none());
    assert_eq!(s.link_errors(), 0);
}

/// The settings CRC is the CRC-32 of the settings encoding, and tells two drives apart.
#[test]
fn the_settings_crc_is_that_of_the_encoding() {
    use pil_link::board::session::settings_crc;
    let cfg = table1();
    let mut w = Writer::new();
    pil_link::settings::encode(&cfg, &mut w).unwrap();
    assert_eq!(settings_crc(&cfg), pil_link::crc32(w.as_slice()));
    let mut other = cfg;
    other.velocity_bandwidth_rad_s = 50.0;
    assert_ne!(settings_crc(&other), settings_crc(&cfg));
}

/// Fault names: the link's own, controller-core's, none, and a code nobody defines.
#[test]
fn fault_names_cover_the_link_the_drive_none_and_unknown_codes() {
    use controller_core::Fault;
    use controller_core::words::fault_code;
    use pil_link::board::session::fault_name;
    assert_eq!(fault_name(LINK_FAULT_CODE), "console link");
    assert_eq!(fault_name(fault_code(Some(Fault::Overspeed))), "overspeed");
    assert_eq!(fault_name(fault_code(Some(Fault::Stall))), "stall");
    assert_eq!(fault_name(fault_code(None)), "none");
    assert_eq!(fault_name(0xF0), "unknown");
}

/// identify's frequency-response run: ±0.3 pu PRBS of 13 bits, 0.8 pu preload.
const RUN: IdentifyRun = IdentifyRun {
    amplitude_pu: 0.3,
    prbs_bits: 13,
    prbs_hold_ticks: 1,
    prbs_periods: 2,
    velocity_bandwidth_rad_s: 15.0,
    load_pu: 0.8,
    reverse_every_ticks: 0,
    ticks: 16_382,
};

#[test]
fn identify_runs_the_measurement_loop_and_answers_the_record_s_rate_and_channels() {
    let (mut s, mut d) = (session(), MockDrive::default());
    let running = *s.settings();
    let body = ask(&mut s, &mut d, &Request::Identify(RUN)).unwrap();
    let info = ScopeInfo::decode(&body).unwrap();
    assert_eq!((info.rate_hz, info.channels), (4000, CHANNELS));
    let (cfg, run) = d.identified.unwrap();
    // The request arrived whole, and the drive runs identify's loop on the running drive.
    assert_eq!(run, RUN);
    assert_eq!(cfg.position_bandwidth_rad_s, 0.0);
    assert_eq!(cfg.accel_feedback.mode, controller_core::AfbMode::Off);
    assert_eq!(cfg.velocity_bandwidth_rad_s, 15.0);
    assert_eq!(cfg.current_bandwidth_rad_s, running.current_bandwidth_rad_s);
    assert_eq!(*s.settings(), running, "the running settings stay");
    // The run is its own enable: nothing else runs beside it.
    let (code, msg) = ask(&mut s, &mut d, &Request::Identify(RUN)).unwrap_err();
    assert_eq!(code, Refusal::Enabled);
    assert!(msg.contains("identify"), "{msg}");
}

#[test]
fn identify_is_refused_while_enabled_faulted_or_out_of_range_naming_the_key() {
    let (mut s, mut d) = (session(), MockDrive::default());
    ask(&mut s, &mut d, &Request::Enable).unwrap();
    let (code, _) = ask(&mut s, &mut d, &Request::Identify(RUN)).unwrap_err();
    assert_eq!(code, Refusal::Enabled);
    let mut d = MockDrive {
        fault: 3,
        ..MockDrive::default()
    };
    let (code, _) = ask(&mut s, &mut d, &Request::Identify(RUN)).unwrap_err();
    assert_eq!(code, Refusal::Faulted);
    let mut d = MockDrive::default();
    for (run, key) in [
        (
            IdentifyRun {
                prbs_bits: 3,
                ..RUN
            },
            "identify.prbs_bits",
        ),
        (
            IdentifyRun {
                amplitude_pu: 5.0,
                ..RUN
            },
            "identify.amplitude_pu",
        ),
        (
            IdentifyRun {
                load_pu: f32::NAN,
                ..RUN
            },
            "identify.load_pu",
        ),
        (
            IdentifyRun {
                velocity_bandwidth_rad_s: -1.0,
                ..RUN
            },
            "velocity_bandwidth_rad_s",
        ),
    ] {
        let (code, msg) = ask(&mut s, &mut d, &Request::Identify(run)).unwrap_err();
        assert_eq!(code, Refusal::Invalid, "{msg}");
        assert!(msg.contains(key), "{key}: {msg}");
        assert!(d.identified.is_none() && !d.enabled);
    }
}

#[test]
fn a_run_of_the_host_s_default_length_is_asked_whole_and_a_cut_stream_is_marked() {
    // 13 bits held 1 tick: 8191 ticks a period.
    assert_eq!(RUN.prbs_period_ticks(), Some(8_191));
    let reversal = IdentifyRun {
        amplitude_pu: 0.0,
        reverse_every_ticks: 4_000,
        ..RUN
    };
    assert_eq!(reversal.prbs_period_ticks(), None);
    // identify's default record, 32 periods: four times the board's 65,536-sample ring,
    // which the board streams while it records.
    let default_run = IdentifyRun {
        prbs_periods: 32,
        ticks: 32 * 8_191,
        ..RUN
    };
    let (mut s, mut d) = (session(), MockDrive::default());
    ask(&mut s, &mut d, &Request::Identify(default_run)).unwrap();
    assert_eq!(d.identified.map(|(_, r)| r.ticks), Some(262_112));
    // The request carries the length whole.
    let mut w = Writer::new();
    default_run.encode(&mut w).unwrap();
    let mut r = pil_link::wire::Reader::new(FrameKind::BoardRequest, w.as_slice());
    assert_eq!(IdentifyRun::decode(&mut r).unwrap(), default_run);
    // An empty chunk below the run's ticks marks a run the board ended early, through
    // the wire and back; a chunk with samples, or one at the end, does not.
    let mut w = Writer::new();
    ScopeChunk::new(70_000).encode(&mut w).unwrap();
    let mark = ScopeChunk::decode(w.as_slice()).unwrap();
    assert!(is_cut_end(&mark, default_run.ticks));
    assert!(!is_cut_end(&mark, 70_000));
    let mut with_sample = ScopeChunk::new(0);
    with_sample.push(ScopeSample::default());
    assert!(!is_cut_end(&with_sample, default_run.ticks));
    // A run of no ticks names the keys that set its length, and fits a reply.
    let msg = IdentifyError::NoTicks.to_string();
    assert!(
        msg.contains("identify.prbs_periods") && msg.contains("identify.reversal_hold_s"),
        "{msg}"
    );
    // The reply's head is 3 bytes: version, op, refusal.
    assert!(msg.len() + 3 <= MAX_PAYLOAD, "{} bytes: {msg}", msg.len());
    // The widest register saturates instead of overflowing.
    let wide = IdentifyRun {
        prbs_bits: 32,
        prbs_hold_ticks: u16::MAX,
        ..RUN
    };
    assert_eq!(wide.prbs_period_ticks(), Some(u32::MAX));
}

#[test]
fn a_board_without_measurements_refuses_identify() {
    /// The trait's own `identify`.
    struct Plain(MockDrive);
    impl Drive for Plain {
        fn apply(&mut self, cfg: &DriveConfig) -> Result<(), ConfigError> {
            self.0.apply(cfg)
        }
        fn enabled(&self) -> bool {
            self.0.enabled()
        }
        fn set_enabled(&mut self, on: bool) {
            self.0.set_enabled(on);
        }
        fn fault_code(&self) -> u8 {
            self.0.fault_code()
        }
        fn save(&mut self, record: &[u8; RECORD_LEN]) -> Result<(), SaveError> {
            self.0.save(record)
        }
        fn fault_history(&self) -> FaultHistory {
            self.0.fault_history()
        }
        fn scope(&mut self, on: bool) -> ScopeInfo<'_> {
            self.0.scope(on)
        }
        fn enter_safe_state(&mut self) {
            self.0.enter_safe_state();
        }
    }
    let mut s = session();
    let mut d = Plain(MockDrive::default());
    let replies: Vec<_> = wire(&Request::Identify(RUN), 3)
        .iter()
        .filter_map(|&b| s.on_byte(b, &mut d))
        .collect();
    let reply = Reply::decode(replies[0].payload()).unwrap();
    let (code, msg) = reply.result.unwrap_err();
    assert_eq!(code, Refusal::Invalid);
    assert!(msg.contains("does not run measurements"), "{msg}");
    assert!(!d.0.enabled);
}

/// Table 1's drive with a `[drive.pmsm]` whose encoder offset is not measured.
fn uncalibrated_pmsm() -> BoardSession {
    let mut cfg = table1();
    cfg.pmsm = Some(controller_core::foc::PmsmConfig {
        pole_pairs: 7,
        d_inductance_pu_s: 3e-4,
        q_inductance_pu_s: 4.5e-4,
        flux_linkage_pu: 1.0,
        dc_bus_pu: 2.2,
        encoder_offset_elec_deg: None,
        encoder_reversed: false,
        angle_advance_ticks: 1.5,
        pwm_period_counts: 4200,
        commutation_min_speed_pu: 0.05,
        commutation_trip_s: 0.02,
    });
    BoardSession::new(cfg, Origin::Baked, 0x0001_0000, "pmsm")
}

fn settings() -> CalibrationSettings {
    CalibrationSettings {
        current_rate_hz: 4000.0,
        ..CalibrationSettings::default()
    }
}

#[test]
fn an_uncalibrated_pmsm_drive_refuses_to_run_until_its_calibration_is_set() {
    let (mut s, mut d) = (uncalibrated_pmsm(), MockDrive::default());
    for request in [Request::Enable, Request::Identify(RUN)] {
        let (code, msg) = ask(&mut s, &mut d, &request).unwrap_err();
        assert_eq!(code, Refusal::Uncalibrated, "{msg}");
        assert!(
            msg.contains("drive.pmsm.encoder_offset_elec_deg is not set")
                && msg.contains("stiffdrive identify --board")
                && msg.contains("calibrate"),
            "{msg}"
        );
        assert!(!d.enabled && d.identified.is_none());
    }
    // No offset to get yet; the calibration's keys set, the offset last.
    let get = |s: &mut BoardSession, d: &mut MockDrive, key| {
        ask(s, d, &Request::Get(key)).map(|b| get_f64(&b).unwrap())
    };
    let (code, _) = get(&mut s, &mut d, "drive.pmsm.encoder_offset_elec_deg").unwrap_err();
    assert_eq!(code, Refusal::NotPresent);
    for (key, value) in [
        ("drive.pmsm.pole_pairs", 5.0),
        ("drive.pmsm.d_inductance_pu_s", 2e-4),
        ("drive.pmsm.q_inductance_pu_s", 2.5e-4),
        ("drive.pmsm.encoder_reversed", 1.0),
        ("drive.pmsm.encoder_offset_elec_deg", 137.25),
    ] {
        ask(&mut s, &mut d, &Request::Set(key, value)).unwrap();
        assert_eq!(get(&mut s, &mut d, key).unwrap(), f64::from(value as f32));
    }
    let p = s.settings().pmsm.unwrap();
    assert_eq!(p.encoder_offset_elec_deg, Some(137.25));
    assert!(p.encoder_reversed);
    assert_eq!(d.applied.and_then(|c| c.pmsm), Some(p), "the drive rebuilt");
    // Out of range, or not 0 or 1: refused naming the key.
    for (key, value) in [
        ("drive.pmsm.encoder_offset_elec_deg", 400.0),
        ("drive.pmsm.encoder_reversed", 0.5),
        ("drive.pmsm.pole_pairs", 0.0),
    ] {
        let (code, msg) = ask(&mut s, &mut d, &Request::Set(key, value)).unwrap_err();
        assert_eq!(code, Refusal::Invalid, "{msg}");
        assert!(msg.contains(key), "{msg}");
    }
    ask(&mut s, &mut d, &Request::Enable).unwrap();
    assert!(d.enabled);
    // A DC drive has none of these keys.
    let (mut s, mut d) = (session(), MockDrive::default());
    let (code, _) = get(&mut s, &mut d, "drive.pmsm.pole_pairs").unwrap_err();
    assert_eq!(code, Refusal::NotPresent);
}

#[test]
fn calibrate_runs_the_sequence_on_a_pmsm_drive_and_is_refused_naming_why() {
    let (mut s, mut d) = (uncalibrated_pmsm(), MockDrive::default());
    let body = ask(&mut s, &mut d, &Request::Calibrate(settings())).unwrap();
    let info = ScopeInfo::decode(&body).unwrap();
    assert_eq!((info.rate_hz, info.channels), (4000, calibrate::CHANNELS));
    let (cfg, seq) = d.calibrated.unwrap();
    assert_eq!(cfg, *s.settings(), "on the running settings");
    assert_eq!(
        seq,
        Calibration::new(&settings()).unwrap(),
        "the request's sequence"
    );
    // Its own enable: nothing else beside it.
    let (code, msg) = ask(&mut s, &mut d, &Request::Calibrate(settings())).unwrap_err();
    assert_eq!(code, Refusal::Enabled, "{msg}");
    let mut d = MockDrive {
        fault: 3,
        ..MockDrive::default()
    };
    let (code, _) = ask(&mut s, &mut d, &Request::Calibrate(settings())).unwrap_err();
    assert_eq!(code, Refusal::Faulted);
    let mut d = MockDrive::default();
    for (bad, says) in [
        (
            CalibrationSettings {
                current_rate_hz: 8000.0,
                ..settings()
            },
            "current_rate_hz",
        ),
        (
            CalibrationSettings {
                sweep_hz: 0.0,
                ..settings()
            },
            "sweep_hz",
        ),
    ] {
        let (code, msg) = ask(&mut s, &mut d, &Request::Calibrate(bad)).unwrap_err();
        assert_eq!(code, Refusal::Invalid, "{msg}");
        assert!(msg.contains(says), "{says}: {msg}");
        assert!(d.calibrated.is_none() && !d.enabled);
    }
    // A DC drive has no motor calibration.
    let (mut s, mut d) = (session(), MockDrive::default());
    let (code, msg) = ask(&mut s, &mut d, &Request::Calibrate(settings())).unwrap_err();
    assert_eq!(code, Refusal::Invalid);
    assert!(msg.contains("[drive.pmsm]"), "{msg}");
}
