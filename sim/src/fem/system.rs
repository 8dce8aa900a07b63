//! The sparse symmetric system on the free degrees of freedom, its fixed sparsity pattern, the
//! element scatter map and the faer Cholesky factorisation.
//!
//! - **Numbering.** Held nodes (fixed, or used by no tetrahedron) have no unknowns: the system
//!   is the reduced one on the free DOFs, which eliminates Dirichlet nodes symmetrically and
//!   keeps the matrix SPD. Free nodes are ordered on the *node* graph by approximate minimum
//!   degree (faer's AMD) or by geometric nested dissection, whichever gives the smaller factor
//!   (`ordering.rs`), and node `k` in that order owns DOFs `3k..3k+3`: the fill-reducing order
//!   is built into the numbering, so the factorisation itself runs with the identity ordering
//!   and never permutes the matrix, and 3×3 node blocks stay contiguous (supernode friendly).
//! - **Pattern.** One triangle of the matrix in CSC form: the lower one when faer chose the
//!   supernodal factorisation, the upper one for the simplicial factorisation — the triangle
//!   each reads, so faer makes no copy. The pattern holds every DOF pair of every node pair
//!   that shares a tetrahedron; it never changes.
//! - **Scatter map.** For each element, the position in the CSC value array of each of the 78
//!   stored entries of its 12×12 matrix (the 6 upper-triangle node blocks with 9 entries and
//!   the 4 diagonal node blocks with 6), or `NONE` where a node is held. Assembly is then a
//!   scatter-add: no search, no allocation.
//! - **Factorisation.** By the crate's sparse SPD solver (`solve/sparse.rs`): symbolic once per
//!   candidate ordering (identity ordering on the pre-ordered numbering; faer chooses
//!   supernodal or simplicial by its flop estimate); numeric LLᵀ into reused buffers, in double
//!   precision (direct solves) or single precision (the corotational preconditioner). On top of
//!   it, this system repacks supernodal factors for its own solves (`packed.rs`).

use std::fmt;

use faer::sparse::linalg::cholesky::{SymbolicCholesky, SymbolicCholeskyRaw};
use faer::Side;

use super::element::{stiffness_block, Element};
use super::ordering::{self, Graph};
use super::packed::{HalfFactor, PackedFactor};
use crate::solve::sparse::{analyse, Method, Ordering, SparseSpd};
pub(crate) use crate::solve::sparse::{NotPositiveDefinite, Precision};

/// "No DOF" / "not stored" marker.
pub(crate) const NONE: u32 = u32::MAX;

/// Entries of an element matrix that are stored (one triangle): 6 off-diagonal node blocks of
/// 9 plus 4 diagonal node blocks of 6.
pub(crate) const ELEMENT_ENTRIES: usize = 78;

/// Node pairs `(a, b)`, `a <= b`, in scatter-map order.
const PAIRS: [(usize, usize); 10] = [
    (0, 0),
    (0, 1),
    (0, 2),
    (0, 3),
    (1, 1),
    (1, 2),
    (1, 3),
    (2, 2),
    (2, 3),
    (3, 3),
];

/// A fixed-pattern SPD system with its Cholesky factor.
pub(crate) struct System {
    /// Per node: its first DOF (x; y and z follow), or [`NONE`] for a held node.
    pub dof: Vec<u32>,
    /// Number of free DOFs.
    pub n_dof: usize,
    /// The matrix (one triangle, CSC; values filled by [`System::clear_with_mass`] and
    /// [`System::add_element`]), its symbolic factorisation and faer's numeric factor in double
    /// or single precision, filled by [`System::factorize`].
    matrix: SparseSpd,
    /// Per DOF: index of its diagonal entry in `values`.
    diag: Vec<u32>,
    /// Per element: the value index of each stored entry, in [`PAIRS`] order.
    scatter: Vec<[u32; ELEMENT_ENTRIES]>,
    /// The single-precision factor rounded to half precision (supernodal factors only;
    /// allocated on first use), and whether it holds the current factor: the single-precision
    /// solves use it instead of faer's (`packed.rs`).
    half: Option<HalfFactor>,
    half_current: bool,
    /// Factor size (values) from which the half-precision copy is used: [`HALF_MIN_VALUES`].
    half_min_values: usize,
    /// The double-precision supernodal factor repacked for our own solves (`packed.rs`;
    /// allocated on first use), and whether it holds the current factor: the double-precision
    /// solves use it instead of faer's (faster at every size measured: the linear liver's
    /// solve pair 100 → 74 µs, the 100k-tetrahedra box's 47 → 36 ms). `use_packed` is off
    /// only in tests, for faer's solve as the reference.
    packed: Option<PackedFactor<f64>>,
    packed_current: bool,
    use_packed: bool,
    /// The fill-reducing ordering in use.
    ordering: NodeOrdering,
    /// Floating-point operations of one numeric factorisation, estimated from the symbolic
    /// structure.
    factor_flops: f64,
}

impl System {
    /// Builds numbering, pattern, scatter map and symbolic factorisation. `nodes` are the rest
    /// positions (for nested dissection), `held[i]` marks nodes without unknowns.
    /// `supernodal`: `None` lets faer choose by its flop estimate. `ordering`: `Auto` analyses
    /// both orderings and keeps the one with the smaller factor.
    pub fn new(
        nodes: &[[f64; 3]],
        elements: &[Element],
        held: &[bool],
        supernodal: Option<bool>,
        ordering: NodeOrdering,
    ) -> Result<System, faer::sparse::FaerError> {
        let n_nodes = nodes.len();
        // Free-node adjacency (both directions, sorted, no self loops).
        let mut free_index = vec![NONE; n_nodes];
        let mut n_free = 0u32;
        for (i, h) in held.iter().enumerate() {
            if !h {
                free_index[i] = n_free;
                n_free += 1;
            }
        }
        let n_free = n_free as usize;
        let mut adj: Vec<Vec<u32>> = vec![Vec::new(); n_free];
        for e in elements {
            for &a in &e.nodes {
                for &b in &e.nodes {
                    let (fa, fb) = (free_index[a as usize], free_index[b as usize]);
                    if a != b && fa != NONE && fb != NONE {
                        adj[fa as usize].push(fb);
                    }
                }
            }
        }
        for list in &mut adj {
            list.sort_unstable();
            list.dedup();
        }
        let mut node_of_free = vec![0u32; n_free];
        for (i, &f) in free_index.iter().enumerate() {
            if f != NONE {
                node_of_free[f as usize] = i as u32;
            }
        }
        let mut ptr = Vec::with_capacity(n_free + 1);
        let mut idx = Vec::new();
        ptr.push(0u32);
        for list in &adj {
            idx.extend_from_slice(list);
            ptr.push(idx.len() as u32);
        }
        let graph = Graph {
            ptr: &ptr,
            idx: &idx,
        };

        // Candidate orderings (perm[new] = old, on free indices), each with its symbolic
        // factorisation; the one with the smaller factor wins.
        let mut candidates = Vec::new();
        if ordering != NodeOrdering::NestedDissection {
            candidates.push((NodeOrdering::Amd, ordering::minimum_degree(&graph)?));
        }
        if ordering != NodeOrdering::Amd {
            let coords: Vec<[f64; 3]> = node_of_free.iter().map(|&i| nodes[i as usize]).collect();
            candidates.push((
                NodeOrdering::NestedDissection,
                ordering::nested_dissection(&graph, &coords)?,
            ));
        }
        let mut best: Option<Candidate> = None;
        for (kind, perm) in candidates {
            let mut perm_inv = vec![0u32; n_free];
            for (k, &old) in perm.iter().enumerate() {
                perm_inv[old as usize] = k as u32;
            }
            // Node-block neighbours in the new order, for the upper pattern first.
            let mut nb: Vec<Vec<u32>> = vec![Vec::new(); n_free];
            for (f, list) in adj.iter().enumerate() {
                let k = perm_inv[f] as usize;
                nb[k] = list.iter().map(|&g| perm_inv[g as usize]).collect();
                nb[k].push(k as u32);
                nb[k].sort_unstable();
            }
            let symbolic = symbolic_factor(&nb, supernodal)?;
            if best
                .as_ref()
                .is_none_or(|b| symbolic.len_val() < b.symbolic.len_val())
            {
                best = Some(Candidate {
                    kind,
                    perm,
                    nb,
                    symbolic,
                });
            }
        }
        let Candidate {
            kind: chosen,
            perm,
            nb,
            symbolic,
        } = best.expect("at least one ordering");
        let mut dof = vec![NONE; n_nodes];
        for (k, &old) in perm.iter().enumerate() {
            dof[node_of_free[old as usize] as usize] = 3 * k as u32;
        }
        let n_dof = 3 * n_free;
        let lower = matches!(symbolic.raw(), SymbolicCholeskyRaw::Supernodal(_));
        let (col_ptr, row_idx) = build_pattern(&nb, lower);
        let factor_flops = factor_flops(&symbolic);
        let side = if lower { Side::Lower } else { Side::Upper };
        let matrix = SparseSpd::with_symbolic(n_dof, col_ptr, row_idx, side, symbolic)?;

        // Diagonal positions and element scatter map.
        let find = |row: u32, col: u32| -> u32 {
            matrix.position(row, col).expect("entry is in the pattern") as u32
        };
        let diag: Vec<u32> = (0..n_dof as u32).map(|d| find(d, d)).collect();
        let scatter = elements
            .iter()
            .map(|e| {
                let mut map = [NONE; ELEMENT_ENTRIES];
                let mut k = 0;
                for (a, b) in PAIRS {
                    let (da, db) = (dof[e.nodes[a] as usize], dof[e.nodes[b] as usize]);
                    for r in 0..3u32 {
                        for c in 0..3u32 {
                            if a == b && c < r {
                                continue;
                            }
                            if da != NONE && db != NONE {
                                map[k] = find(da + r, db + c);
                            }
                            k += 1;
                        }
                    }
                }
                map
            })
            .collect();

        Ok(System {
            dof,
            n_dof,
            matrix,
            diag,
            scatter,
            half: None,
            half_current: false,
            half_min_values: HALF_MIN_VALUES,
            packed: None,
            packed_current: false,
            use_packed: true,
            ordering: chosen,
            factor_flops,
        })
    }

    /// Stored non-zeros of the matrix (one triangle) and of its Cholesky factor.
    pub fn nnz(&self) -> (usize, usize) {
        self.matrix.nnz()
    }

    /// The fill-reducing ordering chosen (never `Auto`).
    pub fn ordering(&self) -> NodeOrdering {
        self.ordering
    }

    /// The cost of a numeric factorisation in preconditioned CG iterations, estimated from
    /// the structure as `√(flops / nnz(L))`, at least [`MIN_REFACTOR_PRICE`].
    ///
    /// An iteration is dominated by the two triangular solves, which stream the factor
    /// (memory-bound: ∝ nnz(L)); a factorisation by its dense updates (∝ flops), which run
    /// faster the larger the supernodes, so the price grows more slowly than the flop ratio.
    /// Measured on the 2-core development machine (single precision, refactorisation incl.
    /// assembly over iteration incl. the matrix-free product): liver ~10, 10k-tet box ~14,
    /// 30k ~22, 50k ~26, 100k ~25-30; the estimate gives 9.4, 16.5, 23, 27 and 33.
    pub fn refactor_price(&self) -> usize {
        let flops_per_entry = self.factor_flops / self.matrix.nnz().1.max(1) as f64;
        (flops_per_entry.sqrt().round() as usize).max(MIN_REFACTOR_PRICE)
    }

    /// Numeric factorisations attempted since construction.
    pub fn factorizations(&self) -> u64 {
        self.matrix.factorizations()
    }

    /// Sets the count of [`System::factorizations`] (a swapped-in system keeps the body's).
    pub fn set_factorizations(&mut self, n: u64) {
        self.matrix.set_factorizations(n);
    }

    /// True if faer runs the supernodal factorisation.
    pub fn is_supernodal(&self) -> bool {
        self.matrix.is_supernodal()
    }

    /// Starts an assembly: `values = diag(mass_coef · mᵢ)` on the free DOFs.
    pub fn clear_with_mass(&mut self, mass: &[f64], mass_coef: f64) {
        let values = self.matrix.values_mut();
        values.fill(0.0);
        for (i, &d) in self.dof.iter().enumerate() {
            if d != NONE {
                for c in 0..3 {
                    values[self.diag[d as usize + c] as usize] += mass_coef * mass[i];
                }
            }
        }
    }

    /// Adds element `e`'s stiffness built from its (rest or rotated) gradients `g`, with
    /// `vl = Vλ`, `vm = Vμ`: a scatter-add through the precomputed map.
    #[inline]
    pub fn add_element(&mut self, e: usize, g: &[[f64; 3]; 4], vl: f64, vm: f64) {
        let map = &self.scatter[e];
        let values = self.matrix.values_mut();
        let mut k = 0;
        for (a, b) in PAIRS {
            let block = stiffness_block(g[a], g[b], vl, vm);
            for r in 0..3 {
                for c in 0..3 {
                    if a == b && c < r {
                        continue;
                    }
                    let at = map[k];
                    if at != NONE {
                        values[at as usize] += block[r][c];
                    }
                    k += 1;
                }
            }
        }
    }

    /// Adds `s · b` to the node block of DOF blocks starting at `a` and `b` (first DOFs of two
    /// free nodes; `b` is symmetric, and for `a == b` only the stored triangle is touched).
    /// Returns false, adding nothing, if the two nodes share no tetrahedron (the block is not
    /// in the pattern) or either is held.
    pub fn add_node_block(&mut self, a: u32, b: u32, blk: &[[f64; 3]; 3], s: f64) -> bool {
        if a == NONE || b == NONE {
            return false;
        }
        if a == b {
            for r in 0..3 {
                for c in 0..=r {
                    match self.matrix.position(a + r as u32, a + c as u32) {
                        Some(at) => self.matrix.values_mut()[at] += s * blk[r][c],
                        None => return false,
                    }
                }
            }
            return true;
        }
        if self.matrix.position(a, b).is_none() {
            return false;
        }
        for r in 0..3 {
            for c in 0..3 {
                if let Some(at) = self.matrix.position(a + r as u32, b + c as u32) {
                    self.matrix.values_mut()[at] += s * blk[r][c];
                }
            }
        }
        true
    }

    /// Numeric Cholesky factorisation of `values` into the owned factor buffer of the given
    /// precision (allocated on its first use). Single precision halves the memory traffic of
    /// factorisation and solves; it serves as a preconditioner only.
    pub fn factorize(&mut self, precision: Precision) -> Result<(), NotPositiveDefinite> {
        self.half_current = false;
        self.packed_current = false;
        self.matrix.factorize(precision)?;
        let m = &self.matrix;
        let SymbolicCholeskyRaw::Supernodal(sn) = m.symbolic().raw() else {
            return Ok(());
        };
        let diag = &self.diag;
        let values = m.values();
        let a_ii = |i: usize| values[diag[i] as usize];
        match precision {
            Precision::Single if m.nnz().1 >= self.half_min_values => {
                let half = self.half.get_or_insert_with(|| HalfFactor::new(sn));
                self.half_current = half.fill(sn, m.factor32(), a_ii);
            }
            Precision::Double if self.use_packed => {
                let packed = self.packed.get_or_insert_with(|| PackedFactor::new(sn));
                self.packed_current = packed.fill(sn, m.factor64(), a_ii);
            }
            _ => {}
        }
        Ok(())
    }

    /// Solves for the `ncols` columns of `b` (column-major, `n_dof` rows) with the current
    /// factor: one blocked solve with the double-precision factor, else one solve per column
    /// ([`System::solve_patch_in_place`]: the patch's columns).
    pub fn solve_columns(&mut self, b: &mut [f64], ncols: usize) {
        if self.n_dof == 0 || ncols == 0 {
            return;
        }
        if self.matrix.current() == Some(Precision::Double) {
            self.matrix.solve_columns(b, ncols);
        } else {
            for col in b.chunks_exact_mut(self.n_dof).take(ncols) {
                self.solve_patch_in_place(col);
            }
        }
    }

    /// Bytes one solve pair of [`System::solve_patch_in_place`] streams from the current
    /// factor: its values twice, at the precision that solve reads them in (0 without a
    /// factor). What a sum of cached `K̃⁻¹` columns is weighed against (`patch.rs`).
    pub fn solve_bytes(&self) -> usize {
        let bytes = match self.matrix.current() {
            None => return 0,
            Some(Precision::Double) => 8,
            Some(Precision::Single) if self.half_for_patch() => 2,
            Some(Precision::Single) => 4,
        };
        2 * bytes * self.matrix.nnz().1
    }

    /// Whether the contact patch's solves use the half-precision copy: only from
    /// [`HALF_PATCH_MIN_VALUES`].
    fn half_for_patch(&self) -> bool {
        self.half_current && self.matrix.nnz().1 >= HALF_PATCH_MIN_VALUES
    }

    /// [`System::solve_in_place`] for the contact patch's `K̃⁻¹` columns and correction,
    /// whose accuracy sets how closely the patch's gaps close and so the force a held press
    /// settles at: in the factor's own precision below [`HALF_PATCH_MIN_VALUES`], even where
    /// CG's preconditioner uses the half-precision copy (CG converges to its tolerance
    /// whatever the preconditioner's rounding; the patch does not iterate).
    pub fn solve_patch_in_place(&mut self, rhs: &mut [f64]) {
        let half = self.half_for_patch();
        self.solve_with(rhs, half);
    }

    /// Solves `A x = rhs` in place with the current factor (in its precision; the result is
    /// `f64` either way). Without a factor, leaves `rhs` unchanged.
    pub fn solve_in_place(&mut self, rhs: &mut [f64]) {
        let half = self.half_current;
        self.solve_with(rhs, half);
    }

    /// The solve behind both: the packed double-precision factor when it is current, the
    /// half-precision copy of a single-precision one when `half`, else faer's factor.
    fn solve_with(&mut self, rhs: &mut [f64], half: bool) {
        if self.n_dof == 0 {
            return;
        }
        match self.matrix.current() {
            Some(Precision::Double) if self.packed_current => {
                if let Some(packed) = &mut self.packed {
                    packed.solve_in_place(rhs);
                }
            }
            Some(Precision::Single) if half => {
                if let Some(h) = &mut self.half {
                    h.solve_in_place(rhs);
                }
            }
            _ => self.matrix.solve_in_place(rhs),
        }
    }
}

/// Single-precision factors of at least this many values (1 MB) are solved with their
/// half-precision copy (`packed.rs`) in CG's preconditioner (the contact patch's solves from
/// [`HALF_PATCH_MIN_VALUES`]). Smaller ones sit in a core's L2 cache, where the solve is
/// not memory-bound and the half copy saves little, while its rounding costs the settled
/// organ meshes their one-iteration steps (the shipped liver, 165k values, with the tool: 1.0
/// → 2.0 CG iterations per step, 0.34 → 0.42 ms; the recipe's 2k-tetrahedra organs have
/// 140–190k). The recipe's 5k organs (530–640k values, 2.1–2.5 MB in single precision: more
/// than the 2 MB L2 of a core of the development machine) step faster with it: pressed by
/// their poke at 1 ms, contact step p50 0.77 → 0.65 ms (kidney), 0.87 → 0.70 ms (ellipsoid),
/// p99 1.4–1.9 → 1.1–1.6 ms (`lopd simulate`, four runs each alternating, 2026-11-29); with
/// the earlier 4 MB threshold they used the single-precision factor.
pub(crate) const HALF_MIN_VALUES: usize = 1 << 18;

/// The contact patch's solves (its `K̃⁻¹` columns and correction) use the half-precision copy
/// only from this many factor values (4 MB in single precision), as every solve did before the
/// copy served smaller factors. Below, the patch keeps single precision: with the half copy a
/// block's held press settled 2.6 % lower after a change of period (`fem_background.rs`),
/// against 1.1 % in single precision. Above, the single-precision solve streams twice the bytes
/// and the columns of the nodes a moving patch newly reaches dominate the long periods' steps:
/// the 20k liver's contact step at 10 ms, p90 13.2 → 17.1 ms with single-precision columns.
pub(crate) const HALF_PATCH_MIN_VALUES: usize = 1 << 20;

/// Floor of [`System::refactor_price`]: on small meshes a factorisation costs about ten
/// iterations (it was the fixed price before the estimate).
pub(crate) const MIN_REFACTOR_PRICE: usize = 10;

/// Floating-point operations of a numeric Cholesky factorisation with this structure: per
/// supernode of `w` columns with `m` rows below them, `w³/3 + w²m + wm²` (the diagonal block,
/// the panel solve and the update it sends to its ancestors); per simplicial column with `m`
/// entries below the diagonal, `m²`.
fn factor_flops(symbolic: &SymbolicCholesky<u32>) -> f64 {
    match symbolic.raw() {
        SymbolicCholeskyRaw::Supernodal(sn) => (0..sn.n_supernodes())
            .map(|k| {
                let w = (sn.supernode_end()[k] - sn.supernode_begin()[k]) as f64;
                let m = (sn.col_ptr_for_row_idx()[k + 1] - sn.col_ptr_for_row_idx()[k]) as f64;
                w * w * w / 3.0 + w * w * m + w * m * m
            })
            .sum(),
        SymbolicCholeskyRaw::Simplicial(sc) => sc
            .col_ptr()
            .windows(2)
            .map(|c| {
                let m = (c[1] - c[0]).saturating_sub(1) as f64;
                m * m
            })
            .sum(),
    }
}

/// Fill-reducing ordering of the free nodes (`ordering.rs`).
#[doc(hidden)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum NodeOrdering {
    /// Both candidates; keep the one with the smaller factor.
    #[default]
    Auto,
    /// Approximate minimum degree.
    Amd,
    /// Geometric nested dissection.
    NestedDissection,
}

/// An ordering being considered by [`System::new`]: the node permutation (`perm[new] = old`,
/// on free indices), the node-block neighbours in the new numbering (per node, sorted, itself
/// included) and the symbolic factorisation.
struct Candidate {
    kind: NodeOrdering,
    perm: Vec<u32>,
    nb: Vec<Vec<u32>>,
    symbolic: SymbolicCholesky<u32>,
}

/// Symbolic Cholesky factorisation (identity ordering: the numbering is already ordered) of
/// the DOF matrix whose node blocks are `nb`; `supernodal` as in [`System::new`].
fn symbolic_factor(
    nb: &[Vec<u32>],
    supernodal: Option<bool>,
) -> Result<SymbolicCholesky<u32>, faer::sparse::FaerError> {
    let n_dof = 3 * nb.len();
    let (ptr, idx) = build_pattern(nb, false);
    analyse(
        n_dof,
        &ptr,
        &idx,
        Side::Upper,
        Ordering::Identity,
        Method::from_choice(supernodal),
    )
}

/// CSC pattern (one triangle) of the DOF matrix whose node blocks are `nb` (per node, its
/// sorted neighbours including itself). `lower`: rows >= cols, else rows <= cols.
fn build_pattern(nb: &[Vec<u32>], lower: bool) -> (Vec<u32>, Vec<u32>) {
    let mut col_ptr = Vec::with_capacity(3 * nb.len() + 1);
    let mut row_idx = Vec::new();
    col_ptr.push(0u32);
    for (q, list) in nb.iter().enumerate() {
        let q = q as u32;
        for c in 0..3u32 {
            let col = 3 * q + c;
            for &p in list {
                for r in 0..3u32 {
                    let row = 3 * p + r;
                    if (lower && row >= col) || (!lower && row <= col) {
                        row_idx.push(row);
                    }
                }
            }
            col_ptr.push(row_idx.len() as u32);
        }
    }
    (col_ptr, row_idx)
}

impl Clone for System {
    fn clone(&self) -> System {
        System {
            dof: self.dof.clone(),
            n_dof: self.n_dof,
            matrix: self.matrix.clone(),
            diag: self.diag.clone(),
            scatter: self.scatter.clone(),
            half: self.half.clone(),
            half_current: self.half_current,
            half_min_values: self.half_min_values,
            packed: self.packed.clone(),
            packed_current: self.packed_current,
            use_packed: self.use_packed,
            ordering: self.ordering,
            factor_flops: self.factor_flops,
        }
    }
}

impl fmt::Debug for System {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (a, l) = self.nnz();
        f.debug_struct("System")
            .field("dofs", &self.n_dof)
            .field("nnz", &a)
            .field("factor_nnz", &l)
            .field("supernodal", &self.is_supernodal())
            .finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::element::lame;
    use crate::fem::shapes::box_mesh;

    /// The packed double-precision solve agrees with faer's to rounding, and the
    /// half-precision one to about binary16's rounding (SIMD and portable kernels), on a soft
    /// bar's `K̃` (forced supernodal).
    #[test]
    fn packed_solves_match_faer() {
        let mesh = box_mesh([0.2, 0.1, 0.1], [8, 4, 4], |p| p[0] < 1e-9);
        let elements: Vec<Element> = mesh
            .tets
            .iter()
            .map(|t| Element::new(*t, t.map(|k| mesh.nodes[k as usize])).unwrap())
            .collect();
        let mut held = vec![false; mesh.nodes.len()];
        for &f in &mesh.fixed {
            held[f as usize] = true;
        }
        let mut mass = vec![0.0; mesh.nodes.len()];
        for e in &elements {
            for &k in &e.nodes {
                mass[k as usize] += 1000.0 * e.volume / 4.0;
            }
        }
        let mut sys = System::new(
            &mesh.nodes,
            &elements,
            &held,
            Some(true),
            NodeOrdering::Auto,
        )
        .unwrap();
        sys.half_min_values = 0;
        let (lambda, mu) = lame(3000.0, 0.45);
        sys.clear_with_mass(&mass, 1.0 / (0.01 * 0.01) + 1.0 / 0.02);
        for (e, el) in elements.iter().enumerate() {
            sys.add_element(e, &el.grad, el.volume * lambda, el.volume * mu);
        }
        let n = sys.n_dof;
        let b: Vec<f64> = (0..n).map(|i| ((i * 37) % 17) as f64 - 8.0).collect();
        sys.use_packed = false;
        sys.factorize(Precision::Double).unwrap();
        assert!(!sys.packed_current);
        let mut exact = b.clone();
        sys.solve_in_place(&mut exact);
        let norm = exact.iter().map(|v| v * v).sum::<f64>().sqrt();
        let error = |x: &[f64]| {
            let e2 = x
                .iter()
                .zip(&exact)
                .map(|(a, b)| (a - b) * (a - b))
                .sum::<f64>();
            e2.sqrt() / norm
        };
        // Solves with the SIMD kernels and the portable ones (`portable(sys, true)`).
        let both = |sys: &mut System, portable: fn(&mut System, bool)| {
            [false, true].map(|p| {
                portable(sys, p);
                let mut x = b.clone();
                sys.solve_in_place(&mut x);
                error(&x)
            })
        };
        // The packed double-precision solve: faer's to rounding.
        sys.use_packed = true;
        sys.factorize(Precision::Double).unwrap();
        assert!(sys.packed_current);
        let err = both(&mut sys, |s, p| {
            s.packed.as_mut().unwrap().force_portable(p)
        });
        assert!(
            err.iter().all(|&e| e < 1e-13),
            "packed: relative errors {err:?}"
        );
        // The half-precision one: to about binary16's rounding (and not exact).
        sys.factorize(Precision::Single).unwrap();
        assert!(sys.half_current);
        let err = both(&mut sys, |s, p| s.half.as_mut().unwrap().force_portable(p));
        assert!(
            err.iter().all(|&e| e < 1e-3 && e > 0.0),
            "half: relative errors {err:?}"
        );
    }
}
