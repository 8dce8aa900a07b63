//! Linearised backward Euler for the mass-spring body (see the parent module's docs for the
//! scheme, the filtered spring Jacobian and the solver choice).
//!
//! Unknowns are the velocity changes `Δv` of the free nodes, three per node, numbered in node
//! order; fixed and massless nodes are eliminated. The matrix
//! `A = M + hγI + h²(K_springs + K_tool)` is stored as its lower triangle in compressed columns
//! whose pattern is built once: per free node a 3×3 diagonal block, per spring between free nodes
//! a 3×3 block in the columns of the lower-numbered node. `diag` and `off` hold where each block's
//! values live, so assembly writes straight into the value array.

use faer::Side;

use super::forces::{self, Loads, Network};
use crate::contact::{add, dot, norm, scale, sub};
use crate::interaction::ContactReport;
use crate::patch::{PatchSolve, ToolPatch};
use crate::solve::sparse::{Method, Ordering, Precision, SparseSpd};

/// Marks an eliminated node or a block that is not stored.
const NONE: usize = usize::MAX;

/// The implicit Euler system of one body and its reusable factorisation.
#[derive(Clone)]
pub(super) struct ImplicitSolver {
    /// Unknown block of each node (`NONE` when eliminated).
    dof: Vec<usize>,
    /// Lower triangle of `A` (pattern fixed at construction, values rewritten every step) and
    /// its reusable factorisation; `None` when no node can move.
    a: Option<SparseSpd>,
    /// Per unknown block `d`, per column `c` of it: index of entry `(3d + c, 3d + c)`; the
    /// column's rows `3d + c ..= 3d + 2` follow it.
    diag: Vec<[usize; 3]>,
    /// Per spring between free nodes, per column `c` of its lower-numbered node: index of the
    /// first of the three rows of the higher-numbered node (`NONE` if an end is eliminated).
    off: Vec<[usize; 3]>,
    /// Filled with the conservative forces plus the tool load at the start of the step; read by
    /// the right-hand side.
    force: Vec<[f64; 3]>,
    /// Filled with `K v` during assembly; read by the right-hand side.
    kv: Vec<[f64; 3]>,
    /// Right-hand side `h (f − γv − hKv)` on entry to the solve, `Δv` on exit.
    rhs: Vec<f64>,
    /// The contact patch's solve (`patch_correct`).
    pub(super) patch: PatchSolve,
    /// What the last step's patch did.
    patch_report: Option<ContactReport>,
}

impl std::fmt::Debug for ImplicitSolver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ImplicitSolver")
            .field("unknowns", &self.rhs.len())
            .field("matrix_entries", &self.a.as_ref().map_or(0, |a| a.nnz().0))
            .field("factor_entries", &self.a.as_ref().map_or(0, |a| a.nnz().1))
            .finish()
    }
}

impl ImplicitSolver {
    /// Builds the pattern and runs the symbolic analysis (AMD ordering) once.
    pub fn new(net: &Network) -> ImplicitSolver {
        let n = net.mass.len();
        let mut dof = vec![NONE; n];
        let mut blocks = 0;
        for (i, d) in dof.iter_mut().enumerate() {
            if net.inv_mass[i] > 0.0 {
                *d = blocks;
                blocks += 1;
            }
        }
        // Per unknown block, the higher-numbered blocks it shares a spring with.
        let mut upper: Vec<Vec<(usize, usize)>> = vec![Vec::new(); blocks];
        for (s, sp) in net.springs.iter().enumerate() {
            let (da, db) = (dof[sp.a as usize], dof[sp.b as usize]);
            if da != NONE && db != NONE {
                upper[da.min(db)].push((da.max(db), s));
            }
        }
        let dim = 3 * blocks;
        let mut col_ptr = Vec::with_capacity(dim + 1);
        let mut row_idx = Vec::new();
        let mut diag = vec![[0; 3]; blocks];
        let mut off = vec![[NONE; 3]; net.springs.len()];
        for (d, up) in upper.iter_mut().enumerate() {
            up.sort_unstable();
            for c in 0..3 {
                col_ptr.push(row_idx.len());
                diag[d][c] = row_idx.len();
                row_idx.extend((c..3).map(|r| 3 * d + r));
                for &(q, s) in up.iter() {
                    off[s][c] = row_idx.len();
                    row_idx.extend((0..3).map(|r| 3 * q + r));
                }
            }
        }
        col_ptr.push(row_idx.len());
        let as_u32 = |v: Vec<usize>| -> Vec<u32> {
            v.into_iter()
                .map(|i| u32::try_from(i).expect("fewer than 2³² matrix entries"))
                .collect()
        };
        let (col_ptr, row_idx) = (as_u32(col_ptr), as_u32(row_idx));
        let a = (blocks > 0).then(|| {
            let mut a = SparseSpd::new(
                dim,
                col_ptr,
                row_idx,
                Side::Lower,
                Ordering::Amd,
                // Measured 3-4x faster than the simplicial variant faer picks by itself on the
                // shipped meshes (see the module docs of `msd`).
                Method::Supernodal,
            )
            .expect("symbolic Cholesky analysis fails only when out of memory");
            a.reserve(Precision::Double);
            a
        });
        ImplicitSolver {
            dof,
            a,
            diag,
            off,
            force: vec![[0.0; 3]; n],
            kv: vec![[0.0; 3]; n],
            rhs: vec![0.0; dim],
            patch: PatchSolve::new(dim),
            patch_report: None,
        }
    }

    /// One linearised backward-Euler step of size `h`. Returns false (state untouched) if the
    /// matrix could not be factorised, which only happens with non-finite values.
    pub fn step(
        &mut self,
        net: &Network,
        x: &mut [[f64; 3]],
        v: &mut [[f64; 3]],
        loads: &Loads<'_, '_>,
        h: f64,
    ) -> bool {
        if self.a.is_none() {
            return true;
        }
        self.assemble(net, x, v, loads, h);
        if !self.solve() {
            return false;
        }
        self.patch_report = loads
            .contact
            .and_then(|c| c.patch)
            .map(|p| self.patch_correct(&p, x, v, h));
        for (i, &d) in self.dof.iter().enumerate() {
            if d == NONE {
                continue;
            }
            let dv = [self.rhs[3 * d], self.rhs[3 * d + 1], self.rhs[3 * d + 2]];
            v[i] = add(v[i], dv);
            x[i] = add(x[i], scale(v[i], h));
        }
        true
    }

    /// Fills `A = M + hγI + h²K(x)` and the right-hand side `h (f − γv − hKv)` at `(x, v)`.
    fn assemble(
        &mut self,
        net: &Network,
        x: &[[f64; 3]],
        v: &[[f64; 3]],
        loads: &Loads<'_, '_>,
        h: f64,
    ) {
        net.conservative_forces(x, loads, &mut self.force);
        // A contact patch is solved after the step's factorisation (`patch_correct`).
        let touch = loads
            .contact
            .filter(|c| c.patch.is_none())
            .and_then(|c| forces::touch(c, x));
        if let Some(t) = &touch {
            for k in 0..3 {
                let i = t.tri[k] as usize;
                self.force[i] = add(self.force[i], scale(t.on_tissue, t.weights[k]));
            }
        }

        let h2 = h * h;
        let Some(a) = self.a.as_mut() else {
            return;
        };
        let vals = a.values_mut();
        vals.fill(0.0);
        self.kv.iter_mut().for_each(|k| *k = [0.0; 3]);
        for (i, &d) in self.dof.iter().enumerate() {
            if d != NONE {
                let m = net.mass[i] + h * net.damping;
                for c in 0..3 {
                    vals[self.diag[d][c]] = m;
                }
            }
        }
        let k = net.stiffness;
        for (s, sp) in net.springs.iter().enumerate() {
            let (a, b) = (sp.a as usize, sp.b as usize);
            let dx = sub(x[b], x[a]);
            let len = norm(dx);
            if !(len > 0.0) {
                continue;
            }
            let u = scale(dx, 1.0 / len);
            // Filtered geometric term: a compressed spring adds no negative stiffness.
            let geo = k * (1.0 - sp.rest / len).max(0.0);
            let kb = block(k - geo, u, geo);
            let kdv = mul(&kb, sub(v[b], v[a]));
            self.kv[a] = sub(self.kv[a], kdv);
            self.kv[b] = add(self.kv[b], kdv);
            add_diag(vals, &self.diag, self.dof[a], &kb, h2);
            add_diag(vals, &self.diag, self.dof[b], &kb, h2);
            add_off(vals, &self.off[s], &kb, -h2);
        }
        if let Some(t) = &touch {
            self.add_tool_jacobian(net, t, v, h2);
        }
        for s in loads.springs {
            if let Some(t) = s.touch(x) {
                for k in 0..3 {
                    let i = t.tri[k] as usize;
                    self.force[i] = add(self.force[i], scale(t.on_tissue, t.weights[k]));
                }
                self.add_tool_jacobian(net, &t, v, h2);
            }
        }

        for (i, &d) in self.dof.iter().enumerate() {
            if d == NONE {
                continue;
            }
            let r = sub(
                sub(self.force[i], scale(v[i], net.damping)),
                scale(self.kv[i], h),
            );
            for (slot, rc) in self.rhs[3 * d..3 * d + 3].iter_mut().zip(r) {
                *slot = h * rc;
            }
        }
    }

    /// The last step's complementarity problem (see [`super::MassSpring::patch_solution`]).
    pub fn patch_solution(&mut self) -> &mut crate::patch::Lcp {
        &mut self.patch.lcp
    }

    /// What the last step's contact patch did, if it had one.
    pub fn patch_report(&self) -> Option<ContactReport> {
        self.patch_report
    }

    /// With `rhs` holding `Δv` of the step without the tool: solves the contact patch (see
    /// [`crate::patch`]) with this step's factor of `A` (the points' columns solved together)
    /// and adds its response. The contact forces `λ` enter the right-hand side as `h C λ`, so
    /// the velocity changes by `h A⁻¹ C λ` and the positions by `h² A⁻¹ C λ`.
    fn patch_correct(
        &mut self,
        patch: &ToolPatch<'_>,
        x: &[[f64; 3]],
        v: &[[f64; 3]],
        h: f64,
    ) -> ContactReport {
        let (Some(a), Some(patch)) = (self.a.as_mut(), PatchSolve::limit(patch)) else {
            return ContactReport::default();
        };
        let (dof, rhs) = (&self.dof, &self.rhs);
        self.patch.begin(&patch, |k| {
            let i = k as usize;
            match unknown(dof, k) {
                Some(d) => add(x[i], scale(add(v[i], [rhs[d], rhs[d + 1], rhs[d + 2]]), h)),
                None => x.get(i).copied().unwrap_or([f64::NAN; 3]),
            }
        });
        self.patch.matrix_by_solves(
            &patch,
            |i| unknown(dof, i),
            h * h,
            |b, m| a.solve_columns(b, m),
        );
        if !(self.patch.solve(&patch) && self.patch.correction_by_solves(h)) {
            return ContactReport::default();
        }
        self.rhs
            .iter_mut()
            .zip(&self.patch.correction)
            .for_each(|(d, c)| *d += c);
        self.patch.report(&patch, 0)
    }

    /// Numeric refactorisation into the reused buffers, then the solve: `rhs` becomes `Δv`.
    /// False if `A` is not numerically positive definite (non-finite values).
    fn solve(&mut self) -> bool {
        let Some(a) = self.a.as_mut() else {
            return true;
        };
        if a.factorize(Precision::Double).is_err() {
            return false;
        }
        a.solve_in_place(&mut self.rhs);
        true
    }

    /// Adds the tool's stiffness `dF/dd (w wᵀ) ⊗ (n nᵀ)` over the touched triangle to `A` (times
    /// `h²`) and to `K v`. The triangle's nodes are joined by mesh edges, so every block exists;
    /// a pair without a spring (spring networks) keeps only its diagonal blocks, which is still
    /// positive semi-definite.
    fn add_tool_jacobian(&mut self, net: &Network, t: &forces::Touch, v: &[[f64; 3]], h2: f64) {
        let n = t.normal;
        // A grab's spring is isotropic: `dF/dd (w wᵀ) ⊗ I`.
        let nn = if t.isotropic {
            block(0.0, n, 1.0)
        } else {
            block(1.0, n, 0.0)
        };
        let vw = (0..3).fold([0.0; 3], |acc, k| {
            add(acc, scale(v[t.tri[k] as usize], t.weights[k]))
        });
        let kvw = if t.isotropic {
            vw
        } else {
            scale(n, dot(vw, n))
        };
        let Some(a) = self.a.as_mut() else {
            return;
        };
        let vals = a.values_mut();
        for p in 0..3 {
            let i = t.tri[p] as usize;
            let wi = t.weights[p];
            self.kv[i] = add(self.kv[i], scale(kvw, t.stiffness * wi));
            add_diag(
                vals,
                &self.diag,
                self.dof[i],
                &nn,
                h2 * t.stiffness * wi * wi,
            );
            for q in p + 1..3 {
                let key = (t.tri[p].min(t.tri[q]), t.tri[p].max(t.tri[q]));
                if let Ok(s) = net.springs.binary_search_by_key(&key, |s| (s.a, s.b)) {
                    let wj = t.weights[q];
                    add_off(vals, &self.off[s], &nn, h2 * t.stiffness * wi * wj);
                }
            }
        }
    }
}

/// `axial u uᵀ + iso I`.
fn block(axial: f64, u: [f64; 3], iso: f64) -> [[f64; 3]; 3] {
    let mut b = [[0.0; 3]; 3];
    for r in 0..3 {
        for c in 0..3 {
            b[r][c] = axial * u[r] * u[c];
        }
        b[r][r] += iso;
    }
    b
}

fn mul(b: &[[f64; 3]; 3], v: [f64; 3]) -> [f64; 3] {
    [dot(b[0], v), dot(b[1], v), dot(b[2], v)]
}

/// Adds `s · b` (symmetric) to the diagonal block of unknown block `d` (nothing if `NONE`).
fn add_diag(vals: &mut [f64], diag: &[[usize; 3]], d: usize, b: &[[f64; 3]; 3], s: f64) {
    if d == NONE {
        return;
    }
    for c in 0..3 {
        let start = diag[d][c];
        for r in c..3 {
            vals[start + r - c] += s * b[r][c];
        }
    }
}

/// Adds `s · b` (symmetric) to a spring's off-diagonal block (nothing if it is not stored).
fn add_off(vals: &mut [f64], off: &[usize; 3], b: &[[f64; 3]; 3], s: f64) {
    if off[0] == NONE {
        return;
    }
    for c in 0..3 {
        for r in 0..3 {
            vals[off[c] + r] += s * b[r][c];
        }
    }
}

/// The first unknown of node `i`, if it is free.
fn unknown(dof: &[usize], i: u32) -> Option<usize> {
    dof.get(i as usize).filter(|&&d| d != NONE).map(|&d| 3 * d)
}
