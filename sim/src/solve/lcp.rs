//! A linear complementarity problem with a symmetric positive definite matrix, solved exactly
//! by principal pivoting: `w = q + A λ ≥ 0`, `λ ≥ 0`, `wᵀλ = 0`. Block pivoting (every violated
//! index flips) for a few rounds, then Murty's least-index rule, which terminates for every
//! positive definite `A`. The tool's contact patch (`crate::patch`) is its user: its gaps after
//! a model's implicit step are linear in the contact forces.

/// The ridges added to `A`'s diagonal, relative to its largest diagonal entry, each tried when
/// the one before leaves an active set that is not positive definite. The smallest keeps
/// coincident points (two faces' shared edge) solvable. The larger ones are for rows that are
/// dependent in exact arithmetic: on a flat patch a face point moves as the barycentric
/// combination of its triangle's nodes, so with those nodes active its row adds nothing, and
/// a matrix made from a single-precision factor's columns (errors ~1e-7 of its entries) can
/// then be indefinite by far more than 1e-12. A block held by the god-object's patch at 1 ms
/// found such a matrix on 3 steps of its press, and the patch then applied no force for a step.
/// A ridge `ε · max diag` is a compliance in series with each point: at 1e-3 it moves a held
/// point by a thousandth of what the stiffest point's compliance would.
const RIDGES: [f64; 4] = [1e-12, 1e-9, 1e-6, 1e-3];

/// A solver for the linear complementarity problem `w = q + A λ ≥ 0`, `λ ≥ 0`, `wᵀλ = 0`
/// with `A` symmetric positive definite, in buffers sized once for a largest problem.
#[derive(Debug, Clone)]
pub struct Lcp {
    /// `A`, column-major `m × m`; filled by the caller through [`Lcp::matrix`].
    a: Vec<f64>,
    q: Vec<f64>,
    lambda: Vec<f64>,
    active: Vec<bool>,
    idx: Vec<usize>,
    sub: Vec<f64>,
    rhs: Vec<f64>,
    m: usize,
    /// The largest problem the buffers were sized for.
    capacity: usize,
}

impl Lcp {
    /// Buffers for problems of up to `capacity` unknowns: solving one allocates nothing.
    pub fn with_capacity(capacity: usize) -> Lcp {
        Lcp {
            a: Vec::with_capacity(capacity * capacity),
            q: Vec::with_capacity(capacity),
            lambda: Vec::with_capacity(capacity),
            active: Vec::with_capacity(capacity),
            idx: Vec::with_capacity(capacity),
            sub: Vec::with_capacity(capacity * capacity),
            rhs: Vec::with_capacity(capacity),
            m: 0,
            capacity,
        }
    }

    /// Starts a problem of size `m` (at most the capacity): `A` and `q` zeroed, to be filled
    /// through [`Lcp::matrix`] and [`Lcp::q`].
    pub fn reset(&mut self, m: usize) {
        let m = m.min(self.capacity);
        self.m = m;
        self.a.clear();
        self.a.resize(m * m, 0.0);
        self.q.clear();
        self.q.resize(m, 0.0);
        self.lambda.clear();
        self.lambda.resize(m, 0.0);
    }

    /// `A`, column-major.
    pub fn matrix(&mut self) -> &mut [f64] {
        &mut self.a
    }

    /// `q`.
    pub fn q(&mut self) -> &mut [f64] {
        &mut self.q
    }

    /// The last solution `λ`.
    pub fn lambda(&self) -> &[f64] {
        &self.lambda
    }

    /// Solves the problem; false (and `λ = 0`) if `A` or `q` is not finite, or if even with
    /// the largest of [`RIDGES`] `A` is not positive definite or pivoting did not finish.
    pub fn solve(&mut self) -> bool {
        let m = self.m;
        if !self.a.iter().chain(&self.q).all(|x| x.is_finite()) {
            self.lambda.iter_mut().for_each(|l| *l = 0.0);
            return false;
        }
        let diag_max = (0..m).map(|j| self.a[j * m + j]).fold(0.0, f64::max);
        let mut added = 0.0;
        for r in RIDGES {
            for j in 0..m {
                self.a[j * m + j] += r * diag_max - added;
            }
            added = r * diag_max;
            if self.pivot() {
                return true;
            }
        }
        false
    }

    /// After a [`solve`](Self::solve), solves again for a new `q` (written through
    /// [`Lcp::q`]) with the same `A` (its ridge already added): the same problem size, the
    /// active set found afresh. False (and `λ = 0`) as [`solve`](Self::solve).
    pub fn resolve(&mut self) -> bool {
        if !self.q.iter().all(|x| x.is_finite()) || self.a.len() != self.m * self.m {
            self.lambda.iter_mut().for_each(|l| *l = 0.0);
            return false;
        }
        self.pivot()
    }

    /// The principal pivoting of [`solve`](Self::solve) on `A` as it stands.
    fn pivot(&mut self) -> bool {
        let m = self.m;
        let q_scale = self.q.iter().fold(0.0f64, |s, x| s.max(x.abs()));
        let w_tol = 1e-10 * q_scale;
        self.active.clear();
        self.active.extend(self.q.iter().map(|&qj| qj < 0.0));
        if !self.active.iter().any(|&a| a) {
            self.lambda.iter_mut().for_each(|l| *l = 0.0);
            return true;
        }
        // Block pivoting (every violated index flips) for a few rounds, then one index at a
        // time, the least first (Murty): finite for a positive definite A.
        let max_iter = 20 + 10 * m;
        for iter in 0..max_iter {
            if !self.solve_active() {
                self.lambda.iter_mut().for_each(|l| *l = 0.0);
                return false;
            }
            let l_scale = self.lambda.iter().fold(0.0f64, |s, x| s.max(x.abs()));
            let l_tol = 1e-12 * l_scale;
            let mut flipped = false;
            for j in 0..m {
                let violated = if self.active[j] {
                    self.lambda[j] < -l_tol
                } else {
                    let w = self.q[j]
                        + (0..m)
                            .filter(|&k| self.active[k])
                            .map(|k| self.a[k * m + j] * self.lambda[k])
                            .sum::<f64>();
                    w < -w_tol
                };
                if violated {
                    self.active[j] = !self.active[j];
                    flipped = true;
                    if iter >= 5 {
                        break;
                    }
                }
            }
            if !flipped {
                self.lambda.iter_mut().for_each(|l| *l = l.max(0.0));
                return true;
            }
        }
        self.lambda.iter_mut().for_each(|l| *l = 0.0);
        false
    }

    /// After a successful [`solve`](Self::solve): `x = A_SS⁻¹ b_S` on the active set `S` of
    /// the last pivot, with the factor of `A_SS` that pivot left (one substitution, no
    /// allocation), `b_j` given by `b(j)`. Returns `S` (ascending) and `x`, or `None` when there
    /// is no factor (nothing touched, or no solve yet) or `b` names an index `S` does not have
    /// (`in_range(j)` false).
    pub fn solve_on_active_set(
        &mut self,
        in_range: impl Fn(usize) -> bool,
        b: impl Fn(usize) -> f64,
    ) -> Option<(&[usize], &[f64])> {
        let s = self.idx.len();
        let factored = s > 0
            && self.sub.len() == s * s
            && self.idx.iter().all(|&j| in_range(j) && self.active[j]);
        if !factored {
            return None;
        }
        self.rhs.clear();
        self.rhs.extend(self.idx.iter().map(|&j| b(j)));
        crate::solve::dense::spd_solve_factored(&self.sub, s, &mut self.rhs);
        Some((&self.idx, &self.rhs))
    }

    /// `λ_S = −A_SS⁻¹ q_S` on the active set `S`, zero elsewhere.
    fn solve_active(&mut self) -> bool {
        let m = self.m;
        self.idx.clear();
        self.idx.extend((0..m).filter(|&j| self.active[j]));
        let s = self.idx.len();
        self.lambda.iter_mut().for_each(|l| *l = 0.0);
        if s == 0 {
            return true;
        }
        self.sub.clear();
        for &c in &self.idx {
            for &r in &self.idx {
                self.sub.push(self.a[c * m + r]);
            }
        }
        self.rhs.clear();
        self.rhs.extend(self.idx.iter().map(|&j| -self.q[j]));
        if !crate::solve::dense::spd_solve_in_place(&mut self.sub, s, &mut self.rhs) {
            return false;
        }
        for (k, &j) in self.idx.iter().enumerate() {
            self.lambda[j] = self.rhs[k];
        }
        self.lambda.iter().all(|l| l.is_finite())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use lop_test_support::rng::Rng;

    /// On small random positive definite problems the solution meets every condition that
    /// defines it (feasible, non-negative, complementary), which makes it the unique one.
    #[test]
    fn lcp_solutions_meet_the_complementarity_conditions() {
        let mut rng = Rng::new(7);
        let mut rnd = || rng.signed();
        let mut lcp = Lcp::with_capacity(8);
        for m in 1..=6 {
            for _ in 0..30 {
                let b: Vec<f64> = (0..m * m).map(|_| rnd()).collect();
                let mut a = vec![0.0; m * m];
                for i in 0..m {
                    for j in 0..m {
                        a[j * m + i] = (0..m).map(|k| b[i * m + k] * b[j * m + k]).sum::<f64>()
                            + if i == j { 0.1 } else { 0.0 };
                    }
                }
                let q: Vec<f64> = (0..m).map(|_| rnd()).collect();
                lcp.reset(m);
                lcp.matrix().copy_from_slice(&a);
                lcp.q().copy_from_slice(&q);
                assert!(lcp.solve());
                let l = lcp.lambda().to_vec();
                for j in 0..m {
                    let w = q[j] + (0..m).map(|k| a[k * m + j] * l[k]).sum::<f64>();
                    assert!(l[j] >= 0.0 && w >= -1e-9, "m {m}: λ {l:?}, w_{j} {w}");
                    assert!((l[j] * w).abs() < 1e-9, "complementarity");
                }
            }
        }
    }

    /// Two points whose rows are the same but for rounding (a face point on a flat patch and
    /// its triangle's nodes): the matrix is indefinite by 1e-9 of its entries, beyond the
    /// smallest ridge. The problem is solved with a larger one, to that ridge's accuracy.
    #[test]
    fn lcp_solves_rows_dependent_but_for_rounding() {
        let mut lcp = Lcp::with_capacity(4);
        let (d, e) = (1.0, 1e-9);
        lcp.reset(2);
        lcp.matrix().copy_from_slice(&[d, d + e, d + e, d]);
        lcp.q().copy_from_slice(&[-1.0, -1.0]);
        assert!(lcp.solve(), "solved");
        let l = lcp.lambda().to_vec();
        assert!(l.iter().all(|&x| x >= 0.0), "{l:?}");
        // Together the two points carry the load: w = q + A λ = 0 to the ridge's accuracy.
        let w = -1.0 + d * l[0] + (d + e) * l[1];
        assert!(w.abs() < 1e-5, "w {w}, λ {l:?}");
    }

    #[test]
    fn lcp_refuses_non_finite_input() {
        let mut lcp = Lcp::with_capacity(8);
        lcp.reset(2);
        lcp.matrix().copy_from_slice(&[1.0, 0.0, 0.0, f64::NAN]);
        lcp.q().copy_from_slice(&[-1.0, -1.0]);
        assert!(!lcp.solve());
        assert_eq!(lcp.lambda(), &[0.0, 0.0]);
    }
}
