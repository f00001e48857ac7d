//! Drive faults. A faulted drive commands zero torque and stays faulted until
//! [`crate::Controller::reset`].

use core::fmt;

/// A latched drive fault.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fault {
    /// |velocity estimate| above `faults.overspeed_pu`.
    Overspeed,
    /// |commanded − measured position| above `faults.following_error_rev` (× `encoder_cpr`
    /// counts).
    FollowingError,
    /// Encoder counts changed between two ticks by more than the speed allows.
    EncoderJump,
    /// The external fault input was set.
    External,
    /// |measured current| above `faults.overcurrent_ratio × torque_limit_pu` for
    /// `faults.overcurrent_ticks` current ticks in a row ([`crate::protection`]).
    Overcurrent,
    /// The I²t thermal model of the winding reached its trip level ([`crate::protection`]).
    Overload,
    /// The torque reference at its limit with the speed under `faults.stall_speed_pu` for
    /// `faults.stall_time_s` ([`crate::protection`]).
    Stall,
    /// A PMSM's electrical angle looks more than 30° off (a wrong encoder offset or pole
    /// pair count) for `pmsm.commutation_trip_s` ([`crate::foc::CommutationCheck`]).
    Commutation,
}

impl Fault {
    /// A short, stable identifier (`snake_case`), for summaries and logs.
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            Self::Overspeed => "overspeed",
            Self::FollowingError => "following_error",
            Self::EncoderJump => "encoder_jump",
            Self::External => "external",
            Self::Overcurrent => "overcurrent",
            Self::Overload => "overload",
            Self::Stall => "stall",
            Self::Commutation => "commutation",
        }
    }
}

impl fmt::Display for Fault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::Overspeed => "overspeed",
            Self::FollowingError => "following error",
            Self::EncoderJump => "encoder count jump",
            Self::External => "external fault input",
            Self::Overcurrent => "overcurrent",
            Self::Overload => "overload (I²t)",
            Self::Stall => "stall",
            Self::Commutation => "commutation (electrical angle off)",
        })
    }
}
