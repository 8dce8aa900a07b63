//! The static contact reference of `lop-bench haptics`: a rigid frictionless sphere pressed
//! into a linear-elastic body, solved here from scratch so that it shares nothing with
//! lop-sim's tool contact.
//!
//! **Problem.** Linear tetrahedra (`K_ij = V (λ bᵢbⱼᵀ + μ bⱼbᵢᵀ + μ (bᵢ·bⱼ) I)`, the textbook
//! element; a test checks `K u` against lop-sim's `Fem::rest_stiffness_product`, which is
//! validated against an independent FE code), fixed nodes clamped, a sphere of radius `R`
//! pressed along the inward normal `−n` at a point `c` of the undeformed surface, its centre at
//! `s = c + n (R − d)` for the indentation `d` (on the block `c` is the top face's centre and
//! `n = +z`; on a curved body, [`vertex_normal`]); every candidate surface node `j` must stay
//! outside it, `|x_j + u_j − s| ≥ R`, and may only be pushed, along
//! `n_j = (x_j + u_j − s)/|·|`, by `λ_j ≥ 0`.
//!
//! **Algorithm.** Only nodes near the contact can touch the sphere (the *candidates*: free
//! surface nodes within [`ContactReference::new`]'s radius of `c`, a 3D distance), so the
//! problem is condensed onto them:
//! `K` is factorised once (faer's sparse Cholesky, AMD ordering) and the candidates' compliance
//! `C = P K⁻¹ Pᵀ` (3m × 3m, dense) is formed from 3m solves. Each indentation is then a small
//! problem, solved by an active set with the constraints linearised at the current normals:
//!
//! ```text
//! (N_Aᵀ C N_A + I/k_p) λ_A = g_A,   g_j = R − n_jᵀ(x_j − s),   u = C N_A λ_A
//! ```
//!
//! (`k_p = ∞`: Lagrange multipliers, exact; finite: a penalty `λ = k_p · penetration`), then the
//! normals are recomputed at `x + u`, nodes with `λ < 0` leave the set, penetrating nodes join
//! it, until the set and the normals no longer change and no node penetrates by more than
//! `1e-4 d`. A final full solve `K u = f` checks that no surface node outside the candidates
//! penetrates, and gives the support reactions (`Σ contact forces = −Σ reactions`).
//!
//! **Faces.** Without samples only nodes touch the sphere and the faces between them may cut
//! into it: on a mesh finer than the tool that is the usual node-to-surface discretisation (the
//! block: the cut is second order in the edge length). On a mesh coarser than the tool (the
//! liver's 13 mm edges under a 3 mm tip) the sphere pressed on a node soon rests on the faces
//! around it; nodes alone let that node slip round the sphere (on the liver, past 1 mm). With
//! `face_samples = k`, the candidate faces (those whose closest point to `c` is within the
//! radius) contribute the material points `(i, j, k − i − j)/k` strictly inside them as further
//! constraints, spread over their nodes by the barycentric weights (the columns of `N` become
//! `G`'s). Neighbouring samples are nearly the same constraint, so: a penalty (exact multipliers
//! make the system singular), one change of the active set per iteration (batches cycle), and
//! the indentation in steps of `R/30` from the previous solution (at `d = R` the sphere's
//! centre is the undeformed contact point, and the undeformed directions mean nothing).
//! Tried first and dropped: the faces' closest points as constraints (near a node they repeat
//! its constraint, and the active set cycles).
//!
//! The FE assembly and its factor are in `assembly.rs`; this file is the contact solver.

use anyhow::{bail, Result};
use glam::DVec3;
use lop_sim::mesh::TetMesh;
use nalgebra::{DMatrix, DVector};

mod assembly;
pub use assembly::{Material, Stiffness};

/// No degree of freedom (a fixed node).
const NONE: u32 = u32::MAX;
/// Right-hand sides solved at once when forming the compliance.
const BATCH: usize = 64;
/// Active-set iterations before giving up.
const MAX_ITERATIONS: usize = 200;
/// The same with face samples, which change one at a time.
const MAX_ITERATIONS_SAMPLED: usize = 5000;
/// Normals are converged when no component moves more than this between iterations.
const NORMAL_TOLERANCE: f64 = 1e-10;

/// How the contact constraint is enforced.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Penalty {
    /// Lagrange multipliers: no penetration at all.
    Exact,
    /// A penalty of this stiffness per point, N/m: an active point penetrates by `λ/k_p`. (The
    /// block uses `Exact`; the tests show the two agree. The liver's face samples need it.)
    Stiffness(f64),
}

/// Where a solve ended, to start the next (deeper) one from.
struct Warm {
    /// Which points were in contact.
    active: Vec<bool>,
    /// The candidates' displacements.
    u: Vec<f64>,
}

/// A material point of a surface face: its nodes and barycentric weights.
#[derive(Debug, Clone, Copy)]
struct Sample {
    nodes: [u32; 3],
    weights: [f64; 3],
}

/// The solution at one indentation.
#[derive(Debug, Clone)]
pub struct Contact {
    /// Indentation of the undeformed surface along the press direction, m.
    pub depth: f64,
    /// The outward normal at the contact point (the press goes along its opposite).
    pub normal: [f64; 3],
    /// Sum of the contact forces on the sphere, N (its component along `normal` is the force
    /// pushing the tool back, positive).
    pub force_on_tool: [f64; 3],
    /// Points in contact (nodes and face samples).
    pub active: usize,
    /// Of which face samples (0 without them).
    pub active_samples: usize,
    /// Active-set iterations.
    pub iterations: usize,
    /// Largest penetration of a candidate node, m (0 with [`Penalty::Exact`] up to round-off).
    pub penetration: f64,
    /// The nodal contact forces on the tissue, N, per node of the mesh.
    pub nodal_forces: Vec<[f64; 3]>,
}

impl Contact {
    /// The force pushing the tool back along the outward normal, N.
    pub fn force(&self) -> f64 {
        v(self.force_on_tool).dot(v(self.normal))
    }
}

/// A sphere pressed into the surface of a clamped body at a point along the inward normal,
/// condensed onto the candidate nodes (module docs).
pub struct ContactReference {
    stiffness: Stiffness,
    nodes: Vec<[f64; 3]>,
    /// Every surface node (sorted), and the candidates among them (within the candidate
    /// radius).
    surface: Vec<u32>,
    candidates: Vec<u32>,
    /// Each node's index among the candidates, or [`NONE`].
    local: Vec<u32>,
    /// Material points inside the candidate faces (none without face sampling).
    samples: Vec<Sample>,
    /// `C`, 3m × 3m, row-major.
    compliance: Vec<f64>,
    radius: f64,
    /// The contact point on the undeformed surface, m.
    contact: [f64; 3],
    /// The outward unit normal there.
    normal: [f64; 3],
}

impl ContactReference {
    /// Assembles, factorises and condenses: candidates are the free surface nodes within
    /// `candidate_radius` (3D distance) of `contact`, the point of the undeformed surface with
    /// outward unit normal `normal` under the sphere of radius `radius`.
    ///
    /// With `face_samples` `k > 0`, the surface triangles whose closest point to `contact` lies
    /// within that radius are sampled too, at the barycentric points `(i, j, k − i − j)/k`
    /// strictly inside them, and those material points must stay outside the sphere as the
    /// nodes do (their free nodes join the candidates): the sphere against the faces, for a
    /// mesh coarser than the tool.
    ///
    /// # Errors
    /// From [`Stiffness::new`]; a normal that is not unit; no candidate node.
    pub fn new(
        mesh: &TetMesh,
        material: Material,
        radius: f64,
        contact: [f64; 3],
        normal: [f64; 3],
        candidate_radius: f64,
        face_samples: usize,
    ) -> Result<ContactReference> {
        if !((v(normal).length() - 1.0).abs() < 1e-9) {
            bail!("the contact normal {normal:?} is not a unit vector");
        }
        let stiffness = Stiffness::new(mesh, material)?;
        let surface = mesh.surface_nodes();
        let mut candidates: Vec<u32> = surface
            .iter()
            .copied()
            .filter(|&i| {
                let p = mesh.nodes[i as usize];
                (v(p) - v(contact)).length() <= candidate_radius && !stiffness.is_fixed(i as usize)
            })
            .collect();
        if candidates.is_empty() {
            bail!("no free surface node within {candidate_radius} m of the contact point");
        }
        let mut samples = Vec::new();
        if face_samples > 0 {
            let k = face_samples;
            for t in &mesh.surface {
                let corners = t.map(|i| v(mesh.nodes[i as usize]));
                let w = closest_bary(v(contact), corners);
                let near = (corners[0] * w[0] + corners[1] * w[1] + corners[2] * w[2] - v(contact))
                    .length()
                    <= candidate_radius;
                if !near || t.iter().all(|&i| stiffness.is_fixed(i as usize)) {
                    continue;
                }
                for i in 1..k {
                    for j in 1..k - i {
                        samples.push(Sample {
                            nodes: *t,
                            weights: [i, j, k - i - j].map(|x| x as f64 / k as f64),
                        });
                    }
                }
                candidates.extend(t.iter().filter(|&&i| !stiffness.is_fixed(i as usize)));
            }
            candidates.sort_unstable();
            candidates.dedup();
        }
        let mut local = vec![NONE; mesh.nodes.len()];
        for (j, &i) in candidates.iter().enumerate() {
            local[i as usize] = j as u32;
        }
        // C = P K⁻¹ Pᵀ, BATCH columns at a time.
        let m3 = 3 * candidates.len();
        let cand_dof: Vec<usize> = candidates
            .iter()
            .flat_map(|&i| {
                let d = stiffness.dof[i as usize] as usize;
                [d, d + 1, d + 2]
            })
            .collect();
        let n_dof = stiffness.n_dof();
        let mut compliance = vec![0.0; m3 * m3];
        let mut block = vec![0.0; n_dof * BATCH];
        for start in (0..m3).step_by(BATCH) {
            let cols = BATCH.min(m3 - start);
            block[..n_dof * cols].fill(0.0);
            for c in 0..cols {
                block[c * n_dof + cand_dof[start + c]] = 1.0;
            }
            stiffness.solve_columns(&mut block[..n_dof * cols], cols);
            for c in 0..cols {
                for (r, &d) in cand_dof.iter().enumerate() {
                    compliance[r * m3 + start + c] = block[c * n_dof + d];
                }
            }
        }
        Ok(ContactReference {
            stiffness,
            nodes: mesh.nodes.clone(),
            surface,
            candidates,
            local,
            samples,
            compliance,
            radius,
            contact,
            normal,
        })
    }

    /// Candidate nodes.
    pub fn candidates(&self) -> usize {
        self.candidates.len()
    }

    /// Face samples (0 without them).
    pub fn samples(&self) -> usize {
        self.samples.len()
    }

    /// The sphere's radius, m.
    pub fn radius(&self) -> f64 {
        self.radius
    }

    /// The factorised stiffness.
    pub fn stiffness(&self) -> &Stiffness {
        &self.stiffness
    }

    /// `|Σ reactions − force on the tool| / |force on the tool|`: zero for an exact solve (the
    /// body is in equilibrium between the tool and its supports).
    pub fn equilibrium_residual(&self, contact: &Contact) -> f64 {
        let r = self.support_reaction(contact);
        let f = contact.force_on_tool;
        (v(r) - v(f)).length() / v(f).length()
    }

    /// The mean point stiffness of the candidates, `1 / C_zz`, N/m: the scale for a penalty.
    pub fn point_stiffness(&self) -> f64 {
        let m3 = 3 * self.candidates.len();
        let mean: f64 = (0..self.candidates.len())
            .map(|j| self.compliance[(3 * j + 2) * m3 + 3 * j + 2])
            .sum::<f64>()
            / self.candidates.len() as f64;
        1.0 / mean
    }

    /// The sphere's centre for indentation `depth`, m: `c + n R − n d` (in this order, so
    /// that the flat block's `n = +z` gives its centre to the last bit).
    pub fn sphere_center(&self, depth: f64) -> [f64; 3] {
        let (c, n) = (self.contact, self.normal);
        [0, 1, 2].map(|k| c[k] + n[k] * self.radius - n[k] * depth)
    }

    /// The contact at indentation `depth` (m) of the undeformed surface along `−n`.
    ///
    /// # Errors
    /// The active set does not settle in 200 iterations; a node outside the candidates
    /// penetrates the sphere (the candidate radius is too small).
    pub fn solve(&self, depth: f64, penalty: Penalty) -> Result<Contact> {
        if self.samples.is_empty() {
            return Ok(self.solve_from(depth, penalty, None)?.0);
        }
        // With face samples, close to the node the directions are only well defined from a
        // nearby deformed state (at d = R the sphere's centre is the undeformed contact point):
        // the indentation goes in steps of at most R/30, each starting from the last.
        let steps = (depth / (self.radius / 30.0)).ceil().max(1.0) as usize;
        let mut warm = None;
        for k in 1..steps {
            let d = depth * k as f64 / steps as f64;
            warm = Some(self.solve_from(d, penalty, warm.as_ref())?.1);
        }
        Ok(self.solve_from(depth, penalty, warm.as_ref())?.0)
    }

    /// [`solve`](Self::solve) from scratch (`warm` `None`: directions from the undeformed
    /// surface) or from a previous solution (its active set, and directions from its deformed
    /// surface). Returns the contact and the state to continue from.
    fn solve_from(
        &self,
        depth: f64,
        penalty: Penalty,
        warm: Option<&Warm>,
    ) -> Result<(Contact, Warm)> {
        let s = self.sphere_center(depth);
        let m = self.candidates.len();
        let m3 = 3 * m;
        let np = m + self.samples.len();
        // The points: each candidate node (weight 1 on itself), then each face sample
        // (barycentric weights on its free nodes).
        let mut weights: Vec<Vec<(usize, f64)>> = (0..m).map(|j| vec![(j, 1.0)]).collect();
        let mut rel: Vec<[f64; 3]> = self
            .candidates
            .iter()
            .map(|&i| (v(self.nodes[i as usize]) - v(s)).to_array())
            .collect();
        for sample in &self.samples {
            let mut p = DVec3::ZERO;
            let mut w = Vec::with_capacity(3);
            for k in 0..3 {
                p += v(self.nodes[sample.nodes[k] as usize]) * sample.weights[k];
                let l = self.local[sample.nodes[k] as usize];
                if l != NONE {
                    w.push((l as usize, sample.weights[k]));
                }
            }
            weights.push(w);
            rel.push((p - v(s)).to_array());
        }
        let zero = vec![0.0; m3];
        let u0 = warm.map_or(&zero, |w| &w.u);
        let deformed: Vec<[f64; 3]> = (0..np)
            .map(|j| {
                let mut p = rel[j];
                for &(a, w) in &weights[j] {
                    for c in 0..3 {
                        p[c] += w * u0[3 * a + c];
                    }
                }
                p
            })
            .collect();
        // A point at the sphere's centre (the contact node itself at d = R) has no direction
        // from it yet: it starts pushed along the press normal.
        let mut normal: Vec<[f64; 3]> = deformed
            .iter()
            .map(|&r| {
                if v(r).length() > 1e-9 * self.radius {
                    v(r).normalize().to_array()
                } else {
                    self.normal
                }
            })
            .collect();
        let mut active: Vec<bool> = (0..np)
            .map(|j| v(deformed[j]).length() < self.radius || warm.is_some_and(|w| w.active[j]))
            .collect();
        let mut lambda = vec![0.0; np];
        let mut u = vec![0.0; m3];
        let tolerance = 1e-4 * depth;
        let reg = match penalty {
            Penalty::Exact => 0.0,
            Penalty::Stiffness(k) => 1.0 / k,
        };
        let max_iterations = if self.samples.is_empty() {
            MAX_ITERATIONS
        } else {
            MAX_ITERATIONS_SAMPLED
        };
        for iteration in 1..=max_iterations {
            let set: Vec<usize> = (0..np).filter(|&j| active[j]).collect();
            let na = set.len();
            lambda.fill(0.0);
            if na > 0 {
                // (G_Aᵀ C G_A + I/k_p) λ = g, G's column j spreading n_j over the point's nodes.
                let mut a = vec![0.0; na * na];
                let mut g = vec![0.0; na];
                for (p, &j) in set.iter().enumerate() {
                    g[p] = self.radius - v(normal[j]).dot(v(rel[j]));
                    for (q, &k) in set.iter().enumerate().skip(p) {
                        let mut v = 0.0;
                        for &(aj, wj) in &weights[j] {
                            for &(ak, wk) in &weights[k] {
                                let mut s = 0.0;
                                for x in 0..3 {
                                    for y in 0..3 {
                                        s += normal[j][x]
                                            * self.compliance[(3 * aj + x) * m3 + 3 * ak + y]
                                            * normal[k][y];
                                    }
                                }
                                v += wj * wk * s;
                            }
                        }
                        a[p * na + q] = v;
                        a[q * na + p] = v;
                    }
                    a[p * na + p] += reg;
                }
                let Some(chol) = nalgebra::Cholesky::new(DMatrix::from_vec(na, na, a)) else {
                    bail!("depth {depth}: the contact system is singular");
                };
                let g = chol.solve(&DVector::from_vec(g));
                for (p, &j) in set.iter().enumerate() {
                    lambda[j] = g[p];
                }
            }
            // u = C G λ.
            let mut f = vec![0.0; m3];
            for j in 0..np {
                for &(a, w) in &weights[j] {
                    for x in 0..3 {
                        f[3 * a + x] += lambda[j] * w * normal[j][x];
                    }
                }
            }
            for (r, ur) in u.iter_mut().enumerate() {
                let row = &self.compliance[r * m3..(r + 1) * m3];
                *ur = row.iter().zip(&f).map(|(c, f)| c * f).sum();
            }
            // New normals and gaps.
            let mut change: f64 = 0.0;
            let mut penetrating = Vec::new();
            let mut gaps = vec![0.0; np];
            let mut deepest: f64 = 0.0;
            for j in 0..np {
                let mut p = rel[j];
                for &(a, w) in &weights[j] {
                    for c in 0..3 {
                        p[c] += w * u[3 * a + c];
                    }
                }
                let r = v(p).length();
                let n = (v(p) / r).to_array();
                for c in 0..3 {
                    change = change.max((n[c] - normal[j][c]).abs());
                }
                normal[j] = n;
                let pen = self.radius - r;
                gaps[j] = pen;
                if active[j] {
                    deepest = deepest.max(pen);
                }
                if !active[j] && pen > tolerance {
                    penetrating.push(j);
                }
            }
            let gap_of = |j: usize| gaps[j];
            let pulling: Vec<usize> = (0..np).filter(|&j| active[j] && lambda[j] < 0.0).collect();
            if pulling.is_empty() && penetrating.is_empty() && change < NORMAL_TOLERANCE {
                let mut nodal_forces = vec![[0.0; 3]; self.nodes.len()];
                let mut total = [0.0; 3];
                for j in 0..np {
                    let fj = (v(normal[j]) * lambda[j]).to_array();
                    for &(a, w) in &weights[j] {
                        let i = self.candidates[a] as usize;
                        for c in 0..3 {
                            nodal_forces[i][c] += w * fj[c];
                        }
                    }
                    total = [0, 1, 2].map(|c| total[c] - fj[c]);
                }
                let contact = Contact {
                    depth,
                    normal: self.normal,
                    force_on_tool: total,
                    active: set.len(),
                    active_samples: set.iter().filter(|&&j| j >= m).count(),
                    iterations: iteration,
                    penetration: deepest,
                    nodal_forces,
                };
                self.check_outside_candidates(&contact, s, tolerance)?;
                return Ok((contact, Warm { active, u }));
            }
            if self.samples.is_empty() {
                if !pulling.is_empty() {
                    for j in pulling {
                        active[j] = false;
                    }
                } else {
                    for j in penetrating {
                        active[j] = true;
                    }
                }
            } else if let Some(&j) = pulling
                .iter()
                .min_by(|&&a, &&b| lambda[a].total_cmp(&lambda[b]))
            {
                // Neighbouring samples are nearly the same constraint, and changing them in
                // batches cycles: one at a time, the most pulling first, else the deepest.
                active[j] = false;
            } else if let Some(&j) = penetrating
                .iter()
                .max_by(|&&a, &&b| gap_of(a).total_cmp(&gap_of(b)))
            {
                active[j] = true;
            }
        }
        bail!("depth {depth}: the active set did not settle in {max_iterations} iterations")
    }

    /// Displacements of every node under the contact's forces.
    pub fn displacements(&self, contact: &Contact) -> Vec<[f64; 3]> {
        self.stiffness.displacements(&contact.nodal_forces)
    }

    /// Sum of the support reactions on the body for the contact, N.
    pub fn support_reaction(&self, contact: &Contact) -> [f64; 3] {
        let u = self.displacements(contact);
        let ku = self.stiffness.product(&u);
        let mut sum = [0.0; 3];
        for (i, f) in ku.iter().enumerate() {
            if self.stiffness.is_fixed(i) {
                for c in 0..3 {
                    sum[c] += f[c];
                }
            }
        }
        sum
    }

    fn check_outside_candidates(&self, contact: &Contact, s: [f64; 3], tol: f64) -> Result<()> {
        let u = self.displacements(contact);
        for &i in &self.surface {
            if self.candidates.binary_search(&i).is_ok() {
                continue;
            }
            let p = [0, 1, 2].map(|c| self.nodes[i as usize][c] + u[i as usize][c] - s[c]);
            if v(p).length() < self.radius - tol {
                bail!(
                    "depth {}: node {i} outside the candidates penetrates the sphere by {:e} m: \
                     widen the candidate radius",
                    contact.depth,
                    self.radius - v(p).length()
                );
            }
        }
        Ok(())
    }
}

/// The outward unit normal of `mesh`'s surface at node `node`: the area-weighted mean of the
/// normals of the surface triangles around it (the sum of their cross products); `None` if the
/// node is not on the surface.
pub fn vertex_normal(mesh: &TetMesh, node: u32) -> Option<[f64; 3]> {
    let mut sum = DVec3::ZERO;
    for t in mesh.surface.iter().filter(|t| t.contains(&node)) {
        let [a, b, c] = t.map(|k| v(mesh.nodes[k as usize]));
        // Counter-clockwise seen from outside: (b − a) × (c − a) points out, |·| = 2 × area.
        sum += (b - a).cross(c - a);
    }
    (sum.length() > 0.0).then(|| sum.normalize().to_array())
}

/// Barycentric weights of the point of triangle `t` closest to `p` (Ericson, Real-Time
/// Collision Detection §5.1.5).
pub fn closest_bary(p: DVec3, t: [DVec3; 3]) -> [f64; 3] {
    let [a, b, c] = t;
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return [1.0, 0.0, 0.0];
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return [0.0, 1.0, 0.0];
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let w = d1 / (d1 - d3);
        return [1.0 - w, w, 0.0];
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return [0.0, 0.0, 1.0];
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return [1.0 - w, 0.0, w];
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return [0.0, 1.0 - w, w];
    }
    let denom = 1.0 / (va + vb + vc);
    let (wb, wc) = (vb * denom, vc * denom);
    [1.0 - wb - wc, wb, wc]
}

/// A point as a glam vector.
fn v(a: [f64; 3]) -> DVec3 {
    DVec3::from_array(a)
}

#[cfg(test)]
mod tests {
    //! The reference is only worth what its checks are: its stiffness against lop-sim's
    //! (validated against an independent FE code), its force against Hertz, its answer
    //! independent of the penalty, and its forces in equilibrium with the supports.

    use super::*;
    use crate::haptics::block::{self, CONTACT, HEIGHT, NORMAL};
    use crate::haptics::hertz::{bonded_layer_factor, hertz_force};
    use lop_sim::fem::{box_mesh, Fem, FemMode, FemParameters};

    const GEL: Material = Material {
        young: 30e3,
        poisson: 0.3,
    };
    const R: f64 = 3e-3;

    fn reference(size: f64) -> ContactReference {
        let b = block::block(size, &block::cache_dir()).expect("gmsh block (scripts/setup.sh)");
        ContactReference::new(&b.mesh, GEL, R, CONTACT, NORMAL, 1.7e-3, 0).unwrap()
    }

    #[test]
    fn stiffness_product_matches_lop_sim() {
        let mesh = box_mesh([0.01, 0.012, 0.008], [3, 4, 2], |p| p[2] < 1e-12);
        let params = FemParameters {
            young: GEL.young,
            poisson: GEL.poisson,
            density: 1000.0,
            damping: 0.0,
            dt: 1e-3,
            mode: FemMode::Linear,
        };
        let fem = Fem::new(&mesh, params).unwrap();
        let k = Stiffness::new(&mesh, GEL).unwrap();
        // A deterministic, non-smooth displacement field.
        let u: Vec<[f64; 3]> = (0..mesh.nodes.len())
            .map(|i| [0, 1, 2].map(|c| (((i * 7 + c * 13) % 11) as f64 - 5.0) * 1e-5))
            .collect();
        let ours = k.product(&u);
        let theirs = fem.rest_stiffness_product(&u);
        let scale = theirs.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
        for (a, b) in ours.iter().zip(&theirs) {
            for c in 0..3 {
                assert!((a[c] - b[c]).abs() <= 1e-12 * scale, "{a:?} vs {b:?}");
            }
        }
        // And the factor solves what the product multiplies: K⁻¹ (K u) = u on the free nodes.
        let mut free_u = u.clone();
        for &f in &mesh.fixed {
            free_u[f as usize] = [0.0; 3];
        }
        let back = k.displacements(&k.product(&free_u));
        for (a, b) in back.iter().zip(&free_u) {
            for c in 0..3 {
                assert!((a[c] - b[c]).abs() < 1e-12, "{a:?} vs {b:?}");
            }
        }
    }

    /// Hertz assumes a half-space; the block is a 20 mm layer bonded to a rigid base, which
    /// Dimitriadis et al.'s factor corrects (+2.4 % at 0.1 mm). What is left is mostly the
    /// mesh: linear tetrahedra are too stiff and converge from above, more so the fewer
    /// elements span the contact radius (0.55 mm here, two edges of the 0.26 mm mesh). Measured
    /// by `lop-bench haptics`: F / (Hertz × layer) at 0.1 mm is 1.13 on the 0.4 mm mesh, 1.06
    /// on this one, 1.04 on the 0.1 mm one (docs/benchmarks.md, "Haptics", part 1). Hence the
    /// band: not softer than the continuum by more than the discrete contact's few per cent, not
    /// stiffer than 12 %.
    #[test]
    fn reference_matches_hertz_at_small_depth() {
        let r = reference(0.2e-3);
        let d = 0.1e-3;
        let f = r.solve(d, Penalty::Exact).unwrap().force();
        let expected = hertz_force(GEL.young, GEL.poisson, R, d)
            * bonded_layer_factor(GEL.poisson, R, d, HEIGHT);
        let ratio = f / expected;
        assert!(
            (0.97..1.12).contains(&ratio),
            "F {f} N, Hertz×layer {expected} N: {ratio}"
        );
    }

    #[test]
    fn the_answer_does_not_depend_on_the_penalty() {
        let r = reference(0.8e-3);
        let d = 0.3e-3;
        let exact = r.solve(d, Penalty::Exact).unwrap();
        assert!(exact.penetration <= 1e-4 * d, "{}", exact.penetration);
        let k = 1e3 * r.point_stiffness();
        let err = |k: f64| {
            let c = r.solve(d, Penalty::Stiffness(k)).unwrap();
            assert_eq!(c.active, exact.active);
            c.force() / exact.force() - 1.0
        };
        let (half, base, double) = (err(0.5 * k), err(k), err(2.0 * k));
        // Halving or doubling the penalty moves the force by well under 1 %...
        for e in [half, base, double] {
            assert!(e.abs() < 1e-2, "{half} {base} {double}");
        }
        // ...and the penalty's error is first order in 1/k_p: it halves when k_p doubles.
        assert!(
            half < 0.0 && base < 0.0 && double < 0.0,
            "{half} {base} {double}"
        );
        assert!((base / half - 0.5).abs() < 0.05, "{half} {base}");
        assert!((double / base - 0.5).abs() < 0.05, "{base} {double}");
    }

    /// The curved-surface form: the block turned by an arbitrary rotation and pressed along its
    /// turned normal (the one `vertex_normal` finds at the contact node) is the flat block's
    /// problem in other coordinates, so it must give the same force, turned.
    #[test]
    fn a_rotated_block_gives_the_rotated_force() {
        let b = block::block(0.8e-3, &block::cache_dir()).expect("gmsh block (scripts/setup.sh)");
        let flat = ContactReference::new(&b.mesh, GEL, R, CONTACT, NORMAL, 1.7e-3, 0).unwrap();
        let node = (0..b.mesh.nodes.len())
            .find(|&i| (v(b.mesh.nodes[i]) - v(CONTACT)).length() < 1e-9)
            .expect("a node at the contact point") as u32;
        let flat_normal = vertex_normal(&b.mesh, node).unwrap();
        assert!(
            (v(flat_normal) - v(NORMAL)).length() < 1e-12,
            "{flat_normal:?}"
        );
        let q = glam::DQuat::from_axis_angle(DVec3::new(1.0, 2.0, 0.5).normalize(), 0.7);
        let mut mesh = b.mesh.clone();
        for p in mesh.nodes.iter_mut() {
            *p = (q * v(*p)).to_array();
        }
        let normal = vertex_normal(&mesh, node).unwrap();
        assert!((v(normal) - q * v(NORMAL)).length() < 1e-12, "{normal:?}");
        let contact = mesh.nodes[node as usize];
        let turned = ContactReference::new(&mesh, GEL, R, contact, normal, 1.7e-3, 0).unwrap();
        assert_eq!(turned.candidates(), flat.candidates());
        for d in [0.1e-3, 0.3e-3] {
            let a = flat.solve(d, Penalty::Exact).unwrap();
            let c = turned.solve(d, Penalty::Exact).unwrap();
            assert_eq!(a.active, c.active);
            let expected = q * v(a.force_on_tool);
            assert!(
                (v(c.force_on_tool) - expected).length() < 1e-8 * a.force(),
                "d {d}: {:?} vs {expected:?}",
                c.force_on_tool
            );
            assert!((c.force() / a.force() - 1.0).abs() < 1e-8);
        }
    }

    #[test]
    fn contact_forces_balance_the_support_reactions() {
        let r = reference(0.8e-3);
        for d in [0.1e-3, 0.4e-3] {
            let c = r.solve(d, Penalty::Exact).unwrap();
            let reaction = r.support_reaction(&c);
            // The force on the tool is −Σ contact forces on the tissue = Σ reactions.
            for k in 0..3 {
                assert!(
                    (reaction[k] - c.force_on_tool[k]).abs() < 1e-8 * c.force(),
                    "d {d}: reactions {reaction:?}, contact {:?}",
                    c.force_on_tool
                );
            }
            assert!(c.force() > 0.0 && c.active > 0);
        }
    }
}
