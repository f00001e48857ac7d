//! Loop-in-the-loop: replay a recorded sensor sequence through the firmware's tick code and
//! compare every output word, bit for bit, with the host build of controller-core.
//!
//! `build.rs` reads the recording `lil/inputs.csv`, runs [`words::reference_run`] (host
//! core) on it and embeds both the inputs ([`INPUTS`]) and the expected words
//! ([`EXPECTED`]) in the image. [`replay`] feeds the records to [`App::on_current_tick`] and
//! [`App::on_velocity_tick`] through a board stand-in, exactly as the timer interrupts do,
//! and compares. The `fw-lil` image runs it on the Cortex-M4F under QEMU; the host test
//! `tests/loop_in_loop.rs` runs it on the host.

pub mod words;

use controller_core::{CurrentOutputs, Pu};

use crate::app::{velocity_inputs, App, SetpointSource};
use crate::board::{CurrentLoopIo, VelocityLoopIo};
use words::{tick_ratio, velocity_after, LilInput, INPUT_RECORD_BYTES};

/// The recorded inputs, [`INPUT_RECORD_BYTES`] per 4 kHz period.
pub static INPUTS: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/lil_inputs.bin"));
/// The expected output words (u32 LE), in run order, from the host build of the core.
pub static EXPECTED: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/lil_expected.bin"));

/// The board stand-in of a replay: serves one record to both loops and keeps what the
/// current loop applied.
#[derive(Clone, Copy, Debug, Default)]
pub struct ReplayIo {
    /// The record of this period.
    pub record: LilInput,
    /// Voltage the current tick applied [pu].
    pub applied_voltage_pu: Pu,
    /// Enable output the current tick set.
    pub enabled: bool,
}

impl CurrentLoopIo for ReplayIo {
    fn encoder_count(&mut self) -> u32 {
        self.record.encoder_count
    }
    fn current_pu(&mut self) -> Option<Pu> {
        Some(self.record.current_pu)
    }
    fn set_voltage_pu(&mut self, voltage_pu: Pu) -> bool {
        self.applied_voltage_pu = voltage_pu;
        true
    }
    fn set_enable(&mut self, enabled: bool) -> bool {
        self.enabled = enabled;
        true
    }
}

impl VelocityLoopIo for ReplayIo {
    fn encoder_count(&mut self) -> u32 {
        self.record.encoder_count
    }
    fn fault_input(&mut self) -> bool {
        self.record.fault_input
    }
}

/// The first output word that differed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Mismatch {
    /// 4 kHz period.
    pub period: u32,
    /// Index of the word in the whole run.
    pub word: u32,
    /// Host core's word.
    pub expected: u32,
    /// This build's word.
    pub actual: u32,
}

/// Result of a replay.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReplayReport {
    /// Periods replayed.
    pub periods: u32,
    /// Output words compared.
    pub words: u32,
    /// Words that differed.
    pub mismatches: u32,
    /// The first difference.
    pub first_mismatch: Option<Mismatch>,
    /// FNV-1a digest of this build's output words.
    pub digest: u32,
    /// Expected words left over (the run produced fewer than recorded): must be 0.
    pub missing_words: u32,
    /// Current ticks that ran with the power stage enabled.
    pub enabled_ticks: u32,
    /// Last current-tick outputs.
    pub last: CurrentOutputs,
}

/// FNV-1a over 32-bit words (byte-wise, little endian).
#[must_use]
pub fn fnv1a(mut hash: u32, word: u32) -> u32 {
    for b in word.to_le_bytes() {
        hash ^= u32::from(b);
        hash = hash.wrapping_mul(0x0100_0193);
    }
    hash
}

/// FNV-1a offset basis.
pub const FNV_OFFSET: u32 = 0x811C_9DC5;

/// Replay `inputs` through `app` (the interrupts' code) with `profile`, comparing with
/// `expected` words.
pub fn replay<S: SetpointSource>(
    app: &mut App,
    profile: &mut S,
    ratio: u32,
    inputs: &[u8],
    expected: &[u8],
) -> ReplayReport {
    let mut expected_words = expected.chunks_exact(4).map(|c| {
        c.iter()
            .rev()
            .fold(0_u32, |acc, b| (acc << 8) | u32::from(*b))
    });
    let mut report = ReplayReport {
        periods: 0,
        words: 0,
        mismatches: 0,
        first_mismatch: None,
        digest: FNV_OFFSET,
        missing_words: 0,
        enabled_ticks: 0,
        last: CurrentOutputs::default(),
    };
    let mut check = |report: &mut ReplayReport, period: u32, words: &[u32]| {
        for &actual in words {
            report.digest = fnv1a(report.digest, actual);
            match expected_words.next() {
                Some(expected) if expected == actual => {}
                Some(expected) => {
                    report.mismatches += 1;
                    if report.first_mismatch.is_none() {
                        report.first_mismatch = Some(Mismatch {
                            period,
                            word: report.words,
                            expected,
                            actual,
                        });
                    }
                }
                None => report.mismatches += 1,
            }
            report.words += 1;
        }
    };
    let mut io = ReplayIo::default();
    for (k, chunk) in (0_u32..).zip(inputs.chunks_exact(INPUT_RECORD_BYTES)) {
        let mut rec = [0_u8; INPUT_RECORD_BYTES];
        rec.copy_from_slice(chunk);
        // A record that names no input (a fault-input word other than 0 or 1) is a
        // mismatch, and the replay stops there.
        let Ok(record) = LilInput::from_bytes(&rec) else {
            report.mismatches += 1;
            break;
        };
        io.record = record;
        let out = app.on_current_tick(&mut io);
        report.enabled_ticks += u32::from(io.enabled);
        report.last = out;
        check(&mut report, k, &out.to_words());
        if velocity_after(k, ratio) {
            let v = app.on_velocity_tick(velocity_inputs(&mut io, profile));
            check(&mut report, k, &v.to_words());
        }
        report.periods += 1;
    }
    report.missing_words = expected_words.count() as u32;
    report
}

/// Build the run's app (the baked drive, [`crate::drive::baked`]) and profile and replay the
/// embedded recording.
///
/// # Errors
/// The app's configuration error (a baked drive that does not decode is
/// [`crate::app::AppError::Settings`]).
pub fn replay_embedded() -> Result<ReplayReport, crate::app::AppError> {
    let cfg = crate::drive::baked().map_err(crate::app::AppError::Settings)?;
    let mut app = App::new(&cfg, cfg.counter_bits, crate::app::DEFAULT_TRACE)?;
    app.set_enable_request(true);
    let mut profile = controller_core::Profile::new(&words::profile_config(), &cfg)
        .map_err(crate::app::AppError::Config)?;
    Ok(replay(
        &mut app,
        &mut profile,
        tick_ratio(&cfg),
        INPUTS,
        EXPECTED,
    ))
}
