//! The precise model's rest compliance seen through the cage, for
//! [`CageDynamics::Projected`](super::CageDynamics::Projected).
//!
//! The cage's stiffness is chosen so that its static response to a load is the *best fit*
//! (mass-weighted least squares) of the precise model's response, instead of the Galerkin
//! `GᵀKG`, which is the best fit in the energy norm and therefore stiffer than the body
//! whenever the cage cannot bend exactly like it (locking). With `M_r = GᵀMG` and the loads
//! seen through the cage (`Gᵀ f`),
//!
//! ```text
//! C_r = (MG)ᵀ K⁻¹ (MG),    K_r = M_r C_r⁻¹ M_r
//! ```
//!
//! so `K_r⁻¹ Gᵀ f = G⁺ K⁻¹ (Π f)` with `G⁺ = M_r⁻¹GᵀM` the mass-weighted fit and
//! `Π = MG M_r⁻¹ Gᵀ` the load smoothed onto the cage (`GᵀΠf = Gᵀf`: the same total force and
//! moment, as the cage reproduces affine motions). `K_r` is symmetric positive definite when `K`
//! is (the body has fixed nodes).
//!
//! `K` itself is only available as a product `u ↦ K u` (the precise models do not expose their
//! matrices), so it is assembled here by *probing*: the nodes are coloured so that no two nodes
//! within two tetrahedron edges of each other share a colour, and one product per colour and
//! axis (a unit displacement of every node of that colour) recovers every column of `K`, since
//! a node's force then comes from at most one displaced neighbour. About 3 × 40 products for an
//! organ mesh instead of 3N; a final product with a dense test field checks the assembly.
//! The sparse matrix is then factorised once (the crate's sparse SPD solver, faer's Cholesky
//! with AMD) for the `3V` solves `K⁻¹MG`.

use faer::sparse::{SparseColMat, Triplet};
use faer::Side;
use nalgebra::{Cholesky, DMatrix};

use super::cage_model::{CageModelError, StiffnessProduct};
use crate::mesh::TetMesh;
use crate::solve::sparse::{Method, Ordering, Precision, SparseSpd};

const NONE: usize = usize::MAX;

/// The cage stiffness `K_r = M_r C_r⁻¹ M_r` matched to the precise model's rest compliance.
/// `mg` is `MG` (3N × 3V, zero rows on held nodes), `m_r` is `GᵀMG`. `Ok(None)` when the rest
/// stiffness is singular on the free nodes (a body with no support): compliance is undefined
/// there, and the caller falls back to the Galerkin stiffness. `tolerance`: how closely (relative
/// to the largest force) the assembled matrix must reproduce one more product; a product by
/// finite differences needs a looser one.
pub(super) fn matched_stiffness(
    mesh: &TetMesh,
    held: &[bool],
    stiffness: StiffnessProduct<'_>,
    mg: &DMatrix<f64>,
    m_r: &DMatrix<f64>,
    tolerance: f64,
) -> Result<Option<DMatrix<f64>>, CageModelError> {
    let n = mesh.nodes.len();
    let m = mg.ncols();
    // Free-node numbering: node k owns DOFs 3·dof[k] .. 3·dof[k] + 3.
    let mut dof = vec![NONE; n];
    let mut free = Vec::new();
    for k in 0..n {
        if !held[k] {
            dof[k] = free.len();
            free.push(k);
        }
    }
    if free.is_empty() {
        return Ok(None);
    }
    let nf = 3 * free.len();
    let neighbours = free_neighbours(mesh, &dof, free.len());
    let colour = distance_two_colouring(&neighbours);
    let colours = colour.iter().copied().max().map_or(0, |c| c + 1);

    // Probe: one product per colour and axis; store the lower triangle (row ≥ column).
    let mut triplets: Vec<Triplet<usize, usize, f64>> = Vec::new();
    let mut u = vec![[0.0; 3]; n];
    for c in 0..colours {
        for a in 0..3 {
            for (f, &k) in free.iter().enumerate() {
                u[k] = [0.0; 3];
                if colour[f] == c {
                    u[k][a] = 1.0;
                }
            }
            let y = stiffness(&u);
            if y.len() != n {
                return Err(CageModelError::Parameter(
                    "the precise model gave no rest stiffness to project".into(),
                ));
            }
            for (i, list) in neighbours.iter().enumerate() {
                // The one node of colour `c` next to (or at) node `i`, if any.
                let Some(j) = std::iter::once(i)
                    .chain(list.iter().copied())
                    .find(|&j| colour[j] == c)
                else {
                    continue;
                };
                let col = 3 * j + a;
                for (b, &v) in y[free[i]].iter().enumerate() {
                    let row = 3 * i + b;
                    if row >= col && v != 0.0 {
                        triplets.push(Triplet::new(row, col, v));
                    }
                }
            }
        }
    }
    let k_ff = SparseColMat::<usize, f64>::try_new_from_triplets(nf, nf, &triplets)
        .map_err(|e| CageModelError::Parameter(format!("assembling the rest stiffness: {e:?}")))?;
    check_assembly(&k_ff, &free, n, stiffness, tolerance)?;

    let Some(mut k_ff) = factorize(&k_ff) else {
        return Ok(None);
    };
    // X = K⁻¹ MG on the free DOFs, then C_r = (MG)ᵀ X.
    let mut x = vec![0.0; nf * m];
    for c in 0..m {
        for (f, &k) in free.iter().enumerate() {
            for b in 0..3 {
                x[c * nf + 3 * f + b] = mg[(3 * k + b, c)];
            }
        }
    }
    k_ff.solve_columns(&mut x, m);
    let mut c_r = DMatrix::zeros(m, m);
    for c in 0..m {
        for r in 0..m {
            let mut s = 0.0;
            for (f, &k) in free.iter().enumerate() {
                for b in 0..3 {
                    s += mg[(3 * k + b, r)] * x[c * nf + 3 * f + b];
                }
            }
            c_r[(r, c)] = s;
        }
    }
    let c_r = (&c_r + c_r.transpose()) * 0.5;
    let c_inv = Cholesky::new(c_r)
        .ok_or(CageModelError::Singular)?
        .inverse();
    let k_r = m_r * c_inv * m_r;
    Ok(Some((&k_r + k_r.transpose()) * 0.5))
}

/// The Cholesky factorisation (AMD ordering) of the matrix whose lower triangle is `k`; `None`
/// if it is not positive definite (or the analysis runs out of memory).
fn factorize(k: &SparseColMat<usize, f64>) -> Option<SparseSpd> {
    let pattern = k.symbolic();
    assert!(pattern.col_nnz().is_none(), "compressed columns");
    let as_u32 =
        |v: &[usize]| -> Option<Vec<u32>> { v.iter().map(|&i| u32::try_from(i).ok()).collect() };
    let mut spd = SparseSpd::new(
        k.nrows(),
        as_u32(pattern.col_ptr())?,
        as_u32(pattern.row_idx())?,
        Side::Lower,
        Ordering::Amd,
        Method::Auto,
    )
    .ok()?;
    spd.values_mut().copy_from_slice(k.val());
    spd.factorize(Precision::Double).ok()?;
    Some(spd)
}

/// Per free node (in free numbering), the free nodes it shares a tetrahedron with.
fn free_neighbours(mesh: &TetMesh, dof: &[usize], free: usize) -> Vec<Vec<usize>> {
    let mut out: Vec<Vec<usize>> = vec![Vec::new(); free];
    for t in &mesh.tets {
        for &a in t {
            for &b in t {
                let (da, db) = (dof[a as usize], dof[b as usize]);
                if a != b && da != NONE && db != NONE {
                    out[da].push(db);
                }
            }
        }
    }
    for list in &mut out {
        list.sort_unstable();
        list.dedup();
    }
    out
}

/// Greedy colouring in which no two nodes within two edges of each other share a colour.
fn distance_two_colouring(neighbours: &[Vec<usize>]) -> Vec<usize> {
    let n = neighbours.len();
    let mut colour = vec![NONE; n];
    // `taken[c] == i + 1`: colour c is used near node i.
    let mut taken: Vec<usize> = Vec::new();
    for i in 0..n {
        for &j in &neighbours[i] {
            for &k in std::iter::once(&j).chain(&neighbours[j]) {
                let c = colour[k];
                if c != NONE {
                    taken[c] = i + 1;
                }
            }
        }
        let c = (0..taken.len())
            .find(|&c| taken[c] != i + 1)
            .unwrap_or_else(|| {
                taken.push(0);
                taken.len() - 1
            });
        colour[i] = c;
    }
    colour
}

/// Checks the assembled matrix against one more product with a field that moves every free
/// node differently: a product that couples nodes sharing no tetrahedron would not survive it.
fn check_assembly(
    k_ff: &SparseColMat<usize, f64>,
    free: &[usize],
    n: usize,
    stiffness: StiffnessProduct<'_>,
    tolerance: f64,
) -> Result<(), CageModelError> {
    let mut u = vec![[0.0; 3]; n];
    let mut x = vec![0.0; 3 * free.len()];
    for (f, &k) in free.iter().enumerate() {
        for b in 0..3 {
            let v = ((3 * f + b) as f64 * 0.618_033_988_749_895).fract() - 0.5;
            u[k][b] = v;
            x[3 * f + b] = v;
        }
    }
    let y = stiffness(&u);
    // Symmetric product from the stored lower triangle.
    let mut z = vec![0.0; x.len()];
    let k = k_ff.as_ref();
    for col in 0..x.len() {
        for (row, v) in k.row_idx_of_col(col).zip(k.val_of_col(col)) {
            z[row] += v * x[col];
            if row != col {
                z[col] += v * x[row];
            }
        }
    }
    let (mut diff, mut size) = (0.0f64, 0.0f64);
    for (f, &k) in free.iter().enumerate() {
        for b in 0..3 {
            diff = diff.max((y[k][b] - z[3 * f + b]).abs());
            size = size.max(y[k][b].abs());
        }
    }
    if diff <= tolerance * size.max(f64::MIN_POSITIVE) {
        Ok(())
    } else {
        Err(CageModelError::Parameter(format!(
            "the precise model's stiffness couples nodes that share no tetrahedron (probe \
             mismatch {diff:.3e} of {size:.3e}); use dynamics = \"galerkin\""
        )))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn colouring_separates_nodes_two_edges_apart() {
        // A path 0-1-2-3-4 and a triangle 4-5-6.
        let edges = [(0, 1), (1, 2), (2, 3), (3, 4), (4, 5), (5, 6), (4, 6)];
        let mut nb = vec![Vec::new(); 7];
        for (a, b) in edges {
            nb[a].push(b);
            nb[b].push(a);
        }
        let c = distance_two_colouring(&nb);
        for i in 0..7 {
            for &j in &nb[i] {
                assert_ne!(c[i], c[j], "{i}-{j}");
                for &k in &nb[j] {
                    if k != i {
                        assert_ne!(c[i], c[k], "{i}-{j}-{k}");
                    }
                }
            }
        }
        // Nodes 3, 4, 5 and 6 are all within two edges of each other: four colours, no more.
        assert_eq!(c.iter().max(), Some(&3), "{c:?}");
    }
}
