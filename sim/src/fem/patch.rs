//! The tool's contact patch inside the implicit step (see [`crate::patch`]): the gaps of the
//! patch's points after the step are linear in their forces through `K̃⁻¹`, the complementarity
//! problem gives the forces, and `K̃⁻¹ C λ` is added to the increment.

use super::system::NONE;
use super::{Factor, Fem, FemMode};
use crate::interaction::ContactReport;
use crate::patch::{project, report, spread, ToolPatch, MAX_PATCH};

impl Fem {
    /// With `sol` the increment of the step without the tool: solves the patch with the
    /// current factor of `K̃` (one blocked solve for the points' columns, kept for the correction) and adds its
    /// response to `sol`. In the lagged-factor CG mode the factor is the lagged one, so the
    /// gaps close to its accuracy; the forces still balance the tool spring exactly. A patch
    /// that cannot be solved (non-finite data) applies no force.
    pub(super) fn patch_correct(&mut self, patch: &ToolPatch<'_>) -> ContactReport {
        let m = patch.points.len().min(MAX_PATCH);
        if m == 0 || !(patch.stiffness > 0.0 && patch.stiffness.is_finite()) {
            return ContactReport::default();
        }
        let patch = ToolPatch {
            points: &patch.points[..m],
            ..*patch
        };
        self.s.lcp.reset(m);
        let s = &mut *self.s;
        {
            let (dof, x, sol) = (&self.system.dof, &self.x, &s.sol);
            let predicted = |k: u32| {
                let i = k as usize;
                match dof.get(i) {
                    Some(&d) if d != NONE => {
                        let d = d as usize;
                        [x[i][0] + sol[d], x[i][1] + sol[d + 1], x[i][2] + sol[d + 2]]
                    }
                    _ => x.get(i).copied().unwrap_or([f64::NAN; 3]),
                }
            };
            patch.free_gaps(predicted, s.lcp.q());
        }
        let n = self.system.n_dof;
        let cached = self.factor == Factor::RestDynamic && self.params.mode == FemMode::Linear;
        if cached {
            // Linear body, fixed factor: K̃⁻¹'s columns for each node of the patch, kept
            // while the node stays in reach (the patch on a fine mesh holds a hundred nodes
            // for many steps; one blocked solve per step would redo them all).
            self.s.pc_clock += 1;
            for j in 0..m {
                let p = patch.points[j];
                for k in 0..3 {
                    if p.weights[k] != 0.0 {
                        if let Some(&d) = self.system.dof.get(p.nodes[k] as usize) {
                            if d != NONE {
                                self.patch_slot(p.nodes[k], d);
                            }
                        }
                    }
                }
            }
            let s = &mut *self.s;
            let dof = &self.system.dof;
            let a = s.lcp.matrix();
            for (k, pk) in patch.points.iter().enumerate() {
                for (j, pj) in patch.points.iter().enumerate().take(k + 1) {
                    let mut sum = 0.0;
                    for kb in 0..3 {
                        let (wb, nb) = (pk.weights[kb], pk.nodes[kb] as usize);
                        if wb == 0.0 || dof.get(nb).is_none_or(|&d| d == NONE) {
                            continue;
                        }
                        let slot = s.pc_slot_of[nb] as usize;
                        for ja in 0..3 {
                            let (wa, na) = (pj.weights[ja], pj.nodes[ja] as usize);
                            let Some(&da) = dof.get(na).filter(|&&d| wa != 0.0 && d != NONE) else {
                                continue;
                            };
                            // n_jᵀ G(a, b) n_k with G's column c of node b at node a's rows.
                            for c in 0..3 {
                                let col = &s.pc_cols[(3 * slot + c) * n..(3 * slot + c + 1) * n];
                                let r = da as usize;
                                let g = pj.normal[0] * col[r]
                                    + pj.normal[1] * col[r + 1]
                                    + pj.normal[2] * col[r + 2];
                                sum += wa * wb * g * pk.normal[c];
                            }
                        }
                    }
                    a[k * m + j] = sum;
                    a[j * m + k] = sum;
                }
            }
        } else {
            // A = Cᵀ K̃⁻¹ C: the columns c_k solved together.
            let s = &mut *self.s;
            if s.patch_cols.len() < m * n {
                s.patch_cols.resize(m * n, 0.0);
            }
            let cols = &mut s.patch_cols[..m * n];
            cols.fill(0.0);
            for (k, col) in cols.chunks_exact_mut(n).enumerate() {
                spread(&patch, k, 1.0, |i| first_dof(&self.system.dof, i), col);
            }
            self.system.solve_columns(cols, m);
            let a = s.lcp.matrix();
            for (k, col) in cols.chunks_exact(n).enumerate() {
                for j in 0..m {
                    a[k * m + j] = project(&patch, j, |i| first_dof(&self.system.dof, i), col);
                }
            }
        }
        let s = &mut *self.s;
        patch.add_tool_compliance(s.lcp.matrix());
        if !s.lcp.solve() {
            return ContactReport::default();
        }
        // d += K̃⁻¹ C λ = Σ λ_j (K̃⁻¹ c_j).
        s.patch_tmp.fill(0.0);
        if cached {
            for (p, &l) in patch.points.iter().zip(s.lcp.lambda()) {
                if l == 0.0 {
                    continue;
                }
                for k in 0..3 {
                    let node = p.nodes[k] as usize;
                    if p.weights[k] == 0.0 || self.system.dof.get(node).is_none_or(|&d| d == NONE) {
                        continue;
                    }
                    let slot = s.pc_slot_of[node] as usize;
                    for c in 0..3 {
                        let f = l * p.weights[k] * p.normal[c];
                        let col = &s.pc_cols[(3 * slot + c) * n..(3 * slot + c + 1) * n];
                        s.patch_tmp
                            .iter_mut()
                            .zip(col)
                            .for_each(|(t, g)| *t += f * g);
                    }
                }
            }
        } else {
            for (col, &l) in s.patch_cols[..m * n].chunks_exact(n).zip(s.lcp.lambda()) {
                if l != 0.0 {
                    s.patch_tmp
                        .iter_mut()
                        .zip(col)
                        .for_each(|(t, c)| *t += l * c);
                }
            }
        }
        if !s.patch_tmp.iter().all(|d| d.is_finite()) {
            return ContactReport::default();
        }
        s.sol
            .iter_mut()
            .zip(&s.patch_tmp)
            .for_each(|(d, c)| *d += c);
        report(&patch, s.lcp.lambda())
    }
}

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
    /// [`PATCH_CACHE_NODES`] slots, then reuses the least recently used one.
    fn patch_slot(&mut self, node: u32, d: u32) {
        let n = self.system.n_dof;
        let s = &mut *self.s;
        let clock = s.pc_clock;
        let node = node as usize;
        if s.pc_slot_of.len() != self.x.len() {
            s.pc_slot_of = vec![NONE; self.x.len()];
        }
        if s.pc_slot_of[node] != NONE {
            s.pc_used[s.pc_slot_of[node] as usize] = clock;
            return;
        }
        let slot = if s.pc_node.len() < PATCH_CACHE_NODES {
            s.pc_node.push(NONE);
            s.pc_used.push(0);
            s.pc_cols.resize(s.pc_cols.len() + 3 * n, 0.0);
            s.pc_node.len() - 1
        } else {
            // The least recently used slot, never one used this step.
            let (slot, _) = s
                .pc_used
                .iter()
                .enumerate()
                .filter(|(_, &u)| u != clock)
                .min_by_key(|(_, &u)| u)
                .expect("a patch holds fewer points than the cache has slots");
            s.pc_slot_of[s.pc_node[slot] as usize] = NONE;
            slot
        };
        for c in 0..3 {
            let col = &mut s.pc_cols[(3 * slot + c) * n..(3 * slot + c + 1) * n];
            col.fill(0.0);
            col[d as usize + c] = 1.0;
            self.system.solve_in_place(col);
        }
        s.pc_node[slot] = node as u32;
        s.pc_used[slot] = clock;
        s.pc_slot_of[node] = slot as u32;
    }

    /// Forgets the patch cache (the factor changed).
    pub(super) fn clear_patch_cache(&mut self) {
        let s = &mut *self.s;
        s.pc_slot_of.iter_mut().for_each(|k| *k = NONE);
        s.pc_node.iter_mut().for_each(|k| *k = NONE);
        s.pc_used.iter_mut().for_each(|u| *u = 0);
    }
}
