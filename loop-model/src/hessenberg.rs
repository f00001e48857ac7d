//! Frequency responses C·(zI − M)⁻¹·B at many z through the Hessenberg form of M.
//!
//! M = Q·H·Qᵀ with H upper Hessenberg and Q orthogonal (once, O(n³)). Then
//! C·(zI − M)⁻¹·B = (Qᵀ·Cᵀ)ᵀ·(zI − H)⁻¹·(Qᵀ·B), and zI − H is Hessenberg too, so each
//! frequency is one O(n²) elimination (with partial pivoting between the two rows that can
//! hold a pivot) instead of an O(n³) LU of a full matrix.

use nalgebra::{Complex, DMatrix, DVector};

/// M in Hessenberg form with B and C carried along.
#[derive(Debug, Clone)]
pub struct HessenbergResponse {
    h: DMatrix<f64>,
    b: DVector<f64>,
    c: DVector<f64>,
}

impl HessenbergResponse {
    /// The form of the loop z⁺ = M·z + B·w, y = C·z.
    #[must_use]
    pub fn new(m: &DMatrix<f64>, b: &DVector<f64>, c: &DVector<f64>) -> Self {
        let (q, h) = m.clone().hessenberg().unpack();
        Self {
            b: q.transpose() * b,
            c: q.transpose() * c,
            h,
        }
    }

    /// C·(zI − M)⁻¹·B; `None` where zI − M is singular.
    #[must_use]
    pub fn at(&self, z: Complex<f64>) -> Option<Complex<f64>> {
        let zero = Complex::new(0.0, 0.0);
        let n = self.h.nrows();
        // a = zI − H (upper Hessenberg), x = Qᵀ·B; reduced to upper triangular in place.
        let mut a: DMatrix<Complex<f64>> = DMatrix::from_fn(n, n, |i, j| {
            let h = self.h.get((i, j)).copied().unwrap_or(0.0);
            if i == j { z - h } else { Complex::new(-h, 0.0) }
        });
        let mut x: DVector<Complex<f64>> = self.b.map(Complex::from);
        let get =
            |a: &DMatrix<Complex<f64>>, i: usize, j: usize| a.get((i, j)).copied().unwrap_or(zero);
        for k in 0..n.saturating_sub(1) {
            if get(&a, k + 1, k).norm() > get(&a, k, k).norm() {
                a.swap_rows(k, k + 1);
                x.swap_rows(k, k + 1);
            }
            let pivot = get(&a, k, k);
            if pivot == zero {
                return None;
            }
            let f = get(&a, k + 1, k) / pivot;
            if f != zero {
                let (upper, mut lower) = a.rows_range_pair_mut(k..=k, k + 1..=k + 1);
                for (dst, v) in lower.iter_mut().zip(upper.iter()).skip(k) {
                    *dst -= f * v;
                }
                let xk = x.get(k).copied().unwrap_or(zero);
                if let Some(v) = x.get_mut(k + 1) {
                    *v -= f * xk;
                }
            }
        }
        for k in (0..n).rev() {
            let row = a.row(k);
            let s = row
                .iter()
                .zip(x.iter())
                .skip(k + 1)
                .fold(x.get(k).copied().unwrap_or(zero), |s, (a, x)| s - a * x);
            let pivot = get(&a, k, k);
            if pivot == zero {
                return None;
            }
            if let Some(v) = x.get_mut(k) {
                *v = s / pivot;
            }
        }
        Some(self.c.iter().zip(x.iter()).map(|(c, x)| x * *c).sum())
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn matches_a_full_lu_solve() {
        let n = 29;
        // A deterministic, non-symmetric matrix with a spread of entries.
        let mut s = 0x2545_f491_u64;
        let mut next = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s % 2001) as f64 / 1000.0 - 1.0
        };
        let m = DMatrix::from_fn(n, n, |_, _| 0.3 * next());
        let b = DVector::from_fn(n, |_, _| next());
        let c = DVector::from_fn(n, |_, _| next());
        let fast = HessenbergResponse::new(&m, &b, &c);
        for k in 0..40 {
            let z = Complex::from_polar(1.0, 0.0785 * f64::from(k));
            let a = DMatrix::<Complex<f64>>::identity(n, n) * z - m.map(Complex::from);
            let x = a.lu().solve(&b.map(Complex::from)).unwrap();
            let full = c.map(Complex::from).dot(&x);
            let got = fast.at(z).unwrap();
            assert!(
                (got - full).norm() <= 1e-10 * full.norm().max(1.0),
                "z = {z}: {got} against {full}"
            );
        }
    }
}
