//! Matrix exponential for the exact zero-order-hold discretisation of one contact mode.
//!
//! exp([[A, B], [0, 0]]·h) = [[Φ, Γ], [0, I]] with Φ = e^{A·h} and Γ = ∫₀ʰ e^{A·s} ds · B,
//! so x(t+h) = Φ·x(t) + Γ·u exactly when u is held over the step.

use nalgebra::SMatrix;

/// e^M by scaling and squaring with a Taylor series (‖M/2^s‖₁ ≤ 0.5, 20 terms: truncation
/// below 1e-25 relative). Never panics; cost ~ (20 + s) products of 8×8 matrices.
pub(crate) fn expm<const N: usize>(m: &SMatrix<f64, N, N>) -> SMatrix<f64, N, N> {
    let norm = m
        .column_iter()
        .map(|c| c.iter().map(|v| v.abs()).sum::<f64>())
        .fold(0.0_f64, f64::max);
    let mut squarings = 0_u32;
    let mut scale = 1.0;
    while norm * scale > 0.5 && squarings < 64 {
        scale *= 0.5;
        squarings += 1;
    }
    let ms = m * scale;
    let mut sum = SMatrix::<f64, N, N>::identity();
    let mut term = SMatrix::<f64, N, N>::identity();
    for k in 1..=20 {
        term = term * ms / f64::from(k);
        sum += term;
    }
    for _ in 0..squarings {
        sum = sum * sum;
    }
    sum
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Matrix2;

    #[test]
    fn rotation_matches_closed_form() {
        // e^{[[0, w], [-w, 0]] t} = [[cos, sin], [-sin, cos]].
        let wt = 3.7_f64;
        let e = expm(&Matrix2::new(0.0, wt, -wt, 0.0));
        let want = Matrix2::new(wt.cos(), wt.sin(), -wt.sin(), wt.cos());
        assert!((e - want).amax() < 1e-13, "{e} vs {want}");
    }
}
