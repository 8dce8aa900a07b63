//! The tool's contact patch inside the implicit step (see [`crate::patch`]): the gaps of the
//! patch's points after the step are linear in their forces through `K̃⁻¹`, the complementarity
//! problem gives the forces, and `K̃⁻¹ C λ` is added to the increment.

use super::cg::dot_n;
use super::system::NONE;
use super::{Factor, Fem, PatchCorrection};
use crate::interaction::ContactReport;
use crate::patch::{PatchSolve, ToolPatch};

impl Fem {
    /// The last step's solved contact patch (its forces and the factor of its active set),
    /// if the step applied one; for the reports of a patch's other tools
    /// ([`crate::patch::report`]).
    pub fn patch_solution(&mut self) -> Option<&mut crate::patch::Lcp> {
        let s = &mut *self.s;
        s.patch_applied.then_some(&mut s.patch.lcp)
    }

    /// The last step's patch solve, if the step applied one: for the reports of its tools
    /// (presses and grabs).
    pub(crate) fn patch_solve(&mut self) -> Option<&mut PatchSolve> {
        let s = &mut *self.s;
        s.patch_applied.then_some(&mut s.patch)
    }

    /// With `sol` the increment of the step without the tool: solves the patch with the
    /// current factor of `K̃` and adds its response to `sol`. A linear body keeps `K̃⁻¹`'s
    /// columns of the patch's nodes across steps (`patch_slot`); otherwise the points' columns
    /// are solved together each step. In the lagged-factor CG mode (`lagged`) the factor is
    /// the lagged one, so the gaps close to its accuracy; the forces still balance the tool
    /// spring exactly. Tools grabbing the body come as the patch's holds (`crate::grasp`),
    /// solved with its points; in the lagged mode the patch is then corrected against CG's
    /// operator ([`Fem::refine_patch`]). A patch that cannot be solved (non-finite data)
    /// applies no force.
    pub(super) fn patch_correct(&mut self, patch: &ToolPatch<'_>, lagged: bool) -> ContactReport {
        self.s.patch_applied = false;
        let Some(patch) = PatchSolve::limit(patch) else {
            return ContactReport::default();
        };
        {
            let (dof, x, sol) = (&self.system.dof, &self.x, &self.s.sol);
            self.s.patch.begin(&patch, |k| {
                let i = k as usize;
                match first_dof(dof, k) {
                    Some(d) => [x[i][0] + sol[d], x[i][1] + sol[d + 1], x[i][2] + sol[d + 2]],
                    None => x.get(i).copied().unwrap_or([f64::NAN; 3]),
                }
            });
        }
        // Grabs (`crate::grasp`) are solved with the points' columns, never from the cache.
        let cached = matches!(self.factor, Factor::RestDynamic | Factor::WarpedDynamic)
            && patch.holds.is_empty()
            && self.cache_patch_nodes(&patch);
        if cached {
            self.cached_matrix(&patch);
        } else {
            // The DOF map is borrowed while the system solves: held aside meanwhile.
            let dof = std::mem::take(&mut self.system.dof);
            let system = &mut self.system;
            self.s.patch.matrix_by_solves(
                &patch,
                |i| first_dof(&dof, i),
                1.0,
                |b, m| system.solve_columns(b, m),
            );
            self.system.dof = dof;
        }
        let s = &mut *self.s;
        if !s.patch.solve(&patch) {
            return ContactReport::default();
        }
        let finite = if cached {
            self.cached_correction(&patch)
        } else {
            self.s.patch.correction_by_solves(1.0)
        };
        if !finite {
            return ContactReport::default();
        }
        if lagged && !patch.holds.is_empty() {
            if !self.refine_patch(&patch) {
                return ContactReport::default();
            }
        } else {
            let s = &mut *self.s;
            s.sol
                .iter_mut()
                .zip(&s.patch.correction)
                .for_each(|(d, c)| *d += c);
        }
        let s = &mut *self.s;
        s.patch_applied = true;
        s.patch.report(&patch, 0)
    }

    /// The patch solved with the lagged factor's compliance made consistent with the step's
    /// operator `K̃` (CG's), when grabs share the body (module docs of `crate::grasp`). With
    /// `sol = K̃⁻¹ b` (CG) and the patch solved once with `Z = K̃_lag⁻¹ C` (`correction = Z λ₀`),
    /// each round solves the step with the patch's forces, `K̃ d = b + C λ_j`, by CG from the
    /// last increment; the rows' gaps at that `d` differ from the lagged prediction by
    /// `Cᵀ e`, `e = d − K̃⁻¹ b − Z λ_j`, so the problem is solved again with its free gaps
    /// moved by `Cᵀ e` (its matrix kept), and `d = K̃⁻¹ b + e + Z λ_{j+1}`. A fixed point is
    /// the mixed problem with the step's own operator; the rounds contract by the lagged
    /// compliance's mismatch (a few rounds: [`PATCH_ROUNDS`], until the forces move by less
    /// than [`PATCH_FORCE_TOLERANCE`] of themselves). The gaps close at the increment applied
    /// (each grab's force is its spring's), and `K̃ d` misses `b + C λ` by that mismatch times
    /// the last round's change of `λ` and CG's residual ([`PATCH_CG_TOLERANCE`]). Leaves the
    /// increment in `sol` and `correction = d − K̃⁻¹ b`; false (`sol` the step without the
    /// tool) if a round cannot be solved.
    fn refine_patch(&mut self, patch: &ToolPatch<'_>) -> bool {
        let n = self.system.n_dof;
        {
            let s = &mut *self.s;
            if s.refine_b.len() != n {
                // Not a corotational body: nothing to refine.
                s.sol
                    .iter_mut()
                    .zip(&s.patch.correction)
                    .for_each(|(d, c)| *d += c);
                return true;
            }
            s.refine_b.copy_from_slice(&s.rhs);
            s.refine_free.copy_from_slice(&s.sol);
            s.sol
                .iter_mut()
                .zip(&s.patch.correction)
                .for_each(|(d, c)| *d += c);
        }
        let b2 = dot_n(&self.s.refine_b, &self.s.refine_b);
        let mut iterations = 0;
        let mut solved = true;
        for _ in 0..PATCH_ROUNDS {
            // rhs = b + C λ_j.
            let tol2 = {
                let (dof, s) = (&self.system.dof, &mut *self.s);
                s.rhs.copy_from_slice(&s.refine_b);
                s.patch.add_forces(patch, |k| first_dof(dof, k), &mut s.rhs);
                let f2: f64 = s
                    .rhs
                    .iter()
                    .zip(&s.refine_b)
                    .map(|(r, b)| (r - b) * (r - b))
                    .sum();
                PATCH_CG_TOLERANCE * PATCH_CG_TOLERANCE * (b2 + f2)
            };
            let run = self.cg_from_start(PATCH_CG_MAX_ITERATIONS, tol2);
            iterations += match run {
                Ok(it) | Err(it) => it,
            };
            let (dof, s) = (&self.system.dof, &mut *self.s);
            if !s.sol.iter().all(|d| d.is_finite()) {
                solved = false;
                break;
            }
            for k in 0..n {
                s.refine_gap[k] = s.sol[k] - s.refine_free[k] - s.patch.correction[k];
            }
            s.patch.keep_forces();
            if !s
                .patch
                .resolve_shifted(patch, |k| first_dof(dof, k), &s.refine_gap)
                || !s.patch.correction_by_solves(1.0)
            {
                solved = false;
                break;
            }
            for k in 0..n {
                s.sol[k] = s.refine_free[k] + s.refine_gap[k] + s.patch.correction[k];
            }
            let moved = s.patch.forces_moved();
            if run.is_err() || moved <= PATCH_FORCE_TOLERANCE {
                break;
            }
        }
        let s = &mut *self.s;
        s.rhs.copy_from_slice(&s.refine_b);
        self.last_iterations += iterations;
        self.counters.cg_iterations += iterations as u64;
        if !solved {
            s.sol.copy_from_slice(&s.refine_free);
            return false;
        }
        // What the patch added to the step, for CG's next warm start.
        for k in 0..n {
            s.patch.correction[k] = s.sol[k] - s.refine_free[k];
        }
        true
    }

    /// Puts every free node of the patch in the column cache; false if they do not all fit.
    fn cache_patch_nodes(&mut self, patch: &ToolPatch<'_>) -> bool {
        self.s.pc_clock += 1;
        for p in patch.points {
            for k in 0..3 {
                if p.weights[k] != 0.0 {
                    if let Some(d) = first_dof(&self.system.dof, p.nodes[k]) {
                        if !self.patch_slot(p.nodes[k], d) {
                            return false;
                        }
                    }
                }
            }
        }
        true
    }

    /// `A = Cᵀ K̃⁻¹ C` from the cached columns: `n_jᵀ G(a, b) n_k` summed over the points'
    /// nodes with their weights, `G(a, b)` the 3×3 block of `K̃⁻¹` at node `a`'s rows and
    /// node `b`'s columns.
    fn cached_matrix(&mut self, patch: &ToolPatch<'_>) {
        let m = patch.points.len();
        let (dof, n) = (&self.system.dof, self.system.n_dof);
        let s = &mut *self.s;
        let cache = ColumnCache {
            cols: &s.pc_cols,
            slot_of: &s.pc_slot_of,
            n,
        };
        let a = s.patch.lcp.matrix();
        for (k, pk) in patch.points.iter().enumerate() {
            for (j, pj) in patch.points.iter().enumerate().take(k + 1) {
                let mut sum = 0.0;
                for kb in 0..3 {
                    if pk.weights[kb] == 0.0 || first_dof(dof, pk.nodes[kb]).is_none() {
                        continue;
                    }
                    for ja in 0..3 {
                        let Some(r) =
                            first_dof(dof, pj.nodes[ja]).filter(|_| pj.weights[ja] != 0.0)
                        else {
                            continue;
                        };
                        for c in 0..3 {
                            let col = cache.column(pk.nodes[kb], c);
                            let g = pj.normal[0] * col[r]
                                + pj.normal[1] * col[r + 1]
                                + pj.normal[2] * col[r + 2];
                            sum += pj.weights[ja] * pk.weights[kb] * g * pk.normal[c];
                        }
                    }
                }
                a[k * m + j] = sum;
                a[j * m + k] = sum;
            }
        }
    }

    /// `correction = K̃⁻¹ C λ`: the nodes' forces `Σ λ_j w n_j` summed over the cached
    /// columns of their nodes, or by one solve with the factor when that streams fewer bytes
    /// (three columns per node against the factor's values twice: on the 20k-tetrahedra liver
    /// pressed by 2–6 points, 1–4 MB of columns against a 22 MB solve, 1.4 ms a step). Both
    /// apply the same factor ([`super::system::System::solve_patch_in_place`]), so they agree
    /// to rounding; the choice depends on the patch's size only, so runs stay deterministic.
    /// False if it is not finite.
    fn cached_correction(&mut self, patch: &ToolPatch<'_>) -> bool {
        let dof = &self.system.dof;
        let s = &mut *self.s;
        let forces = &mut s.pc_force;
        forces.clear();
        for (p, &l) in patch.points.iter().zip(s.patch.lcp.lambda()) {
            for k in 0..3 {
                if l == 0.0 || p.weights[k] == 0.0 || first_dof(dof, p.nodes[k]).is_none() {
                    continue;
                }
                let f = p.normal.map(|c| l * p.weights[k] * c);
                match forces.iter_mut().find(|(n, _)| *n == p.nodes[k]) {
                    Some((_, sum)) => (0..3).for_each(|c| sum[c] += f[c]),
                    None => forces.push((p.nodes[k], f)),
                }
            }
        }
        let n = self.system.n_dof;
        let out = &mut s.patch.correction;
        out.fill(0.0);
        let by_columns = match s.pc_correction {
            PatchCorrection::Cheaper => {
                3 * forces.len() * n * std::mem::size_of::<f64>() < self.system.solve_bytes()
            }
            PatchCorrection::Columns => true,
            PatchCorrection::Solve => false,
        };
        if by_columns {
            let cache = ColumnCache {
                cols: &s.pc_cols,
                slot_of: &s.pc_slot_of,
                n,
            };
            for (node, f) in forces.iter() {
                for (c, &fc) in f.iter().enumerate() {
                    for (o, g) in out.iter_mut().zip(cache.column(*node, c)) {
                        *o += fc * g;
                    }
                }
            }
        } else {
            for (node, f) in forces.iter() {
                let d = dof[*node as usize] as usize;
                out[d..d + 3].copy_from_slice(f);
            }
            self.system.solve_patch_in_place(out);
        }
        out.iter().all(|d| d.is_finite())
    }
}

/// The linear body's cached `K̃⁻¹` columns (see `Fem::patch_slot`).
struct ColumnCache<'a> {
    cols: &'a [f64],
    slot_of: &'a [u32],
    n: usize,
}

impl ColumnCache<'_> {
    /// Column `c` (0–2) of node `node`'s block.
    fn column(&self, node: u32, c: usize) -> &[f64] {
        let slot = self.slot_of[node as usize] as usize;
        &self.cols[(3 * slot + c) * self.n..(3 * slot + c + 1) * self.n]
    }
}

/// Most correction rounds of [`Fem::refine_patch`] in one step.
const PATCH_ROUNDS: usize = 8;
/// The rounds stop once no force of the patch moves by more than this fraction of the largest.
const PATCH_FORCE_TOLERANCE: f64 = 1e-6;
/// A round's CG stops at `‖r‖ ≤ PATCH_CG_TOLERANCE · (‖b‖² + ‖C λ‖²)^½`: at rest `b ≈ −C λ`,
/// so this is the share of the patch's forces the body's balance may miss. Until 2026-11-30 it
/// was 1e-8: on the shipped two-handed scene (`lopd simulate --scene abdomen-two-hands
/// --device mock --device mock --steps 6000`) the grabbed liver took 7.7–9.7 CG iterations a
/// step, by phase, against 5.8–6.7 now, and the contact force on the liver moved by at most
/// 0.2 µN at any step (forces up to 0.48 N). At 1e-5 (the step's own CG tolerance, relative to
/// its right-hand side) 4.5–5.2 iterations and 2.3 µN, but a held force 9e-5 off the static
/// one in `grasp::jaws_on_a_clamped_body_hold_the_static_force` (5e-7 now).
const PATCH_CG_TOLERANCE: f64 = 1e-6;
/// A round's CG iterations at most (its start is the last round's increment).
const PATCH_CG_MAX_ITERATIONS: usize = 40;

/// The first DOF of node `i`, if it is free.
fn first_dof(dof: &[u32], i: u32) -> Option<usize> {
    dof.get(i as usize)
        .filter(|&&d| d != NONE)
        .map(|&d| d as usize)
}

/// Nodes whose `K̃⁻¹` columns a linear body keeps for its contact patch; beyond, the least
/// recently used are recomputed. 256 nodes cover the patch of a 3 mm tool on a 0.2 mm mesh.
pub(super) const PATCH_CACHE_NODES: usize = 256;

impl Fem {
    /// Makes sure node `node` (first DOF `d`) has its three `K̃⁻¹` columns in the patch cache;
    /// three solves with the rest factor when it has not. The cache grows to
    /// [`PATCH_CACHE_NODES`] slots, then reuses the least recently used one; false if every
    /// slot holds a node of this step's patch.
    fn patch_slot(&mut self, node: u32, d: usize) -> bool {
        let n = self.system.n_dof;
        let s = &mut *self.s;
        let clock = s.pc_clock;
        let node = node as usize;
        if s.pc_slot_of[node] != NONE {
            s.pc_used[s.pc_slot_of[node] as usize] = clock;
            return true;
        }
        let slot = if s.pc_node.len() < PATCH_CACHE_NODES {
            s.pc_node.push(NONE);
            s.pc_used.push(0);
            s.pc_cols.resize(s.pc_cols.len() + 3 * n, 0.0);
            s.pc_node.len() - 1
        } else {
            // The least recently used slot, never one this step's patch uses.
            let Some((slot, _)) = s
                .pc_used
                .iter()
                .enumerate()
                .filter(|(_, &u)| u != clock)
                .min_by_key(|(_, &u)| u)
            else {
                return false;
            };
            if s.pc_node[slot] != NONE {
                s.pc_slot_of[s.pc_node[slot] as usize] = NONE;
            }
            slot
        };
        for c in 0..3 {
            let col = &mut s.pc_cols[(3 * slot + c) * n..(3 * slot + c + 1) * n];
            col.fill(0.0);
            col[d + c] = 1.0;
            self.system.solve_patch_in_place(col);
        }
        s.pc_node[slot] = node as u32;
        s.pc_used[slot] = clock;
        s.pc_slot_of[node] = slot as u32;
        true
    }

    /// Forgets the patch cache (the factor changed).
    pub(super) fn clear_patch_cache(&mut self) {
        let s = &mut *self.s;
        s.pc_slot_of.iter_mut().for_each(|k| *k = NONE);
        s.pc_node.iter_mut().for_each(|k| *k = NONE);
        s.pc_used.iter_mut().for_each(|u| *u = 0);
    }
}
