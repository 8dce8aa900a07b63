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

use crate::contact::{closest_on_surface, ToolSphere};
use crate::lop::{Damping, GcModel};
use crate::msd::MassSpring;
use crate::vec3::{add, dot, norm, scale, sub};

/// The tool's contact with a body during one step: the penalty spring is integrated inside the
/// sub-steps (the tool position is a kinematic boundary condition), which keeps a stiff tool on
/// light tissue stable.
#[derive(Debug, Clone, Copy)]
pub struct ToolContact<'a> {
    /// The tool tip.
    pub tool: ToolSphere,
    /// The body's outward surface triangles.
    pub surface: &'a [[u32; 3]],
    /// Indices into `surface` that may be touched this step (found by the caller around the
    /// closest triangle); only these are tested in each sub-step. Unused with an `anchor`.
    pub candidates: &'a [u32],
    /// Where the god-object holds the body, if it decides the contact (see [`ToolAnchor`]);
    /// `None`: the sphere presses on the closest candidate triangle.
    pub anchor: Option<ToolAnchor>,
}

/// The god-object's hold on a body for one step (the haptic loop's contact, thesis §5.2.1).
///
/// The god-object (the proxy of the tool tip, resting on the surface or holding it) sits at
/// `p + offset`, `p` the material point `bary` of `triangle`. The hand feels the law's force
/// along the gap `g = p + offset − c` (`c` the device/tool centre); the tissue receives exactly
/// the opposite at `p`, with `p` moving during the step — so the coupling is implicit in the
/// models (stable for a stiff tool on light tissue) and action equals reaction.
/// - Pressing (`grab: false`): only while the device is behind the proxy (`g · offset > 0`).
/// - Grabbing (`grab: true`): in every direction, pulling too.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ToolAnchor {
    /// Index into the body's surface triangles.
    pub triangle: u32,
    /// Barycentric weights of the material point.
    pub bary: [f64; 3],
    /// The god-object minus the material point, m.
    pub offset: [f64; 3],
    /// Holding the tissue (picking).
    pub grab: bool,
}

impl ToolAnchor {
    /// The anchor of a god-object at `proxy` on the material point `bary` of `triangle` of a
    /// surface at positions `x` (the offset from the point's current position). `None` if the
    /// triangle or weights are invalid.
    pub fn from_proxy(
        surface: &[[u32; 3]],
        x: &[[f64; 3]],
        triangle: u32,
        bary: [f64; 3],
        proxy: [f64; 3],
        grab: bool,
    ) -> Option<ToolAnchor> {
        let tri = surface.get(triangle as usize)?;
        if tri.iter().any(|&k| k as usize >= x.len())
            || !bary.iter().chain(proxy.iter()).all(|v| v.is_finite())
        {
            return None;
        }
        let [p0, p1, p2] = tri.map(|k| x[k as usize]);
        let p = add(
            add(scale(p0, bary[0]), scale(p1, bary[1])),
            scale(p2, bary[2]),
        );
        Some(ToolAnchor {
            triangle,
            bary,
            offset: sub(proxy, p),
            grab,
        })
    }
}

/// A unilateral penalty spring acting on one body during one step: organ-to-organ collision
/// (built by [`crate::collide::Collisions::add_springs`]).
///
/// It pushes the material point `p = Σ weights[k] · x[nodes[k]]` along the unit `normal` with
/// force `stiffness · (target − normal · p)` while that is positive. A penetrating vertex uses
/// one node (`nodes = [i, i, i]`, `weights = [1, 0, 0]`); the point of the other body's
/// surface it is in uses the three nodes of its triangle. The spring is active if it pushes at
/// the start of the step, and is then integrated implicitly over the step with that active set
/// (its stiffness enters the model's system matrix), so it holds stiff contacts on light tissue
/// without the `m/Δt²` limit of an explicit or position-based response.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactSpring {
    /// Nodes carrying the point.
    pub nodes: [u32; 3],
    /// Their weights (sum 1).
    pub weights: [f64; 3],
    /// Unit direction of the push.
    pub normal: [f64; 3],
    /// The spring pushes while `normal · p < target`, m.
    pub target: f64,
    /// N/m.
    pub stiffness: f64,
}

impl ContactSpring {
    /// The spring as a touch on positions `x`, if it pushes there (and its data is sound).
    pub(crate) fn touch(&self, x: &[[f64; 3]]) -> Option<Touch> {
        if self.nodes.iter().any(|&k| k as usize >= x.len()) {
            return None;
        }
        let mut p = [0.0; 3];
        for k in 0..3 {
            p = add(p, scale(x[self.nodes[k] as usize], self.weights[k]));
        }
        let gap = self.target - dot(self.normal, p);
        let f = self.stiffness * gap;
        if !(gap > 0.0) || !f.is_finite() || !self.normal.iter().all(|c| c.is_finite()) {
            return None;
        }
        Some(Touch {
            tri: self.nodes,
            weights: self.weights,
            normal: self.normal,
            depth: gap,
            on_tissue: scale(self.normal, f),
            stiffness: self.stiffness,
            isotropic: false,
        })
    }
}

/// What the tool did to a body over a step.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ContactReport {
    /// Force the tissue received at the end of the step, N (the hand feels the opposite).
    pub force_on_tissue: [f64; 3],
    /// Penetration depth at the end of the step, m.
    pub depth: f64,
}

/// Why a step was rejected and the body reset.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BlowUp {
    /// A position or velocity became NaN or infinite.
    NonFinite,
    /// A node moved faster than the runaway limit.
    Runaway,
}

/// Nodal speed above which a body is considered to have blown up, m/s. Tissue under a hand-held
/// tool moves at well under 1 m/s; 50 m/s only happens when integration diverges.
pub const RUNAWAY_SPEED: f64 = 50.0;

/// Which model a body runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ModelKind {
    /// Mass-spring-damper.
    MassSpring,
    /// Finite elements.
    Fem,
    /// Green-coordinates cage.
    Gc,
}

/// A body's deformation model.
#[derive(Debug, Clone)]
pub enum Model {
    /// Mass-spring-damper.
    MassSpring(MassSpring),
    /// Finite elements (linear or corotational).
    Fem(crate::fem::Fem),
    /// Green-coordinates cage (boxed: it is large and rarely moved).
    Gc(Box<GcModel>),
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
    /// Sub-steps (or solver iterations) per step, for logs.
    pub fn substeps(&self) -> usize {
        match self {
            Model::MassSpring(m) => m.substeps(),
            Model::Fem(m) => m.substeps(),
            Model::Gc(_) => 1,
        }
    }
    /// Replaces positions and velocities (state transfer between levels of precision). Held
    /// nodes stay at rest. A cage fits itself to the shape (see [`GcModel::take_over`]).
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

/// The tool touching the body: where, how deep, how hard.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Touch {
    /// Nodes of the touched triangle.
    pub tri: [u32; 3],
    /// Barycentric weights of the contact point on it.
    pub weights: [f64; 3],
    /// Unit outward normal.
    pub normal: [f64; 3],
    /// Penetration, m (> 0).
    pub depth: f64,
    /// Force the tissue receives, N.
    pub on_tissue: [f64; 3],
    /// `dF/dd` of the force law at this depth, N/m.
    pub stiffness: f64,
    /// The stiffness acts in every direction (the god-object's spring: `F = −k g` is linear in
    /// the point for the linear law, so its exact Jacobian is `k I`), not only along `normal`.
    pub isotropic: bool,
}

impl Touch {
    /// The push along the normal in the form of a [`ContactSpring`]'s touch, for a solver that
    /// resolves springs implicitly: `normal` the direction of the force on the tissue, `depth`
    /// the gap `F / k'` (so that `k'·(gap − change)` is the linearised force law), `stiffness`
    /// `k'`. `None` for an isotropic (grab) touch, a zero force or no stiffness.
    pub(crate) fn as_spring(&self) -> Option<Touch> {
        let f = norm(self.on_tissue);
        if self.isotropic || !(f > 0.0 && f.is_finite()) || !(self.stiffness > 0.0) {
            return None;
        }
        Some(Touch {
            normal: scale(self.on_tissue, 1.0 / f),
            depth: f / self.stiffness,
            ..*self
        })
    }
}

/// The tool's contact on positions `x`: the closest candidate triangle, if the tool penetrates
/// it. Allocation-free.
pub(crate) fn touch(c: &ToolContact<'_>, x: &[[f64; 3]]) -> Option<Touch> {
    if let Some(a) = c.anchor {
        return anchored_touch(c, a, x);
    }
    let mut best: Option<(usize, crate::contact::SurfaceHit)> = None;
    for &t in c.candidates {
        let Some(tri) = c.surface.get(t as usize) else {
            continue;
        };
        if let Some(hit) = closest_on_surface(x, std::slice::from_ref(tri), c.tool.center) {
            if best.is_none_or(|(_, b)| hit.distance < b.distance) {
                best = Some((t as usize, hit));
            }
        }
    }
    let (t, hit) = best?;
    let depth = c.tool.depth(&hit);
    if !(depth > 0.0) {
        return None;
    }
    Some(Touch {
        tri: c.surface[t],
        weights: hit.barycentric,
        normal: hit.normal,
        depth,
        on_tissue: scale(c.tool.force_on_tool(&hit), -1.0),
        stiffness: c.tool.max_stiffness(depth),
        isotropic: false,
    })
}

/// The tool's contact on positions `x` at the god-object's anchor (see [`ToolAnchor`]).
pub(crate) fn anchored_touch(c: &ToolContact<'_>, a: ToolAnchor, x: &[[f64; 3]]) -> Option<Touch> {
    let tri = *c.surface.get(a.triangle as usize)?;
    if tri.iter().any(|&k| k as usize >= x.len()) || !a.bary.iter().all(|w| w.is_finite()) {
        return None;
    }
    let [p0, p1, p2] = tri.map(|k| x[k as usize]);
    let w = a.bary;
    let p = add(add(scale(p0, w[0]), scale(p1, w[1])), scale(p2, w[2]));
    let g = sub(add(p, a.offset), c.tool.center);
    let depth = norm(g);
    if !(depth > 1e-12) || (!a.grab && !(dot(g, a.offset) > 0.0)) {
        return None;
    }
    let normal = scale(g, 1.0 / depth);
    let f = c.tool.force_magnitude(depth);
    if !(depth > 0.0) || !(f > 0.0) || !f.is_finite() {
        return None;
    }
    Some(Touch {
        tri,
        weights: w,
        normal,
        depth,
        on_tissue: scale(normal, -f),
        stiffness: c.tool.max_stiffness(depth),
        isotropic: true,
    })
}
