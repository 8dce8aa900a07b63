//! Holding tissue: grabs as bilateral springs inside the contact patch's problem, so that
//! several tools may hold one body in the same step, with other tools pressing beside them,
//! and a grasper's jaws, which hold a footprint of the surface rather than one point.
//!
//! # The model
//! A grab ([`PatchHold`]) holds a material point of the surface, `p = Σ w_k x_k` over its nodes
//! (a triangle's three with their barycentric weights, or a jaw's footprint, below), rigidly to
//! the god-object at `p + o`; the god-object is held to the device `c` by the tool spring `k`
//! (the linear law), so the tissue receives `λ = k (c − o − p)` at `p`, spread over the nodes by
//! their weights, and the hand feels `−λ`: **exactly its spring's force**. It pulls as well as
//! pushes, so it is a bilateral condition on the step's positions.
//!
//! In a model's implicit step the positions after the step are linear in the contact forces
//! (`crate::patch`): `p = p̂ + Σ_r (C_Gᵀ K̃⁻¹ c_r) λ_r`, `p̂` after the step without any tool.
//! Each hold gives three rows (the axes `e_a`: `c_{h,a}` spreads `e_a` over its nodes with
//! their weights) with the gap `w_G = (p̂ + o − c) + λ_G / k`, which must vanish. Together with
//! the presses' points `P` (unilateral, `w_P ≥ 0 ⊥ λ_P ≥ 0`) the step solves one mixed problem
//!
//! ```text
//! ⎡w_G⎤   ⎡q_G⎤   ⎡A_GG A_GP⎤ ⎡λ_G⎤        A = Cᵀ K̃⁻¹ C + (tool springs' compliance),
//! ⎣w_P⎦ = ⎣q_P⎦ + ⎣A_PG A_PP⎦ ⎣λ_P⎦,       w_G = 0 (λ_G free),  0 ≤ w_P ⊥ λ_P ≥ 0,
//! ```
//!
//! `A_GG = C_Gᵀ K̃⁻¹ C_G + I/k` per hold (each tool's spring couples only its own rows; a tool
//! holds or presses, never both). The grabs are eliminated by their Schur complement: from the
//! first block row `λ_G = −A_GG⁻¹ (q_G + A_GP λ_P)`, so the presses solve the complementarity
//! problem
//!
//! ```text
//! w_P = (q_P − A_PG A_GG⁻¹ q_G) + (A_PP − A_PG A_GG⁻¹ A_GP) λ_P,
//! ```
//!
//! whose matrix is symmetric positive definite (a Schur complement of the positive definite
//! `A`), so the patch's solver ([`crate::patch::Lcp`]) solves it exactly as before; then
//! `λ_G` follows, and the model adds `K̃⁻¹ (C_G λ_G + C_P λ_P)` as it adds the patch's
//! correction. `A_GG` has at most `3 × MAX_HOLDS` rows and is factored densely. A press
//! beside a grab thus sees the tissue as the grabs hold it (its local model's stiffness is
//! the Schur complement's, the grabbing devices held), and the tissue between two grabs passes
//! each one's pull on to the other: on a free body, whatever the springs, the tools' forces
//! sum to the momentum the body gains, zero at rest.
//!
//! Every model that resolves the patch through its step's compliance gets the grabs from the
//! same code (`PatchSolve`): FEM with its factor (always by solving the rows' columns, never
//! the linear body's column cache), implicit mass-spring with its factor, the explicit
//! integrators with the sub-step's lumped compliance `h² M⁻¹`. The cage does not: a body a
//! tool grabs runs its precise model (the world keeps the one-point grab for a cage).
//!
//! # The corotational FEM's lagged factor
//! Its default step solves `K̃ d = b` by CG, preconditioned by a factor of `K̃` made at an
//! earlier step (`K̃_lag`); the patch's compliance `Z = K̃_lag⁻¹ C` is that factor's, not the
//! step's. A press alone lives with it (its gaps close, its force is off by the mismatch);
//! a grab carries the whole pull, and on a free body or a clamped one the step's fixed point
//! would be off the balance by the mismatch (measured 7e-4 and 6e-2 of the force). So when
//! grabs share the body the step corrects the patch in rounds (`Fem::refine_patch`): CG
//! solves `K̃ d = b + C λ_j` from the last increment, the rows' gaps at that `d` differ from
//! the lagged prediction by `Cᵀ e`, `e = d − K̃⁻¹ b − Z λ_j`, and the mixed problem is solved
//! again with its free gaps moved by `Cᵀ e`, its matrices (and the holds' factor) kept:
//!
//! ```text
//! λ_{j+1} = LCP(A_lag, q + Cᵀ e_j),   d = K̃⁻¹ b + e_j + Z λ_{j+1},
//! ```
//!
//! a splitting of the problem with `A = Cᵀ K̃⁻¹ C + …` preconditioned by `A_lag`, which
//! contracts by the factor's mismatch (on the tests' cube a round gains about three digits
//! at rest, a factor of five early in a large pull). The rounds stop when no force moves by
//! more than 1e-6 of the largest: the gaps close at the increment applied, and the body's
//! balance misses by the mismatch times that last change plus the rounds' CG tolerance (1e-6
//! of the forces). Two or three rounds a step, each a CG run of a few iterations from its
//! start, the last often none. The mismatch grows with the period (the stiffness's share of
//! the system) and with a factor left stale: a body whose pace lengthens its period leaves
//! the real-time refactor policy for the amortized one (`lop_scene::refactor_policy`). A body
//! with presses alone keeps its single lagged solve.
//!
//! # Verlet's rest under a hold
//! The explicit patch acts after each kick-drift-kick sub-step as an impulse: positions move
//! by `h² M⁻¹ C λ`, velocities by `h M⁻¹ C λ` (a kick-then-drift of the tool's force), while
//! the body's own force `f` is kicked half at the start and half at the end. At a rest fixed
//! point (`x` and `v` repeat) that gives `f(x) + f(x − h² M⁻¹ C λ) = −2 C λ` and a standing
//! velocity `≈ −(h/2) M⁻¹ C λ`, kicked back every sub-step: the body holds the load
//! `C λ + ½ K h² M⁻¹ C λ` plus the damping of that velocity, not the reported `C λ` — an
//! error of order `(ω h)²` and `γ h / m` at the held nodes (on the tests' clamped cube 5e-2 in
//! shape, 0.13 in force), a property of the explicit coupling, not of the holds' solve. A
//! free body's balance stays exact (its internal forces sum to zero). Making it exact means
//! splitting the multiplier over both half-kicks (as RATTLE does for constraints), left open.
//!
//! A lone grab with the point grip, nothing else on the body, stays the one-point contact of
//! the models' steps (`ToolAnchor` in `ToolContact::anchor`), which is the same physics by a
//! rank-three Sherman–Morrison–Woodbury update; the patch is used when grabs share the body
//! or hold with jaws.
//!
//! # A grasper's jaws ([`Grip::Jaws`])
//! Closing jaws hold a patch of tissue, not a point: the hold's nodes are the anchor
//! triangle's three (barycentric weights `β_k`) and the surface nodes within the jaw radius
//! `R` of the anchored point `p₀`, reached from the anchor triangle over nodes within `R`
//! (the tissue in the jaws, not another fold of the surface across a gap), the
//! [`MAX_HOLD_NODES`]` − 3` nearest at most. Weights
//! `w_k ∝ β_k + φ(|x_k − p₀| / R)`, `φ(t) = (1 − t²)²`, normalised to sum 1: the held point
//! is the footprint's weighted centre, and the force is spread over the footprint by the same
//! weights, smoothly fading at its rim. As `R → 0` no node is within reach, `φ` vanishes and
//! the hold is the point grab's. The god-object stays where the anchor puts it, so the hold's
//! offset is `o' = p₀ + o − p` at the start of the step: action equals reaction up to how the
//! footprint changes shape within one step. The footprint's nodes may move relative to each
//! other (the jaws hold its centre, not a rigid clamp of every node, which would need three
//! rows per node).

use crate::interaction::ToolAnchor;
use crate::patch::{GatherScratch, PatchSolve, ToolPatch};
use crate::vec3::v;
use glam::DVec3;

/// Most nodes one hold spreads over (the anchor triangle's three and the nearest of a jaw's
/// footprint): on the 2–3 mm surface meshes of the shipped organs, a 4–5 mm jaw.
pub const MAX_HOLD_NODES: usize = 16;

/// Most holds in one patch: one per grabbing tool, every tool of a world.
pub const MAX_HOLDS: usize = 4;

/// Rows of the holds' block of the problem.
const MAX_HOLD_ROWS: usize = 3 * MAX_HOLDS;

/// How a tool holds tissue when it grabs: a property of the tool (a probe, a grasper), set
/// once per scene ([`crate::world::World::set_grip`]).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Grip {
    /// The material point the god-object anchors (a probe that picks tissue).
    #[default]
    Point,
    /// A grasper's jaws: the footprint of surface nodes within `radius` (m) of the anchored
    /// point (see the module docs). A radius of zero or less, or not finite, holds the point.
    Jaws {
        /// Jaw radius, m.
        radius: f64,
    },
}

impl Grip {
    /// The jaw radius, if the grip holds a footprint.
    pub fn jaw_radius(self) -> Option<f64> {
        match self {
            Grip::Jaws { radius } if radius > 0.0 && radius.is_finite() => Some(radius),
            _ => None,
        }
    }
}

/// One tool holding the body for one step (see the module docs): a material point
/// `Σ weights[k] · x[nodes[k]]` held rigidly at `offset` from the god-object, the god-object by
/// the tool spring (its [`crate::patch::PatchTool`]) to the device.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PatchHold {
    /// Nodes carrying the held point; the first `count` are used.
    pub nodes: [u32; MAX_HOLD_NODES],
    /// Their weights (sum 1).
    pub weights: [f64; MAX_HOLD_NODES],
    /// Nodes in use (1 to [`MAX_HOLD_NODES`]).
    pub count: usize,
    /// The god-object minus the held point at the start of the step, m.
    pub offset: [f64; 3],
    /// The tool that holds: an index into [`ToolPatch::tools`].
    pub tool: u32,
}

impl PatchHold {
    /// No hold (an empty slot of a fixed array).
    pub const EMPTY: PatchHold = PatchHold {
        nodes: [0; MAX_HOLD_NODES],
        weights: [0.0; MAX_HOLD_NODES],
        count: 0,
        offset: [0.0; 3],
        tool: 0,
    };

    /// The point grab of `anchor` on `surface` (its triangle's nodes and barycentric
    /// weights, its offset); `None` if the triangle is not on the surface.
    pub fn at_anchor(surface: &[[u32; 3]], anchor: &ToolAnchor, tool: u32) -> Option<PatchHold> {
        let tri = surface.get(anchor.triangle as usize)?;
        let mut h = PatchHold::EMPTY;
        h.nodes[..3].copy_from_slice(tri);
        h.weights[..3].copy_from_slice(&anchor.bary);
        h.count = 3;
        h.offset = anchor.offset;
        h.tool = tool;
        Some(h)
    }

    /// The nodes and weights in use.
    pub fn terms(&self) -> impl Iterator<Item = (u32, f64)> + '_ {
        let n = self.count.min(MAX_HOLD_NODES);
        self.nodes[..n]
            .iter()
            .copied()
            .zip(self.weights[..n].iter().copied())
    }

    /// The held point at positions `x`.
    pub fn point(&self, x: impl Fn(u32) -> [f64; 3]) -> [f64; 3] {
        self.terms()
            .fold(DVec3::ZERO, |acc, (k, w)| acc + v(x(k)) * w)
            .to_array()
    }

    /// Whether the hold is usable: nodes in range, finite weights and offset.
    fn sound(&self, nodes: usize, tools: usize) -> bool {
        (1..=MAX_HOLD_NODES).contains(&self.count)
            && (self.tool as usize) < tools
            && self
                .terms()
                .all(|(k, w)| (k as usize) < nodes && w.is_finite())
            && self.offset.iter().all(|c| c.is_finite())
    }
}

/// The jaws' hold of `anchor` on a surface at positions `x` (see the module docs): the anchor
/// triangle's nodes and the surface nodes within `radius` of the anchored point, walking
/// outwards through `node_triangles` (for each node, the surface triangles using it).
/// `None` if the anchor is not on the surface. Allocation-free once `s` is sized.
pub fn jaw_hold(
    surface: &[[u32; 3]],
    node_triangles: &[Vec<u32>],
    x: &[[f64; 3]],
    anchor: &ToolAnchor,
    radius: f64,
    tool: u32,
    s: &mut GatherScratch,
) -> Option<PatchHold> {
    let mut h = PatchHold::at_anchor(surface, anchor, tool)?;
    let p0 = v(anchor.point(surface, x)?);
    if !(radius > 0.0 && radius.is_finite())
        || s.tri_stamp.len() < surface.len()
        || s.node_stamp.len() < x.len()
    {
        return Some(h);
    }
    let stamp = s.next_stamp();
    // The nodes in reach beyond the anchor triangle's, nearest first: (distance, node).
    let mut near = [(f64::INFINITY, 0u32); MAX_HOLD_NODES - 3];
    let mut found = 0;
    for &k in &h.nodes[..3] {
        s.node_stamp[k as usize] = stamp;
    }
    s.queue.clear();
    s.queue.push(anchor.triangle);
    s.tri_stamp[anchor.triangle as usize] = stamp;
    let mut head = 0;
    while head < s.queue.len() {
        let t = s.queue[head];
        head += 1;
        for &k in &surface[t as usize] {
            let first = s.node_stamp[k as usize] != stamp;
            s.node_stamp[k as usize] = stamp;
            let corner = h.nodes[..3].contains(&k);
            let d = (v(x[k as usize]) - p0).length();
            if !(d < radius) && !corner {
                continue;
            }
            if first && !corner {
                // Keep the nearest: insert in order, dropping the farthest when full.
                let mut i = found.min(near.len());
                if i == near.len() && !(d < near[i - 1].0) {
                    continue;
                }
                if i == near.len() {
                    i -= 1;
                }
                while i > 0 && d < near[i - 1].0 {
                    near[i] = near[i - 1];
                    i -= 1;
                }
                near[i] = (d, k);
                found = (found + 1).min(near.len());
            }
            // Walk on from a node in reach (or the anchor triangle's).
            for &n in &node_triangles[k as usize] {
                if s.tri_stamp[n as usize] != stamp {
                    s.tri_stamp[n as usize] = stamp;
                    s.queue.push(n);
                }
            }
        }
    }
    let phi = |d: f64| {
        let t = d / radius;
        if t < 1.0 {
            (1.0 - t * t) * (1.0 - t * t)
        } else {
            0.0
        }
    };
    for k in 0..3 {
        h.weights[k] += phi((v(x[h.nodes[k] as usize]) - p0).length());
    }
    for (j, &(d, k)) in near[..found].iter().enumerate() {
        h.nodes[3 + j] = k;
        h.weights[3 + j] = phi(d);
    }
    h.count = 3 + found;
    let total: f64 = h.weights[..h.count].iter().sum();
    if !(total > 0.0 && total.is_finite()) {
        return PatchHold::at_anchor(surface, anchor, tool);
    }
    h.weights[..h.count].iter_mut().for_each(|w| *w /= total);
    // The god-object stays at the anchor's: the offset from the footprint's centre.
    let centre = v(h.point(|k| x[k as usize]));
    h.offset = (p0 + v(anchor.offset) - centre).to_array();
    Some(h)
}

/// The holds' part of a model's patch solve (`PatchSolve`): their rows' gaps, their blocks of
/// `A`, the factor of `A_GG` and their forces.
#[derive(Debug, Clone)]
pub(crate) struct HoldSolve {
    /// Rows of this step's holds (3 per hold), set by `begin`.
    pub(crate) rows: usize,
    /// `A_GG = scale · C_Gᵀ K̃⁻¹ C_G`, column-major `rows × rows` (written by the matrix
    /// builders; kept for the explicit integrators' sub-steps).
    pub(crate) a_gg: Vec<f64>,
    /// `A_GP`: per patch point, its `rows` entries (written by the matrix builders).
    pub(crate) a_gp: Vec<f64>,
    /// `A_GG + I/k`, then its Cholesky factor (`PatchSolve::solve`).
    factor: Vec<f64>,
    /// `A_GG⁻¹ A_GP`, per point its `rows` entries (`PatchSolve::solve`).
    y: Vec<f64>,
    /// The rows' free gaps `q_G`, then `A_GG⁻¹ q_G`.
    q: [f64; MAX_HOLD_ROWS],
    /// The points' gaps `q_P` of this solve (before the elimination: moved by a correction
    /// round), and the rows' `q_G` and points' `q_P` the problem started with, for the
    /// correction rounds ([`PatchSolve::resolve_shifted`]).
    q_points: Vec<f64>,
    q_free: [f64; MAX_HOLD_ROWS],
    q_points_free: Vec<f64>,
    /// The forces of the last solve, points' then holds' ([`PatchSolve::keep_forces`]).
    kept: Vec<f64>,
    /// The holds' forces on the tissue, three per hold (zero when the solve failed).
    pub(crate) lambda: [f64; MAX_HOLD_ROWS],
}

impl HoldSolve {
    pub(crate) fn new() -> HoldSolve {
        let m = crate::patch::MAX_PATCH;
        HoldSolve {
            rows: 0,
            a_gg: Vec::with_capacity(MAX_HOLD_ROWS * MAX_HOLD_ROWS),
            a_gp: Vec::with_capacity(MAX_HOLD_ROWS * m),
            factor: Vec::with_capacity(MAX_HOLD_ROWS * MAX_HOLD_ROWS),
            y: Vec::with_capacity(MAX_HOLD_ROWS * m),
            q: [0.0; MAX_HOLD_ROWS],
            q_free: [0.0; MAX_HOLD_ROWS],
            q_points: Vec::with_capacity(m),
            q_points_free: Vec::with_capacity(m),
            kept: Vec::with_capacity(m + MAX_HOLD_ROWS),
            lambda: [0.0; MAX_HOLD_ROWS],
        }
    }

    /// The force hold `h` applied to the tissue, N.
    pub(crate) fn force(&self, h: usize) -> [f64; 3] {
        [0, 1, 2].map(|a| self.lambda[3 * h + a])
    }
}

impl ToolPatch<'_> {
    /// Whether the patch's holds are sound for a body of `nodes` nodes (at most
    /// [`MAX_HOLDS`], each naming a tool of the patch that presses no point).
    pub(crate) fn holds_sound(&self, nodes: usize) -> bool {
        self.holds.len() <= MAX_HOLDS
            && self.holds.iter().all(|h| {
                h.sound(nodes, self.tools.len()) && self.points.iter().all(|p| p.tool != h.tool)
            })
    }

    /// Row `r` of the holds (hold `r / 3`, axis `r % 3`): its nodes and weights.
    fn hold_row(&self, r: usize) -> (&PatchHold, usize) {
        (&self.holds[r / 3], r % 3)
    }
}

impl PatchSolve {
    /// Starts the holds' rows: `q_G = p̂ + o − c` per hold, `p̂` the held point at `predicted`.
    pub(crate) fn begin_holds(
        &mut self,
        patch: &ToolPatch<'_>,
        predicted: impl Fn(u32) -> [f64; 3],
    ) {
        let g = &mut self.holds;
        g.rows = 3 * patch.holds.len().min(MAX_HOLDS);
        g.lambda = [0.0; MAX_HOLD_ROWS];
        for (h, hold) in patch.holds.iter().take(MAX_HOLDS).enumerate() {
            let p = hold.point(&predicted);
            let c = patch.tools[hold.tool as usize].device;
            for a in 0..3 {
                g.q[3 * h + a] = p[a] + hold.offset[a] - c[a];
            }
        }
    }

    /// Sizes the holds' blocks of `A` for `patch` (zeroed); the matrix builders call it.
    pub(crate) fn size_holds(&mut self, patch: &ToolPatch<'_>) {
        let g = &mut self.holds;
        g.rows = 3 * patch.holds.len().min(MAX_HOLDS);
        g.a_gg.clear();
        g.a_gg.resize(g.rows * g.rows, 0.0);
        g.a_gp.clear();
        g.a_gp.resize(g.rows * patch.points.len(), 0.0);
    }

    /// Adds `scale · c_r` (hold row `r`: its axis spread over its nodes) to the DOF vector
    /// `out`.
    pub(crate) fn spread_hold(
        patch: &ToolPatch<'_>,
        r: usize,
        scale: f64,
        first_dof: impl Fn(u32) -> Option<usize>,
        out: &mut [f64],
    ) {
        let (hold, a) = patch.hold_row(r);
        for (k, w) in hold.terms() {
            if w != 0.0 {
                if let Some(d) = first_dof(k) {
                    out[d + a] += scale * w;
                }
            }
        }
    }

    /// `c_rᵀ z` for hold row `r` and a DOF vector `z`.
    pub(crate) fn project_hold(
        patch: &ToolPatch<'_>,
        r: usize,
        first_dof: impl Fn(u32) -> Option<usize>,
        z: &[f64],
    ) -> f64 {
        let (hold, a) = patch.hold_row(r);
        hold.terms()
            .filter(|&(_, w)| w != 0.0)
            .filter_map(|(k, w)| first_dof(k).map(|d| w * z[d + a]))
            .sum()
    }

    /// The holds' blocks for a lumped (diagonal) `M⁻¹`: `A_GG` and `A_GP` couple rows through
    /// the nodes they share.
    pub(crate) fn hold_matrix_lumped(
        &mut self,
        patch: &ToolPatch<'_>,
        inv_mass: impl Fn(u32) -> f64,
        scale: f64,
    ) {
        let g = self.holds.rows;
        let m = patch.points.len();
        for r in 0..g {
            let (hr, ar) = patch.hold_row(r);
            for s in 0..=r {
                let (hs, as_) = patch.hold_row(s);
                if ar != as_ {
                    continue;
                }
                let mut sum = 0.0;
                for (kr, wr) in hr.terms() {
                    for (ks, ws) in hs.terms() {
                        if kr == ks {
                            sum += wr * ws * inv_mass(kr);
                        }
                    }
                }
                self.holds.a_gg[s * g + r] = scale * sum;
                self.holds.a_gg[r * g + s] = scale * sum;
            }
            for (j, p) in patch.points.iter().enumerate().take(m) {
                let mut sum = 0.0;
                for (kr, wr) in hr.terms() {
                    for (&kj, &wj) in p.nodes.iter().zip(&p.weights) {
                        if wj != 0.0 && kj == kr {
                            sum += wr * wj * inv_mass(kr) * p.normal[ar];
                        }
                    }
                }
                self.holds.a_gp[j * g + r] = scale * sum;
            }
        }
    }

    /// With the points' problem filled (`A_PP` with the springs' compliance, `q_P`) and the
    /// holds' blocks: eliminates the holds (module docs), solves the complementarity
    /// problem and recovers the holds' forces. False (every force zero) if it cannot be
    /// solved.
    pub(crate) fn solve_with_holds(&mut self, patch: &ToolPatch<'_>) -> bool {
        let g = self.holds.rows;
        let m = patch.points.len();
        let hs = &mut self.holds;
        hs.factor.clear();
        hs.factor.extend_from_slice(&hs.a_gg);
        for (h, hold) in patch.holds.iter().take(MAX_HOLDS).enumerate() {
            let inv_k = 1.0 / patch.tools[hold.tool as usize].stiffness;
            for a in 0..3 {
                let r = 3 * h + a;
                hs.factor[r * g + r] += inv_k;
            }
        }
        hs.q_free[..g].copy_from_slice(&hs.q[..g]);
        hs.q_points.clear();
        hs.q_points.extend_from_slice(self.lcp.q());
        hs.q_points_free.clear();
        hs.q_points_free.extend_from_slice(&hs.q_points);
        let finite = hs
            .factor
            .iter()
            .chain(&hs.a_gp)
            .chain(&hs.q[..g])
            .all(|x| x.is_finite());
        if !finite || !crate::solve::dense::spd_solve_in_place(&mut hs.factor, g, &mut hs.q[..g]) {
            hs.lambda = [0.0; MAX_HOLD_ROWS];
            return false;
        }
        hs.y.clear();
        hs.y.extend_from_slice(&hs.a_gp);
        for col in hs.y.chunks_exact_mut(g) {
            crate::solve::dense::spd_solve_factored(&hs.factor, g, col);
        }
        // S = A_PP − A_PG A_GG⁻¹ A_GP (each entry once, mirrored); q_P's part follows.
        let a = self.lcp.matrix();
        for k in 0..m {
            let yk = &hs.y[k * g..(k + 1) * g];
            for j in k..m {
                let aj = &hs.a_gp[j * g..(j + 1) * g];
                let s: f64 = aj.iter().zip(yk).map(|(x, y)| x * y).sum();
                a[k * m + j] -= s;
                if j != k {
                    a[j * m + k] -= s;
                }
            }
        }
        self.solve_eliminated(false)
    }

    /// With `A` the Schur complement and `q` holding `A_GG⁻¹ q_G`: the points' gaps
    /// `q_P − A_PG A_GG⁻¹ q_G` (`q_P` as kept in `q_points`), the complementarity problem
    /// (solved afresh, or `again` with the matrix of the last solve), then
    /// `λ_G = −A_GG⁻¹ q_G − A_GG⁻¹ A_GP λ_P`. False (every force zero) if it cannot be solved
    /// or the forces are not finite.
    fn solve_eliminated(&mut self, again: bool) -> bool {
        let g = self.holds.rows;
        let hs = &mut self.holds;
        let q = self.lcp.q();
        for (j, qj) in q.iter_mut().enumerate() {
            let aj = &hs.a_gp[j * g..(j + 1) * g];
            *qj = hs.q_points[j] - aj.iter().zip(&hs.q[..g]).map(|(x, y)| x * y).sum::<f64>();
        }
        let solved = if again {
            self.lcp.resolve()
        } else {
            self.lcp.solve()
        };
        if !solved {
            self.holds.lambda = [0.0; MAX_HOLD_ROWS];
            return false;
        }
        let hs = &mut self.holds;
        for r in 0..g {
            let mut l = -hs.q[r];
            for (j, &lj) in self.lcp.lambda().iter().enumerate() {
                if lj != 0.0 {
                    l -= hs.y[j * g + r] * lj;
                }
            }
            hs.lambda[r] = l;
        }
        hs.lambda[..g].iter().all(|l| l.is_finite())
    }

    /// After [`PatchSolve::solve_with_holds`]: solves the problem again with every row's free
    /// gap moved by `cᵀ e` (`e` a DOF vector), `A` as it was: a correction round of a model
    /// whose patch compliance only approximates its step's operator (the corotational FEM's
    /// lagged factor, `Fem::refine_patch`). False (every force zero) if it cannot be solved.
    pub(crate) fn resolve_shifted(
        &mut self,
        patch: &ToolPatch<'_>,
        first_dof: impl Fn(u32) -> Option<usize> + Copy,
        e: &[f64],
    ) -> bool {
        let g = self.holds.rows;
        let m = patch.points.len();
        let hs = &mut self.holds;
        if hs.q_points_free.len() != m {
            return false;
        }
        for r in 0..g {
            hs.q[r] = hs.q_free[r] + PatchSolve::project_hold(patch, r, first_dof, e);
        }
        if !hs.q[..g].iter().all(|x| x.is_finite()) {
            hs.lambda = [0.0; MAX_HOLD_ROWS];
            return false;
        }
        crate::solve::dense::spd_solve_factored(&hs.factor, g, &mut hs.q[..g]);
        for (j, qj) in hs.q_points.iter_mut().enumerate() {
            *qj = hs.q_points_free[j] + crate::patch::project(patch, j, first_dof, e);
        }
        self.solve_eliminated(true)
    }

    /// Keeps the solved forces (the points', then the holds') for [`PatchSolve::forces_moved`].
    pub(crate) fn keep_forces(&mut self) {
        let hs = &mut self.holds;
        hs.kept.clear();
        hs.kept.extend_from_slice(self.lcp.lambda());
        hs.kept.extend_from_slice(&hs.lambda[..hs.rows]);
    }

    /// The largest change of a force since [`PatchSolve::keep_forces`] relative to the largest
    /// force now (0 with no force).
    pub(crate) fn forces_moved(&self) -> f64 {
        let hs = &self.holds;
        let now = self.lcp.lambda().iter().chain(&hs.lambda[..hs.rows]);
        let (mut change, mut size) = (0.0f64, 0.0f64);
        for (a, b) in now.zip(&hs.kept) {
            change = change.max((a - b).abs());
            size = size.max(a.abs());
        }
        if size > 0.0 {
            change / size
        } else {
            0.0
        }
    }
}
