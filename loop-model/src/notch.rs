//! The torque-reference notch of the controller mirror ([`super::mirror`]): the biquad the
//! current tick applies to the torque reference (`controller_core::notch`), as a
//! two-state system in f64 with the controller's quantized coefficients.
//!
//! The controller runs Direct Form I (four delayed signals); the transfer function is what
//! the loop sees, so the mirror holds its minimal, transposed direct form II realization:
//!
//! ```text
//! y   = b0·x + s1
//! s1⁺ = b1·x − a1·y + s2        (a1 = b1, as in the controller)
//! s2⁺ = b2·x − a2·y
//! ```
//!
//! Same input, same output, exactly (in f64); two states instead of four, so the loop
//! model gains only the notch's own pole pair. The output clamp and the error feedback of
//! the fixed-point filter are left out, as every clamp and rounding is in the mirror.

use controller_core::ConfigError;
use controller_core::Gains;
use controller_core::notch::{Notch, NotchDesign};

/// The quantized coefficients of the controller's notch, as f64.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NotchMirror {
    /// The coefficients `Notch::process` runs with.
    pub coefficients: NotchDesign,
}

impl NotchMirror {
    /// The notch of `gains` (designed at the current rate), quantized by controller-core
    /// exactly as the controller quantizes it; `None` without a notch. An error names the
    /// keys, as the controller's does.
    pub fn of(gains: &Gains) -> Result<Option<Self>, ConfigError> {
        gains
            .notch
            .as_ref()
            .map(|d| {
                Notch::quantize(d, super::mirror::NOTCH_PARAM).map(|n| Self {
                    coefficients: n.linear(),
                })
            })
            .transpose()
    }

    /// One step with input `x` \[pu\]; `s` = [s1, s2] (module docs).
    #[must_use]
    pub fn step(&self, s: &mut [f64; 2], x: f64) -> f64 {
        let c = &self.coefficients;
        let y = c.b0 * x + s[0];
        *s = [c.b1 * x - c.b1 * y + s[1], c.b2 * x - c.a2 * y];
        y
    }
}
