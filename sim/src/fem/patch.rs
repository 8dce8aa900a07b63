//! The tool's contact patch inside the implicit step (see [`crate::patch`]): the gaps of the
//! patch's points after the step are linear in their forces through `K̃⁻¹`, the complementarity
//! problem gives the forces, and `K̃⁻¹ C λ` is added to the increment.

use super::system::NONE;
use super::Fem;
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
        let s = &mut *self.s;
        s.lcp.reset(m);
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
        // A = Cᵀ K̃⁻¹ C: the columns c_k solved together.
        let n = self.system.n_dof;
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
        patch.add_tool_compliance(s.lcp.matrix());
        if !s.lcp.solve() {
            return ContactReport::default();
        }
        // d += K̃⁻¹ C λ = Σ λ_j (K̃⁻¹ c_j).
        s.patch_tmp.fill(0.0);
        for (col, &l) in s.patch_cols[..m * n].chunks_exact(n).zip(s.lcp.lambda()) {
            if l != 0.0 {
                s.patch_tmp
                    .iter_mut()
                    .zip(col)
                    .for_each(|(t, c)| *t += l * c);
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
