//! The lagged-factor preconditioner of the corotational CG: the factorisation of `K̃` (warped
//! or at rest, single or double precision), the per-node rotations that turn it to the current
//! shape, the tool's term by Sherman–Morrison, and the refactor policy (ski rental).

use super::contact::{solve_small, Pressed};
use super::element::{self, mat_mul_t, mat_t_vec, mat_vec};
use super::rotation::{self, quat_to_mat, QUAT_IDENTITY};
use super::system::{Precision, System, NONE};
use super::{CorotationalSolver, Factor, Failed, Fem, FemMode};
use crate::parallel::{chunk_range, SharedMut};

impl Fem {
    /// `contact_pc[a] = (Q K̃_lag Qᵀ)⁻¹ c_a`, for the preconditioner.
    pub(super) fn prepare_contact_pc(&mut self, p: &Pressed) {
        self.ensure_node_rotations();
        self.counters.preconditioner_solves += p.m as u64;
        for a in 0..p.m {
            turned_solve(
                &mut self.system,
                &self.s.node_turn,
                &self.s.contact_dir[a],
                &mut self.s.contact_pc[a],
            );
        }
    }

    /// `cg_z = P⁻¹ cg_r`, the preconditioner: `P = Q K̃_lag Qᵀ (+ k' c cᵀ)` — the lagged
    /// factor `K̃_lag` (of the warped matrix at some earlier step, or at rest) turned by `Q`,
    /// the block-diagonal per-node rotations accumulated since that factorisation
    /// (`node_turn`), plus the tool's rank-one stiffness by Sherman–Morrison with
    /// `contact_pc = (Q K̃_lag Qᵀ)⁻¹ c` (prepared by `solve_pcg`).
    pub(super) fn precondition(&mut self, pressed: Option<Pressed>) {
        self.ensure_node_rotations();
        self.counters.preconditioner_solves += 1;
        turned_solve(
            &mut self.system,
            &self.s.node_turn,
            &self.s.cg_r,
            &mut self.s.cg_z,
        );
        if let Some(p) = pressed {
            // Woodbury: z −= PC (I + k' Cᵀ PC)⁻¹ k' Cᵀ z.
            let m = p.m;
            let mut sm = [[0.0; 3]; 3];
            let mut r = [0.0; 3];
            for a in 0..m {
                for b in 0..m {
                    sm[a][b] =
                        (a == b) as u8 as f64 + p.stiffness * p.dot(a, &self.s.contact_pc[b]);
                }
                r[a] = p.stiffness * p.dot(a, &self.s.cg_z);
            }
            if let Some(s) = solve_small(sm, r, m) {
                for a in 0..m {
                    for (z, y) in self.s.cg_z.iter_mut().zip(&self.s.contact_pc[a]) {
                        *z -= s[a] * y;
                    }
                }
            }
        }
    }

    /// [`Fem::update_node_rotations`] if the element rotations moved since it last ran. The
    /// per-node rotations are read only by the preconditioner and by a factor's snapshot, so a
    /// step that applies neither (CG converged from its warm start: about one touched step in
    /// seven on the recipe's 5k organs) does not pay for them. The results are those of
    /// updating every step: the sign alignment against a node's previous rotation sees the
    /// same hemisphere a few steps later.
    pub(super) fn ensure_node_rotations(&mut self) {
        if self.s.node_rot_stale {
            self.counters.node_rotation_updates += 1;
            self.update_node_rotations();
            self.s.node_rot_stale = false;
        }
    }

    /// Per-node rotations: the normalised sum of the adjacent elements' quaternions (signs
    /// aligned with the node's previous rotation), into `node_rot`; and `node_turn`, each free
    /// node's rotation since the factor was made (`R_now R_lagᵀ`), indexed by DOF block.
    pub(super) fn update_node_rotations(&mut self) {
        if let Some(pool) = &self.pool {
            // The same per node, each from its elements in element order (the gather).
            let s = &mut *self.s;
            let n = self.system.dof.len();
            let chunks = (4 * pool.threads()).min(n / 64).max(1);
            let rot = SharedMut::new(&mut s.node_rot);
            let turn = SharedMut::new(&mut s.node_turn);
            let (batch, lag, dof) = (&s.batch, &s.node_rot_lag, &self.system.dof);
            pool.run(chunks, &|c| {
                for node in chunk_range(n, chunks, c) {
                    // SAFETY: each chunk writes its own nodes (and their DOF blocks) only.
                    let rot = unsafe { &mut rot.range(node..node + 1)[0] };
                    let mut q = [0.0; 4];
                    for e in batch.node_elements(node).expect("pool enabled") {
                        let qe = batch.rotation(e);
                        let sign = if quat_dot(rot, &qe) < 0.0 { -1.0 } else { 1.0 };
                        for c in 0..4 {
                            q[c] += sign * qe[c];
                        }
                    }
                    let len = quat_dot(&q, &q).sqrt();
                    if len > 1e-12 && len.is_finite() {
                        *rot = q.map(|c| c / len);
                    }
                    let d = dof[node];
                    if d != NONE {
                        let now = quat_to_mat(rot);
                        let lag = quat_to_mat(&lag[node]);
                        let k = d as usize / 3;
                        unsafe { turn.range(k..k + 1)[0] = mat_mul_t(&now, &lag) };
                    }
                }
            });
            return;
        }
        self.s.node_sum.iter_mut().for_each(|q| *q = [0.0; 4]);
        for (e, el) in self.elements.iter().enumerate() {
            let qe = self.s.batch.rotation(e);
            for &n in &el.nodes {
                let n = n as usize;
                let prev = self.s.node_rot[n];
                let sign = if quat_dot(&prev, &qe) < 0.0 {
                    -1.0
                } else {
                    1.0
                };
                for c in 0..4 {
                    self.s.node_sum[n][c] += sign * qe[c];
                }
            }
        }
        for (n, &d) in self.system.dof.iter().enumerate() {
            let q = self.s.node_sum[n];
            let len = quat_dot(&q, &q).sqrt();
            if len > 1e-12 && len.is_finite() {
                self.s.node_rot[n] = q.map(|c| c / len);
            }
            if d != NONE {
                let now = quat_to_mat(&self.s.node_rot[n]);
                let lag = quat_to_mat(&self.s.node_rot_lag[n]);
                self.s.node_turn[d as usize / 3] = mat_mul_t(&now, &lag);
            }
        }
    }

    /// Assembles and factorises `K̃`, warped (from `grads`) or at rest.
    pub(super) fn factor_dynamic(&mut self, warped: bool) -> Result<(), Failed> {
        let dt = self.params.dt;
        if warped && self.solver == CorotationalSolver::LaggedFactorPcg {
            // The factor's rotations are the ones the lag copies below.
            self.ensure_node_rotations();
        }
        self.factor = Factor::Stale;
        self.assemble(1.0 / (dt * dt) + self.params.damping / (2.0 * dt), warped);
        // The corotational preconditioner is factorised in single precision (half the memory
        // traffic; CG in double precision makes up for it), falling back to double if rounding
        // breaks positive definiteness; direct solves use double.
        let single = self.params.mode == FemMode::Corotational
            && self.solver == CorotationalSolver::LaggedFactorPcg;
        if !(single && self.system.factorize(Precision::Single).is_ok()) {
            self.system
                .factorize(Precision::Double)
                .map_err(|_| Failed)?;
        }
        self.extra_iterations = 0;
        self.baseline_iterations = None;
        self.s.inv_key.iter_mut().for_each(|k| *k = NONE);
        self.clear_patch_cache();
        if warped {
            self.factor = Factor::WarpedDynamic;
            self.s.node_rot_lag.copy_from_slice(&self.s.node_rot);
        } else {
            self.factor = Factor::RestDynamic;
            self.s
                .node_rot_lag
                .iter_mut()
                .for_each(|q| *q = QUAT_IDENTITY);
        }
        self.s
            .node_turn
            .iter_mut()
            .for_each(|t| *t = rotation::IDENTITY);
        Ok(())
    }

    /// The refactor policy (ski rental), after a CG run of `run` iterations with the lagged
    /// factor: refresh it once the iterations it has cost beyond what a fresh factor needs (its
    /// first step's count) add up to about the price of a refactorisation.
    /// Under [`super::RefactorPolicy::RealTime`] nothing is charged: the factor is refreshed
    /// only when CG fails to converge (`cg_with_refactor`).
    pub(super) fn charge_lagged_factor(&mut self, run: usize) {
        if self.refactor == super::RefactorPolicy::RealTime {
            return;
        }
        match self.baseline_iterations {
            None => self.baseline_iterations = Some(run),
            Some(base) => self.extra_iterations += run.saturating_sub(base),
        }
        if self.extra_iterations >= self.system.refactor_price() {
            if let super::RefactorPolicy::Background { .. } = self.refactor {
                // Once asked, the charge starts again with the factor that lands.
                self.extra_iterations = 0;
                self.request_factor(None);
            } else {
                self.factor = Factor::Stale;
            }
        }
    }
}

/// `z = Q K̃⁻¹ Qᵀ r` with the system's factor and the per-node rotations `turn` (one 3×3 block
/// per free node, in DOF order).
fn turned_solve(system: &mut System, turn: &[element::Mat3], r: &[f64], z: &mut [f64]) {
    for (k, t) in turn.iter().enumerate() {
        let d = 3 * k;
        z[d..d + 3].copy_from_slice(&mat_t_vec(t, [r[d], r[d + 1], r[d + 2]]));
    }
    system.solve_in_place(z);
    for (k, t) in turn.iter().enumerate() {
        let d = 3 * k;
        let w = mat_vec(t, [z[d], z[d + 1], z[d + 2]]);
        z[d..d + 3].copy_from_slice(&w);
    }
}

fn quat_dot(a: &[f64; 4], b: &[f64; 4]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3]
}
