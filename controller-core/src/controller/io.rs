//! The inputs and outputs of the two ticks, and the quantized blocks
//! ([`super::Controller::blocks`]).

use crate::accel_feedback::AccelerationFeedback;
use crate::differentiator::Differentiator;
use crate::fault::Fault;
use crate::filter::LowPass;
use crate::notch::Notch;
use crate::observer::Observer;
use crate::per_unit::{Counts, CountsErr, Gain, PosGain, Pu, PuPerS};
use crate::pi::PiCoefficients;

/// Inputs of the current tick.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CurrentInputs {
    /// Raw encoder counter, wraps at `counter_bits`.
    pub encoder_count: u32,
    /// Measured current \[pu\].
    pub current_pu: Pu,
}

/// Outputs of the current tick.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CurrentOutputs {
    /// Voltage command \[pu\], within ±voltage_limit_pu.
    pub voltage_cmd_pu: Pu,
    /// Current (= torque) reference \[pu\], after the notch if one is set, within
    /// ±torque_limit_pu; 0 when faulted.
    pub current_ref_pu: Pu,
    /// Acceleration-feedback term added to the torque reference \[pu\].
    pub accel_fb_pu: Pu,
    /// Latched fault, if any.
    pub fault: Option<Fault>,
}

/// A motion command for one velocity tick (from [`crate::Profile::next`] or elsewhere).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Setpoint {
    /// Commanded position \[counts, unwrapped, Q48.16\].
    pub position_counts: Counts,
    /// Commanded velocity \[pu\].
    pub velocity_pu: Pu,
    /// Commanded acceleration \[pu/s\].
    pub acceleration_pu_s: PuPerS,
}

/// Inputs of the velocity tick.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct VelocityInputs {
    /// Raw encoder counter, wraps at `counter_bits`.
    pub encoder_count: u32,
    /// Motion command.
    pub setpoint: Setpoint,
    /// External fault input (latches [`Fault::External`]).
    pub fault_input: bool,
}

/// Outputs of the velocity tick.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct VelocityOutputs {
    /// Torque reference from the velocity regulator plus feed-forward, plus the AFB term
    /// held at that moment, clamped \[pu\]; before the notch, which runs in the current tick.
    pub current_ref_pu: Pu,
    /// Acceleration-feedback term \[pu torque\].
    pub accel_fb_pu: Pu,
    /// Velocity reference into the velocity regulator \[pu\].
    pub velocity_cmd_pu: Pu,
    /// Velocity feedback used by the regulator \[pu\].
    pub velocity_est_pu: Pu,
    /// Acceleration estimate from the AFB source at this rate \[pu/s\].
    pub acceleration_est_pu_s: PuPerS,
    /// Commanded minus measured position \[counts\] (0 in velocity mode).
    pub position_error_counts: CountsErr,
    /// Observer load-torque estimate \[pu\].
    pub disturbance_est_pu: Pu,
    /// Latched fault, if any.
    pub fault: Option<Fault>,
}

/// The quantized blocks of a [`super::Controller`] ([`super::Controller::blocks`]): each
/// block gives its linear form (`linear()`: its coefficients as f64), each plain gain its
/// value (`to_num`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Blocks {
    /// The state observer (current rate).
    pub observer: Observer,
    /// The velocity-feedback filter (velocity rate).
    pub velocity_filter: LowPass,
    /// Acceleration feedback with its filter.
    pub accel_feedback: AccelerationFeedback,
    /// Velocity PI.
    pub velocity_regulator: PiCoefficients,
    /// Current PI.
    pub current_regulator: PiCoefficients,
    /// The torque-reference notch, if one is configured (current rate).
    pub notch: Option<Notch>,
    /// The position loop's gain k_pos \[pu per count\] (Q1.31; 0 without a position loop).
    pub k_pos: PosGain,
    /// The position loop's velocity feed-forward gain (Q16.16).
    pub velocity_ff: Gain,
    /// The acceleration feed-forward gain \[pu torque per pu/s\] (Q16.16).
    pub k_accel_ff: Gain,
    /// The differentiator at the velocity rate.
    pub diff_velocity_rate: Differentiator,
    /// The differentiator at the current rate.
    pub diff_current_rate: Differentiator,
}
