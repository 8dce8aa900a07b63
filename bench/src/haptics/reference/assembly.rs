//! The reference's finite-element side: linear tetrahedra (the textbook element) assembled
//! into the stiffness of a clamped body on its free degrees of freedom, factorised once by
//! faer's sparse Cholesky (AMD ordering), with solves and products for the contact solver in
//! the [parent module](super).

use anyhow::{bail, Result};
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, LltRef, SymbolicCholesky,
    SymmetricOrdering,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};
use lop_sim::mesh::TetMesh;

use super::{v, NONE};

/// An isotropic linear-elastic material.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Material {
    /// Young's modulus, Pa.
    pub young: f64,
    /// Poisson's ratio.
    pub poisson: f64,
}

impl Material {
    /// Lamé's `(λ, μ)`.
    pub fn lame(&self) -> (f64, f64) {
        let (e, nu) = (self.young, self.poisson);
        (
            e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)),
            e / (2.0 * (1.0 + nu)),
        )
    }
}

/// One tetrahedron's rest data.
#[derive(Debug, Clone, Copy)]
struct Tet {
    nodes: [u32; 4],
    /// Shape-function gradients, 1/m.
    grad: [[f64; 3]; 4],
    /// Rest volume, m³.
    volume: f64,
}

impl Tet {
    fn new(nodes: [u32; 4], x: [[f64; 3]; 4]) -> Option<Tet> {
        let e = [1, 2, 3].map(|k| [0, 1, 2].map(|c| x[k][c] - x[0][c]));
        let c12 = v(e[1]).cross(v(e[2]));
        let det = v(e[0]).dot(c12);
        if !(det > 0.0) {
            return None;
        }
        // Rows of the inverse of the edge matrix [e0 e1 e2] (as columns).
        let b1 = (c12 / det).to_array();
        let b2 = (v(e[2]).cross(v(e[0])) / det).to_array();
        let b3 = (v(e[0]).cross(v(e[1])) / det).to_array();
        let b0 = [0, 1, 2].map(|c| -(b1[c] + b2[c] + b3[c]));
        Some(Tet {
            nodes,
            grad: [b0, b1, b2, b3],
            volume: det / 6.0,
        })
    }

    /// The 3×3 block `K_ij`.
    fn block(&self, i: usize, j: usize, lambda: f64, mu: f64) -> [[f64; 3]; 3] {
        let (bi, bj) = (self.grad[i], self.grad[j]);
        let d = mu * v(bi).dot(v(bj));
        let mut k = [[0.0; 3]; 3];
        for a in 0..3 {
            for b in 0..3 {
                k[a][b] = self.volume * (lambda * bi[a] * bj[b] + mu * bj[a] * bi[b]);
            }
            k[a][a] += self.volume * d;
        }
        k
    }
}

/// The stiffness of a clamped linear-elastic body on its free degrees of freedom, and its
/// sparse Cholesky factor.
pub struct Stiffness {
    tets: Vec<Tet>,
    lambda: f64,
    mu: f64,
    /// Free DOF of each node (`3k`), or [`NONE`].
    pub(super) dof: Vec<u32>,
    n_dof: usize,
    symbolic: SymbolicCholesky<u32>,
    factor: Vec<f64>,
    /// Non-zeros of the stored (upper) triangle and of the factor.
    pub nnz: (usize, usize),
}

impl Stiffness {
    /// Assembles and factorises `K` of `mesh` (its fixed nodes clamped).
    ///
    /// # Errors
    /// A degenerate tetrahedron, or a matrix that is not positive definite (no support).
    pub fn new(mesh: &TetMesh, material: Material) -> Result<Stiffness> {
        let (lambda, mu) = material.lame();
        let mut tets = Vec::with_capacity(mesh.tets.len());
        for (i, t) in mesh.tets.iter().enumerate() {
            let x = t.map(|k| mesh.nodes[k as usize]);
            match Tet::new(*t, x) {
                Some(tet) => tets.push(tet),
                None => bail!("tetrahedron {i} is degenerate or inverted"),
            }
        }
        let n = mesh.nodes.len();
        let mut dof = vec![NONE; n];
        let mut n_dof = 0u32;
        let mut fixed = vec![false; n];
        for &f in &mesh.fixed {
            fixed[f as usize] = true;
        }
        for i in 0..n {
            if !fixed[i] {
                dof[i] = n_dof;
                n_dof += 3;
            }
        }
        // Blocks of the upper triangle by column node: (row node's dof, block).
        let mut columns: Vec<Vec<(u32, [[f64; 3]; 3])>> = vec![Vec::new(); n];
        for t in &tets {
            for i in 0..4 {
                for j in 0..4 {
                    let (di, dj) = (dof[t.nodes[i] as usize], dof[t.nodes[j] as usize]);
                    if di == NONE || dj == NONE || di > dj {
                        continue;
                    }
                    columns[t.nodes[j] as usize].push((di, t.block(i, j, lambda, mu)));
                }
            }
        }
        let mut col_ptr = vec![0u32];
        let mut row_idx = Vec::new();
        let mut values = Vec::new();
        let mut order: Vec<usize> = (0..n).filter(|&i| dof[i] != NONE).collect();
        order.sort_by_key(|&i| dof[i]);
        for node in order {
            let dj = dof[node];
            let col = &mut columns[node];
            col.sort_by_key(|e| e.0);
            // Merge the blocks of the same row node.
            let mut merged: Vec<(u32, [[f64; 3]; 3])> = Vec::with_capacity(col.len());
            for (di, k) in col.drain(..) {
                match merged.last_mut() {
                    Some(last) if last.0 == di => {
                        for a in 0..3 {
                            for b in 0..3 {
                                last.1[a][b] += k[a][b];
                            }
                        }
                    }
                    _ => merged.push((di, k)),
                }
            }
            for b in 0..3 {
                for (di, k) in &merged {
                    for a in 0..3 {
                        if *di == dj && a > b {
                            continue;
                        }
                        row_idx.push(di + a as u32);
                        values.push(k[a][b]);
                    }
                }
                col_ptr.push(row_idx.len() as u32);
            }
            let _ = dj;
        }
        let n_dof = n_dof as usize;
        let pattern = SymbolicSparseColMatRef::new_checked(n_dof, n_dof, &col_ptr, None, &row_idx);
        let symbolic = factorize_symbolic_cholesky(
            pattern,
            Side::Upper,
            SymmetricOrdering::Amd,
            CholeskySymbolicParams::default(),
        )
        .map_err(|e| anyhow::anyhow!("symbolic factorisation: {e:?}"))?;
        let mut factor = vec![0.0; symbolic.len_val()];
        let mut mem = MemBuffer::new(
            symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default()),
        );
        symbolic
            .factorize_numeric_llt::<f64>(
                &mut factor,
                SparseColMatRef::new(pattern, &values),
                Side::Upper,
                LltRegularization::default(),
                Par::Seq,
                MemStack::new(&mut mem),
                Default::default(),
            )
            .map_err(|_| anyhow::anyhow!("the stiffness is not positive definite"))?;
        let nnz = (values.len(), factor.len());
        Ok(Stiffness {
            tets,
            lambda,
            mu,
            dof,
            n_dof,
            symbolic,
            factor,
            nnz,
        })
    }

    /// Free degrees of freedom.
    pub fn n_dof(&self) -> usize {
        self.n_dof
    }

    /// Solves `K X = B` in place for the `ncols` columns of `b` (column-major).
    pub(super) fn solve_columns(&self, b: &mut [f64], ncols: usize) {
        let mut mem = MemBuffer::new(self.symbolic.solve_in_place_scratch::<f64>(ncols, Par::Seq));
        LltRef::<u32, f64>::new(&self.symbolic, &self.factor).solve_in_place_with_conj(
            Conj::No,
            MatMut::from_column_major_slice_mut(b, self.n_dof, ncols),
            Par::Seq,
            MemStack::new(&mut mem),
        );
    }

    /// Displacements of every node (fixed ones zero) under nodal forces `f` (N).
    pub fn displacements(&self, f: &[[f64; 3]]) -> Vec<[f64; 3]> {
        let mut rhs = vec![0.0; self.n_dof];
        for (i, &d) in self.dof.iter().enumerate() {
            if d != NONE {
                rhs[d as usize..d as usize + 3].copy_from_slice(&f[i]);
            }
        }
        self.solve_columns(&mut rhs, 1);
        self.dof
            .iter()
            .map(|&d| {
                if d == NONE {
                    [0.0; 3]
                } else {
                    [0, 1, 2].map(|c| rhs[d as usize + c])
                }
            })
            .collect()
    }

    /// `K u` over every node (the full, unclamped stiffness), N: at a free node the external
    /// force that holds `u`, at a fixed node the support's reaction.
    pub fn product(&self, u: &[[f64; 3]]) -> Vec<[f64; 3]> {
        let mut out = vec![[0.0; 3]; u.len()];
        for t in &self.tets {
            for i in 0..4 {
                let mut f = [0.0; 3];
                for j in 0..4 {
                    let k = t.block(i, j, self.lambda, self.mu);
                    let uj = u[t.nodes[j] as usize];
                    for a in 0..3 {
                        f[a] += v(k[a]).dot(v(uj));
                    }
                }
                let o = &mut out[t.nodes[i] as usize];
                for a in 0..3 {
                    o[a] += f[a];
                }
            }
        }
        out
    }

    /// Whether node `i` is fixed.
    pub fn is_fixed(&self, i: usize) -> bool {
        self.dof[i] == NONE
    }
}
