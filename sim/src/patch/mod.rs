//! The tool as a contact patch: the tool tip's sphere presses every part of the surface it
//! covers, not one material point.
//!
//! # The model
//! The tip is a rigid, frictionless sphere of radius `r` whose centre `s` (the proxy) is held by
//! the tool spring `k` to the device at `c`; it has no mass, so it sits where the spring
//! balances the tissue's push. Its contact with the tissue is unilateral and hard: every
//! contact point `p_j` of the surface the sphere covers stays outside it,
//! `n_j · (p_j − s) ≥ r_j`, with `n_j` the unit direction from the proxy to the point at the
//! start of the step, and pushes the tissue along `n_j` with `λ_j ≥ 0` only while it touches
//! (`λ_j > 0 ⇒` equality). The proxy's balance `k (c − s) = Σ λ_j n_j` closes the system, so
//! the hand feels `k (s − c) = −Σ λ_j n_j`: **exactly the opposite of what the tissue
//! receives**, the patch's resultant.
//!
//! The contact points ([`gather`]):
//! - every surface node within reach (`|x − s| < r + margin`), target `r`: on a mesh finer
//!   than the tool the tissue wraps the sphere node by node;
//! - the closest point of every surface triangle in reach when it lies inside the triangle or
//!   on an edge (a vertex is already a node point), target `r − a_t` with the allowance
//!   `a_t = min(h_t² / (6 r), r / 20)` (`h_t` the longest edge) for a face whose three nodes
//!   are in reach, fading to none as its farthest node lies up to one radius beyond reach (a
//!   face larger than the tool carries the tool itself): the depth the middle of a
//!   triangle whose nodes rest on the sphere reaches, so face points do not fight the node
//!   points of a fine mesh, while on a mesh coarser than the tool (the sphere inside one face)
//!   they keep the sphere from sinking between nodes.
//!
//! Inside a model's implicit step (`K̃ d = b + C λ`, `C`'s column `c_j` spreading `n_j` over
//! the point's nodes with its weights) the gaps after the step are linear in `λ`:
//! `w = q + A λ`, `q_j = n_j · (p̂_j − c) − r_j` with `p̂_j` the point after the step without
//! contact, `A = Cᵀ K̃⁻¹ C + Nᵀ N / k` (`N`'s columns the `n_j`). `A` is symmetric positive
//! definite, and `w ≥ 0, λ ≥ 0, wᵀλ = 0` is a linear complementarity problem that [`Lcp`]
//! solves exactly by principal pivoting (block pivoting first, then Murty's least-index rule,
//! which terminates for every positive definite `A`). The model then adds `K̃⁻¹ C λ`.
//!
//! Which models resolve the patch, and with what compliance in place of `K̃⁻¹`:
//! - FEM (`fem/patch.rs`): its step's factor of `K̃` (a linear body keeps the columns);
//! - implicit mass-spring (`msd/implicit.rs`): its step's factor of `M + hγI + h²K`, scaled to
//!   positions by `h²`;
//! - explicit mass-spring (`msd/explicit.rs`): after every sub-step without the tool, the
//!   sub-step's lumped compliance `h² M⁻¹` (`PatchSolve::matrix_lumped`), the forces moving
//!   positions by `h² M⁻¹ C λ` and velocities by `h M⁻¹ C λ`;
//! - projected cage (`lop/cage_dynamics.rs`): the reduced step's `A⁻¹` in the cage's unknowns,
//!   each point's column `Gᵀ` of its spread normal (`PatchSolve::matrix_by_columns`).
//!
//! The thesis' mass-spring cage keeps the anchor's one-point press (see [`crate::lop`]).
//!
//! Why not a penalty per node: its stiffness is one more parameter to tune against the mesh
//! (too soft and the tool sinks, too stiff and the step needs a new factor every time the set
//! of touching nodes changes); the hard constraint needs neither, keeps the rest factor of a
//! linear body, and its force follows from the tissue alone.
//!
//! The haptic loop's god-object finds the contact (which body, where, no pop-through) and its
//! anchor gives the proxy the patch starts from ([`gather`] walks out from there); where the
//! patch balanced is published with every frame and the god-object rests its proxy there
//! ([`crate::haptic::GodObject::rest_at`]), so the hand feels the patch's resultant within the
//! multirate delay. Its own face-by-face sweep would put the sphere on the faces rather than on
//! the nodes, a few micrometres off, which is 7–10 % of a light press's force.

mod gather;

pub use gather::{gather, GatherScratch, GatherSphere, REACH_MARGIN};

use crate::grasp::HoldSolve;
pub use crate::grasp::PatchHold;
use crate::interaction::{ContactReport, PatchResponse};
use crate::vec3::v;
use glam::DVec3;

/// The patch's complementarity solver, one of the crate's solvers (`solve/lcp.rs`).
pub use crate::solve::lcp::Lcp;

/// Most contact points of one patch. A 3 mm tool pressed 0.3 mm into tissue meshed at 0.2 mm
/// covers about 80 surface nodes; the rest is the ring in reach around it. Points beyond it
/// are left out (the farthest, as the gathering walks outwards).
pub const MAX_PATCH: usize = 192;

/// One contact point of the patch: a material point of the surface and the sphere it must
/// stay out of.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PatchPoint {
    /// Nodes carrying the point (a node point repeats its node).
    pub nodes: [u32; 3],
    /// Their weights (sum 1).
    pub weights: [f64; 3],
    /// Unit direction from the proxy to the point at the start of the step: the tissue is
    /// pushed along it.
    pub normal: [f64; 3],
    /// The point stays at least this far from the proxy along `normal`, m.
    pub reach: f64,
    /// The tool whose sphere the point stays out of: an index into [`ToolPatch::tools`].
    pub tool: u32,
}

/// One tool pressing a patch: the device its spring pulls the proxy to and the spring.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PatchTool {
    /// The device (tool) position the spring pulls the proxy to, m.
    pub device: [f64; 3],
    /// The tool spring between proxy and device, N/m.
    pub stiffness: f64,
}

/// The tools' footprints on one body for one step (see the module docs).
///
/// Several tools may press the same body in one step (a pinch, two hands): each has its own
/// sphere, proxy and spring, and its points name it. They are solved as one complementarity
/// problem, so the tissue between them passes each tool's push on to the other through the
/// model's compliance `K̃⁻¹`, while a tool's spring couples only its own points
/// (`Nᵀ N / k` per tool): a tissue squeezed between two tools pushes back on both, and with
/// nothing else holding it the two resultants are equal and opposite.
#[derive(Debug, Clone, Copy)]
pub struct ToolPatch<'a> {
    /// The tools, in the order the points' [`PatchPoint::tool`] name them.
    pub tools: &'a [PatchTool],
    /// The contact points.
    pub points: &'a [PatchPoint],
    /// The tools grabbing the body (see [`crate::grasp`]): bilateral springs solved with the
    /// points. A tool presses points or holds, never both.
    pub holds: &'a [PatchHold],
}

impl ToolPatch<'_> {
    /// The point `j` at positions `x`.
    pub(crate) fn point(&self, j: usize, x: &impl Fn(u32) -> [f64; 3]) -> DVec3 {
        let p = &self.points[j];
        (0..3).fold(DVec3::ZERO, |acc, k| acc + v(x(p.nodes[k])) * p.weights[k])
    }

    /// `q_j = n_j · (p̂_j − c) − r_j` for every point, with `predicted` the positions after the
    /// step without contact, into `q`.
    pub(crate) fn free_gaps(&self, predicted: impl Fn(u32) -> [f64; 3], q: &mut [f64]) {
        for (j, p) in self.points.iter().enumerate() {
            let c = v(self.tools[p.tool as usize].device);
            q[j] = v(p.normal).dot(self.point(j, &predicted) - c) - p.reach;
        }
    }

    /// The resultant on the tissue of tool `tool`'s points for contact forces `λ`, N.
    pub(crate) fn resultant(&self, tool: usize, lambda: &[f64]) -> [f64; 3] {
        self.points
            .iter()
            .zip(lambda)
            .filter(|(p, _)| p.tool as usize == tool)
            .fold(DVec3::ZERO, |acc, (p, &l)| acc + v(p.normal) * l)
            .to_array()
    }

    /// Adds `Nᵀ N / k` to the column-major `m × m` matrix `a`, each tool's spring over its own
    /// points (two points of different tools are not coupled through a spring).
    pub(crate) fn add_tool_compliance(&self, a: &mut [f64]) {
        let m = self.points.len();
        for j in 0..m {
            let pj = &self.points[j];
            let inv_k = 1.0 / self.tools[pj.tool as usize].stiffness;
            for i in 0..m {
                let pi = &self.points[i];
                if pi.tool == pj.tool {
                    a[j * m + i] += v(pi.normal).dot(v(pj.normal)) * inv_k;
                }
            }
        }
    }
}

/// A model's solve of its contact patch: the points' free gaps, `A = Cᵀ K⁻¹ C` through the
/// model's factor, the complementarity problem, and the displacement the forces add. Its
/// buffers are sized for the model's unknowns once; the columns grow to the largest patch.
#[derive(Debug, Clone)]
pub(crate) struct PatchSolve {
    /// The complementarity problem: `A` and `q` are filled here or by the caller.
    pub(crate) lcp: Lcp,
    /// Per point, per unknown: its column `c_j`, then `K⁻¹ c_j`.
    cols: Vec<f64>,
    /// Per unknown: the displacement the contact forces add, `scale · K⁻¹ C λ`.
    pub(crate) correction: Vec<f64>,
    /// Per unknown: one point's column, rebuilt for projection (`PatchSolve::matrix_by_columns`).
    col: Vec<f64>,
    /// The grabs' rows of the problem ([`crate::grasp`]); none without a grab.
    pub(crate) holds: HoldSolve,
}

impl PatchSolve {
    /// Scratch for a model of `n` unknowns.
    pub(crate) fn new(n: usize) -> PatchSolve {
        PatchSolve {
            lcp: Lcp::with_capacity(MAX_PATCH),
            cols: Vec::new(),
            correction: vec![0.0; n],
            col: vec![0.0; n],
            holds: HoldSolve::new(),
        }
    }

    /// The patch limited to [`MAX_PATCH`] points, or `None` if it has neither points nor
    /// holds, a tool's spring is not a positive finite stiffness, a point names a tool the
    /// patch does not have, or a hold is unsound ([`ToolPatch::holds_sound`]; checked against
    /// its nodes with [`PatchSolve::limit_for`]).
    pub(crate) fn limit<'a>(patch: &ToolPatch<'a>) -> Option<ToolPatch<'a>> {
        Self::limit_for(patch, usize::MAX)
    }

    /// [`PatchSolve::limit`] for a body of `nodes` nodes.
    pub(crate) fn limit_for<'a>(patch: &ToolPatch<'a>, nodes: usize) -> Option<ToolPatch<'a>> {
        let m = patch.points.len().min(MAX_PATCH);
        let springs = patch
            .tools
            .iter()
            .all(|t| t.stiffness > 0.0 && t.stiffness.is_finite());
        let named = patch.points[..m]
            .iter()
            .all(|p| (p.tool as usize) < patch.tools.len());
        let holds = patch.holds.is_empty() || patch.holds_sound(nodes);
        ((m > 0 || !patch.holds.is_empty()) && springs && named && holds).then_some(ToolPatch {
            points: &patch.points[..m],
            ..*patch
        })
    }

    /// Starts the problem: `q` from `predicted`, the nodes' positions after the step without
    /// contact; `A` zero.
    pub(crate) fn begin(&mut self, patch: &ToolPatch<'_>, predicted: impl Fn(u32) -> [f64; 3]) {
        self.lcp.reset(patch.points.len());
        patch.free_gaps(&predicted, self.lcp.q());
        self.begin_holds(patch, predicted);
    }

    /// Fills `A = scale · Cᵀ K⁻¹ C` by one solve of the points' columns together:
    /// `solve_columns(b, m)` solves the model's system for the `m` columns of `b` (`n` rows
    /// each), `scale` turns its solution into the points' displacement.
    pub(crate) fn matrix_by_solves(
        &mut self,
        patch: &ToolPatch<'_>,
        first_dof: impl Fn(u32) -> Option<usize> + Copy,
        scale: f64,
        mut solve_columns: impl FnMut(&mut [f64], usize),
    ) {
        let (m, n) = (patch.points.len(), self.correction.len());
        // The holds' rows follow the points' columns, solved in the same batch.
        self.size_holds(patch);
        let g = self.holds.rows;
        if self.cols.len() < (m + g) * n {
            self.cols.resize((m + g) * n, 0.0);
        }
        let cols = &mut self.cols[..(m + g) * n];
        cols.fill(0.0);
        for (k, col) in cols.chunks_exact_mut(n).enumerate() {
            if k < m {
                spread(patch, k, 1.0, first_dof, col);
            } else {
                PatchSolve::spread_hold(patch, k - m, 1.0, first_dof, col);
            }
        }
        solve_columns(cols, m + g);
        let a = self.lcp.matrix();
        for (k, col) in cols.chunks_exact(n).enumerate().take(m) {
            for j in 0..m {
                a[k * m + j] = scale * project(patch, j, first_dof, col);
            }
        }
        if g > 0 {
            let hs = &mut self.holds;
            for (r, col) in cols.chunks_exact(n).skip(m).enumerate() {
                for s in 0..g {
                    hs.a_gg[r * g + s] = scale * PatchSolve::project_hold(patch, s, first_dof, col);
                }
                for j in 0..m {
                    hs.a_gp[j * g + r] = scale * project(patch, j, first_dof, col);
                }
            }
        }
    }

    /// Fills `A = scale · Cᵀ K⁻¹ C` for a model whose columns are dense vectors of its `n`
    /// unknowns rather than spread over node DOFs (a reduced model): `column(j, out)` adds
    /// `c_j` to `out` (zeroed); `solve_columns(b, m)` as in [`PatchSolve::matrix_by_solves`].
    /// Each `c_j` is built twice (once to be solved, once to be projected) rather than kept.
    pub(crate) fn matrix_by_columns(
        &mut self,
        m: usize,
        column: impl Fn(usize, &mut [f64]),
        scale: f64,
        mut solve_columns: impl FnMut(&mut [f64], usize),
    ) {
        let n = self.correction.len();
        if n == 0 {
            return;
        }
        if self.cols.len() < m * n {
            self.cols.resize(m * n, 0.0);
        }
        let cols = &mut self.cols[..m * n];
        cols.fill(0.0);
        for (j, col) in cols.chunks_exact_mut(n).enumerate() {
            column(j, col);
        }
        solve_columns(cols, m);
        let c = &mut self.col;
        let a = self.lcp.matrix();
        // `A` is symmetric: each entry once, mirrored (half the products, and exactly symmetric
        // for the complementarity solve's factorisation).
        for j in 0..m {
            c.fill(0.0);
            column(j, c);
            for (k, z) in cols.chunks_exact(n).enumerate().take(j + 1) {
                let entry = scale * c.iter().zip(z).map(|(c, z)| c * z).sum::<f64>();
                a[k * m + j] = entry;
                a[j * m + k] = entry;
            }
        }
    }

    /// Fills `A = scale · Cᵀ M⁻¹ C` for a lumped (diagonal) `M⁻¹`, `inv_mass(node)` zero for a
    /// held node: two points couple only through the nodes they share.
    pub(crate) fn matrix_lumped(
        &mut self,
        patch: &ToolPatch<'_>,
        inv_mass: impl Fn(u32) -> f64,
        scale: f64,
    ) {
        let m = patch.points.len();
        let a = self.lcp.matrix();
        for (k, pk) in patch.points.iter().enumerate() {
            for (j, pj) in patch.points.iter().enumerate().take(k + 1) {
                let mut sum = 0.0;
                for (&nk, &wk) in pk.nodes.iter().zip(&pk.weights) {
                    if wk == 0.0 {
                        continue;
                    }
                    for (&nj, &wj) in pj.nodes.iter().zip(&pj.weights) {
                        if wj != 0.0 && nj == nk {
                            sum += wj * wk * inv_mass(nk);
                        }
                    }
                }
                let entry = scale * sum * v(pj.normal).dot(v(pk.normal));
                a[k * m + j] = entry;
                a[j * m + k] = entry;
            }
        }
        self.size_holds(patch);
        if self.holds.rows > 0 {
            self.hold_matrix_lumped(patch, inv_mass, scale);
        }
    }

    /// Adds the tool spring's compliance and solves for `λ`; false if it cannot be solved.
    pub(crate) fn solve(&mut self, patch: &ToolPatch<'_>) -> bool {
        patch.add_tool_compliance(self.lcp.matrix());
        if self.holds.rows > 0 {
            return self.solve_with_holds(patch);
        }
        self.lcp.solve()
    }

    /// After [`PatchSolve::solve`]: the report of tool `tool` of `patch`, a hold's (the force
    /// its spring applied, [`crate::grasp`]) or a press's ([`report`]).
    pub(crate) fn report(&mut self, patch: &ToolPatch<'_>, tool: usize) -> ContactReport {
        let held = patch
            .holds
            .iter()
            .take(self.holds.rows / 3)
            .position(|h| h.tool as usize == tool);
        match (held, patch.tools.get(tool)) {
            (Some(h), Some(t)) => {
                let f = self.holds.force(h);
                ContactReport {
                    force_on_tissue: f,
                    depth: v(f).length() / t.stiffness,
                    proxy: None,
                    response: None,
                }
            }
            _ => report(patch, &mut self.lcp, tool),
        }
    }

    /// After [`PatchSolve::matrix_by_solves`] and [`PatchSolve::solve`]: `correction =
    /// scale · K⁻¹ C λ` from the solved columns; false if it is not finite.
    pub(crate) fn correction_by_solves(&mut self, scale: f64) -> bool {
        let n = self.correction.len();
        let m = self.lcp.lambda().len();
        self.correction.fill(0.0);
        for (col, &l) in self.cols[..m * n].chunks_exact(n).zip(self.lcp.lambda()) {
            if l != 0.0 {
                let f = scale * l;
                self.correction
                    .iter_mut()
                    .zip(col)
                    .for_each(|(t, c)| *t += f * c);
            }
        }
        // The holds' columns follow the points'.
        let g = self.holds.rows;
        let hold_cols = self.cols[m * n..(m + g) * n].chunks_exact(n);
        for (col, &l) in hold_cols.zip(&self.holds.lambda[..g]) {
            if l != 0.0 {
                let f = scale * l;
                self.correction
                    .iter_mut()
                    .zip(col)
                    .for_each(|(t, c)| *t += f * c);
            }
        }
        self.correction.iter().all(|d| d.is_finite())
    }

    /// After [`PatchSolve::solve`]: adds the solved forces `C λ` (points' and holds') to the
    /// DOF vector `out`.
    pub(crate) fn add_forces(
        &self,
        patch: &ToolPatch<'_>,
        first_dof: impl Fn(u32) -> Option<usize> + Copy,
        out: &mut [f64],
    ) {
        for (j, &l) in self.lcp.lambda().iter().enumerate() {
            if l != 0.0 {
                spread(patch, j, l, first_dof, out);
            }
        }
        for (r, &l) in self.holds.lambda[..self.holds.rows].iter().enumerate() {
            if l != 0.0 {
                PatchSolve::spread_hold(patch, r, l, first_dof, out);
            }
        }
    }
}

/// The report of tool `tool` of a solved patch: the resultant of its points on the tissue, its
/// spring's length, the proxy it balances at, and how the resultant answers a move of its
/// device ([`response`]). A model reports its patch's first tool; the world asks for the
/// others ([`crate::model::Model::patch_solution`]).
pub fn report(patch: &ToolPatch<'_>, lcp: &mut Lcp, tool: usize) -> ContactReport {
    let Some(t) = patch.tools.get(tool) else {
        return ContactReport::default();
    };
    let f = v(patch.resultant(tool, lcp.lambda()));
    let stiffness = response(lcp, patch, tool);
    ContactReport {
        force_on_tissue: f.to_array(),
        depth: f.length() / t.stiffness,
        proxy: Some((v(t.device) - f / t.stiffness).to_array()),
        response: stiffness.map(|stiffness| PatchResponse {
            device: t.device,
            stiffness,
        }),
    }
}

/// Adds `scale · c_j` (point `j`'s direction spread over its nodes with their weights) to the
/// DOF vector `out`; `first_dof(node)` is the node's first DOF, `None` if it is held.
fn spread(
    patch: &ToolPatch<'_>,
    j: usize,
    scale: f64,
    first_dof: impl Fn(u32) -> Option<usize>,
    out: &mut [f64],
) {
    let p = &patch.points[j];
    for k in 0..3 {
        let w = p.weights[k] * scale;
        if w != 0.0 {
            if let Some(d) = first_dof(p.nodes[k]) {
                for c in 0..3 {
                    out[d + c] += w * p.normal[c];
                }
            }
        }
    }
}

/// `c_jᵀ z` for a DOF vector `z` (see [`spread`]).
pub(crate) fn project(
    patch: &ToolPatch<'_>,
    j: usize,
    first_dof: impl Fn(u32) -> Option<usize>,
    z: &[f64],
) -> f64 {
    let p = &patch.points[j];
    let mut s = 0.0;
    for k in 0..3 {
        if p.weights[k] != 0.0 {
            if let Some(d) = first_dof(p.nodes[k]) {
                s += p.weights[k]
                    * (p.normal[0] * z[d] + p.normal[1] * z[d + 1] + p.normal[2] * z[d + 2]);
            }
        }
    }
    s
}

pub(super) fn bary_point_of(p: &PatchPoint, x: &[[f64; 3]]) -> DVec3 {
    (0..3).fold(DVec3::ZERO, |acc, k| {
        acc + v(x[p.nodes[k] as usize]) * p.weights[k]
    })
}

/// After a successful [`Lcp::solve`] of `patch`'s problem: how the resultant of tool `tool`'s
/// points on the tissue `R_t = N_t λ` answers a move `δ` of its device while the same points
/// touch, `∂R_t/∂c_t = N_t,S A_SS⁻¹ N_t,Sᵀ` (the gaps of its points fall by `n_j · δ`, so
/// `λ_S` grows by `A_SS⁻¹ N_t,Sᵀ δ`; `N_t`'s columns are zero at the other tools' points),
/// with the factor of `A_SS` the last pivot left. The other tools' devices are held (their
/// forces change too, through the tissue between them). Zero without a touching point;
/// `None` if it is not finite. Three substitutions with the factor.
pub fn response(lcp: &mut Lcp, patch: &ToolPatch<'_>, tool: usize) -> Option<[[f64; 3]; 3]> {
    let mut k = [[0.0; 3]; 3];
    if lcp.lambda().iter().all(|&l| l == 0.0) {
        return Some(k);
    }
    let in_range = |j: usize| j < patch.points.len();
    let mine = |j: usize| patch.points[j].tool as usize == tool;
    for axis in 0..3 {
        let Some((idx, x)) = lcp.solve_on_active_set(in_range, |j| {
            if mine(j) {
                patch.points[j].normal[axis]
            } else {
                0.0
            }
        }) else {
            return Some(k);
        };
        for (&j, &x) in idx.iter().zip(x).filter(|(j, _)| mine(**j)) {
            let n = patch.points[j].normal;
            for (row, &nr) in k.iter_mut().zip(&n) {
                row[axis] += nr * x;
            }
        }
    }
    k.iter().flatten().all(|x| x.is_finite()).then_some(k)
}

#[cfg(test)]
mod tests {
    use super::*;
    use lop_test_support::rng::Rng;

    /// With a diagonal `K⁻¹`, the three ways of filling `A` agree: solving the points' spread
    /// columns, the lumped form, and dense columns built by the caller.
    #[test]
    fn the_ways_of_filling_the_matrix_agree() {
        let normal = |a: f64| [a.cos() * 0.6, a.sin() * 0.6, -0.8];
        let points = [
            PatchPoint {
                nodes: [1; 3],
                weights: [1.0, 0.0, 0.0],
                normal: normal(0.3),
                reach: 1.0,
                tool: 0,
            },
            PatchPoint {
                nodes: [0, 1, 3],
                weights: [0.2, 0.5, 0.3],
                normal: normal(1.9),
                reach: 1.0,
                tool: 0,
            },
            PatchPoint {
                nodes: [3, 2, 0],
                weights: [0.6, 0.1, 0.3],
                normal: normal(4.0),
                reach: 1.0,
                tool: 0,
            },
        ];
        let tools = [PatchTool {
            device: [0.0; 3],
            stiffness: 1.0,
        }];
        let patch = ToolPatch {
            tools: &tools,
            points: &points,
            holds: &[],
        };
        // Node 2 is held.
        let inv_mass = |k: u32| [2.0, 0.5, 0.0, 4.0][k as usize];
        let first_dof = |k: u32| (k != 2).then_some(3 * k as usize);
        let scale = 0.25;
        let m = points.len();
        let mut by_solves = PatchSolve::new(12);
        by_solves.lcp.reset(m);
        by_solves.matrix_by_solves(&patch, first_dof, scale, |b, _| {
            for (i, x) in b.iter_mut().enumerate() {
                *x *= inv_mass((i % 12 / 3) as u32);
            }
        });
        let mut lumped = PatchSolve::new(0);
        lumped.lcp.reset(m);
        lumped.matrix_lumped(&patch, inv_mass, scale);
        let mut by_columns = PatchSolve::new(12);
        by_columns.lcp.reset(m);
        by_columns.matrix_by_columns(
            m,
            |j, out| spread(&patch, j, 1.0, first_dof, out),
            scale,
            |b, _| {
                for (i, x) in b.iter_mut().enumerate() {
                    *x *= inv_mass((i % 12 / 3) as u32);
                }
            },
        );
        let a = by_solves.lcp.matrix().to_vec();
        assert!(a.iter().any(|x| x.abs() > 0.01));
        for (name, other) in [("lumped", &mut lumped), ("by columns", &mut by_columns)] {
            let b = other.lcp.matrix().to_vec();
            for (x, y) in a.iter().zip(&b) {
                assert!((x - y).abs() < 1e-14, "{name}: {a:?} vs {b:?}");
            }
        }
    }

    /// A random tissue for `m` points: its compliance `B Bᵀ + εI` (m/N, column-major; about
    /// 0.01 m/N, 100 N/m per point) and free gaps pressing every point by 0.1–0.3 mm.
    fn random_tissue(m: usize, rnd: &mut impl FnMut() -> f64) -> (Vec<f64>, Vec<f64>) {
        let b: Vec<f64> = (0..m * m).map(|_| 0.01 * rnd()).collect();
        let a_t = (0..m * m)
            .map(|e| {
                let (i, j) = (e % m, e / m);
                (0..m).map(|l| b[i * m + l] * b[j * m + l]).sum::<f64>()
                    + if i == j { 2e-3 } else { 0.0 }
            })
            .collect();
        let q0 = (0..m).map(|_| -2e-4 + 1e-4 * rnd()).collect();
        (a_t, q0)
    }

    /// The response `∂R/∂c` is what a small move of the device does to the solved resultant
    /// (a finite difference, same touching points), symmetric, and no stiffer than the tool
    /// spring (the tissue in series with it).
    #[test]
    fn the_response_is_the_derivative_of_the_resultant() {
        let mut rng = Rng::new(11);
        let mut rnd = || rng.signed();
        let k_tool = 500.0;
        for m in [1usize, 2, 5, 12] {
            let points: Vec<PatchPoint> = (0..m)
                .map(|_| {
                    let n = DVec3::new(0.4 * rnd(), 0.4 * rnd(), -1.0).normalize();
                    PatchPoint {
                        nodes: [0; 3],
                        weights: [1.0, 0.0, 0.0],
                        normal: n.to_array(),
                        reach: 1e-3,
                        tool: 0,
                    }
                })
                .collect();
            let (a_t, q0) = random_tissue(m, &mut rnd);
            let solve = |lcp: &mut Lcp, c: DVec3| -> (DVec3, Option<[[f64; 3]; 3]>) {
                let tools = [PatchTool {
                    device: c.to_array(),
                    stiffness: k_tool,
                }];
                let patch = ToolPatch {
                    tools: &tools,
                    points: &points,
                    holds: &[],
                };
                lcp.reset(m);
                lcp.matrix().copy_from_slice(&a_t);
                for (j, p) in points.iter().enumerate() {
                    lcp.q()[j] = q0[j] - v(p.normal).dot(c);
                }
                patch.add_tool_compliance(lcp.matrix());
                assert!(lcp.solve());
                (
                    v(patch.resultant(0, lcp.lambda())),
                    response(lcp, &patch, 0),
                )
            };
            let mut lcp = Lcp::with_capacity(MAX_PATCH);
            let (r0, k) = solve(&mut lcp, DVec3::ZERO);
            let k = k.expect("finite");
            assert!(r0.length() > 0.0);
            let h = 1e-9;
            for axis in 0..3 {
                let mut d = DVec3::ZERO;
                d[axis] = h;
                let (r1, _) = solve(&mut lcp, d);
                let fd = (r1 - r0) / h;
                for row in 0..3 {
                    let tol = 1e-5 * k_tool;
                    assert!(
                        (fd[row] - k[row][axis]).abs() < tol,
                        "m {m}: ∂R{row}/∂c{axis} {} vs finite difference {}",
                        k[row][axis],
                        fd[row]
                    );
                    assert!((k[row][axis] - k[axis][row]).abs() < 1e-9 * k_tool);
                }
            }
            // No direction is stiffer than the tool spring alone.
            for _ in 0..20 {
                let u = DVec3::new(rnd(), rnd(), rnd()).normalize();
                let ku = DVec3::from_array(k.map(|row| v(row).dot(u)));
                let along = u.dot(ku);
                assert!((-1e-9..=k_tool * (1.0 + 1e-9)).contains(&along), "{along}");
            }
        }
    }

    /// Two tools on one patch: each tool's response is the derivative of its own resultant
    /// with its own device (the other device held), and a tool's spring couples only its own
    /// points (the balance through the tissue is checked on whole bodies, `tests/physics/pinch.rs`).
    #[test]
    fn two_tools_share_one_problem() {
        let mut rng = Rng::new(5);
        let mut rnd = || rng.signed();
        let springs = [400.0, 900.0];
        let m = 8;
        let points: Vec<PatchPoint> = (0..m)
            .map(|j| {
                // Tool 0 presses along −z from above, tool 1 along +z from below.
                let up = if j % 2 == 0 { -1.0 } else { 1.0 };
                let n = DVec3::new(0.3 * rnd(), 0.3 * rnd(), up).normalize();
                PatchPoint {
                    nodes: [0; 3],
                    weights: [1.0, 0.0, 0.0],
                    normal: n.to_array(),
                    reach: 1e-3,
                    tool: (j % 2) as u32,
                }
            })
            .collect();
        let (a_t, q0) = random_tissue(m, &mut rnd);
        let solve = |lcp: &mut Lcp, c: [DVec3; 2]| {
            let tools = [0, 1].map(|t| PatchTool {
                device: c[t].to_array(),
                stiffness: springs[t],
            });
            let patch = ToolPatch {
                tools: &tools,
                points: &points,
                holds: &[],
            };
            lcp.reset(m);
            lcp.matrix().copy_from_slice(&a_t);
            for (j, p) in points.iter().enumerate() {
                lcp.q()[j] = q0[j] - v(p.normal).dot(c[p.tool as usize]);
            }
            patch.add_tool_compliance(lcp.matrix());
            assert!(lcp.solve());
            let r = [0, 1].map(|t| v(patch.resultant(t, lcp.lambda())));
            let k = [0, 1].map(|t| response(lcp, &patch, t).expect("finite"));
            (r, k)
        };
        let mut lcp = Lcp::with_capacity(MAX_PATCH);
        let (r0, k) = solve(&mut lcp, [DVec3::ZERO; 2]);
        assert!(r0[0].length() > 0.0 && r0[1].length() > 0.0);
        let h = 1e-9;
        for t in 0..2 {
            for axis in 0..3 {
                let mut c = [DVec3::ZERO; 2];
                c[t][axis] = h;
                let (r1, _) = solve(&mut lcp, c);
                let fd = (r1[t] - r0[t]) / h;
                for row in 0..3 {
                    assert!(
                        (fd[row] - k[t][row][axis]).abs() < 1e-5 * springs[t],
                        "tool {t}: ∂R{row}/∂c{axis} {} vs finite difference {}",
                        k[t][row][axis],
                        fd[row]
                    );
                }
            }
        }
        // The spring term: entries between the two tools' points carry no `1/k`.
        let mut a = vec![0.0; m * m];
        let tools = [0, 1].map(|t| PatchTool {
            device: [0.0; 3],
            stiffness: springs[t],
        });
        let patch = ToolPatch {
            tools: &tools,
            points: &points,
            holds: &[],
        };
        patch.add_tool_compliance(&mut a);
        for j in 0..m {
            for i in 0..m {
                let same = points[i].tool == points[j].tool;
                assert_eq!(a[j * m + i] != 0.0, same, "({i}, {j})");
            }
        }
    }
}
