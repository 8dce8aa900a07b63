//! A body run as a Green-coordinates cage: the cheap level of precision.
//!
//! This file builds the cage, binds the body to it, fits it to a shape and maps loads and
//! shapes between the body's nodes and the cage; the cage's own dynamics, one per
//! [`CageDynamics`] variant, are in `cage_dynamics.rs`.

use nalgebra::{Cholesky, DMatrix, DVector, Dyn};
use thiserror::Error;

use crate::gc::{
    box_cage, grid_box_cage, subdivided_box_cage, Cage, CageError, GcBinding, GreenCoordinates,
};
use crate::interaction::{touch, BlowUp, ContactReport, ContactSpring, ToolContact, RUNAWAY_SPEED};
use crate::mesh::{extents, smallest_extent, TetMesh};
use crate::vec3::{add, dot, norm, scale, sub};

use super::cage_dynamics::{
    mass_spring_cage, step_mass_spring, CageBasis, Dynamics, Reduced, StepLoads,
};
use super::kernel::Kernel;

/// The cage's shape.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CageShape {
    /// The thesis' cage: the padded bounding box (8 vertices, 12 triangles).
    Box,
    /// The padded bounding box with every edge cut in `n` segments (`6n² + 2` vertices,
    /// `12n²` triangles): more freedom to follow the body's own deformation.
    SubdividedBox(usize),
    /// The padded bounding box cut into roughly cubic cells: each axis gets
    /// `max(1, round(extent / smallest extent))` segments (a 60 × 120 × 60 mm cylinder gets
    /// 1 × 2 × 1, 12 vertices), with at most [`MAX_FITTED_VERTICES`] vertices (see
    /// [`fitted_cells`]). Cheap like the box, but a long body can bend along its length.
    Fitted,
}

/// How the cage moves.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum CageDynamics {
    /// Derived from the body's precise model with nothing to tune: its mass and damping
    /// projected onto the cage's deformation space, and a stiffness matched to its rest
    /// *compliance*, so that the cage's static response to a load is the best fit of the
    /// precise model's (see the module docs). The default: it is the most accurate one. A body
    /// without fixed nodes has no rest compliance; it gets the [`CageDynamics::Galerkin`]
    /// stiffness.
    Projected,
    /// The precise model's rest stiffness, mass and damping all projected onto the cage's
    /// deformation space (a plain Galerkin reduced model, `K_r = GᵀKG`). Nothing to tune
    /// either, but stiffer than the body when the cage cannot bend exactly like it: kept for
    /// comparison.
    Galerkin,
    /// The thesis' way (§4.3): a mass-spring system on the cage vertices with its own,
    /// hand-tuned parameters.
    MassSpring(CageSprings),
}

/// The hand-tuned parameters of a mass-spring cage ([`CageDynamics::MassSpring`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CageSprings {
    /// Spring stiffness, N/m.
    pub stiffness: f64,
    /// Density, kg/m³: the cage's volume times this, shared equally by its vertices.
    pub density: f64,
    /// Damping per vertex, N·s/m.
    pub damping: f64,
}

impl CageSprings {
    /// The thesis' values for every organ (the GC columns of its Tables 6.1 and 6.2): what a
    /// mass-spring cage gets when a scene gives none.
    pub const THESIS: CageSprings = CageSprings {
        stiffness: 50.0,
        density: 20.0,
        damping: 0.3,
    };
}

/// Parameters of a body's GC model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GcParameters {
    /// Cage shape.
    pub shape: CageShape,
    /// Gap between the body's bounding box and the cage, m (> 0: no node may lie on the cage).
    pub padding: f64,
    /// Cage dynamics.
    pub dynamics: CageDynamics,
    /// Time step, s.
    pub dt: f64,
}

/// How the precise model damps, for [`CageDynamics::Projected`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Damping {
    /// `D = αM` (FEM), α in 1/s.
    MassProportional(f64),
    /// `−γ v` on every node (mass-spring, eq. 4.2), γ in N·s/m.
    PerNode(f64),
}

/// `u ↦ K u`: a model's rest stiffness applied to a displacement field, N.
pub type StiffnessProduct<'a> = &'a dyn Fn(&[[f64; 3]]) -> Vec<[f64; 3]>;

/// The precise model's equilibrium under a constant gravity, about which a projected cage is
/// linearised instead of about the rest shape (see [`CageModel::from_precise_under`]).
pub struct Prestress<'a> {
    /// The gravity of the equilibrium, m/s².
    pub gravity: [f64; 3],
    /// Node displacements from rest at the equilibrium, m.
    pub displacement: &'a [[f64; 3]],
    /// `u ↦ K_t u`: the precise model's tangent stiffness at the equilibrium, N.
    pub tangent: StiffnessProduct<'a>,
}

/// The precise model's operators at rest, which [`CageDynamics::Projected`] projects.
pub struct PreciseOperators<'a> {
    /// Lumped nodal masses, kg.
    pub masses: &'a [f64],
    /// Nodes that never move.
    pub held: &'a [bool],
    /// Damping.
    pub damping: Damping,
    /// `u ↦ K u` at rest, N.
    pub stiffness: StiffnessProduct<'a>,
    /// The equilibrium under the scene's gravity, if the cage is to be linearised about it.
    pub prestress: Option<Prestress<'a>>,
}

/// Why a GC model could not be built.
#[derive(Debug, Error)]
pub enum CageModelError {
    /// The cage is not usable or does not hold the body.
    #[error("cage: {0}")]
    Cage(#[from] CageError),
    /// A parameter is out of range.
    #[error("{0}")]
    Parameter(String),
    /// The projected mass matrix is singular: some cage motion moves no free node.
    #[error(
        "the cage has motions that move no free node of the body (projected mass matrix not \
         positive definite); use a coarser cage"
    )]
    Singular,
}

/// A body run as a Green-coordinates cage.
///
/// The body's nodes are bound to the cage once (φ, ψ per node); a step moves the cage by its
/// dynamics and re-evaluates every node, `x = Σ φᵢ vᵢ' + Σ ψⱼ sⱼ n(tⱼ')`. Fixed nodes stay at rest.
#[derive(Debug, Clone)]
pub struct CageModel {
    params: GcParameters,
    gc: GreenCoordinates,
    binding: GcBinding,
    rest_cage: Vec<[f64; 3]>,
    cage: Vec<[f64; 3]>,
    normals: Vec<[f64; 3]>,
    rest: Vec<[f64; 3]>,
    held: Vec<bool>,
    masses: Vec<f64>,
    /// `Gᵀ`, with `G = ∂x/∂q` at rest (3N × 3V; column `c` of `G` is cage vertex `c / 3`, axis
    /// `c % 3`; zero rows on held nodes). Stored transposed so that the row of one node's axis,
    /// which a load on it needs, is contiguous.
    jacobian_t: DMatrix<f64>,
    /// Cholesky factor of `Gᵀ M G`, for fitting the cage to a given shape.
    fit: Cholesky<f64, Dyn>,
    dynamics: Dynamics,
    /// The hot loop, its inputs (cage-vertex displacements, then scaled-normal changes) and
    /// outputs (node displacements the cage alone gives).
    kernel: Kernel,
    rest_normals: Vec<[f64; 3]>,
    w: Vec<[f32; 3]>,
    disp: Vec<[f32; 3]>,
    /// Displayed positions (cage + blend) and velocities, with their energy measures.
    x: Vec<[f64; 3]>,
    v: Vec<[f64; 3]>,
    kinetic: f64,
    speed: f64,
    /// Offset faded out after taking over a shape the cage cannot represent exactly.
    blend: Vec<[f64; 3]>,
    blend_left: f64,
    blend_time: f64,
    /// External loads, scratch (3N), and their cage-space image (3V).
    load_r: DVector<f64>,
    cage_loads: Vec<[f64; 3]>,
}

/// The cage of `shape` around `points`.
pub fn build_cage(shape: CageShape, points: &[[f64; 3]], padding: f64) -> Cage {
    match shape {
        CageShape::Box => box_cage(points, padding),
        CageShape::SubdividedBox(n) => subdivided_box_cage(points, padding, n.max(1)),
        CageShape::Fitted => grid_box_cage(points, padding, fitted_cells(points)),
    }
}

/// Most vertices a [`CageShape::Fitted`] cage gets. A cage step costs about `N × (V + T)` for
/// the nodes plus `3V × 6V` for the dynamics, so this keeps a fitted cage at or above 50× the
/// speed of the body's corotational FEM step on the shipped organs (`lop-bench lop`, Part 2);
/// without it the long, flat pancreas got 5 × 2 × 1 cells, 36 vertices, and only 31×.
pub const MAX_FITTED_VERTICES: usize = 20;

/// Vertices of a grid cage with `cells` segments per axis (its surface points).
fn grid_vertices(cells: [usize; 3]) -> usize {
    let [a, b, c] = cells;
    (a + 1) * (b + 1) * (c + 1) - (a - 1) * (b - 1) * (c - 1)
}

/// Segments per axis of a [`CageShape::Fitted`] cage around `points`: roughly cubic cells
/// (`round(extent / smallest extent)` segments per axis, at most 8), then, while the cage has
/// more than [`MAX_FITTED_VERTICES`] vertices, one segment fewer on the axis with the shortest
/// cells — so a long body keeps its segments along its length, where it bends.
pub fn fitted_cells(points: &[[f64; 3]]) -> [usize; 3] {
    let ext = extents(points);
    let smallest = smallest_extent(points);
    let mut cells = ext.map(|e| {
        let r = (e / smallest).round();
        if r.is_finite() && r >= 1.0 {
            (r as usize).min(8)
        } else {
            1
        }
    });
    while grid_vertices(cells) > MAX_FITTED_VERTICES {
        let Some(axis) = (0..3)
            .filter(|&a| cells[a] > 1)
            .min_by(|&a, &b| (ext[a] / cells[a] as f64).total_cmp(&(ext[b] / cells[b] as f64)))
        else {
            break;
        };
        cells[axis] -= 1;
    }
    cells
}

impl CageModel {
    /// The last step's contact patch problem, for projected dynamics (the mass-spring cage
    /// presses at one point); meaningful only when the step's report came from a patch.
    pub fn patch_solution(&mut self) -> Option<&mut crate::patch::Lcp> {
        match &mut self.dynamics {
            Dynamics::Projected(r) => Some(&mut r.patch.lcp),
            Dynamics::MassSpring(_) => None,
        }
    }

    /// Builds the GC model of the body `mesh` (rest shape, fixed nodes), whose precise model
    /// provides `ops`.
    pub fn new(
        mesh: &TetMesh,
        params: GcParameters,
        ops: &PreciseOperators<'_>,
    ) -> Result<CageModel, CageModelError> {
        if !(params.padding > 0.0 && params.padding.is_finite()) {
            return Err(CageModelError::Parameter(format!(
                "cage padding = {} m: must be a positive distance",
                params.padding
            )));
        }
        if !(params.dt > 0.0 && params.dt <= 1.0) {
            return Err(CageModelError::Parameter(format!(
                "cage dt = {} s: must be in (0, 1]",
                params.dt
            )));
        }
        let n = mesh.nodes.len();
        assert_eq!(ops.masses.len(), n, "one mass per node");
        assert_eq!(ops.held.len(), n, "one held flag per node");
        let cage = build_cage(params.shape, &mesh.nodes, params.padding);
        let gc = GreenCoordinates::new(&cage.vertices, &cage.triangles)?;
        let binding = gc.bind(&mesh.nodes)?;
        let nv = gc.vertex_count();
        let nt = gc.triangle_count();
        let m = 3 * nv;
        let mut held = ops.held.to_vec();
        for &f in &mesh.fixed {
            held[f as usize] = true;
        }

        // Jacobian by central differences of the exact map: the φ part is linear in the cage,
        // the ψ part (scaled normals) smooth, so the O(h²) error at h = 1e-6 of the cage size
        // is far below anything that matters.
        let size = extents(&cage.vertices).into_iter().fold(0.0, f64::max);
        let h = 1e-6 * size;
        let mut jacobian = DMatrix::zeros(3 * n, m);
        let mut deformed = cage.vertices.clone();
        let mut normals = vec![[0.0; 3]; nt];
        let mut plus = vec![[0.0; 3]; n];
        let mut minus = vec![[0.0; 3]; n];
        for c in 0..m {
            let (vi, a) = (c / 3, c % 3);
            deformed[vi][a] = cage.vertices[vi][a] + h;
            gc.scaled_normals(&deformed, &mut normals);
            binding.deform_into(&deformed, &normals, &mut plus);
            deformed[vi][a] = cage.vertices[vi][a] - h;
            gc.scaled_normals(&deformed, &mut normals);
            binding.deform_into(&deformed, &normals, &mut minus);
            deformed[vi][a] = cage.vertices[vi][a];
            let mut col = jacobian.column_mut(c);
            for k in 0..n {
                if held[k] {
                    continue;
                }
                for b in 0..3 {
                    col[3 * k + b] = (plus[k][b] - minus[k][b]) / (2.0 * h);
                }
            }
        }

        // Gᵀ M G.
        let mut mg = jacobian.clone();
        for k in 0..n {
            for b in 0..3 {
                mg.row_mut(3 * k + b).scale_mut(ops.masses[k]);
            }
        }
        let m_r = jacobian.transpose() * &mg;
        let fit = Cholesky::new(m_r.clone()).ok_or(CageModelError::Singular)?;

        let dt = params.dt;
        let basis = CageBasis {
            mesh,
            held: &held,
            jacobian: &jacobian,
            mg: &mg,
            m_r: &m_r,
            fit: &fit,
        };
        let dynamics = match params.dynamics {
            CageDynamics::Projected => {
                Dynamics::Projected(Box::new(Reduced::projected(&basis, ops, dt)?))
            }
            CageDynamics::Galerkin => {
                Dynamics::Projected(Box::new(Reduced::galerkin(&basis, ops, dt)?))
            }
            CageDynamics::MassSpring(CageSprings {
                stiffness,
                density,
                damping,
            }) => Dynamics::MassSpring(Box::new(mass_spring_cage(
                mesh, &cage, &binding, stiffness, density, damping, dt,
            ))),
        };

        let kernel = Kernel::new(&binding, &held);
        let mut rest_normals = vec![[0.0; 3]; nt];
        gc.scaled_normals(&cage.vertices, &mut rest_normals);
        let mut model = CageModel {
            params,
            gc,
            binding,
            rest_cage: cage.vertices.clone(),
            cage: cage.vertices,
            normals: vec![[0.0; 3]; nt],
            rest: mesh.nodes.clone(),
            held,
            masses: ops.masses.to_vec(),
            jacobian_t: jacobian.transpose(),
            fit,
            dynamics,
            kernel,
            rest_normals,
            w: vec![[0.0; 3]; nv + nt],
            disp: vec![[0.0; 3]; n],
            x: mesh.nodes.clone(),
            v: vec![[0.0; 3]; n],
            kinetic: 0.0,
            speed: 0.0,
            blend: vec![[0.0; 3]; n],
            blend_left: 0.0,
            blend_time: 0.0,
            load_r: DVector::zeros(m),
            cage_loads: vec![[0.0; 3]; nv],
        };
        model.evaluate();
        Ok(model)
    }

    /// The parameters.
    pub fn parameters(&self) -> &GcParameters {
        &self.params
    }
    /// The Green coordinates of the rest cage.
    pub fn coordinates(&self) -> &GreenCoordinates {
        &self.gc
    }
    /// The current (deformed) cage vertices, m.
    pub fn cage_vertices(&self) -> &[[f64; 3]] {
        &self.cage
    }
    /// Node positions, m.
    pub fn positions(&self) -> &[[f64; 3]] {
        &self.x
    }
    /// Node velocities, m/s (the change of the displayed positions over the last step).
    pub fn velocities(&self) -> &[[f64; 3]] {
        &self.v
    }
    /// Nodal masses (the precise model's), kg.
    pub fn masses(&self) -> &[f64] {
        &self.masses
    }
    /// Time step, s.
    pub fn dt(&self) -> f64 {
        self.params.dt
    }
    /// Kinetic energy of the nodes, J.
    pub fn kinetic_energy(&self) -> f64 {
        self.kinetic
    }
    /// Largest nodal speed, m/s.
    pub fn max_speed(&self) -> f64 {
        self.speed
    }
    /// Seconds of blending left after the last [`CageModel::take_over`].
    pub fn blending(&self) -> f64 {
        self.blend_left
    }

    /// Back to the rest shape, at rest.
    pub fn reset(&mut self) {
        match &mut self.dynamics {
            Dynamics::Projected(r) => {
                r.state.fill(0.0);
                r.correction.copy_from_slice(&r.rest_correction);
                r.correction_due = false;
            }
            Dynamics::MassSpring(msd) => msd.reset(),
        }
        self.cage.copy_from_slice(&self.rest_cage);
        self.blend_left = 0.0;
        self.blend.iter_mut().for_each(|b| *b = [0.0; 3]);
        self.evaluate();
        for k in 0..self.x.len() {
            self.x[k] = self.cage_position(k);
        }
        self.v.iter_mut().for_each(|v| *v = [0.0; 3]);
        self.kinetic = 0.0;
        self.speed = 0.0;
    }

    /// Where the cage alone puts node `k` (after [`CageModel::evaluate`]).
    #[inline]
    fn cage_position(&self, k: usize) -> [f64; 3] {
        let (r, d) = (self.rest[k], self.disp[k]);
        [r[0] + d[0] as f64, r[1] + d[1] as f64, r[2] + d[2] as f64]
    }

    /// Takes over a body's state from its precise model: fits the cage to the positions and
    /// velocities (mass-weighted least squares over the free nodes), then fades the part the
    /// cage cannot represent out over `blend` seconds, so the displayed shape starts exactly at
    /// `x` and nothing pops (with `blend` 0 it snaps to the fitted cage at once). Returns the largest distance between `x` and the fitted cage's
    /// shape (what would have popped without the blend), m. Allocates a little (set-up path).
    pub fn take_over(&mut self, x: &[[f64; 3]], v: &[[f64; 3]], blend: f64) -> f64 {
        let n = self.rest.len();
        assert_eq!(x.len(), n, "one position per node");
        assert_eq!(v.len(), n, "one velocity per node");
        let q = self.fit_field(|k| sub(x[k], self.rest[k]));
        let qd = self.fit_field(|k| v[k]);
        match &mut self.dynamics {
            Dynamics::Projected(r) => {
                let m = r.d.len();
                r.state[..m].copy_from_slice(q.as_slice());
                r.state[m..].copy_from_slice(qd.as_slice());
                r.correction_due = true;
            }
            Dynamics::MassSpring(msd) => {
                let pos: Vec<[f64; 3]> = (0..self.rest_cage.len())
                    .map(|i| add(self.rest_cage[i], [q[3 * i], q[3 * i + 1], q[3 * i + 2]]))
                    .collect();
                let vel: Vec<[f64; 3]> = (0..self.rest_cage.len())
                    .map(|i| [qd[3 * i], qd[3 * i + 1], qd[3 * i + 2]])
                    .collect();
                msd.set_state(&pos, &vel);
            }
        }
        self.sync_cage();
        self.evaluate();
        let mut residual: f64 = 0.0;
        for (k, xk) in x.iter().enumerate() {
            self.blend[k] = sub(*xk, self.cage_position(k));
            residual = residual.max(norm(self.blend[k]));
        }
        self.blend_time = blend.max(0.0);
        self.blend_left = self.blend_time;
        if self.blend_time == 0.0 {
            self.blend.iter_mut().for_each(|b| *b = [0.0; 3]);
        }
        // Shown now: `x` itself when blending, the fitted cage when snapping (blend 0).
        for k in 0..n {
            self.x[k] = add(self.cage_position(k), self.blend[k]);
        }
        for (k, vk) in self.v.iter_mut().enumerate() {
            *vk = if self.held[k] { [0.0; 3] } else { v[k] };
        }
        self.kinetic = 0.0;
        self.speed = 0.0;
        for (vk, m) in self.v.iter().zip(&self.masses) {
            let s2 = dot(*vk, *vk);
            self.kinetic += 0.5 * m * s2;
            self.speed = self.speed.max(s2);
        }
        self.speed = self.speed.sqrt();
        residual
    }

    /// Mass-weighted least-squares cage displacement reproducing the nodal field `f`.
    fn fit_field(&self, f: impl Fn(usize) -> [f64; 3]) -> DVector<f64> {
        let n = self.rest.len();
        let mut mu = DVector::zeros(3 * n);
        for k in 0..n {
            if self.held[k] {
                continue;
            }
            let fk = f(k);
            for b in 0..3 {
                mu[3 * k + b] = self.masses[k] * fk[b];
            }
        }
        let rhs = &self.jacobian_t * mu;
        self.fit.solve(&rhs)
    }

    /// One step under gravity, nodal loads and (for a body pinned to GC) the tool.
    /// Allocation-free.
    pub fn step(
        &mut self,
        gravity: [f64; 3],
        external: &[[f64; 3]],
        contact: Option<&ToolContact<'_>>,
    ) -> Result<ContactReport, BlowUp> {
        self.step_colliding(gravity, external, contact, &[])
    }

    /// [`CageModel::step`] with organ-to-organ contact springs, resolved through the cage.
    /// Projected dynamics: each pushing spring's stiffness is projected onto the cage,
    /// `k (Gᵀ(w ⊗ n))(Gᵀ(w ⊗ n))ᵀ`, and the step solves the reduced system with it (a dense
    /// 3V × 3V Cholesky factorisation, only in steps with contact), so the contact is implicit
    /// as in the precise models. Mass-spring cage (the thesis' way): the springs' forces at the
    /// start of the step are loads mapped to the cage vertices by φ, explicitly.
    ///
    /// A contact patch in `contact` (the god-object's press) is resolved by the projected
    /// dynamics on top of the springs, and its report carries the proxy; the mass-spring cage
    /// keeps the anchor's one-point press (see the [module docs](super)).
    pub fn step_colliding(
        &mut self,
        gravity: [f64; 3],
        external: &[[f64; 3]],
        contact: Option<&ToolContact<'_>>,
        springs: &[ContactSpring],
    ) -> Result<ContactReport, BlowUp> {
        let dt = self.params.dt;
        // The god-object's press as a contact patch, resolved by the projected dynamics in
        // their implicit step; the mass-spring cage keeps the anchor's point (module docs).
        let patch = match self.dynamics {
            Dynamics::Projected(_) => contact.and_then(|c| c.patch),
            Dynamics::MassSpring(_) => None,
        };
        // Otherwise the tool, as a load on the current shape (explicit: a body pinned to GC is
        // the cheap level; a touched body normally switches to its precise model first).
        let touch = match patch {
            Some(_) => None,
            None => contact.and_then(|c| touch(c, &self.x)),
        };
        let has_loads = touch.is_some() || external.iter().any(|f| *f != [0.0; 3]);
        let mut report = touch.map_or_else(ContactReport::default, |t| ContactReport {
            force_on_tissue: t.on_tissue,
            depth: t.depth,
            proxy: None,
            response: None,
        });
        let loads = StepLoads {
            gravity,
            external,
            touch: touch.as_ref(),
            springs,
            has_loads,
            patch,
        };
        match &mut self.dynamics {
            Dynamics::Projected(r) => {
                let applied = r.step(&loads, dt, &self.x, &self.jacobian_t, &mut self.load_r);
                if let Some(applied) = applied {
                    report = applied;
                }
            }
            Dynamics::MassSpring(msd) => {
                step_mass_spring(msd, &loads, &self.binding, &self.x, &mut self.cage_loads)?;
            }
        }
        self.sync_cage();
        self.evaluate();
        // Displayed = cage + fading offset; velocities from the displayed motion. One pass.
        let w = if self.blend_left > 0.0 {
            self.blend_left = (self.blend_left - dt).max(0.0);
            self.blend_left / self.blend_time
        } else {
            0.0
        };
        let inv_dt = 1.0 / dt;
        let (mut kinetic, mut speed2) = (0.0, 0.0f64);
        for k in 0..self.x.len() {
            let mut new = self.cage_position(k);
            if w > 0.0 {
                new = add(new, scale(self.blend[k], w));
            }
            let vk = scale(sub(new, self.x[k]), inv_dt);
            let s2 = dot(vk, vk);
            kinetic += 0.5 * self.masses[k] * s2;
            speed2 = speed2.max(s2);
            self.x[k] = new;
            self.v[k] = vk;
        }
        self.kinetic = kinetic;
        self.speed = speed2.sqrt();
        // A NaN anywhere makes the energy NaN (max() would skip it).
        if !kinetic.is_finite() || !self.speed.is_finite() {
            self.reset();
            return Err(BlowUp::NonFinite);
        }
        if self.speed > RUNAWAY_SPEED {
            self.reset();
            return Err(BlowUp::Runaway);
        }
        Ok(report)
    }

    /// Copies the dynamics' cage into `self.cage`.
    fn sync_cage(&mut self) {
        match &self.dynamics {
            Dynamics::Projected(r) => {
                for (i, c) in self.cage.iter_mut().enumerate() {
                    *c = add(
                        self.rest_cage[i],
                        [r.q()[3 * i], r.q()[3 * i + 1], r.q()[3 * i + 2]],
                    );
                }
            }
            Dynamics::MassSpring(msd) => self.cage.copy_from_slice(msd.positions()),
        }
    }

    /// Node displacements (`disp`) from the current cage; held nodes have none.
    fn evaluate(&mut self) {
        self.gc.scaled_normals(&self.cage, &mut self.normals);
        let nv = self.cage.len();
        for (i, w) in self.w[..nv].iter_mut().enumerate() {
            let d = sub(self.cage[i], self.rest_cage[i]);
            *w = [d[0] as f32, d[1] as f32, d[2] as f32];
        }
        for (j, w) in self.w[nv..].iter_mut().enumerate() {
            let d = sub(self.normals[j], self.rest_normals[j]);
            *w = [d[0] as f32, d[1] as f32, d[2] as f32];
        }
        self.kernel.apply(&self.w, &mut self.disp);
    }
}
