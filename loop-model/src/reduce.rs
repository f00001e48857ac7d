//! Taking out of the period map what is not a dynamic of the loop: states nothing touches,
//! and an invariant direction (the position shift in speed mode).

use nalgebra::{DMatrix, DVector};

/// `m` and `shift` without the states this configuration never touches: a state j whose
/// column and row of `m` are both e_j holds its value and acts on nothing (a filter or
/// differentiator that is switched off), an eigenvalue 1 that is not the loop's.
pub(super) fn drop_unused(m: &DMatrix<f64>, shift: &DVector<f64>) -> (DMatrix<f64>, DVector<f64>) {
    let n = m.nrows();
    let unused: Vec<usize> = (0..n)
        .filter(|&j| {
            (0..n).all(|i| {
                let want = if i == j { 1.0 } else { 0.0 };
                m.get((i, j)) == Some(&want) && m.get((j, i)) == Some(&want)
            })
        })
        .collect();
    (
        m.clone().remove_rows_at(&unused).remove_columns_at(&unused),
        shift.clone().remove_rows_at(&unused),
    )
}

/// The map `m` with the invariant direction `s` (m·s = s) taken out: in an orthonormal
/// basis whose first vector is s/|s|, the first column of QᵀMQ is e1, so the remaining
/// block holds every other eigenvalue.
pub(super) fn deflate(m: &DMatrix<f64>, s: &DVector<f64>) -> DMatrix<f64> {
    let n = m.nrows();
    let mut basis = DMatrix::zeros(n, n + 1);
    basis.set_column(0, s);
    basis
        .view_mut((0, 1), (n, n))
        .copy_from(&DMatrix::identity(n, n));
    let q = basis.qr().q();
    let q = q.columns(0, n).into_owned();
    let t = q.transpose() * m * &q;
    t.view((1, 1), (n - 1, n - 1)).into_owned()
}
