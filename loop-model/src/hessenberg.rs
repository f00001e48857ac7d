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
    n: usize,
    /// H by rows: entry (i, j) at `i·n + j`, so that the elimination walks each row in
    /// order.
    h: Vec<f64>,
    b: Vec<f64>,
    c: Vec<f64>,
}

impl HessenbergResponse {
    /// The form of the loop z⁺ = M·z + B·w, y = C·z.
    #[must_use]
    pub fn new(m: &DMatrix<f64>, b: &DVector<f64>, c: &DVector<f64>) -> Self {
        let (q, h) = m.clone().hessenberg().unpack();
        Self {
            n: h.nrows(),
            // nalgebra stores by columns: the columns of Hᵀ are the rows of H.
            h: h.transpose().as_slice().to_vec(),
            b: (q.transpose() * b).as_slice().to_vec(),
            c: (q.transpose() * c).as_slice().to_vec(),
        }
    }

    /// C·(zI − M)⁻¹·B; `None` where zI − M is singular.
    #[must_use]
    pub fn at(&self, z: Complex<f64>) -> Option<Complex<f64>> {
        let zero = Complex::new(0.0, 0.0);
        let n = self.n;
        // a = zI − H (upper Hessenberg, by rows), x = Qᵀ·B; reduced to upper triangular in
        // place. The entries left of the diagonal are never read again once their column
        // is eliminated, so each step works on its two rows from the pivot's column on.
        let mut a: Vec<Complex<f64>> = self.h.iter().map(|&h| Complex::new(-h, 0.0)).collect();
        // The diagonal, every (n + 1)-th entry: z − h (−h + z is the same sum, bit for bit).
        for d in a.iter_mut().step_by(n + 1) {
            *d += z;
        }
        let mut x: Vec<Complex<f64>> = self.b.iter().map(|&b| Complex::from(b)).collect();
        for k in 0..n.saturating_sub(1) {
            let (upper, lower) = a.split_at_mut((k + 1) * n);
            let (Some(row), Some(next)) = (upper.get_mut(k * n + k..), lower.get_mut(k..n)) else {
                return None;
            };
            let head = |r: &[Complex<f64>]| r.first().copied().unwrap_or(zero);
            if head(next).norm() > head(row).norm() {
                row.swap_with_slice(next);
                if let Some(pair) = x.get_mut(k..=k + 1) {
                    pair.swap(0, 1);
                }
            }
            let pivot = head(row);
            if pivot == zero {
                return None;
            }
            let f = head(next) / pivot;
            if f != zero {
                for (dst, v) in next.iter_mut().zip(row.iter()) {
                    *dst -= f * v;
                }
                let xk = x.get(k).copied().unwrap_or(zero);
                if let Some(v) = x.get_mut(k + 1) {
                    *v -= f * xk;
                }
            }
        }
        for k in (0..n).rev() {
            let row = a.get(k * n..(k + 1) * n)?;
            let s = row
                .iter()
                .zip(x.iter())
                .skip(k + 1)
                .fold(x.get(k).copied().unwrap_or(zero), |s, (a, x)| s - a * x);
            let pivot = row.get(k).copied().unwrap_or(zero);
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
