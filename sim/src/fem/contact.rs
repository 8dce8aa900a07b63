//! The tool's contact inside the implicit step: finding the pressed triangle (or the
//! god-object's anchor), its contact vectors and Phong normal, and the Sherman–Morrison–Woodbury
//! solves that add its linearised stiffness to a factored `K̃` (with the linear mode's cache of
//! `K̃⁻¹` columns).

use super::element::{add, cross, dot, norm, scale, sub};
use super::system::NONE;
use super::{Factor, Fem};
use crate::contact::{closest_on_surface, SurfaceHit};
use crate::interaction::{anchored_touch, ContactReport, ToolAnchor, ToolContact};

impl Fem {
    /// Finds the tool's contact at the current positions (closest candidate triangle, as the
    /// mass-spring model does); if the tool presses, fills `contact_dir` with `c`.
    pub(super) fn contact_setup(&mut self, c: &ToolContact<'_>) -> Option<Pressed> {
        if let Some(a) = c.anchor {
            return self.anchored_setup(c, a);
        }
        let mut best: Option<(u32, SurfaceHit)> = None;
        for &t in c.candidates {
            let Some(tri) = c.surface.get(t as usize) else {
                continue;
            };
            if tri.iter().any(|&k| k as usize >= self.x.len()) {
                continue;
            }
            if let Some(hit) =
                closest_on_surface(self.x.as_slice(), std::slice::from_ref(tri), c.tool.center)
            {
                if best.is_none_or(|(_, b)| hit.distance < b.distance) {
                    best = Some((t, hit));
                }
            }
        }
        let (t, hit) = best?;
        let depth = c.tool.depth(&hit);
        let force = c.tool.force_magnitude(depth);
        if !(depth > 0.0) || !(force > 0.0) {
            return None;
        }
        let tri = c.surface[t as usize];
        let dofs = tri.map(|k| self.system.dof[k as usize]);
        let normal = self.contact_normal(c.surface, t as usize, &hit);
        let p = Pressed::press(
            dofs,
            hit.barycentric,
            normal,
            depth,
            force,
            c.tool.max_stiffness(depth),
        );
        self.fill_contact_dirs(&p);
        Some(p)
    }

    /// The god-object's contact (see [`ToolAnchor`]): the spring between god-object and device
    /// that the hand feels, `−k g` on the tissue, with its stiffness in every direction
    /// (rank three: along the gap only, the sideways stiffness `F/|g|` of the turning spring
    /// would be explicit, and with the small gaps of soft tissue the point rings). A press
    /// may only push (`outward`), a grab pulls too. The Phong normal below is not used: the
    /// direction is the god-object's, so the tissue receives what the hand feels.
    fn anchored_setup(&mut self, c: &ToolContact<'_>, a: ToolAnchor) -> Option<Pressed> {
        let t = anchored_touch(c, a, &self.x)?;
        let dofs = t.tri.map(|k| self.system.dof[k as usize]);
        // The tissue receives on_tissue = Σ −λ_a n_a with n_a = −e_a: λ = on_tissue.
        let p = Pressed {
            dofs,
            weights: t.weights,
            dirs: [[-1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]],
            m: 3,
            force: t.on_tissue,
            stiffness: t.stiffness,
            depth: t.depth,
            outward: (!a.grab).then_some(a.offset),
        };
        self.fill_contact_dirs(&p);
        Some(p)
    }

    /// Writes the contact vectors `c_a = (w₀ n_a, w₁ n_a, w₂ n_a)` into `contact_dir`.
    fn fill_contact_dirs(&mut self, p: &Pressed) {
        for a in 0..p.m {
            let v = &mut self.s.contact_dir[a];
            v.fill(0.0);
            for k in 0..3 {
                if p.dofs[k] != NONE {
                    for d in 0..3 {
                        v[p.dofs[k] as usize + d] = p.weights[k] * p.dirs[a][d];
                    }
                }
            }
        }
    }

    /// Direction of the tool's push on the contact point: the vertex normals of the triangle
    /// at the current positions (area-weighted means of the adjacent face normals),
    /// interpolated with the barycentric weights and normalised — a Phong normal.
    ///
    /// Why not the triangle's face normal: the contact law acts on the single closest triangle,
    /// and when a stiff tool on soft tissue has pushed a vertex into a pit, the closest
    /// triangle alternates between the pit's walls from one step to the next; with face
    /// normals the push alternates sideways with them and the tissue never settles (a
    /// period-2 limit cycle a large implicit step cannot damp). The interpolated normal is
    /// continuous across triangle edges, so a jump of the closest point between triangles that
    /// share the pressed vertex barely changes the force. On a flat patch it is the face
    /// normal. The depth, and so the force magnitude, is the shared law's. Falls back to the
    /// face normal if `surface` is not this body's surface or a normal degenerates.
    fn contact_normal(&self, surface: &[[u32; 3]], t: usize, hit: &SurfaceHit) -> [f64; 3] {
        if surface.len() != self.surface.len() || surface[t] != self.surface[t] {
            return hit.normal;
        }
        let mut n = [0.0; 3];
        for (k, &node) in surface[t].iter().enumerate() {
            let node = node as usize;
            let mut vn = [0.0; 3];
            for &f in &self.node_faces[self.node_face_ptr[node]..self.node_face_ptr[node + 1]] {
                let [a, b, c] = self.surface[f as usize].map(|i| self.x[i as usize]);
                vn = add(vn, cross(sub(b, a), sub(c, a)));
            }
            let len = norm(vn);
            if !(len > 0.0) {
                return hit.normal;
            }
            n = add(n, scale(vn, hit.barycentric[k] / len));
        }
        let len = norm(n);
        if len > 1e-6 && len.is_finite() {
            scale(n, 1.0 / len)
        } else {
            hit.normal
        }
    }

    /// With `sol = K̃⁻¹ b`: the increment of `(K̃ + k' C Cᵀ) d = b − C F` is
    /// `d = sol − Z λ`, `Z = K̃⁻¹ C`, `(I + k' Cᵀ Z) λ = F + k' Cᵀ sol`; `λ` is the contact
    /// force after the step. A press whose `λ` would pull is dropped.
    pub(super) fn woodbury(&mut self, p: &Pressed) -> ContactReport {
        for a in 0..p.m {
            self.system.solve_in_place(&mut self.s.contact_dir[a]);
        }
        self.woodbury_solved(p)
    }

    /// [`Fem::woodbury`] with `K̃⁻¹ c_a` assembled from cached columns of `K̃⁻¹` (linear mode:
    /// the factor is fixed, and `c_a` only involves the touched triangle's nodes), computed by
    /// three solves the first time a node is touched instead of one solve per direction every
    /// step.
    pub(super) fn woodbury_cached(&mut self, p: &Pressed) -> ContactReport {
        let mut slots = [None; 3];
        for k in 0..3 {
            if p.dofs[k] != NONE && p.weights[k] != 0.0 {
                slots[k] = self.inverse_columns(p.dofs[k]);
                if slots[k].is_none() {
                    return self.woodbury(p);
                }
            }
        }
        let n = self.system.n_dof;
        for a in 0..p.m {
            let z = &mut self.s.contact_dir[a];
            z.fill(0.0);
            for (k, slot) in slots.iter().enumerate() {
                let Some(slot) = *slot else {
                    continue;
                };
                for b in 0..3 {
                    let w = p.weights[k] * p.dirs[a][b];
                    if w != 0.0 {
                        let col = &self.s.inv_cols[(3 * slot + b) * n..(3 * slot + b + 1) * n];
                        z.iter_mut().zip(col).for_each(|(z, c)| *z += w * c);
                    }
                }
            }
        }
        self.woodbury_solved(p)
    }

    /// The cache slot holding the three columns of `K̃⁻¹` for the DOF block starting at `d`,
    /// computed into the least recently used slot if missing. `None` without a cache (not
    /// linear mode) or without the rest factor.
    fn inverse_columns(&mut self, d: u32) -> Option<usize> {
        if self.s.inv_key.is_empty() || self.factor != Factor::RestDynamic {
            return None;
        }
        self.s.inv_clock += 1;
        let clock = self.s.inv_clock;
        if let Some(k) = self.s.inv_key.iter().position(|&key| key == d) {
            self.s.inv_used[k] = clock;
            return Some(k);
        }
        let k = (0..self.s.inv_key.len()).min_by_key(|&k| self.s.inv_used[k])?;
        let n = self.system.n_dof;
        for b in 0..3 {
            let col = &mut self.s.inv_cols[(3 * k + b) * n..(3 * k + b + 1) * n];
            col.fill(0.0);
            col[d as usize + b] = 1.0;
            self.system.solve_in_place(col);
        }
        self.s.inv_key[k] = d;
        self.s.inv_used[k] = clock;
        Some(k)
    }

    /// [`Fem::woodbury`] once `contact_dir` holds `Z = K̃⁻¹ C`.
    fn woodbury_solved(&mut self, p: &Pressed) -> ContactReport {
        let m = p.m;
        let mut sm = [[0.0; 3]; 3];
        let mut r = [0.0; 3];
        for a in 0..m {
            for b in 0..m {
                sm[a][b] = (a == b) as u8 as f64 + p.stiffness * p.dot(a, &self.s.contact_dir[b]);
            }
            r[a] = p.force[a] + p.stiffness * p.dot(a, &self.s.sol);
        }
        let Some(lambda) = solve_small(sm, r, m) else {
            return ContactReport::default();
        };
        if !p.admissible(lambda) {
            return ContactReport::default();
        }
        for a in 0..m {
            for (d, z) in self.s.sol.iter_mut().zip(&self.s.contact_dir[a]) {
                *d -= lambda[a] * z;
            }
        }
        p.report(lambda, &self.s.sol)
    }
}

/// The tool on a triangle during one step: `m` contact vectors `c_a = (w₀n_a, w₁n_a, w₂n_a)`
/// on its nodes — one along the normal for a press, three (the axes) for a grab.
#[derive(Debug, Clone, Copy)]
pub(super) struct Pressed {
    /// First DOF of each triangle node, or `NONE` if held.
    pub(super) dofs: [u32; 3],
    /// Barycentric weights of the contact point.
    pub(super) weights: [f64; 3],
    /// Unit directions `n_a`; the tissue receives `−λ_a n_a`.
    pub(super) dirs: [[f64; 3]; 3],
    /// Directions in use: 1 (press) or 3 (grab).
    pub(super) m: usize,
    /// `λ_a` at the start of the step, N.
    pub(super) force: [f64; 3],
    /// `dF/d depth`, N/m (the same along every direction).
    pub(super) stiffness: f64,
    /// Press: penetration at the start of the step; god-object: the gap's length, m.
    pub(super) depth: f64,
    /// For a contact that may only push: its outward direction (the force on the tissue must
    /// point against it). `None`: a grab, which pulls too.
    pub(super) outward: Option<[f64; 3]>,
}

impl Pressed {
    /// A press along `normal` with force `force` at `depth`.
    fn press(
        dofs: [u32; 3],
        weights: [f64; 3],
        normal: [f64; 3],
        depth: f64,
        force: f64,
        stiffness: f64,
    ) -> Pressed {
        Pressed {
            dofs,
            weights,
            dirs: [normal, [0.0; 3], [0.0; 3]],
            m: 1,
            force: [force, 0.0, 0.0],
            stiffness,
            depth,
            outward: Some(normal),
        }
    }

    /// The force on the tissue for contact forces `λ`.
    fn on_tissue(&self, lambda: [f64; 3]) -> [f64; 3] {
        let mut f = [0.0; 3];
        for a in 0..self.m {
            f = add(f, scale(self.dirs[a], -lambda[a]));
        }
        f
    }

    /// Whether forces `λ` are allowed: a press must push.
    pub(super) fn admissible(&self, lambda: [f64; 3]) -> bool {
        match self.outward {
            None => true,
            Some(o) => dot(self.on_tissue(lambda), o) < 0.0,
        }
    }

    /// What the step applied: forces `λ_a` along `−n_a`; the press's depth grown by `c₀ᵀd`
    /// (a grab's gap: `|λ| / k'`).
    pub(super) fn report(&self, lambda: [f64; 3], d: &[f64]) -> ContactReport {
        let f = self.on_tissue(lambda);
        let depth = if self.m == 3 {
            if self.stiffness > 0.0 {
                norm(lambda) / self.stiffness
            } else {
                self.depth
            }
        } else {
            (self.depth + self.dot(0, d)).max(0.0)
        };
        ContactReport {
            force_on_tissue: f,
            depth,
            proxy: None,
            response: None,
        }
    }

    /// `c_aᵀ v` for a DOF vector `v`.
    pub(super) fn dot(&self, a: usize, v: &[f64]) -> f64 {
        let mut s = 0.0;
        for k in 0..3 {
            let d = self.dofs[k];
            if d != NONE {
                let d = d as usize;
                s += self.weights[k] * dot(self.dirs[a], [v[d], v[d + 1], v[d + 2]]);
            }
        }
        s
    }
}

/// Solves the leading `m × m` block of `a x = b` (m ≤ 3) with nalgebra's LU (partial
/// pivoting) on a fixed-size matrix, so nothing allocates; `None` if singular or not finite.
pub(super) fn solve_small(a: [[f64; 3]; 3], b: [f64; 3], m: usize) -> Option<[f64; 3]> {
    use nalgebra::{SMatrix, SVector};
    let mut x = [0.0; 3];
    macro_rules! solve {
        ($m:literal) => {{
            let am = SMatrix::<f64, $m, $m>::from_fn(|i, j| a[i][j]);
            let bm = SVector::<f64, $m>::from_fn(|i, _| b[i]);
            x[..$m].copy_from_slice(am.lu().solve(&bm)?.as_slice());
        }};
    }
    match m {
        0 => {}
        1 => solve!(1),
        2 => solve!(2),
        3 => solve!(3),
        _ => return None,
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}
