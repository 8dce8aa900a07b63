//! Building a [`Fem`] (elements, lumped masses, held nodes, the sparse system and the scratch)
//! and reading or replacing its state.

use super::batch::Batches;
use super::element::{dot, lame, norm, sub, Element};
use super::params::validate;
use super::rotation::{self, QUAT_IDENTITY};
use super::system::{NodeOrdering, System, NONE};
use super::{
    CorotationalSolver, Factor, Fem, FemError, FemMode, FemParameters, PatchCorrection,
    RefactorPolicy, Scratch, SolverCounters, INVERSE_SLOTS,
};
use crate::mesh::TetMesh;
use crate::parallel::WorkerPool;
use std::sync::Arc;

impl Fem {
    /// Builds the body on `mesh` (rest shape = the mesh's nodes; fixed = `mesh.fixed`),
    /// analyses the sparsity pattern and factorises the system matrix at rest.
    ///
    /// # Errors
    /// [`FemError::InvalidParameter`] for a non-finite or out-of-range parameter,
    /// [`FemError::DegenerateElement`] for a flat or inverted tetrahedron,
    /// [`FemError::Solver`] if the sparse structures cannot be built.
    pub fn new(mesh: &TetMesh, params: FemParameters) -> Result<Fem, FemError> {
        Fem::with_factorization(mesh, params, None)
    }

    /// [`Fem::new`] with the fill-reducing ordering forced instead of the smaller-fill one of
    /// AMD and nested dissection: for benchmarks and tests.
    #[doc(hidden)]
    pub fn with_ordering(
        mesh: &TetMesh,
        params: FemParameters,
        ordering: NodeOrdering,
    ) -> Result<Fem, FemError> {
        Fem::build(mesh, params, None, ordering)
    }

    /// [`Fem::new`] with the factorisation forced supernodal (`Some(true)`) or simplicial
    /// (`Some(false)`) instead of faer's choice: for benchmarks.
    #[doc(hidden)]
    pub fn with_factorization(
        mesh: &TetMesh,
        params: FemParameters,
        supernodal: Option<bool>,
    ) -> Result<Fem, FemError> {
        Fem::build(mesh, params, supernodal, NodeOrdering::Auto)
    }

    fn build(
        mesh: &TetMesh,
        params: FemParameters,
        supernodal: Option<bool>,
        ordering: NodeOrdering,
    ) -> Result<Fem, FemError> {
        validate(&params)?;
        let (lambda, mu) = lame(params.young, params.poisson);
        let n = mesh.nodes.len();
        let mut elements = Vec::with_capacity(mesh.tets.len());
        for (i, t) in mesh.tets.iter().enumerate() {
            let corners = t.map(|k| mesh.nodes[k as usize]);
            let e = Element::new(*t, corners).ok_or_else(|| FemError::DegenerateElement {
                element: i,
                nodes: *t,
                volume: mesh.tet_volume(i),
            })?;
            elements.push(e);
        }
        let mut mass = vec![0.0; n];
        for e in &elements {
            for &k in &e.nodes {
                mass[k as usize] += params.density * e.volume / 4.0;
            }
        }
        let mut held: Vec<bool> = mass.iter().map(|&m| !(m > 0.0)).collect();
        for &f in &mesh.fixed {
            held[f as usize] = true;
        }
        let system = System::new(&mesh.nodes, &elements, &held, supernodal, ordering)
            .map_err(|e| FemError::Solver(format!("{e:?}")))?;
        let n_dof = system.n_dof;
        let mut node_face_ptr = vec![0usize; n + 1];
        for tri in &mesh.surface {
            for &k in tri {
                node_face_ptr[k as usize + 1] += 1;
            }
        }
        for i in 0..n {
            node_face_ptr[i + 1] += node_face_ptr[i];
        }
        let mut node_faces = vec![0u32; node_face_ptr[n]];
        let mut fill = node_face_ptr.clone();
        for (f, tri) in mesh.surface.iter().enumerate() {
            for &k in tri {
                node_faces[fill[k as usize]] = f as u32;
                fill[k as usize] += 1;
            }
        }
        let refine = if params.mode == FemMode::Corotational {
            vec![0.0; n_dof]
        } else {
            Vec::new()
        };
        let s = Box::new(Scratch {
            batch: Batches::new(&elements, &system.dof, lambda, mu),
            node_rot: vec![QUAT_IDENTITY; n],
            node_rot_lag: vec![QUAT_IDENTITY; n],
            node_sum: vec![[0.0; 4]; n],
            node_rot_stale: true,
            node_turn: vec![rotation::IDENTITY; n_dof / 3],
            force: vec![[0.0; 3]; n],
            rhs: vec![0.0; n_dof],
            contact_dir: [vec![0.0; n_dof], vec![0.0; n_dof], vec![0.0; n_dof]],
            contact_pc: [vec![0.0; n_dof], vec![0.0; n_dof], vec![0.0; n_dof]],
            free_v: [vec![0.0; n_dof], vec![0.0; n_dof], vec![0.0; n_dof]],
            sol: vec![0.0; n_dof],
            cg_r: vec![0.0; n_dof],
            cg_z: vec![0.0; n_dof],
            cg_p: vec![0.0; n_dof],
            cg_q: vec![0.0; n_dof],
            inv_cols: if params.mode == FemMode::Linear {
                vec![0.0; 3 * INVERSE_SLOTS * n_dof]
            } else {
                Vec::new()
            },
            inv_key: if params.mode == FemMode::Linear {
                vec![NONE; INVERSE_SLOTS]
            } else {
                Vec::new()
            },
            inv_used: vec![0; INVERSE_SLOTS],
            inv_clock: 0,
            patch: crate::patch::PatchSolve::new(n_dof),
            patch_applied: false,
            refine_b: refine.clone(),
            refine_free: refine.clone(),
            refine_gap: refine,
            pc_slot_of: vec![NONE; n],
            pc_node: Vec::new(),
            pc_used: Vec::new(),
            pc_cols: Vec::new(),
            pc_clock: 0,
            pc_force: Vec::with_capacity(3 * crate::patch::MAX_PATCH),
            pc_correction: PatchCorrection::default(),
        });
        let mut fem = Fem {
            params,
            surface: mesh.surface.clone(),
            node_face_ptr,
            node_faces,
            lambda,
            mu,
            elements,
            mass,
            held,
            rest: mesh.nodes.clone(),
            u: vec![[0.0; 3]; n],
            x: mesh.nodes.clone(),
            v: vec![[0.0; 3]; n],
            system: Box::new(system),
            factor: Factor::Stale,
            solver: CorotationalSolver::LaggedFactorPcg,
            refactor: RefactorPolicy::Amortized,
            last_iterations: 0,
            baseline_iterations: None,
            extra_iterations: 0,
            one_iteration_runs: 0,
            counters: SolverCounters::default(),
            pool: None,
            background: None,
            s,
        };
        fem.factor_dynamic(false)
            .map_err(|_| FemError::Solver("system matrix at rest is not SPD".into()))?;
        Ok(fem)
    }

    /// Node positions, m.
    pub fn positions(&self) -> &[[f64; 3]] {
        &self.x
    }

    /// Node velocities, m/s.
    pub fn velocities(&self) -> &[[f64; 3]] {
        &self.v
    }

    /// Lumped nodal masses, kg.
    pub fn masses(&self) -> &[f64] {
        &self.mass
    }

    /// The body's time step, s: the period of its next step (a change asked by
    /// [`Fem::set_dt`] counts from the step it applies to).
    pub fn dt(&self) -> f64 {
        match self.background.as_deref().and_then(|t| t.due) {
            Some((step, dt)) if step == self.counters.steps => dt,
            _ => self.params.dt,
        }
    }

    /// The parameters the body was built with.
    pub fn parameters(&self) -> &FemParameters {
        &self.params
    }

    /// Sub-steps per step: always 1 (the scheme is implicit).
    pub fn substeps(&self) -> usize {
        1
    }

    /// Free degrees of freedom (3 per node that is neither fixed nor unused).
    pub fn dofs(&self) -> usize {
        self.system.n_dof
    }

    /// Conjugate-gradient iterations of the last corotational step (0 when it was solved
    /// directly, and always 0 in linear mode): for logs and benchmarks.
    pub fn last_iterations(&self) -> usize {
        self.last_iterations
    }

    /// Stored non-zeros of the system matrix (one triangle) and of its Cholesky factor, and
    /// whether faer factorises it supernodally: for logs and benchmarks.
    pub fn solver_info(&self) -> (usize, usize, bool) {
        let (a, l) = self.system.nnz();
        (a, l, self.system.is_supernodal())
    }

    /// The fill-reducing ordering of the system (AMD or nested dissection): for benchmarks.
    #[doc(hidden)]
    pub fn ordering(&self) -> NodeOrdering {
        self.system.ordering()
    }

    /// Factorises `K̃` at rest again, in the precision the body's solver uses (single for the
    /// corotational preconditioner, double otherwise): for benchmarks of the factorisation.
    /// Allocation-free after the first call.
    #[doc(hidden)]
    pub fn refactorize_at_rest(&mut self) -> bool {
        self.factor_dynamic(false).is_ok()
    }

    /// Solves `K̃ x = rhs` in place (one DOF vector, [`Fem::dofs`] long) with the body's
    /// current factor: for benchmarks of the triangular solves.
    ///
    /// # Panics
    /// If `rhs` does not have one entry per DOF.
    #[doc(hidden)]
    pub fn solve_with_factor(&mut self, rhs: &mut [f64]) {
        assert_eq!(rhs.len(), self.system.n_dof, "one entry per DOF");
        self.system.solve_in_place(rhs);
    }

    /// Steps, CG iterations and factorisations since the body was built: for benchmarks.
    #[doc(hidden)]
    pub fn solver_counters(&self) -> SolverCounters {
        let (landed, waits) = self
            .background
            .as_deref()
            .map_or((0, 0), |t| (t.landed, t.waits));
        SolverCounters {
            factorizations: self.system.factorizations(),
            background_factorizations: landed,
            factor_waits: waits,
            ..self.counters
        }
    }

    /// Chooses how corotational steps are solved: for benchmarks.
    #[doc(hidden)]
    pub fn set_corotational_solver(&mut self, solver: CorotationalSolver) {
        self.solver = solver;
    }

    /// Chooses how the contact patch's correction is applied: for tests and benchmarks.
    #[doc(hidden)]
    pub fn set_patch_correction(&mut self, how: PatchCorrection) {
        self.s.pc_correction = how;
    }

    /// Runs the step's element loops (rotations and forces, the matrix-free products, the
    /// per-node rotations) on `pool`, or on the caller alone with `None`. The results are the
    /// same bit for bit whatever the pool's size (`crate::parallel`); the first call with a
    /// pool allocates the gather tables (about 100 bytes per tetrahedron).
    pub fn set_worker_pool(&mut self, pool: Option<Arc<WorkerPool>>) {
        let pool = pool.filter(|p| p.threads() > 1);
        if pool.is_some() {
            self.s.batch.enable_pool(self.x.len());
        }
        self.pool = pool;
    }

    /// Threads the step runs on (1 without a pool).
    pub fn threads(&self) -> usize {
        self.pool.as_ref().map_or(1, |p| p.threads())
    }

    /// Chooses when the lagged factor of a corotational body is refreshed
    /// ([`RefactorPolicy`]); `Amortized` unless set.
    ///
    /// [`RefactorPolicy::Background`] starts the body's factor thread (once; it allocates a
    /// second copy of the sparse system and its factor). Switching from it to another policy
    /// lets a factor in flight land as planned.
    pub fn set_refactor_policy(&mut self, policy: RefactorPolicy) {
        if let RefactorPolicy::Background { delay_steps } = policy {
            self.start_factor_thread(delay_steps.max(1));
            self.refactor = RefactorPolicy::Background {
                delay_steps: delay_steps.max(1),
            };
            return;
        }
        self.refactor = policy;
    }

    /// Changes the step period to `dt` (s). The system matrix `K̃ = M/Δt² + D/(2Δt) + K`
    /// changes with it, so it needs a new factor: under [`RefactorPolicy::Background`] the
    /// factor is made on the factor thread and the new period starts with it, at step
    /// [`Fem::dt_change_due`] (`delay_steps` after this call, or after the factor in flight
    /// lands); otherwise the next step takes the new period and factorises within the step.
    /// The state carries over as it is: displacements, and velocities (the scheme's
    /// `v = (u − u⁻)/Δt` is a velocity, not an increment), so positions and the forces that
    /// depend on them are continuous across the change. [`Fem::dt`] is always the period of
    /// the next step.
    ///
    /// # Errors
    /// [`FemError::InvalidParameter`] for a period that is not finite and positive.
    pub fn set_dt(&mut self, dt: f64) -> Result<(), FemError> {
        if !(dt > 0.0 && dt.is_finite()) {
            return Err(FemError::InvalidParameter {
                name: "dt",
                value: dt,
                expected: "finite and > 0",
            });
        }
        if self.background.is_some() {
            self.request_factor(Some(dt));
        } else if dt != self.params.dt {
            self.params.dt = dt;
            self.factor = Factor::Stale;
        }
        Ok(())
    }

    /// Tests only: the factor thread sleeps `micros` µs before each factorisation (a slow or
    /// busy machine), to show that runs do not depend on its speed.
    #[doc(hidden)]
    pub fn slow_factor_thread(&mut self, micros: u64) {
        if let Some(t) = &self.background {
            t.slow_down(micros);
        }
    }

    /// The step from which a period change asked by [`Fem::set_dt`] applies, and the period,
    /// while it is pending on the factor thread (a queued change: once the factor in flight
    /// lands, then unknown).
    pub fn dt_change_due(&self) -> Option<(u64, f64)> {
        let t = self.background.as_deref()?;
        match t.due {
            Some((step, dt)) if dt != self.params.dt => Some((step, dt)),
            _ => None,
        }
    }

    /// The refactor policy in use.
    pub fn refactor_policy(&self) -> RefactorPolicy {
        self.refactor
    }

    /// Kinetic energy, J.
    pub fn kinetic_energy(&self) -> f64 {
        self.v
            .iter()
            .zip(&self.mass)
            .map(|(v, m)| 0.5 * m * dot(*v, *v))
            .sum()
    }

    /// Largest nodal speed, m/s.
    pub fn max_speed(&self) -> f64 {
        self.v.iter().map(|v| norm(*v)).fold(0.0, f64::max)
    }

    /// Back to the rest shape, at rest.
    pub fn reset(&mut self) {
        self.x.copy_from_slice(&self.rest);
        self.u.iter_mut().for_each(|u| *u = [0.0; 3]);
        self.v.iter_mut().for_each(|v| *v = [0.0; 3]);
        self.s.free_v.iter_mut().for_each(|w| w.fill(0.0));
        self.one_iteration_runs = 0;
        self.s.batch.reset_rotations();
        self.s.node_rot.iter_mut().for_each(|q| *q = QUAT_IDENTITY);
        self.s.node_rot_stale = true;
    }

    /// Replaces the state (for levels-of-precision switching, or to prescribe boundary
    /// displacements before [`Fem::solve_static`]). Fixed nodes take the given positions and
    /// are held there, at zero velocity. The rotation search restarts cold, so what follows
    /// depends on `x` and `v` only (and, for the corotational solver's speed, not its result,
    /// on which factor it holds).
    ///
    /// # Panics
    /// If `x` or `v` does not have one entry per node.
    pub fn set_state(&mut self, x: &[[f64; 3]], v: &[[f64; 3]]) {
        assert_eq!(x.len(), self.x.len(), "set_state: one position per node");
        assert_eq!(v.len(), self.v.len(), "set_state: one velocity per node");
        self.x.copy_from_slice(x);
        for ((u, x), r) in self.u.iter_mut().zip(x).zip(&self.rest) {
            *u = sub(*x, *r);
        }
        for (i, vi) in self.v.iter_mut().enumerate() {
            *vi = if self.held[i] { [0.0; 3] } else { v[i] };
        }
        for w in self.s.free_v.iter_mut() {
            for (i, &d) in self.system.dof.iter().enumerate() {
                if d != super::system::NONE {
                    w[d as usize..d as usize + 3].copy_from_slice(&self.v[i]);
                }
            }
        }
        self.one_iteration_runs = 0;
        self.s.batch.reset_rotations();
        self.s.node_rot.iter_mut().for_each(|q| *q = QUAT_IDENTITY);
        self.s.node_rot_stale = true;
    }

    /// Whether node `i` is held (fixed by the mesh, or used by no tetrahedron).
    pub fn is_held(&self, i: usize) -> bool {
        self.held[i]
    }
}
