//! `Identify`: the board runs one of identify's measurements in its own loops and streams
//! the record (`machine-workflows/src/identify/measure.rs` describes the two runs).
//!
//! The drive runs the running settings changed as identify's measurement wants them: speed
//! mode at zero speed (position loop off), acceleration feedback off, the velocity loop at
//! [`IdentifyRun::velocity_bandwidth_rad_s`]; with a PRBS ([`IdentifyRun::excitation`],
//! controller-core's generator, the one the host measurement uses) added to the torque
//! reference. The rig's load torque is [`IdentifyRun::load_pu`] from the first tick,
//! reversed every [`IdentifyRun::reverse_every_ticks`] (the lost-motion test); on QEMU the
//! virtual machine takes it, a real board has no rig and ignores it. It is its own enable:
//! refused while the user has the drive enabled or a fault is latched; the drive is
//! enabled for [`IdentifyRun::ticks`] current ticks, each recorded, then disabled, and the
//! running settings are back.
//!
//! The reply is a [`ScopeInfo`](super::scope::ScopeInfo) (the current-loop rate, the
//! channels [`CHANNELS`]); `ScopeData` frames follow with every recorded tick, numbered
//! from 0 without a gap, while the board records: the board holds only what the link is
//! behind, so a run is as long as the link keeps up with it, not as long as the board's
//! memory. A run that ends before its ticks (the board's buffer overran on a slow link,
//! or a `Disable`) ends its stream with an empty chunk numbered with the ticks it
//! recorded ([`is_cut_end`]); an overrun is in the board's fault history as a
//! console-link fault.

use crate::LinkError;
use crate::wire::{Reader, Writer};
use controller_core::excitation::{
    ExcitationConfig, ExcitationParams, Injection, MAX_AMPLITUDE_PU, Waveform,
};
use controller_core::{AfbMode, ConfigError, DriveConfig};

/// The record's channels, per current tick: the excitation, the measured motor torque (a
/// DC winding's current; a PMSM's torque of its measured currents in the drive's model,
/// `Controller::pmsm_measured_torque`) and the torque reference, Q16.16 bits of per unit;
/// the encoder counter as the drive read it (its counter width, wrapping).
pub const CHANNELS: &str = "excitation_pu,current_pu,current_ref_pu,encoder_counts";

/// Whether `chunk` is the mark of a run cut short: no samples, numbered below the run's
/// `ticks` (the ticks recorded).
#[must_use]
pub fn is_cut_end(chunk: &super::scope::ScopeChunk, ticks: u32) -> bool {
    chunk.len == 0 && chunk.first < ticks
}

/// The names an excitation error gives its fields.
pub const EXCITATION_NAMES: ExcitationParams = ExcitationParams {
    amplitude_pu: "identify.amplitude_pu",
    start_or_bits: "identify.prbs_bits",
    end_or_hold: "identify.prbs_hold_ticks",
    duration_or_periods: "identify.prbs_periods",
};

/// One measurement run on the board.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IdentifyRun {
    /// PRBS amplitude on the torque reference \[pu\]; 0: no excitation.
    pub amplitude_pu: f32,
    /// PRBS register length \[bits\].
    pub prbs_bits: u8,
    /// Current ticks each PRBS bit is held.
    pub prbs_hold_ticks: u16,
    /// Whole PRBS periods.
    pub prbs_periods: u16,
    /// Velocity-loop bandwidth during the run \[rad/s\].
    pub velocity_bandwidth_rad_s: f32,
    /// The rig's load torque from the first tick \[pu\].
    pub load_pu: f32,
    /// Current ticks between reversals of the load torque; 0: never.
    pub reverse_every_ticks: u32,
    /// Current ticks recorded.
    pub ticks: u32,
}

/// Why a board cannot run an [`IdentifyRun`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum IdentifyError {
    /// The run's settings or excitation are refused (the error names the `identify.` key).
    Config(ConfigError),
    /// A run of zero ticks.
    NoTicks,
    /// This board does not run measurements.
    Unsupported,
}

impl core::fmt::Display for IdentifyError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Config(e) => write!(f, "identify: {e}"),
            Self::NoTicks => write!(
                f,
                "identify: a run of 0 ticks (identify.prbs_periods, identify.reversal_hold_s)"
            ),
            Self::Unsupported => write!(f, "identify: this board does not run measurements"),
        }
    }
}

impl IdentifyRun {
    /// The excitation, `None` for a run without one.
    #[must_use]
    pub fn excitation(&self) -> Option<ExcitationConfig> {
        (self.amplitude_pu != 0.0).then_some(ExcitationConfig {
            waveform: Waveform::Prbs {
                bits: self.prbs_bits,
                hold_ticks: self.prbs_hold_ticks,
                periods: self.prbs_periods,
            },
            amplitude_pu: self.amplitude_pu,
            injection: Injection::TorqueReference,
        })
    }

    /// Ticks in one PRBS period, `(2^prbs_bits - 1) * prbs_hold_ticks` (saturating); `None`
    /// for a run without excitation.
    #[must_use]
    pub fn prbs_period_ticks(&self) -> Option<u32> {
        self.excitation().map(|_| {
            let states = 1_u32
                .checked_shl(u32::from(self.prbs_bits))
                .map_or(u32::MAX, |n| n - 1);
            states.saturating_mul(u32::from(self.prbs_hold_ticks))
        })
    }

    /// The rig's load torque at current tick `tick` of the run \[pu\].
    #[must_use]
    pub fn load_at(&self, tick: u32) -> f32 {
        let reversals = tick.checked_div(self.reverse_every_ticks).unwrap_or(0);
        if reversals.is_multiple_of(2) {
            self.load_pu
        } else {
            -self.load_pu
        }
    }

    /// The settings the run's drive uses: `running` in speed mode, acceleration feedback
    /// off, the run's velocity bandwidth; checked by `design`, the excitation by its
    /// generator, the load torque against ±2 pu.
    ///
    /// # Errors
    /// [`IdentifyError::Config`] naming the `identify.` key or the `drive.` key refused.
    pub fn drive_config(&self, running: &DriveConfig) -> Result<DriveConfig, IdentifyError> {
        let mut cfg = *running;
        cfg.position_bandwidth_rad_s = 0.0;
        cfg.accel_feedback.mode = AfbMode::Off;
        cfg.velocity_bandwidth_rad_s = self.velocity_bandwidth_rad_s;
        let load_ok = self.load_pu.is_finite() && self.load_pu.abs() <= MAX_AMPLITUDE_PU;
        if !load_ok {
            return Err(IdentifyError::Config(ConfigError::OutOfRange {
                param: "identify.load_pu",
                value: self.load_pu,
                min: -MAX_AMPLITUDE_PU,
                max: MAX_AMPLITUDE_PU,
                min_exclusive: false,
            }));
        }
        controller_core::design(&cfg).map_err(IdentifyError::Config)?;
        if let Some(e) = self.excitation() {
            let rate = cfg.current_rate_hz as f32;
            controller_core::excitation::Excitation::new(&e, rate, EXCITATION_NAMES)
                .map_err(IdentifyError::Config)?;
        }
        Ok(cfg)
    }

    /// Writes the request arguments.
    ///
    /// # Errors
    /// `BufferTooSmall` (never in a fresh payload).
    pub fn encode(&self, w: &mut Writer) -> Result<(), LinkError> {
        w.u32(self.amplitude_pu.to_bits())?
            .u8(self.prbs_bits)?
            .u16(self.prbs_hold_ticks)?
            .u16(self.prbs_periods)?
            .u32(self.velocity_bandwidth_rad_s.to_bits())?
            .u32(self.load_pu.to_bits())?
            .u32(self.reverse_every_ticks)?
            .u32(self.ticks)?;
        Ok(())
    }

    /// Reads the request arguments.
    ///
    /// # Errors
    /// `BadPayload` for too few bytes.
    pub fn decode(r: &mut Reader<'_>) -> Result<Self, LinkError> {
        Ok(Self {
            amplitude_pu: f32::from_bits(r.u32()?),
            prbs_bits: r.u8()?,
            prbs_hold_ticks: r.u16()?,
            prbs_periods: r.u16()?,
            velocity_bandwidth_rad_s: f32::from_bits(r.u32()?),
            load_pu: f32::from_bits(r.u32()?),
            reverse_every_ticks: r.u32()?,
            ticks: r.u32()?,
        })
    }
}
