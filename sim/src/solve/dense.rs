//! Dense symmetric positive definite solves through nalgebra's Cholesky decomposition, for the
//! small reduced systems (e.g. the Green-coordinates cage's contact springs), allocation-free.

use nalgebra::{Cholesky, DMatrix, DVectorViewMut};

/// Solves `A x = b` in place for a symmetric positive definite `A`, given as the column-major
/// `m × m` buffer `a` (only its lower triangle is read), which is overwritten by the Cholesky
/// factor `L` (lower triangle; the strict upper triangle is left as it was).
///
/// False, with `b` untouched, if `A` is not numerically positive definite (a pivot that is not
/// positive and finite: non-finite input). The buffer is moved into nalgebra's matrix and back,
/// so nothing is allocated.
pub(crate) fn spd_solve_in_place(a: &mut Vec<f64>, m: usize, b: &mut [f64]) -> bool {
    assert_eq!(a.len(), m * m, "an m × m matrix");
    assert_eq!(b.len(), m, "one right-hand side entry per row");
    // `new_unchecked` takes square roots without checking; a failed pivot shows in the
    // factor's diagonal (zero, NaN or infinite), which is checked instead.
    let chol = Cholesky::new_unchecked(DMatrix::from_vec(m, m, std::mem::take(a)));
    let l = chol.l_dirty();
    let ok = (0..m).all(|j| {
        let d = l[(j, j)];
        d > 0.0 && d.is_finite()
    });
    if ok {
        chol.solve_mut(&mut DVectorViewMut::from_slice(b, m));
    }
    *a = chol.unpack_dirty().data.into();
    ok
}

/// Solves `A x = b` in place with the Cholesky factor `L` of `A` that
/// [`spd_solve_in_place`] left in `l` (column-major `m × m`, lower triangle read): forward and
/// back substitution, no allocation.
pub(crate) fn spd_solve_factored(l: &[f64], m: usize, b: &mut [f64]) {
    debug_assert!(l.len() >= m * m && b.len() >= m);
    for j in 0..m {
        let x = b[j] / l[j * m + j];
        b[j] = x;
        for i in j + 1..m {
            b[i] -= l[j * m + i] * x;
        }
    }
    for j in (0..m).rev() {
        let mut x = b[j];
        for i in j + 1..m {
            x -= l[j * m + i] * b[i];
        }
        b[j] = x / l[j * m + j];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solves_spd_and_rejects_the_rest() {
        // A = B Bᵀ + I for a fixed B.
        let m = 7;
        let bm = DMatrix::from_fn(m, m, |i, j| ((i * 5 + j * 3) % 7) as f64 - 3.0);
        let a0 = &bm * bm.transpose() + DMatrix::identity(m, m);
        let rhs: Vec<f64> = (0..m).map(|i| i as f64 - 2.0).collect();
        let mut a = a0.as_slice().to_vec();
        let mut x = rhs.clone();
        assert!(spd_solve_in_place(&mut a, m, &mut x));
        let r = &a0 * DMatrix::from_column_slice(m, 1, &x);
        for i in 0..m {
            assert!((r[i] - rhs[i]).abs() < 1e-10);
        }
        assert_eq!(a.len(), m * m);
        // The factor left in `a` solves again.
        let mut y = rhs.clone();
        spd_solve_factored(&a, m, &mut y);
        for i in 0..m {
            assert!((y[i] - x[i]).abs() < 1e-12);
        }
        // Indefinite and non-finite matrices.
        for bad in [-1.0, f64::NAN, f64::INFINITY] {
            let mut a = a0.as_slice().to_vec();
            a[2 * m + 2] = bad;
            let mut x = rhs.clone();
            assert!(!spd_solve_in_place(&mut a, m, &mut x));
            assert_eq!(x, rhs);
            assert_eq!(a.len(), m * m);
        }
    }
}
