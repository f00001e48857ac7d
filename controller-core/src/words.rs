//! Tick outputs as raw 32-bit words, and the fault codes: the one layout the firmware's
//! loop-in-the-loop check, its trace, the PIL link and the harness share. Fixed-point values
//! are their two's-complement bits; a fault is its [`Fault::code`] (0 = none).
//!
//! ```text
//! current tick  (4 words): voltage_cmd | current_ref | accel_fb | fault
//! velocity tick (8 words): current_ref | accel_fb | velocity_cmd | velocity_est |
//!                          acceleration_est | position_error (Q24.8) | disturbance_est | fault
//! ```

use crate::controller::{CurrentOutputs, VelocityOutputs};
use crate::fault::Fault;

/// Output words of a current tick.
pub const CURRENT_WORDS: usize = 4;
/// Output words of a velocity tick.
pub const VELOCITY_WORDS: usize = 8;
/// The name of each word of [`CurrentOutputs::to_words`].
pub const CURRENT_FIELDS: [&str; CURRENT_WORDS] =
    ["voltage_cmd_pu", "current_ref_pu", "accel_fb_pu", "fault"];
/// The name of each word of [`VelocityOutputs::to_words`].
pub const VELOCITY_FIELDS: [&str; VELOCITY_WORDS] = [
    "current_ref_pu",
    "accel_fb_pu",
    "velocity_cmd_pu",
    "velocity_est_pu",
    "acceleration_est_pu_s",
    "position_error_counts",
    "disturbance_est_pu",
    "fault",
];

impl Fault {
    /// Every fault, in code order (codes 1, 2, ...).
    pub const ALL: [Self; 8] = [
        Self::Overspeed,
        Self::FollowingError,
        Self::EncoderJump,
        Self::External,
        Self::Overcurrent,
        Self::Overload,
        Self::Stall,
        Self::Commutation,
    ];

    /// The fault's code, 1..=8 (0 is "no fault"). Stable across versions.
    #[must_use]
    pub const fn code(self) -> u8 {
        match self {
            Self::Overspeed => 1,
            Self::FollowingError => 2,
            Self::EncoderJump => 3,
            Self::External => 4,
            Self::Overcurrent => 5,
            Self::Overload => 6,
            Self::Stall => 7,
            Self::Commutation => 8,
        }
    }

    /// The fault of a code 1..=8; `None` for any other code.
    ///
    /// ```
    /// use controller_core::Fault;
    /// for f in Fault::ALL {
    ///     assert_eq!(Fault::from_code(f.code()), Some(f));
    /// }
    /// assert_eq!(Fault::from_code(0), None);
    /// ```
    #[must_use]
    pub const fn from_code(code: u8) -> Option<Self> {
        match code {
            1 => Some(Self::Overspeed),
            2 => Some(Self::FollowingError),
            3 => Some(Self::EncoderJump),
            4 => Some(Self::External),
            5 => Some(Self::Overcurrent),
            6 => Some(Self::Overload),
            7 => Some(Self::Stall),
            8 => Some(Self::Commutation),
            _ => None,
        }
    }
}

/// The code of a latched fault state: 0 = none, else [`Fault::code`].
#[must_use]
pub const fn fault_code(fault: Option<Fault>) -> u8 {
    match fault {
        None => 0,
        Some(f) => f.code(),
    }
}

/// Inverse of [`fault_code`]: `Ok(None)` for 0, `Err(code)` for a code that names no fault.
pub const fn fault_from_code(code: u8) -> Result<Option<Fault>, u8> {
    match (code, Fault::from_code(code)) {
        (0, _) => Ok(None),
        (_, Some(f)) => Ok(Some(f)),
        (c, None) => Err(c),
    }
}

impl CurrentOutputs {
    /// The outputs as words (module layout).
    #[must_use]
    pub fn to_words(&self) -> [u32; CURRENT_WORDS] {
        [
            self.voltage_cmd_pu.to_bits() as u32,
            self.current_ref_pu.to_bits() as u32,
            self.accel_fb_pu.to_bits() as u32,
            u32::from(fault_code(self.fault)),
        ]
    }
}

impl VelocityOutputs {
    /// The outputs as words (module layout).
    #[must_use]
    pub fn to_words(&self) -> [u32; VELOCITY_WORDS] {
        [
            self.current_ref_pu.to_bits() as u32,
            self.accel_fb_pu.to_bits() as u32,
            self.velocity_cmd_pu.to_bits() as u32,
            self.velocity_est_pu.to_bits() as u32,
            self.acceleration_est_pu_s.to_bits() as u32,
            self.position_error_counts.to_bits() as u32,
            self.disturbance_est_pu.to_bits() as u32,
            u32::from(fault_code(self.fault)),
        ]
    }
}
