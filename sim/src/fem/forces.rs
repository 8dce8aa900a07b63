//! Elastic forces, linear and corotational (`f_int`, element by element or in the SIMD
//! batches), and the assembly of `mass_coef · M + K` into the sparse system.

use super::element::{self, add, mat_t_mul, mat_vec, scale, stress, sub, Element};
use super::rotation::{closest_rotation, quat_to_mat, quat_to_mat_minus_identity, QUAT_IDENTITY};
use super::{Fem, FemMode};

impl Fem {
    /// Elastic force on every node at the current positions, N: `−K(x − X)` (linear) or
    /// `−Σₑ Rₑ Kₑ (Rₑᵀx − X)` (corotational). On a fixed node it is the load the node passes
    /// to its support. Allocates; not for the real-time path.
    pub fn elastic_forces(&self) -> Vec<[f64; 3]> {
        let mut out = vec![[0.0; 3]; self.x.len()];
        for (e, el) in self.elements.iter().enumerate() {
            let mut q = self.s.batch.rotation(e);
            let (f, _) =
                element_forces(el, &self.u, self.params.mode, self.lambda, self.mu, &mut q);
            for (k, &n) in el.nodes.iter().enumerate() {
                out[n as usize] = add(out[n as usize], f[k]);
            }
        }
        out
    }

    /// `K u`: the rest (linear) stiffness applied to a displacement field `u` (m, one per
    /// node), N — what a linear body would push back with, `−f_int(X + u)`. The same in both
    /// modes (corotational elements linearise to it at rest). For reduced models built on top of
    /// this one, such as the cage dynamics of `crate::lop`. Allocates; not for the real-time
    /// path.
    ///
    /// # Panics
    /// If `u` does not have one entry per node.
    pub fn rest_stiffness_product(&self, u: &[[f64; 3]]) -> Vec<[f64; 3]> {
        assert_eq!(u.len(), self.x.len(), "one displacement per node");
        let mut out = vec![[0.0; 3]; u.len()];
        for el in &self.elements {
            let mut q = QUAT_IDENTITY;
            let (f, _) = element_forces(el, u, FemMode::Linear, self.lambda, self.mu, &mut q);
            for (k, &n) in el.nodes.iter().enumerate() {
                out[n as usize] = sub(out[n as usize], f[k]);
            }
        }
        out
    }

    /// Fills `force` with `−f_int(x)` and (corotational) `grads` with the rotated gradients.
    pub(super) fn internal_forces(&mut self) {
        // The element rotations move (corotational): the per-node ones follow when needed.
        self.s.node_rot_stale = true;
        if let (FemMode::Corotational, Some(pool)) = (self.params.mode, &self.pool) {
            let (u, force) = (&self.u, &mut self.s.force);
            self.s
                .batch
                .corotational_forces_pooled(pool, u, self.lambda, self.mu, force);
            return;
        }
        self.s.force.iter_mut().for_each(|f| *f = [0.0; 3]);
        if self.params.mode == FemMode::Corotational {
            let (u, force) = (&self.u, &mut self.s.force);
            self.s
                .batch
                .corotational_forces(u, self.lambda, self.mu, force);
            return;
        }
        for el in &self.elements {
            let mut q = QUAT_IDENTITY;
            let (f, _) = element_forces(el, &self.u, FemMode::Linear, self.lambda, self.mu, &mut q);
            for (k, &n) in el.nodes.iter().enumerate() {
                self.s.force[n as usize] = add(self.s.force[n as usize], f[k]);
            }
        }
    }

    /// Assembles `mass_coef · M + K` into the system matrix, `K` warped (from `grads`) or at
    /// rest.
    pub(super) fn assemble(&mut self, mass_coef: f64, warped: bool) {
        self.system.clear_with_mass(&self.mass, mass_coef);
        for (e, el) in self.elements.iter().enumerate() {
            let (vl, vm) = (el.volume * self.lambda, el.volume * self.mu);
            let g = if warped {
                self.s.batch.warped_gradients(e)
            } else {
                el.grad
            };
            self.system.add_element(e, &g, vl, vm);
        }
    }
}

/// Elastic forces on an element's four nodes (`−f_int`) and the gradients its stiffness is
/// built from (`R bᵢ`, or `bᵢ` in linear mode). `q` is the rotation's warm start.
#[inline]
pub(super) fn element_forces(
    el: &Element,
    u: &[[f64; 3]],
    mode: FemMode,
    lambda: f64,
    mu: f64,
    q: &mut [f64; 4],
) -> ([[f64; 3]; 4], [[f64; 3]; 4]) {
    let g = el.displacement_gradient(u);
    let mut out = [[0.0; 3]; 4];
    match mode {
        FemMode::Linear => {
            let s = stress(&g, lambda, mu);
            for k in 0..4 {
                out[k] = scale(mat_vec(&s, el.grad[k]), -el.volume);
            }
            (out, el.grad)
        }
        FemMode::Corotational => {
            let h = corotated_strain(&g, q);
            let r = quat_to_mat(q);
            let s = stress(&h, lambda, mu);
            let mut c = [[0.0; 3]; 4];
            for k in 0..4 {
                // −V R σ bᵢ, and R bᵢ for the warped stiffness.
                out[k] = scale(mat_vec(&r, mat_vec(&s, el.grad[k])), -el.volume);
                c[k] = mat_vec(&r, el.grad[k]);
            }
            (out, c)
        }
    }
}

/// `RᵀF − I` for the displacement gradient `g = F − I`, with `R` the rotation closest to `F`
/// (stored in `q`, warm-started from it), computed without cancellation.
#[inline]
fn corotated_strain(g: &element::Mat3, q: &mut [f64; 4]) -> element::Mat3 {
    let mut f = *g;
    for (k, row) in f.iter_mut().enumerate() {
        row[k] += 1.0;
    }
    closest_rotation(&f, q);
    let r = quat_to_mat(q);
    // RᵀF − I = Rᵀ ∇u + (R − I)ᵀ.
    let mut h = mat_t_mul(&r, g);
    let rm = quat_to_mat_minus_identity(q);
    for a in 0..3 {
        for b in 0..3 {
            h[a][b] += rm[b][a];
        }
    }
    h
}
