//! Drive faults. A faulted drive commands zero torque and stays faulted until
//! [`crate::Controller::reset`].

use core::fmt;

/// A latched drive fault.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fault {
    /// |velocity estimate| above `faults.overspeed_pu`.
    Overspeed,
    /// |commanded − measured position| above `faults.following_error_counts`.
    FollowingError,
    /// Encoder counts changed between two ticks by more than the speed allows.
    EncoderJump,
    /// The external fault input was set.
    External,
}

impl fmt::Display for Fault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::Overspeed => "overspeed",
            Self::FollowingError => "following error",
            Self::EncoderJump => "encoder count jump",
            Self::External => "external fault input",
        })
    }
}
