//! The corotational step solved iteratively: conjugate gradients on the warped `K̃` applied
//! matrix-free, warm-started from the last steps' increments, preconditioned by the lagged
//! factor (`precondition.rs`), with the tool's rank-one stiffness in the operator.

use super::contact::Pressed;
use super::system::NONE;
use super::{Factor, Failed, Fem, RefactorPolicy};
use crate::interaction::ContactReport;

/// CG stops at `‖r‖ ≤ CG_TOLERANCE · ‖b‖`. On the liver swinging under gravity (Table 6.2)
/// this keeps the trajectory within 1.2e-8 m of the one solved exactly by refactorisation
/// (200 steps, 7 cm of motion); equilibria are exact whatever the tolerance, since the
/// right-hand side always holds the true elastic forces.
const CG_TOLERANCE: f64 = 1e-5;
/// CG iterations before giving up on the lagged factor and refactorising within the step.
const CG_MAX_ITERATIONS: usize = 20;
/// [`RefactorPolicy::Background`]: a CG run of more iterations than this asks for a new factor
/// (about what a refactorisation costs on the organ meshes: `system::MIN_REFACTOR_PRICE`)…
const BACKGROUND_STALL_ITERATIONS: usize = 10;
/// …and CG's limit while the new factor is on its way (a stale preconditioner slows CG down;
/// it still converges). Beyond it (or on non-finite numbers) the step fails as a blow-up.
const BACKGROUND_CG_MAX_ITERATIONS: usize = 200;

impl Fem {
    /// Corotational, iterative: CG on `K̃_w + k' C Cᵀ` with the lagged factor as
    /// preconditioner (module docs).
    pub(super) fn solve_pcg(&mut self, pressed: Option<Pressed>) -> Result<ContactReport, Failed> {
        if self.factor != Factor::WarpedDynamic && self.factor != Factor::RestDynamic {
            self.factor_dynamic(true)?;
        }
        // With contact: (K̃ + k' C Cᵀ) d = b − C F.
        if let Some(p) = pressed {
            self.prepare_contact_pc(&p);
            for a in 0..p.m {
                for (b, c) in self.s.rhs.iter_mut().zip(&self.s.contact_dir[a]) {
                    *b -= p.force[a] * c;
                }
            }
        }
        let (mut iterations, run) = self.cg_with_refactor(pressed)?;
        let mut report = ContactReport::default();
        if let Some(p) = pressed {
            let mut lambda = [0.0; 3];
            for (a, l) in lambda.iter_mut().enumerate().take(p.m) {
                *l = p.force[a] + p.stiffness * p.dot(a, &self.s.sol);
            }
            if p.admissible(lambda) {
                report = p.report(lambda, &self.s.sol);
            } else {
                // The linearised penalty would pull: solve again without the tool.
                for a in 0..p.m {
                    for (b, c) in self.s.rhs.iter_mut().zip(&self.s.contact_dir[a]) {
                        *b += p.force[a] * c;
                    }
                }
                iterations += self.cg_with_refactor(None)?.0;
            }
        }
        self.last_iterations = iterations;
        self.counters.cg_iterations += iterations as u64;
        self.charge_lagged_factor(run);
        Ok(report)
    }

    /// CG from zero; if it has not converged in [`CG_MAX_ITERATIONS`], refactorise with the
    /// current matrix and run it again (then it converges in one or two iterations). Returns
    /// the iterations done in all, and those of the run that converged.
    fn cg_with_refactor(&mut self, pressed: Option<Pressed>) -> Result<(usize, usize), Failed> {
        if let RefactorPolicy::Background { .. } = self.refactor {
            // Never a factorisation here: CG goes on with the factor it has, and a stall asks
            // the factor thread for a new one (`background.rs`).
            let it = self
                .cg(pressed, BACKGROUND_CG_MAX_ITERATIONS, false)
                .map_err(|_| Failed)?;
            if it > BACKGROUND_STALL_ITERATIONS {
                self.request_factor(None);
            }
            return Ok((it, it));
        }
        let spent = match self.cg(pressed, CG_MAX_ITERATIONS, true) {
            Ok(it) => return Ok((it, it)),
            Err(spent) => spent,
        };
        self.factor_dynamic(true)?;
        if let Some(p) = pressed {
            self.prepare_contact_pc(&p);
        }
        self.cg(pressed, CG_MAX_ITERATIONS, false)
            .map(|it| (it + spent, it))
            .map_err(|_| Failed)
    }

    /// Preconditioned CG for `A sol = rhs`, `A = K̃_w (+ k' c cᵀ)` applied matrix-free, the
    /// preconditioner the current factor. Returns the iterations, or as an error those done
    /// when `max` did not reach the tolerance (or the numbers went non-finite). With
    /// `give_up_early` it also stops as soon as, from the third iteration on, the residual's
    /// mean rate of decrease so far predicts more than `max` iterations (or none at all): a
    /// preconditioner that stale is refreshed at once rather than after `max` wasted
    /// iterations.
    ///
    /// It starts from the increment extrapolated quadratically from the last three steps'
    /// solutions of this same system, the tool-free velocities `w = K̃⁻¹ b / Δt` (before the
    /// contact patch's correction): `g = Δt (3w − 3w⁻ + w⁻⁻)`, scaled by the `α` that
    /// minimises the error in the `A`-norm along it (`α = gᵀb / gᵀAg`), so the start is never
    /// worse than zero in that norm. One extra product; on a smoothly moving body the initial
    /// residual is 1–5 % of `‖b‖`, which saves about one preconditioned iteration of the usual
    /// four (linear extrapolation, `Δt (2w − w⁻)`, leaves about twice the residual and needs
    /// ~9 % more iterations on the 50k-tet bar). Until 2026-11-30 it extrapolated the body's
    /// velocities, which hold the patch's correction `K̃⁻¹ C λ`, less the last correction: the
    /// corrections' change between steps was left in the start, and the recipe's organs
    /// pressed by their pokes (`lopd simulate --steps 2200`, 5k, 10k and 20k tetrahedra) took
    /// 1.24–2.08 iterations a step where they now take 0.64–1.16, with the contact force
    /// within 2.7 µN at every step. The stopping test stays relative to `‖b‖`. When the
    /// last two runs' first iterations alone reduced their residuals by the tolerance (a
    /// settled body: one iteration whatever the start), the start is zero instead.
    fn cg(
        &mut self,
        pressed: Option<Pressed>,
        max: usize,
        give_up_early: bool,
    ) -> Result<usize, usize> {
        let b_norm2 = self.s.rhs.iter().map(|b| b * b).sum::<f64>();
        let tol2 = CG_TOLERANCE * CG_TOLERANCE * b_norm2;
        self.s.sol.fill(0.0);
        self.s.cg_r.copy_from_slice(&self.s.rhs);
        if b_norm2 == 0.0 {
            return Ok(0);
        }
        if self.one_iteration_runs < 2 {
            self.warm_start(pressed);
        }
        self.cg_iterate(pressed, max, give_up_early, tol2, true)
    }

    /// CG for `K̃_w sol = rhs` (no tool in the operator) from the start already in `sol`,
    /// until `‖r‖² ≤ tol2`, without a give-up or a refactorisation: the patch's correction
    /// rounds (`patch.rs`), whose start is close. Returns the iterations, or as an error those
    /// done when `max` did not reach the tolerance (`sol` holds the last iterate) or the numbers
    /// went non-finite.
    pub(super) fn cg_from_start(&mut self, max: usize, tol2: f64) -> Result<usize, usize> {
        self.s.cg_p.copy_from_slice(&self.s.sol);
        self.apply_dynamic(None);
        for ((r, b), q) in self.s.cg_r.iter_mut().zip(&self.s.rhs).zip(&self.s.cg_q) {
            *r = b - q;
        }
        self.cg_iterate(None, max, false, tol2, false)
    }

    /// CG's iterations from the start in `sol` with its residual in `cg_r` (see [`Fem::cg`]);
    /// `track_runs` counts the runs its first iteration settles (the warm start's choice).
    fn cg_iterate(
        &mut self,
        pressed: Option<Pressed>,
        max: usize,
        give_up_early: bool,
        tol2: f64,
        track_runs: bool,
    ) -> Result<usize, usize> {
        let r2_start = dot_n(&self.s.cg_r, &self.s.cg_r);
        if !r2_start.is_finite() {
            return Err(0);
        }
        if r2_start <= tol2 {
            return Ok(0);
        }
        self.precondition(pressed);
        self.s.cg_p.copy_from_slice(&self.s.cg_z);
        let mut rz = dot_n(&self.s.cg_r, &self.s.cg_z);
        for it in 1..=max {
            self.apply_dynamic(pressed);
            let pq = dot_n(&self.s.cg_p, &self.s.cg_q);
            if !(pq > 0.0) {
                return Err(it);
            }
            let alpha = rz / pq;
            let mut r2 = 0.0;
            for k in 0..self.s.sol.len() {
                self.s.sol[k] += alpha * self.s.cg_p[k];
                self.s.cg_r[k] -= alpha * self.s.cg_q[k];
                r2 += self.s.cg_r[k] * self.s.cg_r[k];
            }
            if !r2.is_finite() {
                return Err(it);
            }
            if it == 1 && track_runs {
                self.one_iteration_runs = if r2 <= CG_TOLERANCE * CG_TOLERANCE * r2_start {
                    self.one_iteration_runs.saturating_add(1)
                } else {
                    0
                };
            }
            if r2 <= tol2 {
                return Ok(it);
            }
            if give_up_early && it >= 3 {
                // ln of the mean reduction per iteration so far, and the iterations it
                // would still take (residuals squared: the factors of ½ cancel).
                let rate = (r2 / r2_start).ln() / it as f64;
                if !(rate < 0.0) || it as f64 + (tol2 / r2).ln() / rate > max as f64 {
                    return Err(it);
                }
            }
            self.precondition(pressed);
            // Polak–Ribière β = z⁺ᵀ(r⁺ − r)/zᵀr with r⁺ − r = −αq: "flexible" CG, robust to the
            // rounding of the single-precision preconditioner.
            let beta = -alpha * dot_n(&self.s.cg_z, &self.s.cg_q) / rz;
            rz = dot_n(&self.s.cg_r, &self.s.cg_z);
            for (p, z) in self.s.cg_p.iter_mut().zip(&self.s.cg_z) {
                *p = z + beta * *p;
            }
        }
        Err(max)
    }

    /// CG's start (see [`Fem::cg`]): with `sol = 0` and `cg_r = rhs` on entry, sets
    /// `sol = α g` and `cg_r = rhs − α A g` for the extrapolated increment `g`; leaves them
    /// if `gᵀAg` is not positive (a body at rest) or not finite.
    fn warm_start(&mut self, pressed: Option<Pressed>) {
        let dt = self.params.dt;
        let mut moving = false;
        // Pressed by the patch and held still, the tool-free increment is the rebound
        // `−K̃⁻¹ C λ`, not zero: its history says so.
        let s = &mut *self.s;
        let [w, w1, w2] = &s.free_v;
        for (k, g) in s.cg_p.iter_mut().enumerate() {
            *g = dt * (3.0 * (w[k] - w1[k]) + w2[k]);
            moving |= *g != 0.0;
        }
        if !moving {
            return;
        }
        self.apply_dynamic(pressed);
        let gag = dot_n(&self.s.cg_p, &self.s.cg_q);
        let gb = dot_n(&self.s.cg_p, &self.s.rhs);
        if !(gag > 0.0 && gag.is_finite() && gb.is_finite()) {
            return;
        }
        let alpha = gb / gag;
        for k in 0..self.s.sol.len() {
            self.s.sol[k] = alpha * self.s.cg_p[k];
            self.s.cg_r[k] -= alpha * self.s.cg_q[k];
        }
    }

    /// `cg_q = (M/Δt² + D/(2Δt) + K_w + k' c cᵀ) cg_p`, matrix-free.
    fn apply_dynamic(&mut self, pressed: Option<Pressed>) {
        let dt = self.params.dt;
        let coef = 1.0 / (dt * dt) + self.params.damping / (2.0 * dt);
        if let Some(pool) = &self.pool {
            let s = &mut *self.s;
            s.batch
                .dynamic_product_pooled(pool, &self.mass, coef, &s.cg_p, &mut s.cg_q);
        } else {
            for (i, &d) in self.system.dof.iter().enumerate() {
                if d != NONE {
                    let m = coef * self.mass[i];
                    for c in 0..3 {
                        let k = d as usize + c;
                        self.s.cg_q[k] = m * self.s.cg_p[k];
                    }
                }
            }
            self.s
                .batch
                .add_stiffness_product(&self.s.cg_p, &mut self.s.cg_q);
        }
        if let Some(p) = pressed {
            for a in 0..p.m {
                let s = p.stiffness * p.dot(a, &self.s.cg_p);
                for k in 0..3 {
                    if p.dofs[k] != NONE {
                        let d = p.dofs[k] as usize;
                        for c in 0..3 {
                            self.s.cg_q[d + c] += s * p.weights[k] * p.dirs[a][c];
                        }
                    }
                }
            }
        }
    }
}

pub(super) fn dot_n(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}
