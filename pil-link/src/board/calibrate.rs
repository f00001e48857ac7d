//! `Calibrate`: the board runs a PMSM's motor calibration in its own current-loop
//! interrupt and streams every tick (the estimation is the host's,
//! `machine-workflows/src/calibrate/estimate.rs`).
//!
//! The excitation is controller-core's sequencer ([`Calibration`]), the one the host's
//! simulated calibration drives, with the request's [`CalibrationSettings`]: each tick the
//! board samples the two phase currents and the encoder, runs the sequencer on the α
//! current, and sets the three duties of its voltage through the drive's modulator
//! (`[drive.pmsm]`'s bus and PWM period) with the stage on. No current loop and no encoder
//! offset are needed, so an uncalibrated drive runs it. It is its own enable: refused while
//! the drive is enabled or a fault is latched; the stage is off after its last tick.
//!
//! The reply is a [`ScopeInfo`](super::scope::ScopeInfo) (the current-loop rate, the
//! channels [`CHANNELS`]); `ScopeData` frames follow with the record, [`SAMPLES_PER_TICK`]
//! samples a tick ([`CalibrationRow::to_samples`]), numbered from 0 without a gap, as an
//! `Identify` record streams (`super::identify`: a run cut short ends with the mark
//! [`super::identify::is_cut_end`]).

use crate::LinkError;
use crate::wire::{Reader, Writer};
use controller_core::foc::calibration::{Calibration, CalibrationSettings, Stage};
use controller_core::per_unit::Pu;
use controller_core::{ConfigError, DriveConfig};

use super::scope::SCOPE_CHANNELS;

/// The record's channels, per current tick: the stage ([`stage_code`]), the voltage set
/// (α, β; Q16.16 bits of per unit), the commanded electrical angle (2^32 a turn), the two
/// phase currents as sampled (Q16.16 bits), the encoder counter as the drive read it.
pub const CHANNELS: &str = "stage,v_alpha_pu,v_beta_pu,phase,i_a_pu,i_b_pu,encoder_counts";

/// Record samples a tick takes: its seven channels in two scope samples of four.
pub const SAMPLES_PER_TICK: u32 = 2;

/// Why a board cannot run a calibration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CalibrateError {
    /// The settings are refused (the error names the key).
    Config(ConfigError),
    /// The drive has no `[drive.pmsm]`: a DC winding has no motor calibration.
    NotPmsm,
    /// Refused while the drive is enabled.
    Enabled,
    /// This board does not run the calibration.
    Unsupported,
}

impl core::fmt::Display for CalibrateError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Config(e) => write!(f, "calibrate: {e}"),
            Self::NotPmsm => write!(
                f,
                "calibrate: the drive has no [drive.pmsm] (a DC winding has no motor calibration)"
            ),
            Self::Enabled => write!(
                f,
                "calibrate: refused while the drive is enabled (disable it first; the \
                 calibration is its own enable)"
            ),
            Self::Unsupported => write!(f, "calibrate: this board does not run the calibration"),
        }
    }
}

/// The calibration `settings` checked for the drive `cfg`: a PMSM drive, the settings'
/// tick rate the drive's current-loop rate, the sequence buildable.
///
/// # Errors
/// [`CalibrateError::NotPmsm`], or the settings' error naming the setting.
pub fn sequence(
    cfg: &DriveConfig,
    settings: &CalibrationSettings,
) -> Result<Calibration, CalibrateError> {
    if cfg.pmsm.is_none() {
        return Err(CalibrateError::NotPmsm);
    }
    let rate = cfg.current_rate_hz as f32;
    if settings.current_rate_hz != rate {
        return Err(CalibrateError::Config(ConfigError::OutOfRange {
            param: "calibration current_rate_hz (the drive's current_rate_hz)",
            value: settings.current_rate_hz,
            min: rate,
            max: rate,
            min_exclusive: false,
        }));
    }
    Calibration::new(settings).map_err(CalibrateError::Config)
}

/// Writes the request arguments (ten 32-bit words).
///
/// # Errors
/// `BufferTooSmall` (never in a fresh payload).
pub fn encode(s: &CalibrationSettings, w: &mut Writer) -> Result<(), LinkError> {
    for x in [
        s.current_pu,
        s.ramp_pu_per_s,
        s.settle_s,
        s.record_s,
        s.square_pu,
        s.square_s,
    ] {
        w.u32(x.to_bits())?;
    }
    w.u32(s.turns)?;
    for x in [s.sweep_hz, s.current_rate_hz, s.voltage_limit_pu] {
        w.u32(x.to_bits())?;
    }
    Ok(())
}

/// Reads the request arguments.
///
/// # Errors
/// `BadPayload` for too few bytes.
pub fn decode(r: &mut Reader<'_>) -> Result<CalibrationSettings, LinkError> {
    let mut real = || r.u32().map(f32::from_bits);
    let (current_pu, ramp_pu_per_s, settle_s) = (real()?, real()?, real()?);
    let (record_s, square_pu, square_s) = (real()?, real()?, real()?);
    let turns = r.u32()?;
    let mut real = || r.u32().map(f32::from_bits);
    Ok(CalibrationSettings {
        current_pu,
        ramp_pu_per_s,
        settle_s,
        record_s,
        square_pu,
        square_s,
        turns,
        sweep_hz: real()?,
        current_rate_hz: real()?,
        voltage_limit_pu: real()?,
    })
}

/// The stage's number in the record: the levels 0 to 3 (level 0 settling, recording, level
/// 1 settling, recording), the square wave 4, the sweeps 5 and 6, done 7.
#[must_use]
pub const fn stage_code(stage: Stage) -> i32 {
    match stage {
        Stage::Level { index, recording } => 2 * (index as i32 & 1) + recording as i32,
        Stage::Square => 4,
        Stage::Forward => 5,
        Stage::Backward => 6,
        Stage::Done => 7,
    }
}

/// The stage of record number `code`; `None` for no stage.
#[must_use]
pub const fn stage_of(code: i32) -> Option<Stage> {
    Some(match code {
        0..=3 => Stage::Level {
            index: (code / 2) as u8,
            recording: code % 2 == 1,
        },
        4 => Stage::Square,
        5 => Stage::Forward,
        6 => Stage::Backward,
        7 => Stage::Done,
        _ => return None,
    })
}

/// One tick of the calibration as the board recorded it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CalibrationRow {
    /// The stage.
    pub stage: Stage,
    /// The α voltage set this tick \[pu\].
    pub v_alpha: Pu,
    /// The β voltage \[pu\].
    pub v_beta: Pu,
    /// The commanded electrical angle (2^32 a turn).
    pub phase: u32,
    /// Phase current a as sampled at the tick's start \[pu\].
    pub i_a: Pu,
    /// Phase current b \[pu\].
    pub i_b: Pu,
    /// The encoder counter as the drive read it (its counter width).
    pub count: u32,
}

impl CalibrationRow {
    /// The row as its two record samples.
    #[must_use]
    pub fn to_samples(&self) -> [[i32; SCOPE_CHANNELS]; SAMPLES_PER_TICK as usize] {
        [
            [
                stage_code(self.stage),
                self.v_alpha.to_bits(),
                self.v_beta.to_bits(),
                self.phase as i32,
            ],
            [self.i_a.to_bits(), self.i_b.to_bits(), self.count as i32, 0],
        ]
    }

    /// The row of two record samples; `None` for an unknown stage.
    #[must_use]
    pub fn from_samples(
        first: &[i32; SCOPE_CHANNELS],
        second: &[i32; SCOPE_CHANNELS],
    ) -> Option<Self> {
        let [stage, v_alpha, v_beta, phase] = *first;
        let [i_a, i_b, count, _] = *second;
        Some(Self {
            stage: stage_of(stage)?,
            v_alpha: Pu::from_bits(v_alpha),
            v_beta: Pu::from_bits(v_beta),
            phase: phase as u32,
            i_a: Pu::from_bits(i_a),
            i_b: Pu::from_bits(i_b),
            count: count as u32,
        })
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn the_settings_and_a_row_round_trip() {
        let s = CalibrationSettings {
            turns: 5,
            sweep_hz: 1.5,
            ..CalibrationSettings::default()
        };
        let mut w = Writer::new();
        encode(&s, &mut w).unwrap();
        assert_eq!(w.as_slice().len(), 40);
        let mut r = Reader::new(crate::FrameKind::BoardRequest, w.as_slice());
        assert_eq!(decode(&mut r).unwrap(), s);
        r.finish().unwrap();
        for code in 0..8 {
            assert_eq!(stage_code(stage_of(code).unwrap()), code);
        }
        assert_eq!(stage_of(8), None);
        let row = CalibrationRow {
            stage: Stage::Backward,
            v_alpha: Pu::from_num(-0.125),
            v_beta: Pu::from_num(1.25),
            phase: 0xF000_0001,
            i_a: Pu::from_num(-3.5),
            i_b: Pu::from_num(0.25),
            count: 65_535,
        };
        let [a, b] = row.to_samples();
        assert_eq!(CalibrationRow::from_samples(&a, &b), Some(row));
    }
}
