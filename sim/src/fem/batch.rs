//! The corotational element loops — elastic forces with the rotation search, and the
//! matrix-free product with the warped stiffness — run on [`LANES`] elements at a time.
//!
//! Per element, the forces are a few hundred flops in long dependency chains (the Newton
//! steps of the rotation search end in a square root and a division each) and the product
//! about a hundred: one element at a time, the core waits on latencies. Here the elements'
//! rest data are stored as a structure of arrays, `LANES` elements side by side, and every
//! operation is written on a whole row of lanes ([`V`]), which the compiler turns into vector
//! instructions (AVX when the CPU has it, checked at run time; SSE2 otherwise).
//!
//! The arithmetic is the scalar code's, operation for operation and in the same order
//! (additions, multiplications, divisions and square roots only, no fused multiply-add, which
//! would round differently), and the results are scattered in element order: the forces,
//! rotations and products are bit-for-bit those of [`super::forces::element_forces`] and
//! [`super::element::apply_stiffness`], which the tests check. The rotation search follows
//! [`super::rotation::closest_rotation`] lane by lane (a lane stops when it has converged,
//! the others go on); the rare lane that needs the SVD fallback gets it afterwards, alone.
//!
//! The last batch is padded with empty elements (no volume, no gradients, no unknowns),
//! which are never scattered.

use super::element::Element;
use super::lanes::*;
use super::rotation::QUAT_IDENTITY;
use super::system::NONE;
use crate::parallel::{chunk_range, SharedMut, WorkerPool};

/// Elements per batch.
pub(crate) const LANES: usize = 4;

/// One value per lane.
pub(super) type Lanes = [f64; LANES];

/// One batch's rotated gradients, `[k][c][lane]` (as [`Batches`] keeps them).
pub(crate) type WarpedBatch = [[Lanes; 3]; 4];

/// Element `e`'s rotated gradients from a copy of [`Batches::warped_batches`].
#[inline]
pub(crate) fn warped_of(w: &[WarpedBatch], e: usize) -> [[f64; 3]; 4] {
    let (i, l) = (e / LANES, e % LANES);
    let mut g = [[0.0; 3]; 4];
    for k in 0..4 {
        for c in 0..3 {
            g[k][c] = w[i][k][c][l];
        }
    }
    g
}

/// Rest data and per-step state of a body's elements, [`LANES`] to a batch.
#[derive(Debug, Clone)]
pub(crate) struct Batches {
    /// Elements (the last batch may be partly padding).
    len: usize,
    /// Per batch: node of each corner, per lane (padding: node 0, never read for its value).
    nodes: Vec<[[u32; LANES]; 4]>,
    /// Per batch: first DOF of each corner, per lane, or `NONE` (held nodes and padding).
    dofs: Vec<[[u32; LANES]; 4]>,
    /// Per batch: rest shape-function gradients `bₖ`, `grad[k][c][lane]`.
    grad: Vec<[[Lanes; 3]; 4]>,
    /// Per batch: rest volumes (padding: 0).
    volume: Vec<Lanes>,
    /// Per batch: `(Vλ, Vμ)` per lane.
    moduli: Vec<[Lanes; 2]>,
    /// Per batch: the rotation search's warm start, unit quaternions `rot[c][lane]`.
    rot: Vec<[Lanes; 4]>,
    /// Per batch: the rotated gradients `R bₖ` of the last force evaluation (the warped
    /// stiffness), `warped[k][c][lane]`.
    warped: Vec<[[Lanes; 3]; 4]>,
    /// The pooled kernels' gather and output buffer (`None` until [`Batches::enable_pool`]).
    gather: Option<Box<Gather>>,
}

impl Batches {
    /// The batches of `elements`, with `dof` the first DOF of each node (or `NONE`).
    pub fn new(elements: &[Element], dof: &[u32], lambda: f64, mu: f64) -> Batches {
        let n = elements.len().div_ceil(LANES);
        let mut b = Batches {
            len: elements.len(),
            nodes: vec![[[0; LANES]; 4]; n],
            dofs: vec![[[NONE; LANES]; 4]; n],
            grad: vec![[[[0.0; LANES]; 3]; 4]; n],
            volume: vec![[0.0; LANES]; n],
            moduli: vec![[[0.0; LANES]; 2]; n],
            rot: vec![[[0.0; LANES]; 4]; n],
            warped: vec![[[[0.0; LANES]; 3]; 4]; n],
            gather: None,
        };
        for (e, el) in elements.iter().enumerate() {
            let (i, l) = (e / LANES, e % LANES);
            for k in 0..4 {
                b.nodes[i][k][l] = el.nodes[k];
                b.dofs[i][k][l] = dof[el.nodes[k] as usize];
                for c in 0..3 {
                    b.grad[i][k][c][l] = el.grad[k][c];
                    b.warped[i][k][c][l] = el.grad[k][c];
                }
            }
            b.volume[i][l] = el.volume;
            b.moduli[i][0][l] = el.volume * lambda;
            b.moduli[i][1][l] = el.volume * mu;
        }
        b.reset_rotations();
        b
    }

    /// All rotations back to the identity (a cold start for the search).
    pub fn reset_rotations(&mut self) {
        for q in &mut self.rot {
            for (c, row) in q.iter_mut().enumerate() {
                *row = [QUAT_IDENTITY[c]; LANES];
            }
        }
    }

    /// Element `e`'s rotation (unit quaternion) from the last force evaluation.
    #[inline]
    pub fn rotation(&self, e: usize) -> [f64; 4] {
        let (i, l) = (e / LANES, e % LANES);
        let q = &self.rot[i];
        [q[0][l], q[1][l], q[2][l], q[3][l]]
    }

    /// Every batch's rotated gradients from the last force evaluation (for a snapshot).
    pub fn warped_batches(&self) -> &[WarpedBatch] {
        &self.warped
    }

    /// Element `e`'s rotated gradients `R bₖ` from the last force evaluation.
    #[inline]
    pub fn warped_gradients(&self, e: usize) -> [[f64; 3]; 4] {
        let (i, l) = (e / LANES, e % LANES);
        let w = &self.warped[i];
        let mut g = [[0.0; 3]; 4];
        for k in 0..4 {
            for c in 0..3 {
                g[k][c] = w[k][c][l];
            }
        }
        g
    }

    /// Corotational elastic forces at the displacements `u`: adds each element's `−f_int` to
    /// `force` (per node, in element order), and updates the rotations (warm-started from the
    /// last ones) and the rotated gradients.
    pub fn corotational_forces(
        &mut self,
        u: &[[f64; 3]],
        lambda: f64,
        mu: f64,
        force: &mut [[f64; 3]],
    ) {
        #[cfg(target_arch = "x86_64")]
        if avx_available() {
            // SAFETY: the CPU has AVX (checked above).
            unsafe { self.forces_avx(u, lambda, mu, force) };
            return;
        }
        self.forces_impl::<Portable>(u, lambda, mu, force);
    }

    /// `q += K_w p`: the warped stiffness (of the last force evaluation) applied to the DOF
    /// vector `p`, matrix-free.
    pub fn add_stiffness_product(&self, p: &[f64], q: &mut [f64]) {
        #[cfg(target_arch = "x86_64")]
        if avx_available() {
            // SAFETY: the CPU has AVX (checked above).
            unsafe { self.product_avx(p, q) };
            return;
        }
        self.product_impl::<Portable>(p, q);
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx,avx2")]
    unsafe fn forces_avx(&mut self, u: &[[f64; 3]], lambda: f64, mu: f64, f: &mut [[f64; 3]]) {
        self.forces_impl::<avx::Avx>(u, lambda, mu, f);
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx,avx2")]
    unsafe fn product_avx(&self, p: &[f64], q: &mut [f64]) {
        self.product_impl::<avx::Avx>(p, q);
    }

    #[inline(always)]
    fn forces_impl<S: Simd>(
        &mut self,
        u: &[[f64; 3]],
        lambda: f64,
        mu: f64,
        force: &mut [[f64; 3]],
    ) {
        let (lambda, mu) = (S::splat(lambda), S::splat(mu));
        for i in 0..self.nodes.len() {
            let out = force_batch::<S>(
                &self.nodes[i],
                &self.grad[i],
                &self.volume[i],
                &mut self.rot[i],
                &mut self.warped[i],
                u,
                lambda,
                mu,
            );
            let nodes = &self.nodes[i];
            let lanes = LANES.min(self.len - i * LANES);
            for l in 0..lanes {
                for k in 0..4 {
                    let n = nodes[k][l] as usize;
                    for c in 0..3 {
                        force[n][c] += out[k][c][l];
                    }
                }
            }
        }
    }

    #[inline(always)]
    fn product_impl<S: Simd>(&self, p: &[f64], q: &mut [f64]) {
        for i in 0..self.dofs.len() {
            let dofs = &self.dofs[i];
            let out = product_batch::<S>(dofs, &self.warped[i], &self.moduli[i], p);
            for l in 0..LANES {
                for k in 0..4 {
                    let d = dofs[k][l];
                    if d != NONE {
                        let d = d as usize;
                        for c in 0..3 {
                            q[d + c] += out[k][c][l];
                        }
                    }
                }
            }
        }
    }

    // -----------------------------------------------------------------------------------------
    // On a worker pool (`crate::parallel`): the same kernels, batch by batch into `out`, then
    // gathered node by node in element order — bit for bit the serial scatter above, whatever
    // the number of threads.

    /// Prepares the gather (node → its elements' corners, in element order) and the per-batch
    /// output buffer for the pooled kernels; `nodes` is the body's node count. Allocates, once.
    pub fn enable_pool(&mut self, nodes: usize) {
        if self.gather.is_some() {
            return;
        }
        let mut ptr = vec![0u32; nodes + 1];
        for e in 0..self.len {
            let (i, l) = (e / LANES, e % LANES);
            for k in 0..4 {
                ptr[self.nodes[i][k][l] as usize + 1] += 1;
            }
        }
        for n in 0..nodes {
            ptr[n + 1] += ptr[n];
        }
        let mut src = vec![0u32; ptr[nodes] as usize];
        let mut fill = ptr.clone();
        for e in 0..self.len {
            let (i, l) = (e / LANES, e % LANES);
            for k in 0..4 {
                let n = self.nodes[i][k][l] as usize;
                src[fill[n] as usize] = (e * 4 + k) as u32;
                fill[n] += 1;
            }
        }
        let node_dof = (0..nodes).map(|_| NONE).collect::<Vec<u32>>();
        let mut g = Gather {
            ptr,
            src,
            node_dof,
            out: vec![[[[0.0; LANES]; 3]; 4]; self.nodes.len()],
        };
        for i in 0..self.nodes.len() {
            for k in 0..4 {
                for l in 0..LANES.min(self.len - i * LANES) {
                    g.node_dof[self.nodes[i][k][l] as usize] = self.dofs[i][k][l];
                }
            }
        }
        self.gather = Some(Box::new(g));
    }

    /// [`Batches::corotational_forces`] on `pool`, with `force` overwritten rather than added
    /// to (it is the sum of the elements' contributions, in element order, from zero).
    /// Needs [`Batches::enable_pool`].
    pub fn corotational_forces_pooled(
        &mut self,
        pool: &WorkerPool,
        u: &[[f64; 3]],
        lambda: f64,
        mu: f64,
        force: &mut [[f64; 3]],
    ) {
        let Some(g) = self.gather.as_mut() else {
            unreachable!("enable_pool first")
        };
        let batches = self.nodes.len();
        let chunks = chunk_count(pool, batches);
        {
            let rot = SharedMut::new(&mut self.rot);
            let warped = SharedMut::new(&mut self.warped);
            let out = SharedMut::new(&mut g.out);
            let (nodes, grad, volume) = (&self.nodes, &self.grad, &self.volume);
            pool.run(chunks, &|c| {
                let r = chunk_range(batches, chunks, c);
                // SAFETY: the chunks' batch ranges are disjoint.
                let (rot, warped, out) = unsafe {
                    (
                        rot.range(r.clone()),
                        warped.range(r.clone()),
                        out.range(r.clone()),
                    )
                };
                let (nodes, grad, volume) = (&nodes[r.clone()], &grad[r.clone()], &volume[r]);
                #[cfg(target_arch = "x86_64")]
                if avx_available() {
                    // SAFETY: the CPU has AVX (checked above).
                    unsafe {
                        forces_chunk_avx(nodes, grad, volume, rot, warped, out, u, lambda, mu)
                    };
                    return;
                }
                forces_chunk::<Portable>(nodes, grad, volume, rot, warped, out, u, lambda, mu);
            });
        }
        let g = &**g;
        let n = force.len();
        let chunks = chunk_count(pool, n / 64);
        let dst = SharedMut::new(force);
        pool.run(chunks, &|c| {
            let r = chunk_range(n, chunks, c);
            let start = r.start;
            // SAFETY: the chunks' node ranges are disjoint.
            let f = unsafe { dst.range(r.clone()) };
            for (j, node) in r.enumerate() {
                let mut acc = [0.0; 3];
                for &s in &g.src[g.ptr[node] as usize..g.ptr[node + 1] as usize] {
                    let (e, k) = (s as usize / 4, s as usize % 4);
                    let o = &g.out[e / LANES][k];
                    for c in 0..3 {
                        acc[c] += o[c][e % LANES];
                    }
                }
                debug_assert_eq!(j + start, node);
                f[j] = acc;
            }
        });
    }

    /// `q = mass_coef · M p + K_w p` on `pool` ([`Batches::add_stiffness_product`] after
    /// `q = mass_coef · mᵢ · p` on the free DOFs, bit for bit). `mass` per node. Needs
    /// [`Batches::enable_pool`].
    pub fn dynamic_product_pooled(
        &mut self,
        pool: &WorkerPool,
        mass: &[f64],
        mass_coef: f64,
        p: &[f64],
        q: &mut [f64],
    ) {
        let Some(g) = self.gather.as_mut() else {
            unreachable!("enable_pool first")
        };
        let batches = self.dofs.len();
        let chunks = chunk_count(pool, batches);
        {
            let out = SharedMut::new(&mut g.out);
            let (dofs, warped, moduli) = (&self.dofs, &self.warped, &self.moduli);
            pool.run(chunks, &|c| {
                let r = chunk_range(batches, chunks, c);
                // SAFETY: the chunks' batch ranges are disjoint.
                let out = unsafe { out.range(r.clone()) };
                let (dofs, warped, moduli) = (&dofs[r.clone()], &warped[r.clone()], &moduli[r]);
                #[cfg(target_arch = "x86_64")]
                if avx_available() {
                    // SAFETY: the CPU has AVX (checked above).
                    unsafe { product_chunk_avx(dofs, warped, moduli, out, p) };
                    return;
                }
                product_chunk::<Portable>(dofs, warped, moduli, out, p);
            });
        }
        let g = &**g;
        let n = mass.len();
        let chunks = chunk_count(pool, n / 64);
        let dst = SharedMut::new(q);
        pool.run(chunks, &|c| {
            let r = chunk_range(n, chunks, c);
            for node in r {
                let d = g.node_dof[node];
                if d == NONE {
                    continue;
                }
                let d = d as usize;
                let m = mass_coef * mass[node];
                let mut acc = [m * p[d], m * p[d + 1], m * p[d + 2]];
                for &s in &g.src[g.ptr[node] as usize..g.ptr[node + 1] as usize] {
                    let (e, k) = (s as usize / 4, s as usize % 4);
                    let o = &g.out[e / LANES][k];
                    for c in 0..3 {
                        acc[c] += o[c][e % LANES];
                    }
                }
                // SAFETY: each free node owns its three DOFs, and the chunks' nodes are disjoint.
                unsafe { dst.range(d..d + 3) }.copy_from_slice(&acc);
            }
        });
    }

    /// The gather of the pooled kernels, if enabled: per node, its elements' corners.
    pub fn node_elements(&self, node: usize) -> Option<impl Iterator<Item = usize> + '_> {
        let g = self.gather.as_ref()?;
        let r = g.ptr[node] as usize..g.ptr[node + 1] as usize;
        Some(g.src[r].iter().map(|&s| s as usize / 4))
    }
}

/// Chunks for `work` items on `pool`: a few per thread (for balance when a thread is late),
/// never more than the items, at least one.
fn chunk_count(pool: &WorkerPool, work: usize) -> usize {
    (4 * pool.threads()).min(work).max(1)
}

/// Per body, for the pooled kernels: per node its elements' corners `4e + k`, in element order
/// (`src[ptr[n]..ptr[n + 1]]`), its first DOF (or `NONE`), and per batch the kernels' output
/// (written by the batch phase, read by the gather phase).
#[derive(Debug, Clone)]
struct Gather {
    ptr: Vec<u32>,
    src: Vec<u32>,
    node_dof: Vec<u32>,
    out: Vec<[[Lanes; 3]; 4]>,
}

/// One batch of the corotational forces: updates the rotation warm start `rot` and the rotated
/// gradients `warped`, returns `−f_int` per corner and lane.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn force_batch<S: Simd>(
    nodes: &[[u32; LANES]; 4],
    grad: &[[Lanes; 3]; 4],
    volume: &Lanes,
    rot: &mut [Lanes; 4],
    warped: &mut [[Lanes; 3]; 4],
    u: &[[f64; 3]],
    lambda: S,
    mu: S,
) -> [[Lanes; 3]; 4] {
    let grad = load_vectors::<S>(grad);
    // ∇u = Σₖ uₖ ⊗ bₖ, as `Element::displacement_gradient`.
    let mut g = [[S::splat(0.0); 3]; 3];
    for k in 0..4 {
        let n = [
            u[nodes[k][0] as usize],
            u[nodes[k][1] as usize],
            u[nodes[k][2] as usize],
            u[nodes[k][3] as usize],
        ];
        for r in 0..3 {
            let ur = S::new([n[0][r], n[1][r], n[2][r], n[3][r]]);
            for c in 0..3 {
                g[r][c] = g[r][c] + ur * grad[k][c];
            }
        }
    }
    let mut q = [S::splat(0.0); 4];
    for c in 0..4 {
        q[c] = S::load(&rot[c]);
    }
    let f = plus_identity(g);
    let svd = closest_rotation(&f, &mut q);
    if svd != 0 {
        svd_fallback(&f, &mut q, svd);
    }
    for c in 0..4 {
        rot[c] = q[c].to_array();
    }
    // RᵀF − I = Rᵀ∇u + (R − I)ᵀ, as `corotated_strain`.
    let rm = quat_to_mat_minus_identity(&q);
    let r = plus_identity(rm);
    let mut h = mat_t_mul(&r, &g);
    for a in 0..3 {
        for b in 0..3 {
            h[a][b] = h[a][b] + rm[b][a];
        }
    }
    // σ = λ tr(ε) I + 2μ ε, as `element::stress`.
    let s = isotropic(&h, lambda, mu);
    let neg_vol = -S::load(volume);
    let mut out = [[[0.0; LANES]; 3]; 4];
    for k in 0..4 {
        // −V R σ bₖ, and R bₖ for the warped stiffness.
        let sb = mat_vec(&s, &grad[k]);
        let rsb = mat_vec(&r, &sb);
        let rb = mat_vec(&r, &grad[k]);
        for c in 0..3 {
            out[k][c] = (rsb[c] * neg_vol).to_array();
            warped[k][c] = rb[c].to_array();
        }
    }
    out
}

/// One batch of the matrix-free product `K_w p`: per corner and lane (zero at held corners'
/// inputs; the caller skips their outputs).
#[inline(always)]
fn product_batch<S: Simd>(
    dofs: &[[u32; LANES]; 4],
    warped: &[[Lanes; 3]; 4],
    moduli: &[Lanes; 2],
    p: &[f64],
) -> [[Lanes; 3]; 4] {
    let w = load_vectors::<S>(warped);
    // G = Σⱼ pⱼ ⊗ cⱼ, as `element::apply_stiffness`; held corners contribute zero.
    let mut g = [[S::splat(0.0); 3]; 3];
    for j in 0..4 {
        let d = dofs[j];
        let held = [d[0] == NONE, d[1] == NONE, d[2] == NONE, d[3] == NONE];
        let at = |l: usize, a: usize| if held[l] { 0.0 } else { p[d[l] as usize + a] };
        for a in 0..3 {
            let pa = S::new([at(0, a), at(1, a), at(2, a), at(3, a)]);
            for b in 0..3 {
                g[a][b] = g[a][b] + pa * w[j][b];
            }
        }
    }
    let (vl, vm) = (S::load(&moduli[0]), S::load(&moduli[1]));
    let s = isotropic(&g, vl, vm);
    let mut out = [[[0.0; LANES]; 3]; 4];
    for k in 0..4 {
        let o = mat_vec(&s, &w[k]);
        for c in 0..3 {
            out[k][c] = o[c].to_array();
        }
    }
    out
}

#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn forces_chunk<S: Simd>(
    nodes: &[[[u32; LANES]; 4]],
    grad: &[[[Lanes; 3]; 4]],
    volume: &[Lanes],
    rot: &mut [[Lanes; 4]],
    warped: &mut [[[Lanes; 3]; 4]],
    out: &mut [[[Lanes; 3]; 4]],
    u: &[[f64; 3]],
    lambda: f64,
    mu: f64,
) {
    let (lambda, mu) = (S::splat(lambda), S::splat(mu));
    for i in 0..nodes.len() {
        out[i] = force_batch::<S>(
            &nodes[i],
            &grad[i],
            &volume[i],
            &mut rot[i],
            &mut warped[i],
            u,
            lambda,
            mu,
        );
    }
}

#[cfg(target_arch = "x86_64")]
#[allow(clippy::too_many_arguments)]
#[target_feature(enable = "avx,avx2")]
unsafe fn forces_chunk_avx(
    nodes: &[[[u32; LANES]; 4]],
    grad: &[[[Lanes; 3]; 4]],
    volume: &[Lanes],
    rot: &mut [[Lanes; 4]],
    warped: &mut [[[Lanes; 3]; 4]],
    out: &mut [[[Lanes; 3]; 4]],
    u: &[[f64; 3]],
    lambda: f64,
    mu: f64,
) {
    forces_chunk::<avx::Avx>(nodes, grad, volume, rot, warped, out, u, lambda, mu);
}

#[inline(always)]
fn product_chunk<S: Simd>(
    dofs: &[[[u32; LANES]; 4]],
    warped: &[[[Lanes; 3]; 4]],
    moduli: &[[Lanes; 2]],
    out: &mut [[[Lanes; 3]; 4]],
    p: &[f64],
) {
    for i in 0..dofs.len() {
        out[i] = product_batch::<S>(&dofs[i], &warped[i], &moduli[i], p);
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx,avx2")]
unsafe fn product_chunk_avx(
    dofs: &[[[u32; LANES]; 4]],
    warped: &[[[Lanes; 3]; 4]],
    moduli: &[[Lanes; 2]],
    out: &mut [[[Lanes; 3]; 4]],
    p: &[f64],
) {
    product_chunk::<avx::Avx>(dofs, warped, moduli, out, p);
}

#[cfg(test)]
mod tests {
    use super::super::element::{apply_stiffness, lame};
    use super::super::forces::element_forces;
    use super::super::FemMode;
    use super::*;
    use lop_test_support::rng::Rng;

    /// A small irregular mesh: random points in a unit cube, tetrahedra from a lattice of
    /// jittered cubes (5 of each kind per cube; degenerate ones skipped).
    fn elements() -> (Vec<Element>, Vec<[f64; 3]>) {
        let mut rng = Rng::new(0x2545_f491_4f6c_dd1d);
        let mut rnd = || rng.unit();
        let n = 4;
        let mut nodes = Vec::new();
        for i in 0..n {
            for j in 0..n {
                for k in 0..n {
                    nodes.push([
                        i as f64 + 0.2 * rnd(),
                        j as f64 + 0.2 * rnd(),
                        k as f64 + 0.2 * rnd(),
                    ]);
                }
            }
        }
        let id = |i: usize, j: usize, k: usize| (i * n * n + j * n + k) as u32;
        let mut els = Vec::new();
        for i in 0..n - 1 {
            for j in 0..n - 1 {
                for k in 0..n - 1 {
                    let c = [
                        id(i, j, k),
                        id(i + 1, j, k),
                        id(i, j + 1, k),
                        id(i + 1, j + 1, k),
                        id(i, j, k + 1),
                        id(i + 1, j, k + 1),
                        id(i, j + 1, k + 1),
                        id(i + 1, j + 1, k + 1),
                    ];
                    for t in [
                        [0, 1, 3, 5],
                        [0, 3, 2, 6],
                        [0, 5, 4, 6],
                        [3, 5, 6, 7],
                        [0, 3, 5, 6],
                    ] {
                        let mut tn = t.map(|v| c[v]);
                        let corners = |tn: [u32; 4]| tn.map(|v| nodes[v as usize]);
                        let e = Element::new(tn, corners(tn)).or_else(|| {
                            tn.swap(0, 1);
                            Element::new(tn, corners(tn))
                        });
                        els.extend(e);
                    }
                }
            }
        }
        (els, nodes)
    }

    #[test]
    fn batched_forces_and_products_are_the_scalar_ones() {
        let (els, nodes) = elements();
        let n = nodes.len();
        assert!(
            els.len() % LANES != 0 && els.len() > 100,
            "{} elements",
            els.len()
        );
        let (lambda, mu) = lame(3000.0, 0.45);
        // Every seventh node held.
        let dof: Vec<u32> = (0..n as u32)
            .map(|i| if i % 7 == 3 { NONE } else { 3 * i })
            .collect();
        // The dispatching entry points (AVX on a CPU that has it) and the portable kernels.
        let mut native = Batches::new(&els, &dof, lambda, mu);
        let mut portable = native.clone();
        let mut inverted = 0;
        let mut rot = vec![QUAT_IDENTITY; els.len()];
        let mut rng = Rng::new(7);
        let mut rnd = || rng.unit() - 0.5;
        // Three steps of a rotating, stretching, partly inverting motion: warm starts, Newton,
        // and the SVD fallback (inverted elements) all run.
        for step in 0..3 {
            let angle = 0.6 * step as f64;
            let (s, c) = angle.sin_cos();
            let u: Vec<[f64; 3]> = (0..n)
                .map(|i| {
                    let p = nodes[i];
                    let x = [c * p[0] - s * p[1], s * p[0] + c * p[1], 1.3 * p[2]];
                    let jitter = if i % 11 == 0 { 3.0 } else { 0.05 };
                    [
                        x[0] - p[0] + jitter * rnd(),
                        x[1] - p[1] + jitter * rnd(),
                        x[2] - p[2] + jitter * rnd(),
                    ]
                })
                .collect();
            let mut want = vec![[0.0; 3]; n];
            let mut want_grads = Vec::new();
            for (e, el) in els.iter().enumerate() {
                let mut f = el.displacement_gradient(&u);
                for (k, row) in f.iter_mut().enumerate() {
                    row[k] += 1.0;
                }
                let det = f[0][0] * (f[1][1] * f[2][2] - f[1][2] * f[2][1])
                    - f[0][1] * (f[1][0] * f[2][2] - f[1][2] * f[2][0])
                    + f[0][2] * (f[1][0] * f[2][1] - f[1][1] * f[2][0]);
                inverted += (det <= 0.0) as usize;
                let (f, g) = element_forces(el, &u, FemMode::Corotational, lambda, mu, &mut rot[e]);
                for k in 0..4 {
                    for c in 0..3 {
                        want[el.nodes[k] as usize][c] += f[k][c];
                    }
                }
                want_grads.push(g);
            }
            let mut got = vec![[0.0; 3]; n];
            native.corotational_forces(&u, lambda, mu, &mut got);
            assert_eq!(got, want, "forces, step {step}");
            let mut got = vec![[0.0; 3]; n];
            portable.forces_impl::<Portable>(&u, lambda, mu, &mut got);
            assert_eq!(got, want, "portable forces, step {step}");
            for b in [&native, &portable] {
                for e in 0..els.len() {
                    assert_eq!(b.rotation(e), rot[e], "rotation of element {e}");
                    let w = b.warped_gradients(e);
                    assert_eq!(w, want_grads[e], "gradients of element {e}");
                }
            }
            // The product, against the scalar one.
            let p: Vec<f64> = (0..3 * n).map(|_| rnd()).collect();
            let mut want_q = vec![0.5; 3 * n];
            for (e, el) in els.iter().enumerate() {
                let d = el.nodes.map(|v| dof[v as usize]);
                let pe = d.map(|d| {
                    if d == NONE {
                        [0.0; 3]
                    } else {
                        [p[d as usize], p[d as usize + 1], p[d as usize + 2]]
                    }
                });
                let out = apply_stiffness(&want_grads[e], el.volume * lambda, el.volume * mu, &pe);
                for k in 0..4 {
                    if d[k] != NONE {
                        for c in 0..3 {
                            want_q[d[k] as usize + c] += out[k][c];
                        }
                    }
                }
            }
            let mut got_q = vec![0.5; 3 * n];
            native.add_stiffness_product(&p, &mut got_q);
            assert_eq!(got_q, want_q, "product, step {step}");
            let mut got_q = vec![0.5; 3 * n];
            portable.product_impl::<Portable>(&p, &mut got_q);
            assert_eq!(got_q, want_q, "portable product, step {step}");
        }
        // The SVD fallback ran (inverted elements), and so did Newton (most of them).
        assert!(inverted > 10 && inverted < els.len(), "{inverted} inverted");
    }
}
