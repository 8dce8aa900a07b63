//! What passes between the world and a model's step: the tool's contact ([`ToolContact`],
//! [`ToolAnchor`]), organ-to-organ contact springs ([`ContactSpring`]), what a step reports back
//! ([`ContactReport`]) or why it was rejected ([`BlowUp`], [`RUNAWAY_SPEED`]), and the touch every
//! model resolves a contact into (`Touch`, `touch`, `anchored_touch`).
//!
//! A leaf: the models (`fem`, `msd`, `lop`'s cage) and the [`crate::model::Model`] enum that
//! dispatches to them all import it, and it imports only tool geometry and vector helpers.

use crate::contact::{closest_on_surface, off_triangle, unit_normal, ToolSphere};
pub use crate::patch::{PatchPoint, ToolPatch};
use crate::vec3::{add, dot, norm, scale, sub, v};
use glam::DVec3;

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
    /// The god-object's press as a contact patch over the tool's footprint (see
    /// [`crate::patch`]): when given, a model that resolves patches uses it instead of the
    /// anchor's point (FEM, mass-spring with every integrator and the projected cage do; the
    /// thesis' mass-spring cage keeps the anchor's point).
    pub patch: Option<ToolPatch<'a>>,
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
        if !proxy.iter().all(|v| v.is_finite()) {
            return None;
        }
        let mut a = ToolAnchor {
            triangle,
            bary,
            offset: [0.0; 3],
            grab,
        };
        a.offset = sub(proxy, a.point(surface, x)?);
        Some(a)
    }

    /// The material point on a surface at positions `x`; `None` if the triangle or the
    /// weights are invalid.
    pub fn point(&self, surface: &[[u32; 3]], x: &[[f64; 3]]) -> Option<[f64; 3]> {
        let tri = surface.get(self.triangle as usize)?;
        if tri.iter().any(|&k| k as usize >= x.len()) || !self.bary.iter().all(|w| w.is_finite()) {
            return None;
        }
        let [p0, p1, p2] = tri.map(|k| x[k as usize]);
        let w = self.bary;
        Some(add(add(scale(p0, w[0]), scale(p1, w[1])), scale(p2, w[2])))
    }

    /// The god-object on a surface at positions `x`: the material point plus the offset.
    pub fn proxy(&self, surface: &[[u32; 3]], x: &[[f64; 3]]) -> Option<[f64; 3]> {
        let p = add(self.point(surface, x)?, self.offset);
        p.iter().all(|c| c.is_finite()).then_some(p)
    }

    /// [`ToolAnchor::proxy`] for a press's patch by a sphere of `radius`, put back on the
    /// surface at `x`: between [`PATCH_CLEARANCE`] and one radius out from the anchor's
    /// triangle (away from its closest point; along its outward normal where the proxy is
    /// behind it).
    ///
    /// The haptic loop rests its proxy a radius out from the surface of the frame it renders,
    /// which is older than the tissue's state by at least one step. The patch's points are
    /// gathered around the proxy and take their directions from it ([`crate::patch`]), so:
    /// - where the tissue has since moved out towards the tool (it springs back while the hand
    ///   holds still, and more so the further the deformation lags the wall clock), that proxy
    ///   lies in or behind the surface: the points' directions point out of the tissue, the
    ///   solve balanced the sphere on the surface or behind it, and the haptic loop, resting
    ///   its proxy there, let the tool fall through;
    /// - where the last step's push moved the tissue away from it by more than the gathering's
    ///   margin ([`crate::patch::REACH_MARGIN`]), no point is in reach: the step has no
    ///   contact, the tissue springs back, the next step pushes again. Measured on the
    ///   two-handed grasp (2026-12-07, a liver stepping 2.3 ms for a 2 ms period): the hook's
    ///   steps alternated between 0.6 N on one point and none, and the hand held 0.8 N against
    ///   0.37 N in 3 runs of 8.
    ///
    /// Only the start of the patch's solve moves: its gaps are measured from the device, so
    /// where the sphere balances still follows from the device, the spring and the tissue.
    pub fn patch_proxy(
        &self,
        surface: &[[u32; 3]],
        x: &[[f64; 3]],
        radius: f64,
    ) -> Option<[f64; 3]> {
        let p = self.proxy(surface, x)?;
        let tri = surface.get(self.triangle as usize)?;
        let [a, b, c] = tri.map(|k| v(x[k as usize]));
        let n = unit_normal(a, b, c);
        let (_, d) = off_triangle(v(p), a, b, c);
        let q = v(p) - d;
        let len = d.length();
        let least = PATCH_CLEARANCE * radius;
        let outside = d.dot(n) > 0.0;
        let target = if outside {
            len.clamp(least, radius)
        } else {
            least
        };
        if n == DVec3::ZERO || (outside && target == len) || !target.is_finite() {
            return Some(p);
        }
        let away = if outside && len > 1e-9 * radius {
            d / len
        } else {
            n
        };
        let seated = q + away * target;
        seated.is_finite().then_some(seated.to_array())
    }
}

/// How close, in tool radii, a press's proxy may start a patch to its anchor's triangle
/// ([`ToolAnchor::patch_proxy`]; one radius is the farthest): a sphere resting on a face is a
/// radius out, a face point's allowance brings it in by a twentieth at most
/// ([`crate::patch`]).
pub const PATCH_CLEARANCE: f64 = 0.95;

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
    /// Penetration depth at the end of the step, m (a god-object contact: the length of the
    /// tool spring, |force| / stiffness).
    pub depth: f64,
    /// A contact patch's proxy (the tool sphere's centre) at the end of the step, m; `None`
    /// for a point contact.
    pub proxy: Option<[f64; 3]>,
    /// How a contact patch's force answers a move of the device (the haptic loop's local
    /// model between frames); `None` for a point contact.
    pub response: Option<PatchResponse>,
}

/// The linear response of a solved contact patch to the device, around the step's solution:
/// moving the device by `δ` from [`device`](Self::device) changes the force on the tissue by
/// `stiffness · δ` while the same points touch. It is the tool spring in series with the
/// tissue's compliance at the patch over one step of the model (the step's `K̃⁻¹`, inertia
/// and damping included), `N_S (Cᵀ K̃⁻¹ C + Nᵀ N / k)_SS⁻¹ N_Sᵀ` over the touching points
/// `S`: symmetric, positive semi-definite, and never stiffer than the tool spring.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PatchResponse {
    /// The device position the step balanced the patch against, m.
    pub device: [f64; 3],
    /// `∂(force on tissue) / ∂(device position)`, row-major, N/m.
    pub stiffness: [[f64; 3]; 3],
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
    let p = a.point(c.surface, x)?;
    let tri = c.surface[a.triangle as usize];
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
        weights: a.bary,
        normal,
        depth,
        on_tissue: scale(normal, -f),
        stiffness: c.tool.max_stiffness(depth),
        isotropic: true,
    })
}
