//! Static equilibrium ([`Fem::solve_static`]): Newton-like iterations on the (warped)
//! stiffness with a line search on the corotated energy.

use super::cg::dot_n;
use super::system::{Precision, NONE};
use super::{Factor, Fem, FemError, FemMode};

/// Result of [`Fem::solve_static`].
#[derive(Debug, Clone, PartialEq)]
pub struct StaticReport {
    /// Equilibrium positions, m (also the body's new state, at rest).
    pub positions: Vec<[f64; 3]>,
    /// Linear solves done.
    pub iterations: usize,
    /// `‖f − f_int‖` on the free DOFs at `positions`, relative to the load (or, with no load,
    /// to the initial residual): at most 1e-10, or the round-off floor of a stiff body (see
    /// [`Fem::solve_static`]).
    pub residual: f64,
}

/// Relative residual at which [`Fem::solve_static`] stops.
const STATIC_TOLERANCE: f64 = 1e-10;
/// [`Fem::solve_static`] also stops when no node moves by more than this many times the
/// largest displacement (a few dozen ulps): the residual is then at its round-off floor.
const STATIC_ROUND_OFF: f64 = 1e-14;
/// Trial steps of [`Fem::solve_static`]'s line search (corotational).
const STATIC_LINE_SEARCH: usize = 8;
/// Iteration limit of [`Fem::solve_static`].
const STATIC_MAX_ITERATIONS: usize = 200;

impl Fem {
    /// Static equilibrium under `gravity` and `external` with the fixed nodes held where they
    /// are (see the module docs); leaves the body there, at rest, and returns the positions.
    ///
    /// Iterates `K d = f − f_int(x)`, `x += d` (`K` warped at the current rotations in
    /// corotational mode) until the relative residual is below 1e-10 or the update is at the
    /// rounding level of the positions (a stiff body whose load is tiny next to its internal
    /// forces cannot get below a residual of about `ε‖K‖‖x‖/‖f‖`). Linear mode: one
    /// factorisation, the second and later solves are iterative refinement.
    ///
    /// # Errors
    /// [`FemError::Unsupported`] for a body without fixed nodes, [`FemError::Singular`] if the
    /// supports leave a rigid motion free, [`FemError::NotConverged`] if the corotational
    /// iteration does not reach a relative residual of 1e-10 in 200 iterations (the state is
    /// then the last iterate).
    pub fn solve_static(
        &mut self,
        gravity: [f64; 3],
        external: &[[f64; 3]],
    ) -> Result<StaticReport, FemError> {
        if !self.held.iter().any(|&h| h) {
            return Err(FemError::Unsupported);
        }
        self.v.iter_mut().for_each(|v| *v = [0.0; 3]);
        self.s.free_v.iter_mut().for_each(|w| w.fill(0.0));
        self.factor = Factor::Stale;
        let n_dof = self.system.n_dof;
        let mut load = vec![0.0; n_dof];
        for (i, &d) in self.system.dof.iter().enumerate() {
            if d != NONE {
                let ext = external.get(i).copied().unwrap_or([0.0; 3]);
                for c in 0..3 {
                    load[d as usize + c] = self.mass[i] * gravity[c] + ext[c];
                }
            }
        }
        let corotational = self.params.mode == FemMode::Corotational;
        let mut residual_vec = vec![0.0; n_dof];
        let mut r = self.static_residual(&load, &mut residual_vec);
        let mut reference = load.iter().map(|f| f * f).sum::<f64>().sqrt();
        if reference == 0.0 {
            reference = r;
        }
        let mut u_start = self.u.clone();
        let mut factored = false;
        let mut at_round_off = false;
        for iteration in 0..=STATIC_MAX_ITERATIONS {
            let residual = if reference > 0.0 { r / reference } else { 0.0 };
            if !residual.is_finite() {
                return Err(FemError::Singular);
            }
            if residual <= STATIC_TOLERANCE || at_round_off {
                return Ok(StaticReport {
                    positions: self.x.clone(),
                    iterations: iteration,
                    residual,
                });
            }
            if iteration == STATIC_MAX_ITERATIONS {
                return Err(FemError::NotConverged {
                    iterations: iteration,
                    residual,
                });
            }
            if !factored || corotational {
                self.assemble(0.0, corotational);
                self.system
                    .factorize(Precision::Double)
                    .map_err(|_| FemError::Singular)?;
                factored = true;
            }
            // The step d = K⁻¹ r, kept in `rhs`.
            self.s.rhs.copy_from_slice(&residual_vec);
            self.system.solve_in_place(&mut self.s.rhs);
            let slope0 = dot_n(&residual_vec, &self.s.rhs);
            u_start.copy_from_slice(&self.u);
            let mut alpha = 1.0;
            for _ in 0..STATIC_LINE_SEARCH {
                self.move_along_step(&u_start, alpha);
                r = self.static_residual(&load, &mut residual_vec);
                if !corotational {
                    break;
                }
                // Curvature (strong Wolfe) test on Π along d: its slope at α is −r(α)ᵀd.
                let slope = dot_n(&residual_vec, &self.s.rhs);
                if !(slope < -0.9 * slope0) {
                    break;
                }
                // Overshot the minimum along d: secant on the slope, kept in bounds.
                alpha *= (slope0 / (slope0 - slope)).clamp(0.1, 0.9);
            }
            let (mut step, mut size) = (0.0f64, 0.0f64);
            for (u, u0) in self.u.iter().zip(&u_start) {
                for c in 0..3 {
                    step = step.max((u[c] - u0[c]).abs());
                    size = size.max(u[c].abs());
                }
            }
            // An update at the rounding level of the displacements: what residual is left is
            // round-off in f_int, which no further iteration can remove.
            at_round_off = step <= STATIC_ROUND_OFF * size;
        }
        unreachable!("the loop returns on its last iteration")
    }

    /// `u = u_start + alpha · d` (`d` in `rhs`) on the free DOFs, positions refreshed.
    fn move_along_step(&mut self, u_start: &[[f64; 3]], alpha: f64) {
        for (i, &d) in self.system.dof.iter().enumerate() {
            if d != NONE {
                for c in 0..3 {
                    self.u[i][c] = u_start[i][c] + alpha * self.s.rhs[d as usize + c];
                    self.x[i][c] = self.rest[i][c] + self.u[i][c];
                }
            }
        }
    }

    /// `f − f_int(u)` on the free DOFs into `out`; returns its norm. Refreshes `force` and
    /// `grads` (the rotations) at the current state.
    fn static_residual(&mut self, load: &[f64], out: &mut [f64]) -> f64 {
        self.internal_forces();
        let mut r2 = 0.0;
        for (i, &d) in self.system.dof.iter().enumerate() {
            if d != NONE {
                for c in 0..3 {
                    let r = load[d as usize + c] + self.s.force[i][c];
                    out[d as usize + c] = r;
                    r2 += r * r;
                }
            }
        }
        r2.sqrt()
    }
}
