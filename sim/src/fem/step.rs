//! The dynamic step (eqs. 4.20–4.22 in increment form): its right-hand side, the choice of
//! solve (linear total form, direct refactorisation, lagged-factor CG, or with contact springs),
//! the state update and the blow-up check.

use super::contact::Pressed;
use super::element::{self, dot};
use super::system::{Precision, NONE};
use super::{CorotationalSolver, Factor, Failed, Fem, FemMode};
use crate::interaction::{BlowUp, ContactReport, ContactSpring, ToolContact, RUNAWAY_SPEED};

impl Fem {
    /// Advances by `dt` under `gravity` (m/s²), the nodal loads `external` (N, one per node;
    /// missing entries count as zero) and the tool. On a blow-up the body is reset to rest and
    /// the cause returned. Allocation-free.
    pub fn step(
        &mut self,
        gravity: [f64; 3],
        external: &[[f64; 3]],
        contact: Option<&ToolContact<'_>>,
    ) -> Result<ContactReport, BlowUp> {
        self.step_colliding(gravity, external, contact, &[])
    }

    /// [`Fem::step`] with organ-to-organ contact springs. While any spring pushes, the step
    /// assembles the springs' stiffness into `K̃` and solves directly (refactorising, in both
    /// modes: their number and place change every step, so neither the linear mode's
    /// factor nor the lagged preconditioner can hold them); the tool still enters by
    /// Sherman–Morrison–Woodbury on that factor.
    pub fn step_colliding(
        &mut self,
        gravity: [f64; 3],
        external: &[[f64; 3]],
        contact: Option<&ToolContact<'_>>,
        springs: &[ContactSpring],
    ) -> Result<ContactReport, BlowUp> {
        // A factor (and period) made off the critical path and due now (`background.rs`).
        if self.land_due_factor().is_err() {
            self.counters.steps += 1;
            return self.blow_up(BlowUp::NonFinite);
        }
        let dt = self.params.dt;
        let colliding = springs.iter().any(|s| s.touch(&self.x).is_some());
        // Linear mode without contact springs solves for the new displacement directly (see
        // `solve_linear_total`): no elastic forces to evaluate.
        let total = self.params.mode == FemMode::Linear && !colliding;
        if !total {
            self.internal_forces();
        }
        // b = f − f_int(x) + (M/Δt − D/2) v on the free DOFs; in linear mode without springs
        // K̃ u + b = f + (M/Δt² + D/(2Δt)) u + (M/Δt − D/2) v instead (f_int = K u cancels).
        let vel_coef = 1.0 / dt - self.params.damping / 2.0;
        let disp_coef = 1.0 / (dt * dt) + self.params.damping / (2.0 * dt);
        for (i, &d) in self.system.dof.iter().enumerate() {
            if d == NONE {
                continue;
            }
            let m = self.mass[i];
            let ext = external.get(i).copied().unwrap_or([0.0; 3]);
            for c in 0..3 {
                let state = if total {
                    m * disp_coef * self.u[i][c]
                } else {
                    self.s.force[i][c]
                };
                self.s.rhs[d as usize + c] =
                    state + m * gravity[c] + ext[c] + m * vel_coef * self.v[i][c];
            }
        }
        // A god-object press over the tool's footprint replaces the one-point contact.
        let patch = contact.and_then(|c| c.patch);
        let pressed = match patch {
            Some(_) => None,
            None => contact.and_then(|c| self.contact_setup(c)),
        };
        let solved = match self.params.mode {
            _ if colliding => self.solve_colliding(pressed, springs),
            FemMode::Linear => self.solve_linear_total(pressed),
            FemMode::Corotational => match self.solver {
                CorotationalSolver::Refactor => self.solve_refactor(pressed),
                CorotationalSolver::LaggedFactorPcg => self.solve_pcg(pressed),
            },
        };
        let iterative = self.params.mode == FemMode::Corotational
            && self.solver == CorotationalSolver::LaggedFactorPcg;
        // CG solved the step with the lagged factor as preconditioner: the patch's
        // compliance is that factor's, not the step's operator.
        let lagged = !colliding && iterative;
        if solved.is_ok() && iterative {
            // The tool-free step (the patch's correction comes next): CG's next first guess.
            // Only CG starts from it (a step with contact springs, solved directly, still
            // adds to its history); the other solvers need none.
            let s = &mut *self.s;
            s.free_v.rotate_right(1);
            s.free_v[0]
                .iter_mut()
                .zip(&s.sol)
                .for_each(|(w, d)| *w = d / dt);
        }
        let solved = match (solved, patch) {
            (Ok(_), Some(p)) => Ok(self.patch_correct(&p, lagged)),
            (r, _) => {
                self.s.patch_applied = false;
                r
            }
        };
        self.counters.steps += 1;
        let Ok(report) = solved else {
            return self.blow_up(BlowUp::NonFinite);
        };
        for (i, &d) in self.system.dof.iter().enumerate() {
            if d == NONE {
                continue;
            }
            for c in 0..3 {
                let inc = self.s.sol[d as usize + c];
                self.u[i][c] += inc;
                self.x[i][c] = self.rest[i][c] + self.u[i][c];
                self.v[i][c] = inc / dt;
            }
        }
        self.check().map(|()| report)
    }

    /// Linear mode: the scene's factor of `K̃`, contact by Sherman–Morrison–Woodbury (module
    /// docs). `rhs` holds `K̃ u + b` (the step's right-hand side plus `K̃` times the current
    /// displacement, which needs no stiffness product since `K u = f_int`): the solve gives the
    /// new displacement, and the increment `K̃⁻¹ b` is its difference with `u` — one sparse
    /// triangular solve pair per step and nothing else. Leaves the increment in `sol`.
    fn solve_linear_total(&mut self, pressed: Option<Pressed>) -> Result<ContactReport, Failed> {
        if self.factor != Factor::RestDynamic {
            self.factor_dynamic(false)?;
        }
        self.system.solve_in_place(&mut self.s.rhs);
        for (i, &d) in self.system.dof.iter().enumerate() {
            if d != NONE {
                for c in 0..3 {
                    let k = d as usize + c;
                    self.s.sol[k] = self.s.rhs[k] - self.u[i][c];
                }
            }
        }
        self.last_iterations = 0;
        // K̃⁻¹ c from the cached columns of the touched nodes (the factor never changes).
        Ok(match pressed {
            Some(p) => self.woodbury_cached(&p),
            None => ContactReport::default(),
        })
    }

    /// Corotational, direct: refactorise the warped `K̃`, solve, and add the tool by
    /// Sherman–Morrison–Woodbury (dropping a push that would pull).
    fn solve_refactor(&mut self, pressed: Option<Pressed>) -> Result<ContactReport, Failed> {
        self.factor_dynamic(true)?;
        self.last_iterations = 0;
        self.s.sol.copy_from_slice(&self.s.rhs);
        self.system.solve_in_place(&mut self.s.sol);
        Ok(match pressed {
            Some(p) => self.woodbury(&p),
            None => ContactReport::default(),
        })
    }

    /// With contact springs: `(K̃ + K_c) d = b + f_c`, assembled (warped in corotational mode)
    /// and factorised for this step only (the factor is marked stale for the next).
    fn solve_colliding(
        &mut self,
        pressed: Option<Pressed>,
        springs: &[ContactSpring],
    ) -> Result<ContactReport, Failed> {
        let dt = self.params.dt;
        let warped = self.params.mode == FemMode::Corotational;
        self.factor = Factor::Stale;
        self.assemble(1.0 / (dt * dt) + self.params.damping / (2.0 * dt), warped);
        for s in springs {
            let Some(t) = s.touch(&self.x) else {
                continue;
            };
            let nn = outer(t.normal);
            for p in 0..3 {
                let dp = self.system.dof[t.tri[p] as usize];
                if dp == NONE || t.weights[p] == 0.0 {
                    continue;
                }
                for c in 0..3 {
                    self.s.rhs[dp as usize + c] += t.weights[p] * t.on_tissue[c];
                }
                for q in 0..3 {
                    let dq = self.system.dof[t.tri[q] as usize];
                    // Each unordered pair once; repeated nodes (a vertex) only on the diagonal.
                    if dq == NONE || t.weights[q] == 0.0 || dq < dp || (dq == dp && q != p) {
                        continue;
                    }
                    let w = t.stiffness * t.weights[p] * t.weights[q];
                    self.system.add_node_block(dp, dq, &nn, w);
                }
            }
        }
        self.system
            .factorize(Precision::Double)
            .map_err(|_| Failed)?;
        self.last_iterations = 0;
        self.s.sol.copy_from_slice(&self.s.rhs);
        self.system.solve_in_place(&mut self.s.sol);
        Ok(match pressed {
            Some(p) => self.woodbury(&p),
            None => ContactReport::default(),
        })
    }

    fn blow_up(&mut self, cause: BlowUp) -> Result<ContactReport, BlowUp> {
        self.reset();
        Err(cause)
    }

    fn check(&mut self) -> Result<(), BlowUp> {
        let mut cause = None;
        for (x, v) in self.x.iter().zip(&self.v) {
            if !(x.iter().chain(v.iter()).all(|c| c.is_finite())) {
                cause = Some(BlowUp::NonFinite);
                break;
            }
            if dot(*v, *v) > RUNAWAY_SPEED * RUNAWAY_SPEED {
                cause = Some(BlowUp::Runaway);
                break;
            }
        }
        match cause {
            Some(c) => self.blow_up(c).map(|_| ()),
            None => Ok(()),
        }
    }
}

/// `n nᵀ`.
fn outer(n: [f64; 3]) -> element::Mat3 {
    let mut m = [[0.0; 3]; 3];
    for r in 0..3 {
        for c in 0..3 {
            m[r][c] = n[r] * n[c];
        }
    }
    m
}
