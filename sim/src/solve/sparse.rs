//! A fixed-pattern sparse symmetric positive definite matrix and its faer Cholesky factor.
//!
//! - **Pattern.** One triangle in compressed columns (`u32` indices), lower or upper, given by
//!   the caller and never changed. The caller assembles straight into [`SparseSpd::values_mut`]
//!   (it knows where each entry lives, or asks [`SparseSpd::position`] once at set-up).
//! - **Symbolic factorisation** once, at construction ([`analyse`]): with faer's AMD ordering,
//!   or with the identity when the caller's numbering is already fill-reducing (the FEM's node
//!   orderings); supernodal or simplicial by faer's flop estimate unless forced. It is shared
//!   by clones (an `Arc`): it never changes.
//! - **Numeric factorisation** ([`SparseSpd::factorize`]) `LLᵀ` of the current values into a
//!   factor buffer owned here, in double precision or, as a preconditioner, in single
//!   precision (the values are rounded into a reused `f32` copy). A precision's buffers are
//!   allocated on its first use, or up front with [`SparseSpd::reserve`].
//! - **Solves** ([`SparseSpd::solve_in_place`]) with the current factor, in place, with one
//!   scratch `MemBuffer` sized at construction for the factorisation and the one-column solve
//!   of both precisions.
//!
//! After set-up (and the first factorisation of each precision, or [`SparseSpd::reserve`]),
//! factorisation and solve allocate nothing.

use std::fmt;
use std::sync::Arc;

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, LltRef, SymbolicCholesky,
    SymbolicCholeskyRaw, SymmetricOrdering,
};
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::{FaerError, SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};

/// The numeric factorisation failed: the matrix is not (numerically) positive definite, which
/// for the systems of this crate only happens with non-finite values.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct NotPositiveDefinite;

/// Precision of the numeric factor.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Precision {
    /// `f64`: direct solves.
    Double,
    /// `f32`: preconditioners (the solve still takes and returns `f64`).
    Single,
}

/// Fill-reducing ordering of the symbolic factorisation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Ordering {
    /// None: the numbering is already fill-reducing, and faer never permutes the matrix.
    Identity,
    /// faer's approximate minimum degree.
    Amd,
}

/// Supernodal or simplicial factorisation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Method {
    /// faer decides by its flop estimate.
    Auto,
    /// Always supernodal.
    Supernodal,
    /// Always simplicial.
    Simplicial,
}

impl Method {
    /// `None` → `Auto`, `Some(true)` → supernodal, `Some(false)` → simplicial.
    pub fn from_choice(supernodal: Option<bool>) -> Method {
        match supernodal {
            None => Method::Auto,
            Some(true) => Method::Supernodal,
            Some(false) => Method::Simplicial,
        }
    }
}

/// Symbolic Cholesky factorisation of the `n × n` symmetric matrix whose `side` triangle has
/// this CSC pattern (rows sorted within each column).
pub(crate) fn analyse(
    n: usize,
    col_ptr: &[u32],
    row_idx: &[u32],
    side: Side,
    ordering: Ordering,
    method: Method,
) -> Result<SymbolicCholesky<u32>, FaerError> {
    // faer's analysis without a permutation reads the pattern as the upper triangle whatever
    // `side` says (faer 0.24), so a lower one is transposed for it first.
    let transposed;
    let (col_ptr, row_idx) = if ordering == Ordering::Identity && side == Side::Lower {
        transposed = transpose(n, col_ptr, row_idx);
        (&transposed.0[..], &transposed.1[..])
    } else {
        (col_ptr, row_idx)
    };
    let a = SymbolicSparseColMatRef::new_checked(n, n, col_ptr, None, row_idx);
    let params = CholeskySymbolicParams {
        supernodal_flop_ratio_threshold: match method {
            Method::Auto => SupernodalThreshold::AUTO,
            Method::Supernodal => SupernodalThreshold::FORCE_SUPERNODAL,
            Method::Simplicial => SupernodalThreshold::FORCE_SIMPLICIAL,
        },
        ..Default::default()
    };
    let ordering = match ordering {
        Ordering::Identity => SymmetricOrdering::Identity,
        Ordering::Amd => SymmetricOrdering::Amd,
    };
    factorize_symbolic_cholesky(a, side, ordering, params)
}

/// The CSC pattern of the transpose of an `n × n` CSC pattern (rows sorted).
fn transpose(n: usize, col_ptr: &[u32], row_idx: &[u32]) -> (Vec<u32>, Vec<u32>) {
    let mut ptr = vec![0u32; n + 1];
    for &r in row_idx {
        ptr[r as usize + 1] += 1;
    }
    for c in 0..n {
        ptr[c + 1] += ptr[c];
    }
    let mut next = ptr.clone();
    let mut idx = vec![0u32; row_idx.len()];
    for c in 0..n {
        for &r in &row_idx[col_ptr[c] as usize..col_ptr[c + 1] as usize] {
            idx[next[r as usize] as usize] = c as u32;
            next[r as usize] += 1;
        }
    }
    (ptr, idx)
}

/// A fixed-pattern SPD matrix (one stored triangle), its symbolic factorisation and its
/// numeric Cholesky factor (module docs).
pub(crate) struct SparseSpd {
    n: usize,
    /// CSC of the stored triangle (`side`).
    col_ptr: Vec<u32>,
    row_idx: Vec<u32>,
    side: Side,
    /// Matrix values, written by the caller, read by [`SparseSpd::factorize`].
    values: Vec<f64>,
    symbolic: Arc<SymbolicCholesky<u32>>,
    /// Numeric factor in double or single precision, filled by `factorize`, read by
    /// `solve_in_place`; `current` says which one holds the factor of `values`, if any.
    l64: Vec<f64>,
    l32: Vec<f32>,
    current: Option<Precision>,
    /// Single precision: `values` and the right-hand side rounded to `f32`.
    values32: Vec<f32>,
    rhs32: Vec<f32>,
    /// Scratch memory for faer's factorisation and solve.
    work: Workspace,
    /// Numeric factorisations attempted so far.
    factorizations: u64,
    /// Scratch of [`SparseSpd::solve_columns`] and the columns it is sized for.
    cols_work: Option<(usize, MemBuffer)>,
}

impl SparseSpd {
    /// Pattern (`side` triangle, CSC, rows sorted) and its symbolic factorisation; values zero.
    pub fn new(
        n: usize,
        col_ptr: Vec<u32>,
        row_idx: Vec<u32>,
        side: Side,
        ordering: Ordering,
        method: Method,
    ) -> Result<SparseSpd, FaerError> {
        let symbolic = analyse(n, &col_ptr, &row_idx, side, ordering, method)?;
        SparseSpd::with_symbolic(n, col_ptr, row_idx, side, symbolic)
    }

    /// As [`SparseSpd::new`], with a symbolic factorisation computed by the caller (from this
    /// pattern or from the other triangle of the same matrix).
    pub fn with_symbolic(
        n: usize,
        col_ptr: Vec<u32>,
        row_idx: Vec<u32>,
        side: Side,
        symbolic: SymbolicCholesky<u32>,
    ) -> Result<SparseSpd, FaerError> {
        assert_eq!(
            symbolic.nrows(),
            n,
            "symbolic factorisation of another size"
        );
        let req = StackReq::any_of(&[
            symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default()),
            symbolic.solve_in_place_scratch::<f64>(1, Par::Seq),
            symbolic.factorize_numeric_llt_scratch::<f32>(Par::Seq, Default::default()),
            symbolic.solve_in_place_scratch::<f32>(1, Par::Seq),
        ]);
        let values = vec![0.0; row_idx.len()];
        Ok(SparseSpd {
            n,
            col_ptr,
            row_idx,
            side,
            values,
            symbolic: Arc::new(symbolic),
            l64: Vec::new(),
            l32: Vec::new(),
            current: None,
            values32: Vec::new(),
            rhs32: Vec::new(),
            work: Workspace::new(req)?,
            factorizations: 0,
            cols_work: None,
        })
    }

    /// Allocates the factor buffers of `precision` now rather than on its first use.
    pub fn reserve(&mut self, precision: Precision) {
        let len = self.symbolic.len_val();
        match precision {
            Precision::Double => {
                if self.l64.len() != len {
                    self.l64 = vec![0.0; len];
                }
            }
            Precision::Single => {
                if self.l32.len() != len {
                    self.l32 = vec![0.0; len];
                    self.values32 = vec![0.0; self.values.len()];
                    self.rhs32 = vec![0.0; self.n];
                }
            }
        }
    }

    /// Stored non-zeros of the matrix (one triangle) and of its Cholesky factor.
    pub fn nnz(&self) -> (usize, usize) {
        (self.values.len(), self.symbolic.len_val())
    }

    /// The symbolic factorisation.
    pub fn symbolic(&self) -> &SymbolicCholesky<u32> {
        &self.symbolic
    }

    /// True if faer runs the supernodal factorisation.
    pub fn is_supernodal(&self) -> bool {
        matches!(self.symbolic.raw(), SymbolicCholeskyRaw::Supernodal(_))
    }

    /// Numeric factorisations attempted since construction.
    pub fn factorizations(&self) -> u64 {
        self.factorizations
    }

    /// Sets the count of [`SparseSpd::factorizations`].
    pub fn set_factorizations(&mut self, n: u64) {
        self.factorizations = n;
    }

    /// CSC column pointers and row indices of the stored triangle.
    pub fn pattern(&self) -> (&[u32], &[u32]) {
        (&self.col_ptr, &self.row_idx)
    }

    /// The stored values.
    pub fn values(&self) -> &[f64] {
        &self.values
    }

    /// The stored values, for assembly (the factor no longer matches them once changed; it is
    /// kept until the next [`SparseSpd::factorize`]).
    pub fn values_mut(&mut self) -> &mut [f64] {
        &mut self.values
    }

    /// Index in the values of the stored entry for `(row, col)` of the symmetric matrix, if
    /// it is in the pattern.
    pub fn position(&self, row: u32, col: u32) -> Option<usize> {
        let lower = self.side == Side::Lower;
        let (r, c) = if lower == (row >= col) {
            (row, col)
        } else {
            (col, row)
        };
        let start = self.col_ptr[c as usize] as usize;
        let end = self.col_ptr[c as usize + 1] as usize;
        self.row_idx[start..end]
            .binary_search(&r)
            .ok()
            .map(|p| start + p)
    }

    /// The precision of the factor of the current values, if there is one.
    pub fn current(&self) -> Option<Precision> {
        self.current
    }

    /// The double-precision factor's values (faer's layout for [`SparseSpd::symbolic`]).
    pub fn factor64(&self) -> &[f64] {
        &self.l64
    }

    /// The single-precision factor's values.
    pub fn factor32(&self) -> &[f32] {
        &self.l32
    }

    /// Numeric Cholesky factorisation of the values in the given precision (its buffers are
    /// allocated on first use unless reserved).
    pub fn factorize(&mut self, precision: Precision) -> Result<(), NotPositiveDefinite> {
        self.current = None;
        self.factorizations += 1;
        self.reserve(precision);
        let n = self.n;
        let pattern =
            SymbolicSparseColMatRef::new_checked(n, n, &self.col_ptr, None, &self.row_idx);
        let stack = MemStack::new(&mut self.work.buf);
        let ok = match precision {
            Precision::Double => self
                .symbolic
                .factorize_numeric_llt::<f64>(
                    &mut self.l64,
                    SparseColMatRef::new(pattern, &self.values),
                    self.side,
                    LltRegularization::default(),
                    Par::Seq,
                    stack,
                    Default::default(),
                )
                .is_ok(),
            Precision::Single => {
                for (s, d) in self.values32.iter_mut().zip(&self.values) {
                    *s = *d as f32;
                }
                self.symbolic
                    .factorize_numeric_llt::<f32>(
                        &mut self.l32,
                        SparseColMatRef::new(pattern, &self.values32),
                        self.side,
                        LltRegularization::default(),
                        Par::Seq,
                        stack,
                        Default::default(),
                    )
                    .is_ok()
            }
        };
        if ok {
            self.current = Some(precision);
            Ok(())
        } else {
            Err(NotPositiveDefinite)
        }
    }

    /// Solves `A x = rhs` in place with the current factor (in its precision; the result is
    /// `f64` either way). Without a factor, leaves `rhs` unchanged.
    pub fn solve_in_place(&mut self, rhs: &mut [f64]) {
        let n = self.n;
        if n == 0 {
            return;
        }
        let stack = MemStack::new(&mut self.work.buf);
        match self.current {
            Some(Precision::Double) => LltRef::<u32, f64>::new(&self.symbolic, &self.l64)
                .solve_in_place_with_conj(
                    Conj::No,
                    MatMut::from_column_major_slice_mut(rhs, n, 1),
                    Par::Seq,
                    stack,
                ),
            Some(Precision::Single) => {
                for (s, d) in self.rhs32.iter_mut().zip(rhs.iter()) {
                    *s = *d as f32;
                }
                LltRef::<u32, f32>::new(&self.symbolic, &self.l32).solve_in_place_with_conj(
                    Conj::No,
                    MatMut::from_column_major_slice_mut(&mut self.rhs32, n, 1),
                    Par::Seq,
                    stack,
                );
                for (d, s) in rhs.iter_mut().zip(&self.rhs32) {
                    *d = f64::from(*s);
                }
            }
            None => debug_assert!(false, "solve without a factor"),
        }
    }

    /// Solves `A X = B` in place for the `ncols` columns of `b` (column-major, `n` rows) with
    /// the double-precision factor, in one blocked solve (faster than one per column: a
    /// contact patch's columns, the cage's compliance). Its scratch is kept for the most
    /// columns asked so far: allocation-free once it has grown to the widest call.
    pub fn solve_columns(&mut self, b: &mut [f64], ncols: usize) {
        let n = self.n;
        if n == 0 || ncols == 0 {
            return;
        }
        assert_eq!(
            self.current,
            Some(Precision::Double),
            "needs a double-precision factor"
        );
        if self.cols_work.as_ref().is_none_or(|(c, _)| *c < ncols) {
            let req = self.symbolic.solve_in_place_scratch::<f64>(ncols, Par::Seq);
            self.cols_work = Some((ncols, MemBuffer::new(req)));
        }
        let Some((_, mem)) = self.cols_work.as_mut() else {
            return;
        };
        LltRef::<u32, f64>::new(&self.symbolic, &self.l64).solve_in_place_with_conj(
            Conj::No,
            MatMut::from_column_major_slice_mut(b, n, ncols),
            Par::Seq,
            MemStack::new(mem),
        );
    }
}

/// Scratch memory for faer; a clone gets a fresh buffer of the same size.
struct Workspace {
    req: StackReq,
    buf: MemBuffer,
}

impl Workspace {
    fn new(req: StackReq) -> Result<Workspace, FaerError> {
        Ok(Workspace {
            req,
            buf: MemBuffer::try_new(req)?,
        })
    }
}

impl Clone for Workspace {
    fn clone(&self) -> Workspace {
        Workspace {
            req: self.req,
            buf: MemBuffer::new(self.req),
        }
    }
}

impl Clone for SparseSpd {
    fn clone(&self) -> SparseSpd {
        SparseSpd {
            n: self.n,
            col_ptr: self.col_ptr.clone(),
            row_idx: self.row_idx.clone(),
            side: self.side,
            values: self.values.clone(),
            symbolic: Arc::clone(&self.symbolic),
            l64: self.l64.clone(),
            l32: self.l32.clone(),
            current: self.current,
            values32: self.values32.clone(),
            rhs32: self.rhs32.clone(),
            work: self.work.clone(),
            factorizations: self.factorizations,
            cols_work: None,
        }
    }
}

impl fmt::Debug for SparseSpd {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (a, l) = self.nnz();
        f.debug_struct("SparseSpd")
            .field("dim", &self.n)
            .field("nnz", &a)
            .field("factor_nnz", &l)
            .field("supernodal", &self.is_supernodal())
            .finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The 1D Laplacian plus identity (`tridiag(-1, 3, -1)`), lower or upper triangle.
    fn laplacian(n: usize, side: Side) -> (Vec<u32>, Vec<u32>, Vec<f64>) {
        let (mut ptr, mut idx, mut val) = (vec![0u32], Vec::new(), Vec::new());
        for c in 0..n as u32 {
            if side == Side::Upper && c > 0 {
                idx.push(c - 1);
                val.push(-1.0);
            }
            idx.push(c);
            val.push(3.0);
            if side == Side::Lower && (c as usize) + 1 < n {
                idx.push(c + 1);
                val.push(-1.0);
            }
            ptr.push(idx.len() as u32);
        }
        (ptr, idx, val)
    }

    /// Every ordering, method, side and precision solves the system (residual check), and
    /// `position` finds both orders of an off-diagonal entry.
    #[test]
    fn solves_in_every_configuration() {
        let n = 40;
        for side in [Side::Lower, Side::Upper] {
            for ordering in [Ordering::Identity, Ordering::Amd] {
                for method in [Method::Auto, Method::Supernodal, Method::Simplicial] {
                    let (ptr, idx, val) = laplacian(n, side);
                    let mut a = SparseSpd::new(n, ptr, idx, side, ordering, method).unwrap();
                    a.values_mut().copy_from_slice(&val);
                    assert_eq!(a.position(3, 4), a.position(4, 3));
                    assert!(a.position(3, 5).is_none());
                    for (precision, tol) in [(Precision::Double, 1e-13), (Precision::Single, 1e-5)]
                    {
                        a.factorize(precision).unwrap();
                        let b: Vec<f64> = (0..n).map(|i| (i % 7) as f64 - 3.0).collect();
                        let mut x = b.clone();
                        a.solve_in_place(&mut x);
                        for i in 0..n {
                            let mut ax = 3.0 * x[i];
                            if i > 0 {
                                ax -= x[i - 1];
                            }
                            if i + 1 < n {
                                ax -= x[i + 1];
                            }
                            assert!((ax - b[i]).abs() < tol, "{side:?} {ordering:?} {method:?}");
                        }
                    }
                    a.values_mut()[0] = f64::NAN;
                    assert_eq!(a.factorize(Precision::Double), Err(NotPositiveDefinite));
                    assert_eq!(a.current(), None);
                }
            }
        }
    }
}
