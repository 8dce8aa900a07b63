//! The interface every deformation model offers the world (and, later, the levels-of-precision
//! controller): state access, one step under loads and the tool, energy measures, reset and
//! state transfer. Models are a closed set, so this is an enum, not a trait object: dispatch is a
//! match, and each model keeps its own concrete API for tests and benchmarks.
//!
//! Contract for every model's `step`:
//! - advances by the model's own `dt` under `gravity`, the nodal loads and the tool contact;
//! - fixed (Dirichlet) nodes never move;
//! - allocation-free after the first steps;
//! - on a blow-up (a non-finite value, or a node faster than [`RUNAWAY_SPEED`]) the model resets
//!   to rest and returns the cause, so nothing non-finite ever leaves it.
//!
//! What a step takes and returns (tool contact, contact springs, reports, blow-ups) lives in
//! [`crate::interaction`], which the models import; it is re-exported here.

use crate::fem::FemMode;
pub use crate::interaction::{
    BlowUp, ContactReport, ContactSpring, ToolAnchor, ToolContact, RUNAWAY_SPEED,
};
use crate::lop::{
    CageDynamics, CageModel, CageModelError, Damping, GcParameters, PreciseOperators, Prestress,
};
use crate::mesh::{extents, TetMesh};
use crate::msd::MassSpring;
use crate::vec3::{add, scale, sub};

/// Which model a body runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ModelKind {
    /// Mass-spring-damper.
    MassSpring,
    /// Finite elements.
    Fem,
    /// Green-coordinates cage.
    Gc,
}

/// Which model a body is held to, or [`ModelPin::Auto`] to let the levels-of-precision
/// controller choose; a scene's `[[body]] model` (`"auto"`, `"gc"`, `"msd"`, `"fem"`) and the
/// control service's pin. A pin names a [`ModelKind`] ([`ModelPin::kind`]) or none.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "kebab-case"))]
pub enum ModelPin {
    /// The LoP controller decides: GC at rest, FEM or MSD (by importance) when touched.
    #[default]
    Auto,
    /// Always Green coordinates.
    Gc,
    /// Always mass-spring-damper.
    Msd,
    /// Always FEM.
    Fem,
}

impl ModelPin {
    /// The model the pin holds the body to; `None` for [`ModelPin::Auto`].
    pub fn kind(self) -> Option<ModelKind> {
        match self {
            ModelPin::Auto => None,
            ModelPin::Gc => Some(ModelKind::Gc),
            ModelPin::Msd => Some(ModelKind::MassSpring),
            ModelPin::Fem => Some(ModelKind::Fem),
        }
    }
}

/// A body's deformation model.
#[derive(Debug, Clone)]
pub enum Model {
    /// Mass-spring-damper.
    MassSpring(MassSpring),
    /// Finite elements (linear or corotational).
    Fem(crate::fem::Fem),
    /// Green-coordinates cage (boxed: it is large and rarely moved).
    Gc(Box<CageModel>),
}

macro_rules! dispatch {
    ($self:ident, $m:ident => $e:expr) => {
        match $self {
            Model::MassSpring($m) => $e,
            Model::Fem($m) => $e,
            Model::Gc($m) => $e,
        }
    };
}

impl Model {
    /// Which model this is.
    pub fn kind(&self) -> ModelKind {
        match self {
            Model::MassSpring(_) => ModelKind::MassSpring,
            Model::Fem(_) => ModelKind::Fem,
            Model::Gc(_) => ModelKind::Gc,
        }
    }
    /// Node positions, m.
    pub fn positions(&self) -> &[[f64; 3]] {
        dispatch!(self, m => m.positions())
    }
    /// Node velocities, m/s.
    pub fn velocities(&self) -> &[[f64; 3]] {
        dispatch!(self, m => m.velocities())
    }
    /// Lumped nodal masses, kg.
    pub fn masses(&self) -> &[f64] {
        dispatch!(self, m => m.masses())
    }
    /// The model's time step, s.
    pub fn dt(&self) -> f64 {
        dispatch!(self, m => m.dt())
    }
    /// Kinetic energy, J.
    pub fn kinetic_energy(&self) -> f64 {
        dispatch!(self, m => m.kinetic_energy())
    }
    /// Largest nodal speed, m/s.
    pub fn max_speed(&self) -> f64 {
        dispatch!(self, m => m.max_speed())
    }
    /// Back to the rest shape, at rest.
    pub fn reset(&mut self) {
        dispatch!(self, m => m.reset())
    }
    /// One step (see the module docs for the contract).
    pub fn step(
        &mut self,
        gravity: [f64; 3],
        external: &[[f64; 3]],
        contact: Option<&ToolContact<'_>>,
    ) -> Result<ContactReport, BlowUp> {
        self.step_colliding(gravity, external, contact, &[])
    }
    /// [`Model::step`] with organ-to-organ contact springs acting too.
    pub fn step_colliding(
        &mut self,
        gravity: [f64; 3],
        external: &[[f64; 3]],
        contact: Option<&ToolContact<'_>>,
        springs: &[ContactSpring],
    ) -> Result<ContactReport, BlowUp> {
        dispatch!(self, m => m.step_colliding(gravity, external, contact, springs))
    }
    /// After a step whose report came from a contact patch (the report has a proxy): the
    /// patch's solved complementarity problem, from which [`crate::patch::report`] gives each
    /// of its tools' share (the step reports the first tool's). `None` for a model that
    /// resolves no patch.
    pub fn patch_solution(&mut self) -> Option<&mut crate::patch::Lcp> {
        match self {
            Model::MassSpring(m) => Some(m.patch_solution()),
            Model::Fem(m) => m.patch_solution(),
            Model::Gc(m) => m.patch_solution(),
        }
    }
    /// [`Model::patch_solution`] with the patch's grabs: the solve every tool of the last
    /// step's patch is reported from ([`crate::patch::PatchSolve::report`]).
    pub(crate) fn patch_solve(&mut self) -> Option<&mut crate::patch::PatchSolve> {
        match self {
            Model::MassSpring(m) => Some(m.patch_solve()),
            Model::Fem(m) => m.patch_solve(),
            Model::Gc(_) => None,
        }
    }
    /// Whether the model resolves grabs in its contact patch ([`crate::grasp`]): the precise
    /// models do, the cage does not.
    pub(crate) fn resolves_holds(&self) -> bool {
        !matches!(self, Model::Gc(_))
    }
    /// Sub-steps (or solver iterations) per step, for logs.
    pub fn substeps(&self) -> usize {
        match self {
            Model::MassSpring(m) => m.substeps(),
            Model::Fem(m) => m.substeps(),
            Model::Gc(_) => 1,
        }
    }
    /// Replaces positions and velocities (state transfer between levels of precision). Held
    /// nodes stay at rest. A cage fits itself to the shape (see [`CageModel::take_over`]).
    pub fn set_state(&mut self, x: &[[f64; 3]], v: &[[f64; 3]]) {
        match self {
            Model::MassSpring(m) => m.set_state(x, v),
            Model::Fem(m) => m.set_state(x, v),
            Model::Gc(m) => {
                m.take_over(x, v, 0.0);
            }
        }
    }
    /// `K u` of the model at rest (precise models), for reduced models built on it.
    pub fn rest_stiffness_product(&self, u: &[[f64; 3]]) -> Option<Vec<[f64; 3]>> {
        match self {
            Model::MassSpring(m) => Some(m.rest_stiffness_product(u)),
            Model::Fem(m) => Some(m.rest_stiffness_product(u)),
            Model::Gc(_) => None,
        }
    }
    /// How the model damps (precise models).
    pub fn damping(&self) -> Option<Damping> {
        match self {
            Model::MassSpring(m) => Some(Damping::PerNode(m.params().damping)),
            Model::Fem(m) => Some(Damping::MassProportional(m.parameters().damping)),
            Model::Gc(_) => None,
        }
    }
    /// Whether node `i` never moves.
    pub fn is_held(&self, i: usize) -> bool {
        match self {
            Model::MassSpring(m) => m.is_held(i),
            Model::Fem(m) => m.is_held(i),
            Model::Gc(_) => false,
        }
    }
}

// The cage's constructors from a precise `Model` live here, beside the enum, so that the cage
// (`crate::lop`) never imports `Model`: it is built from the operators a model hands it.
impl CageModel {
    /// Builds the GC model of `mesh` from its precise model (`Model::MassSpring` or
    /// `Model::Fem`): masses, held nodes, damping and rest stiffness come from it.
    pub fn from_precise(
        mesh: &TetMesh,
        params: GcParameters,
        precise: &Model,
    ) -> Result<CageModel, CageModelError> {
        CageModel::from_model(mesh, params, precise, None)
    }

    /// [`CageModel::new`] with the operators of `precise`, and `prestress` if given.
    fn from_model(
        mesh: &TetMesh,
        params: GcParameters,
        precise: &Model,
        prestress: Option<Prestress<'_>>,
    ) -> Result<CageModel, CageModelError> {
        let damping = precise.damping().ok_or_else(|| {
            CageModelError::Parameter("a cage needs a precise model to stand for".into())
        })?;
        let held: Vec<bool> = (0..mesh.nodes.len()).map(|i| precise.is_held(i)).collect();
        let stiffness = |u: &[[f64; 3]]| precise.rest_stiffness_product(u).unwrap_or_default();
        CageModel::new(
            mesh,
            params,
            &PreciseOperators {
                masses: precise.masses(),
                held: &held,
                damping,
                stiffness: &stiffness,
                prestress,
            },
        )
    }

    /// [`CageModel::from_precise`] for a body that lives under a constant `gravity` (a scene's):
    /// a projected cage is linearised about the precise model's equilibrium under it, with the
    /// *tangent* stiffness there, instead of about the rest shape. A soft, tall body sagging
    /// under its own weight is far more compliant sideways than at rest (the corotational FEM
    /// cylinder of Table 6.1 bends 2.3× farther under the same side load), which a cage built
    /// on the rest stiffness cannot follow. The equilibrium becomes the cage's own under that
    /// gravity; under a different gravity the cage is wrong by the difference, so use the
    /// scene's. Only a corotational FEM body has this effect and a static solver to find the
    /// equilibrium; for other bodies, zero gravity, or an equilibrium that cannot be found or
    /// whose tangent is not positive definite, this is [`CageModel::from_precise`].
    pub fn from_precise_under(
        mesh: &TetMesh,
        params: GcParameters,
        precise: &Model,
        gravity: [f64; 3],
    ) -> Result<CageModel, CageModelError> {
        let fem = match precise {
            Model::Fem(f)
                if f.parameters().mode == FemMode::Corotational
                    && gravity != [0.0; 3]
                    && params.dynamics == CageDynamics::Projected =>
            {
                f
            }
            _ => return CageModel::from_precise(mesh, params, precise),
        };
        let mut eq = fem.clone();
        eq.reset();
        if eq.solve_static(gravity, &[]).is_err() {
            return CageModel::from_precise(mesh, params, precise);
        }
        let x_g = eq.positions().to_vec();
        let n = x_g.len();
        let u_g: Vec<[f64; 3]> = (0..n).map(|k| sub(x_g[k], mesh.nodes[k])).collect();
        // Central differences of the elastic forces about the equilibrium. The step is 1e-7 of
        // the body's size: far below the equilibrium's own displacements, far above the
        // rounding of the forces.
        let size = extents(&mesh.nodes).into_iter().fold(0.0, f64::max);
        let h = 1e-7 * size;
        let zero = vec![[0.0; 3]; n];
        let probe = std::cell::RefCell::new(eq);
        let tangent = |u: &[[f64; 3]]| {
            let mut f = probe.borrow_mut();
            let shifted = |sign: f64| -> Vec<[f64; 3]> {
                (0..n).map(|k| add(x_g[k], scale(u[k], sign * h))).collect()
            };
            f.set_state(&shifted(1.0), &zero);
            let plus = f.elastic_forces();
            f.set_state(&shifted(-1.0), &zero);
            let minus = f.elastic_forces();
            plus.iter()
                .zip(&minus)
                .map(|(p, q)| scale(sub(*p, *q), -0.5 / h))
                .collect()
        };
        CageModel::from_model(
            mesh,
            params,
            precise,
            Some(Prestress {
                gravity,
                displacement: &u_g,
                tangent: &tangent,
            }),
        )
    }
}
