//! Clarke and Park transforms in Q16.16 pu, with sin and cos from `idsp::cossin`.
//!
//! ```text
//! Clarke (amplitude-invariant, i_c = −i_a − i_b):  iα = i_a,  iβ = (i_a + 2·i_b)/√3
//! Park:          d =  cos θ·α + sin θ·β,   q = −sin θ·α + cos θ·β
//! inverse Park:  α =  cos θ·d − sin θ·q,   β =  sin θ·d + cos θ·q
//! ```
//! Each sum is formed in 64 bits from Q16.16 · Q1.31 products, rounded once to nearest and
//! saturated to Q16.16, so the error is that of sin and cos (≤ 9e-6 each, times the
//! vector's length) plus half an LSB (7.6e-6 pu).

use crate::per_unit::{Pu, sat_round_shr};

/// A vector in the stationary frame (α, β) \[pu\].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct AlphaBeta {
    /// α axis (phase a's axis).
    pub alpha: Pu,
    /// β axis, 90° electrical ahead of α.
    pub beta: Pu,
}

/// A vector in the rotor frame (d, q) \[pu\].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Dq {
    /// Direct axis (the magnet's flux).
    pub d: Pu,
    /// Quadrature axis (the torque-making component).
    pub q: Pu,
}

/// cos θ and sin θ as raw Q1.31 (`i32::MAX` ≈ 1) of a 32-bit phase θ.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CosSin {
    /// cos θ, Q1.31.
    pub cos: i32,
    /// sin θ, Q1.31.
    pub sin: i32,
}

impl CosSin {
    /// cos and sin of `phase` (2^32 per turn) from `idsp::cossin`'s table.
    ///
    /// ```
    /// use controller_core::foc::transforms::CosSin;
    /// let cs = CosSin::of(1 << 30); // a quarter turn
    /// assert!(cs.cos.abs() < 1 << 16 && cs.sin > i32::MAX - (1 << 16));
    /// ```
    #[inline]
    #[must_use]
    pub fn of(phase: u32) -> Self {
        // idsp's phase is i32 with i32::MIN at −π: the same turn fraction, reinterpreted.
        let (cos, sin) = idsp::cossin(phase as i32);
        Self { cos, sin }
    }
}

/// 1/√3 in Q1.31.
const INV_SQRT3_Q31: i64 = 1_239_850_262;

/// `(a·x + b·y) / 2^31` with Q16.16 `a`, `b` and Q1.31 `x`, `y`, rounded and saturated.
#[inline(always)]
fn dot(a: Pu, x: i32, b: Pu, y: i32) -> Pu {
    // |a·x + b·y| ≤ |(a, b)|·|(x, y)| < 2^31·√2 · 2^31·(1 + 1e-5) < 2^63: no overflow.
    let s = i64::from(a.to_bits()) * i64::from(x) + i64::from(b.to_bits()) * i64::from(y);
    Pu::from_bits(sat_round_shr::<31>(s))
}

/// Clarke transform of two phase currents (the third is `−i_a − i_b`).
///
/// ```
/// use controller_core::foc::clarke;
/// use controller_core::per_unit::Pu;
/// let ab = clarke(Pu::from_num(1), Pu::from_num(-0.5));
/// assert_eq!(ab.alpha, Pu::from_num(1));
/// assert_eq!(ab.beta, Pu::ZERO);
/// ```
#[inline]
#[must_use]
pub fn clarke(i_a: Pu, i_b: Pu) -> AlphaBeta {
    let sum = i64::from(i_a.to_bits()) + 2 * i64::from(i_b.to_bits());
    // |sum| < 3·2^31, times 2^31: below 2^63.
    AlphaBeta {
        alpha: i_a,
        beta: Pu::from_bits(sat_round_shr::<31>(sum * INV_SQRT3_Q31)),
    }
}

/// Park transform: the stationary vector `v` in the frame at angle `cs`.
#[inline]
#[must_use]
pub fn park(v: AlphaBeta, cs: CosSin) -> Dq {
    Dq {
        d: dot(v.alpha, cs.cos, v.beta, cs.sin),
        q: dot(v.alpha, cs.sin.saturating_neg(), v.beta, cs.cos),
    }
}

/// Inverse Park transform: the rotor-frame vector `v` back to the stationary frame.
#[inline]
#[must_use]
pub fn inverse_park(v: Dq, cs: CosSin) -> AlphaBeta {
    AlphaBeta {
        alpha: dot(v.d, cs.cos, v.q, cs.sin.saturating_neg()),
        beta: dot(v.d, cs.sin, v.q, cs.cos),
    }
}
