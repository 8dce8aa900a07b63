//! The scalar sparse system of one heat body: the conductance matrix `K` in a fixed CSC
//! pattern, the step matrix `A = C/Δt + K + H` built from it, and its faer Cholesky factor.
//!
//! - **Pattern.** The lower triangle (rows >= cols) of the node graph of the tetrahedra, one
//!   unknown per node, columns sorted. It never changes.
//! - **Factorisation.** Symbolic once, with faer's AMD ordering (one unknown per node: there are
//!   no node blocks to keep contiguous, unlike the FEM system, so faer may permute); numeric
//!   `LLᵀ` into reused buffers, all by the crate's sparse SPD solver (`solve/sparse.rs`). `A`
//!   only changes when `Δt` or the air coefficient does, so a body factorises once.

use std::fmt;

use faer::Side;

pub(crate) use crate::solve::sparse::NotPositiveDefinite;
use crate::solve::sparse::{Method, Ordering, Precision, SparseSpd};

/// Local node pairs `(a, b)` of a tetrahedron whose entry is scattered (both orders of an
/// off-diagonal pair land on the one stored lower entry).
pub(crate) const PAIRS: [(usize, usize); 10] = [
    (0, 0),
    (1, 1),
    (2, 2),
    (3, 3),
    (0, 1),
    (0, 2),
    (0, 3),
    (1, 2),
    (1, 3),
    (2, 3),
];

/// Fixed-pattern SPD system of one heat body.
pub(crate) struct HeatSystem {
    n: usize,
    /// Per node: index of its diagonal entry in the value arrays.
    pub diag: Vec<u32>,
    /// Per element: value index of each entry of [`PAIRS`].
    pub scatter: Vec<[u32; 10]>,
    /// Conductance matrix `K`, W/K, assembled once by the body (the step matrix's pattern).
    pub conductance: Vec<f64>,
    /// Step matrix `A` (filled by [`HeatSystem::factorize_with_diagonal`]) and its factor.
    matrix: SparseSpd,
}

impl HeatSystem {
    /// Pattern, scatter map and symbolic factorisation for `n` nodes and these tetrahedra.
    pub fn new(n: usize, tets: &[[u32; 4]]) -> Result<HeatSystem, faer::sparse::FaerError> {
        // Lower neighbours of every node (including itself), sorted unique.
        let mut lower: Vec<Vec<u32>> = (0..n as u32).map(|i| vec![i]).collect();
        for t in tets {
            for &a in t {
                for &b in t {
                    if a > b {
                        lower[b as usize].push(a);
                    }
                }
            }
        }
        let mut col_ptr = Vec::with_capacity(n + 1);
        let mut row_idx = Vec::new();
        col_ptr.push(0u32);
        for list in &mut lower {
            list.sort_unstable();
            list.dedup();
            row_idx.extend_from_slice(list);
            col_ptr.push(row_idx.len() as u32);
        }
        let find = |row: u32, col: u32| -> u32 {
            let (r, c) = if row >= col { (row, col) } else { (col, row) };
            let start = col_ptr[c as usize] as usize;
            let end = col_ptr[c as usize + 1] as usize;
            let pos = row_idx[start..end]
                .binary_search(&r)
                .expect("entry is in the pattern");
            (start + pos) as u32
        };
        let diag: Vec<u32> = (0..n as u32).map(|i| find(i, i)).collect();
        let scatter = tets
            .iter()
            .map(|t| PAIRS.map(|(a, b)| find(t[a], t[b])))
            .collect();
        let nnz = row_idx.len();
        let mut matrix = SparseSpd::new(
            n,
            col_ptr,
            row_idx,
            Side::Lower,
            Ordering::Amd,
            Method::Auto,
        )?;
        matrix.reserve(Precision::Double);
        Ok(HeatSystem {
            n,
            diag,
            scatter,
            conductance: vec![0.0; nnz],
            matrix,
        })
    }

    /// `K x` (both triangles of the symmetric `K`), into `out`.
    pub fn conductance_times(&self, x: &[f64], out: &mut [f64]) {
        out.fill(0.0);
        let (col_ptr, row_idx) = self.matrix.pattern();
        for c in 0..self.n {
            let (s, e) = (col_ptr[c] as usize, col_ptr[c + 1] as usize);
            for (&r, &k) in row_idx[s..e].iter().zip(&self.conductance[s..e]) {
                let r = r as usize;
                out[r] += k * x[c];
                if r != c {
                    out[c] += k * x[r];
                }
            }
        }
    }

    /// Sets `A = K + diag(d)` and factorises it (no allocation: every buffer is sized).
    pub fn factorize_with_diagonal(&mut self, d: &[f64]) -> Result<(), NotPositiveDefinite> {
        let values = self.matrix.values_mut();
        values.copy_from_slice(&self.conductance);
        for (i, &at) in self.diag.iter().enumerate() {
            values[at as usize] += d[i];
        }
        self.matrix.factorize(Precision::Double)
    }

    /// Solves `A x = rhs` in place with the current factor.
    pub fn solve_in_place(&mut self, rhs: &mut [f64]) {
        self.matrix.solve_in_place(rhs);
    }

    /// Stored non-zeros of the matrix (lower triangle) and of its factor.
    pub fn nnz(&self) -> (usize, usize) {
        self.matrix.nnz()
    }
}

impl Clone for HeatSystem {
    fn clone(&self) -> HeatSystem {
        HeatSystem {
            n: self.n,
            diag: self.diag.clone(),
            scatter: self.scatter.clone(),
            conductance: self.conductance.clone(),
            matrix: self.matrix.clone(),
        }
    }
}

impl fmt::Debug for HeatSystem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (a, l) = self.nnz();
        f.debug_struct("HeatSystem")
            .field("nodes", &self.n)
            .field("nnz", &a)
            .field("factor_nnz", &l)
            .finish()
    }
}
