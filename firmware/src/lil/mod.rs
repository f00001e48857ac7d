//! Loop-in-the-loop: replay a recorded sensor sequence through the firmware's tick code and
//! compare every output word, bit for bit, with the host build of controller-core.
//!
//! `build.rs` reads the recording of the baked drive's motor (`lil/inputs.csv` for a DC
//! drive, `lil/inputs-pmsm.csv` for a PMSM), runs [`words::reference_run`] (or
//! [`words::reference_run_pmsm`]; host core) on it and embeds both the inputs ([`INPUTS`])
//! and the expected words ([`EXPECTED`]) in the image. [`replay`] feeds the records to
//! [`App::on_current_tick`] and [`App::on_velocity_tick`] through a board stand-in, exactly
//! as the timer interrupts do, and compares; [`replay_pmsm`] the same with
//! [`App::on_pmsm_tick`] (both [`replay_on`] with their [`ReplayBoard`]). The `fw-lil` image
//! runs it on the Cortex-M4F under QEMU; the host tests `tests/loop_in_loop.rs` and
//! `tests/loop_in_loop_pmsm.rs` run it on the host.

pub mod words;

use controller_core::{Fault, Pu};

use crate::app::{velocity_inputs, App, SetpointSource};
use crate::board::three_phase::PmsmLoopIo;
use crate::board::{CurrentLoopIo, VelocityLoopIo};
use words::{tick_ratio, velocity_after, LilInput, LilRecord, PmsmLilInput};

/// The recorded inputs, [`words::INPUT_RECORD_BYTES`] per period
/// ([`words::PMSM_INPUT_RECORD_BYTES`] for a PMSM drive).
pub static INPUTS: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/lil_inputs.bin"));
/// The expected output words (u32 LE), in run order, from the host build of the core.
pub static EXPECTED: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/lil_expected.bin"));

/// The board stand-in of a replay: serves one record to both loops and keeps what the
/// current loop applied.
#[derive(Clone, Copy, Debug, Default)]
pub struct ReplayIo {
    /// The record of this period.
    pub record: LilInput,
    /// Voltage the current tick applied \[pu\].
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

/// The three-phase board stand-in of a PMSM replay: serves one record to both loops and
/// keeps what the current loop applied.
#[derive(Clone, Copy, Debug, Default)]
pub struct PmsmReplayIo {
    /// The record of this period.
    pub record: PmsmLilInput,
    /// Duties the current tick applied [timer counts].
    pub duties: [u16; 3],
    /// Enable output the current tick set.
    pub enabled: bool,
}

impl PmsmLoopIo for PmsmReplayIo {
    fn encoder_count(&mut self) -> u32 {
        self.record.encoder_count
    }
    fn phase_currents_pu(&mut self) -> Option<[Pu; 2]> {
        Some(self.record.phase_current_pu)
    }
    fn set_duties(&mut self, duties: [u16; 3]) -> bool {
        self.duties = duties;
        true
    }
    fn set_enable(&mut self, enabled: bool) -> bool {
        self.enabled = enabled;
        true
    }
    fn fault_input(&mut self) -> bool {
        self.record.fault_input
    }
}

impl VelocityLoopIo for PmsmReplayIo {
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
    /// The fault the last current tick reported.
    pub final_fault: Option<Fault>,
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

/// The comparison of a replay's output words with the expected ones.
struct Checker<I> {
    expected: I,
    report: ReplayReport,
}

impl<I: Iterator<Item = u32>> Checker<I> {
    fn new(expected: I) -> Self {
        Self {
            expected,
            report: ReplayReport {
                periods: 0,
                words: 0,
                mismatches: 0,
                first_mismatch: None,
                digest: FNV_OFFSET,
                missing_words: 0,
                enabled_ticks: 0,
                final_fault: None,
            },
        }
    }

    /// Compare one tick's `words` of `period`.
    fn check(&mut self, period: u32, words: &[u32]) {
        let report = &mut self.report;
        for &actual in words {
            report.digest = fnv1a(report.digest, actual);
            match self.expected.next() {
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
    }

    /// The report, with the expected words left over.
    fn finish(mut self) -> ReplayReport {
        self.report.missing_words = self.expected.count() as u32;
        self.report
    }
}

/// The expected words (u32 LE) of `expected`.
fn expected_words(expected: &[u8]) -> impl Iterator<Item = u32> + '_ {
    expected.chunks_exact(4).map(|c| {
        c.iter()
            .rev()
            .fold(0_u32, |acc, b| (acc << 8) | u32::from(*b))
    })
}

/// A motor kind's replay: its board stand-in ([`ReplayIo`], [`PmsmReplayIo`]), the record
/// that stand-in serves and the current tick that reads it.
pub trait ReplayBoard: Default + VelocityLoopIo {
    /// One period's record.
    type Record: LilRecord;
    /// Serve `record` to this period's ticks and run `app`'s current tick on it; hand the
    /// tick's output words to `check` and return the fault it reported and the enable
    /// output it set.
    fn current_tick(
        &mut self,
        record: Self::Record,
        app: &mut App,
        check: impl FnOnce(&[u32]),
    ) -> (Option<Fault>, bool);
}

impl ReplayBoard for ReplayIo {
    type Record = LilInput;
    fn current_tick(
        &mut self,
        record: LilInput,
        app: &mut App,
        check: impl FnOnce(&[u32]),
    ) -> (Option<Fault>, bool) {
        self.record = record;
        let out = app.on_current_tick(self);
        check(&out.to_words());
        (out.fault, self.enabled)
    }
}

impl ReplayBoard for PmsmReplayIo {
    type Record = PmsmLilInput;
    fn current_tick(
        &mut self,
        record: PmsmLilInput,
        app: &mut App,
        check: impl FnOnce(&[u32]),
    ) -> (Option<Fault>, bool) {
        self.record = record;
        let out = app.on_pmsm_tick(self);
        check(&out.to_words());
        (out.fault, self.enabled)
    }
}

/// Replay `inputs` (records of `B`) through `app` (the interrupts' code) on board stand-in
/// `B` with `profile`, comparing with `expected` words.
pub fn replay_on<B: ReplayBoard, S: SetpointSource>(
    app: &mut App,
    profile: &mut S,
    ratio: u32,
    inputs: &[u8],
    expected: &[u8],
) -> ReplayReport {
    let mut c = Checker::new(expected_words(expected));
    let mut io = B::default();
    for (k, chunk) in (0_u32..).zip(inputs.chunks_exact(B::Record::BYTES)) {
        // A record that names no input (a fault-input word other than 0 or 1) is a
        // mismatch, and the replay stops there.
        let Some(record) = B::Record::from_chunk(chunk) else {
            c.report.mismatches += 1;
            break;
        };
        let (fault, enabled) = io.current_tick(record, app, |w| c.check(k, w));
        c.report.final_fault = fault;
        c.report.enabled_ticks += u32::from(enabled);
        if velocity_after(k, ratio) {
            let v = app.on_velocity_tick(velocity_inputs(&mut io, profile));
            c.check(k, &v.to_words());
        }
        c.report.periods += 1;
    }
    c.finish()
}

/// Replay `inputs` ([`LilInput`]s) through a DC drive's `app` ([`App::on_current_tick`])
/// with `profile`, comparing with `expected` words.
pub fn replay<S: SetpointSource>(
    app: &mut App,
    profile: &mut S,
    ratio: u32,
    inputs: &[u8],
    expected: &[u8],
) -> ReplayReport {
    replay_on::<ReplayIo, S>(app, profile, ratio, inputs, expected)
}

/// As [`replay`], for a PMSM drive's app ([`App::new_pmsm`]): the records are
/// [`PmsmLilInput`]s, the current ticks [`App::on_pmsm_tick`] (13 words each).
pub fn replay_pmsm<S: SetpointSource>(
    app: &mut App,
    profile: &mut S,
    ratio: u32,
    inputs: &[u8],
    expected: &[u8],
) -> ReplayReport {
    replay_on::<PmsmReplayIo, S>(app, profile, ratio, inputs, expected)
}

/// Build the run's app (the baked drive, [`crate::drive::baked`]) and profile and replay the
/// embedded recording (a PMSM drive's with [`replay_pmsm`]).
///
/// # Errors
/// The app's configuration error (a baked drive that does not decode is
/// [`crate::app::AppError::Settings`]).
pub fn replay_embedded() -> Result<ReplayReport, crate::app::AppError> {
    let cfg = crate::drive::baked().map_err(crate::app::AppError::Settings)?;
    let pmsm = cfg.pmsm.is_some();
    let mut app = if pmsm {
        App::new_pmsm(&cfg, cfg.counter_bits, crate::app::DEFAULT_TRACE)?
    } else {
        App::new(&cfg, cfg.counter_bits, crate::app::DEFAULT_TRACE)?
    };
    app.set_enable_request(true);
    let mut profile = controller_core::Profile::new(&words::profile_config(), &cfg)
        .map_err(crate::app::AppError::Config)?;
    let run = if pmsm { replay_pmsm } else { replay };
    Ok(run(
        &mut app,
        &mut profile,
        tick_ratio(&cfg),
        INPUTS,
        EXPECTED,
    ))
}
