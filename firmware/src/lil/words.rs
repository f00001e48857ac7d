//! Loop-in-the-loop: the run's settings, the record layout and the reference run.
//!
//! The drive of the run is the one `build.rs` bakes (`STIFFDRIVE_DRIVE`, else
//! `configs/machines/table1.toml`; `firmware::drive::baked` in the image). A DC drive replays
//! `lil/inputs.csv` ([`LilInput`]: encoder count, current, fault input); a PMSM drive
//! `lil/inputs-pmsm.csv` ([`PmsmLilInput`]: encoder count, phase currents a and b, fault
//! input), its current ticks `Controller::pmsm_tick` (outputs: `PmsmOutputs`' words). This file depends on controller-core and `core`
//! only, because it is compiled twice: into
//! the firmware library (target and host) and into `build.rs` (host), where
//! [`reference_run`] computes the expected outputs with the HOST build of the core.
//!
//! A run is a sequence of 4 kHz periods. In period `k` the current tick runs on record `k`;
//! when `k % ratio == ratio − 1` (every 2nd period at 4 kHz / 2 kHz) the velocity tick runs
//! after it, on the same record's encoder count and fault input and the next profile
//! setpoint: the order the aligned timer interrupts give on the target.

use controller_core::{
    Controller, CurrentInputs, DriveConfig, PmsmInputs, Profile, ProfileConfig, ProfileKind, Pu,
    Setpoint, VelocityInputs,
};

/// Bytes per input record: encoder count (u32 LE), current (Q16.16 bits, i32 LE), fault
/// input (u32 LE, 0 or 1).
pub const INPUT_RECORD_BYTES: usize = 4 * LilInput::WORDS;

/// One recorded 4 kHz period of sensor inputs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LilInput {
    /// Raw encoder counter \[counts\].
    pub encoder_count: u32,
    /// Measured current \[pu\].
    pub current_pu: Pu,
    /// External fault input.
    pub fault_input: bool,
}

controller_core::tick_words!(LilInput {
    encoder_count: u32,
    current_pu: Pu,
    fault_input: bool,
});

/// Bytes per PMSM input record: encoder count (u32 LE), phase currents a and b (Q16.16
/// bits, i32 LE), fault input (u32 LE, 0 or 1).
pub const PMSM_INPUT_RECORD_BYTES: usize = 4 * PmsmLilInput::WORDS;

/// One recorded period of a PMSM drive's sensor inputs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PmsmLilInput {
    /// Raw encoder counter \[counts\].
    pub encoder_count: u32,
    /// Measured phase currents a and b \[pu\].
    pub phase_current_pu: [Pu; 2],
    /// External fault input.
    pub fault_input: bool,
}

controller_core::tick_words!(PmsmLilInput {
    encoder_count: u32,
    phase_current_pu: [Pu; 2],
    fault_input: bool,
});

/// Words as little-endian bytes (`N` = 4 × the words).
fn words_to_bytes<const N: usize>(words: &[u32]) -> [u8; N] {
    let mut b = [0_u8; N];
    for (chunk, w) in b.chunks_exact_mut(4).zip(words) {
        chunk.copy_from_slice(&w.to_le_bytes());
    }
    b
}

/// Little-endian bytes as words.
fn bytes_to_words<const W: usize>(b: &[u8]) -> [u32; W] {
    let mut words = [0_u32; W];
    for (w, chunk) in words.iter_mut().zip(b.chunks_exact(4)) {
        let mut le = [0_u8; 4];
        le.copy_from_slice(chunk);
        *w = u32::from_le_bytes(le);
    }
    words
}

/// A record type's bytes (`to_bytes`, `from_bytes` with `$bytes` bytes: its words
/// ([`controller_core::words`]), little-endian) and its [`LilRecord`], whose current tick
/// is `$tick` (record, controller → output words).
macro_rules! lil_record {
    ($ty:ident, $bytes:ident, $tick:expr) => {
        impl $ty {
            /// The record as bytes: its words, little-endian.
            #[must_use]
            pub fn to_bytes(self) -> [u8; $bytes] {
                words_to_bytes(&self.to_words())
            }

            /// A record from bytes; a fault-input word other than 0 or 1 is an error.
            pub fn from_bytes(b: &[u8; $bytes]) -> Result<Self, controller_core::words::BadWord> {
                Self::from_words(&bytes_to_words(b))
            }
        }

        impl LilRecord for $ty {
            const BYTES: usize = $bytes;
            fn from_chunk(chunk: &[u8]) -> Option<Self> {
                Self::from_bytes(chunk.try_into().ok()?).ok()
            }
            fn velocity_inputs(&self, setpoint: Setpoint) -> VelocityInputs {
                VelocityInputs {
                    encoder_count: self.encoder_count,
                    setpoint,
                    fault_input: self.fault_input,
                }
            }
            fn core_current_tick(
                &self,
                controller: &mut Controller,
                emit: &mut impl FnMut(&[u32]),
            ) {
                let tick = $tick;
                emit(&tick(self, controller));
            }
        }
    };
}

/// A recorded period's inputs of one motor kind: stored as [`LilRecord::BYTES`] bytes,
/// read by the bare core's ticks in [`reference_run`].
pub trait LilRecord: Sized {
    /// Bytes per record.
    const BYTES: usize;
    /// The record of `chunk`; `None` if it is not [`Self::BYTES`] long or a word names no
    /// input (a fault-input word other than 0 or 1).
    fn from_chunk(chunk: &[u8]) -> Option<Self>;
    /// The core's velocity-tick inputs: the record's encoder count and fault input, and
    /// `setpoint`.
    fn velocity_inputs(&self, setpoint: Setpoint) -> VelocityInputs;
    /// Run the bare core's current tick of this motor kind on the record; hand its output
    /// words to `emit`.
    fn core_current_tick(&self, controller: &mut Controller, emit: &mut impl FnMut(&[u32]));
}

lil_record!(
    LilInput,
    INPUT_RECORD_BYTES,
    |r: &LilInput, c: &mut Controller| c.current_tick(current_inputs(r)).to_words()
);
lil_record!(
    PmsmLilInput,
    PMSM_INPUT_RECORD_BYTES,
    |r: &PmsmLilInput, c: &mut Controller| c.pmsm_tick(r.pmsm_inputs()).to_words()
);

impl PmsmLilInput {
    /// The core's inputs for this record's current tick.
    #[must_use]
    pub fn pmsm_inputs(&self) -> PmsmInputs {
        PmsmInputs {
            encoder_count: self.encoder_count,
            phase_current_pu: self.phase_current_pu,
        }
    }
}

/// The motion of the run: after 25 ms at rest, a trapezoid to 0.5 pu in 0.25 s, 0.25 s at
/// speed, down in 0.25 s.
#[must_use]
pub const fn profile_config() -> ProfileConfig {
    ProfileConfig {
        kind: ProfileKind::Trapezoid,
        peak_velocity_pu: 0.5,
        accel_time_s: 0.25,
        hold_time_s: 0.25,
        decel_time_s: 0.25,
        start_delay_s: 0.025,
    }
}

/// Current ticks per velocity tick of a drive (≥ 1).
#[must_use]
pub fn tick_ratio(cfg: &DriveConfig) -> u32 {
    (cfg.current_rate_hz / cfg.velocity_rate_hz.max(1)).max(1)
}

/// Whether the velocity tick runs after the current tick of period `k`.
#[must_use]
pub fn velocity_after(k: u32, ratio: u32) -> bool {
    k % ratio == ratio - 1
}

/// The core's inputs for period `k`'s ticks.
#[must_use]
pub fn current_inputs(rec: &LilInput) -> CurrentInputs {
    CurrentInputs {
        encoder_count: rec.encoder_count,
        current_pu: rec.current_pu,
    }
}

/// Run the bare controller-core of drive `cfg` over `inputs` and hand every tick's output
/// words ([`controller_core::words`]) to `emit`, in run order. This is the reference the
/// firmware's App path must match.
///
/// # Errors
/// The core's configuration error for the run's settings.
pub fn reference_run<R: LilRecord>(
    cfg: &DriveConfig,
    inputs: impl IntoIterator<Item = R>,
    mut emit: impl FnMut(&[u32]),
) -> Result<(), controller_core::ConfigError> {
    let mut controller = Controller::new(cfg)?;
    let mut profile = Profile::new(&profile_config(), cfg)?;
    let ratio = tick_ratio(cfg);
    for (k, rec) in (0_u32..).zip(inputs) {
        rec.core_current_tick(&mut controller, &mut emit);
        if velocity_after(k, ratio) {
            let out = controller.velocity_tick(rec.velocity_inputs(profile.next()));
            emit(&out.to_words());
        }
    }
    Ok(())
}

/// [`reference_run`] of a PMSM drive's records: its current ticks are
/// `Controller::pmsm_tick` (13 words each: [`controller_core::PmsmOutputs`]).
///
/// # Errors
/// The core's configuration error for the run's settings.
pub fn reference_run_pmsm(
    cfg: &DriveConfig,
    inputs: impl IntoIterator<Item = PmsmLilInput>,
    emit: impl FnMut(&[u32]),
) -> Result<(), controller_core::ConfigError> {
    reference_run(cfg, inputs, emit)
}
