//! The DC winding's current loop (the inner PI of the paper's Fig. 5): v = PI(i_ref − i),
//! within ±voltage_limit. A PMSM drive's current loop is [`crate::foc`] instead.

use crate::per_unit::Pu;
use crate::pi::{PiCoefficients, PiState};

/// The DC current loop's quantized coefficients.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct DcCurrentLoop {
    /// The current PI (limit: the voltage limit).
    pub(super) regulator: PiCoefficients,
    /// |limit| of the regulator (raw, saturating), resolved once.
    limit_abs: i32,
}

impl DcCurrentLoop {
    /// The loop of a quantized PI.
    pub(super) fn new(regulator: PiCoefficients) -> Self {
        Self {
            regulator,
            limit_abs: regulator.abs_limit(),
        }
    }

    /// The voltage command of this tick for the current error `e`.
    #[inline(always)]
    pub(super) fn regulate(&self, st: &mut PiState, e: Pu) -> Pu {
        self.regulator
            .update_within(st, e, Pu::ZERO, self.limit_abs)
    }
}
