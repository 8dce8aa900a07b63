//! The explicit integrators: `substeps` sub-steps of size `h` each, allocation-free (every
//! buffer comes from [`Scratch`]). Fixed and massless nodes have zero inverse mass, so their
//! acceleration is zero and, starting at rest, they never move. With the tool's contact patch
//! ([`ExplicitPatch`]) every sub-step is followed by the patch's hard constraints.

use super::forces::{Loads, Network};
use super::Scratch;
use crate::contact::{add, scale};
use crate::interaction::ContactReport;
use crate::patch::{PatchSolve, ToolPatch, MAX_PATCH};

/// An explicit integrator: `substeps` sub-steps of size `h` of the body `State` under `Loads`.
pub(super) type Integrate = fn(&Network, State<'_>, &mut Scratch, &Loads<'_, '_>, f64, usize);

/// The body's state, advanced in place.
pub(super) struct State<'a> {
    pub x: &'a mut [[f64; 3]],
    pub v: &'a mut [[f64; 3]],
}

/// Forward Euler: `x += h v; v += h a(x, v)`, both from the old state.
pub(super) fn explicit_euler(
    net: &Network,
    s: State<'_>,
    scratch: &mut Scratch,
    loads: &Loads<'_, '_>,
    h: f64,
    substeps: usize,
) {
    let f = &mut scratch.force;
    for _ in 0..substeps {
        net.forces(s.x, s.v, loads, h, f);
        let nodes = s.x.iter_mut().zip(s.v.iter_mut());
        for ((x, v), (f, &w)) in nodes.zip(f.iter().zip(&net.inv_mass)) {
            let a = net.accel(*f, *v, w);
            *x = add(*x, scale(*v, h));
            *v = add(*v, scale(a, h));
        }
    }
}

/// Semi-implicit Euler: `v += h a(x, v); x += h v_new`.
pub(super) fn symplectic_euler(
    net: &Network,
    s: State<'_>,
    scratch: &mut Scratch,
    loads: &Loads<'_, '_>,
    h: f64,
    substeps: usize,
) {
    let f = &mut scratch.force;
    for _ in 0..substeps {
        net.forces(s.x, s.v, loads, h, f);
        let nodes = s.x.iter_mut().zip(s.v.iter_mut());
        for ((x, v), (f, &w)) in nodes.zip(f.iter().zip(&net.inv_mass)) {
            let a = net.accel(*f, *v, w);
            *v = add(*v, scale(a, h));
            *x = add(*x, scale(*v, h));
        }
    }
}

/// Velocity Verlet with symmetric damping:
///
/// ```text
/// v½ = v + ½h (F(x) / m − c v)                 explicit in damping
/// x' = x + h v½
/// v' = (v½ + ½h F(x') / m) / (1 + ½h c)         implicit in damping
/// ```
///
/// with `c = γ/m`. `F(x')` is kept in `scratch.force` for the next sub-step's first half-kick.
/// The contact's velocity-dependent part is added per half-kick into `scratch.total` (with
/// `v` in the first, `v½` in the second).
pub(super) fn verlet(
    net: &Network,
    s: State<'_>,
    scratch: &mut Scratch,
    loads: &Loads<'_, '_>,
    h: f64,
    substeps: usize,
) {
    let Scratch { force, total, .. } = scratch;
    let half = 0.5 * h;
    net.conservative_forces(s.x, loads, force);
    for _ in 0..substeps {
        let kick = kick_force(net, s.x, s.v, loads, h, force, total);
        let nodes = s.x.iter_mut().zip(s.v.iter_mut());
        for ((x, v), (f, &w)) in nodes.zip(kick.iter().zip(&net.inv_mass)) {
            let a = net.accel(*f, *v, w);
            *v = add(*v, scale(a, half));
            *x = add(*x, scale(*v, h));
        }
        net.conservative_forces(s.x, loads, force);
        let kick = kick_force(net, s.x, s.v, loads, h, force, total);
        for (v, (f, &w)) in s.v.iter_mut().zip(kick.iter().zip(&net.inv_mass)) {
            let v_half = add(*v, scale(*f, half * w));
            *v = scale(v_half, 1.0 / (1.0 + half * net.damping * w));
        }
    }
}

/// The force for a Verlet half-kick: `force` itself, or, in contact (tool or organ-to-organ),
/// `force` plus the contact loads, in `total`.
fn kick_force<'f>(
    net: &Network,
    x: &[[f64; 3]],
    v: &[[f64; 3]],
    loads: &Loads<'_, '_>,
    h: f64,
    force: &'f [[f64; 3]],
    total: &'f mut [[f64; 3]],
) -> &'f [[f64; 3]] {
    if loads.contact.is_none() && loads.springs.is_empty() {
        return force;
    }
    total.copy_from_slice(force);
    if let Some(c) = loads.contact {
        net.add_contact_explicit(c, x, v, total, h);
    }
    for s in loads.springs {
        if let Some(t) = s.touch(x) {
            net.add_touch_explicit(&t, v, total, h);
        }
    }
    total
}

/// Classic RK4 on `(x, v)`: four force evaluations at the stage states, the derivatives
/// accumulated as `k1 + 2 k2 + 2 k3 + k4` in `acc_x` / `acc_v`.
pub(super) fn rk4(
    net: &Network,
    s: State<'_>,
    scratch: &mut Scratch,
    loads: &Loads<'_, '_>,
    h: f64,
    substeps: usize,
) {
    let Scratch {
        force,
        xs,
        vs,
        acc_x,
        acc_v,
        ..
    } = scratch;
    let n = s.x.len();
    for _ in 0..substeps {
        // k1 at (x, v).
        net.forces(s.x, s.v, loads, h, force);
        for i in 0..n {
            let a = net.accel(force[i], s.v[i], net.inv_mass[i]);
            acc_x[i] = s.v[i];
            acc_v[i] = a;
            xs[i] = add(s.x[i], scale(s.v[i], 0.5 * h));
            vs[i] = add(s.v[i], scale(a, 0.5 * h));
        }
        // k2 and k3 at the two midpoint stages, then the end stage.
        for (weight, next) in [(2.0, 0.5 * h), (2.0, h)] {
            net.forces(xs, vs, loads, h, force);
            for i in 0..n {
                let a = net.accel(force[i], vs[i], net.inv_mass[i]);
                acc_x[i] = add(acc_x[i], scale(vs[i], weight));
                acc_v[i] = add(acc_v[i], scale(a, weight));
                xs[i] = add(s.x[i], scale(vs[i], next));
                vs[i] = add(s.v[i], scale(a, next));
            }
        }
        // k4 and the update.
        net.forces(xs, vs, loads, h, force);
        for i in 0..n {
            let a = net.accel(force[i], vs[i], net.inv_mass[i]);
            let dx = add(acc_x[i], vs[i]);
            let dv = add(acc_v[i], a);
            s.x[i] = add(s.x[i], scale(dx, h / 6.0));
            s.v[i] = add(s.v[i], scale(dv, h / 6.0));
        }
    }
}

/// The tool's contact patch (see [`crate::patch`]) in the explicit integrators: each sub-step
/// first advances without the tool, then holds the patch as hard unilateral constraints on the
/// positions. Over a sub-step `h` a force `C λ` on the lumped masses moves the nodes by
/// `h² M⁻¹ C λ` and changes their velocities by `h M⁻¹ C λ` (the impulse `h C λ` of a
/// sub-step's constant force, taken at its end as symplectic Euler takes every force), so
/// the gaps after the sub-step are `w = q + A λ` with `A = h² Cᵀ M⁻¹ C + Nᵀ N / k`, `q` the
/// gaps of the sub-step without the tool. Held nodes have no inverse mass: they add no
/// compliance and are not corrected. `A`'s mass part is the same for every sub-step of a step
/// (same points, same `h`), so it is built once per step and copied into each sub-step's
/// problem. What the last sub-step's forces did is the step's report.
#[derive(Debug, Clone)]
pub(super) struct ExplicitPatch {
    /// The complementarity problem (no unknowns of its own: the correction is applied node by
    /// node here).
    pub(super) solve: PatchSolve,
    /// `h² Cᵀ M⁻¹ C` of this step's patch, column-major; sized for [`MAX_PATCH`] points.
    a: Vec<f64>,
    /// What the last step's patch did.
    pub report: Option<ContactReport>,
}

impl ExplicitPatch {
    /// The last sub-step's complementarity problem (see [`MassSpring::patch_solution`]).
    ///
    /// [`MassSpring::patch_solution`]: super::MassSpring::patch_solution
    pub fn solution(&mut self) -> &mut crate::patch::Lcp {
        &mut self.solve.lcp
    }

    pub fn new() -> ExplicitPatch {
        ExplicitPatch {
            solve: PatchSolve::new(0),
            a: Vec::with_capacity(MAX_PATCH * MAX_PATCH),
            report: None,
        }
    }

    /// `substeps` sub-steps of `integrate` under `loads` (which must not carry the tool), each
    /// followed by the patch's correction. An unusable patch (no points, a bad spring) applies
    /// no force, as in the implicit step.
    #[allow(clippy::too_many_arguments)]
    pub fn step(
        &mut self,
        integrate: Integrate,
        net: &Network,
        s: State<'_>,
        scratch: &mut Scratch,
        loads: &Loads<'_, '_>,
        patch: &ToolPatch<'_>,
        h: f64,
        substeps: usize,
    ) {
        let State { x, v } = s;
        let Some(patch) = PatchSolve::limit(patch) else {
            integrate(net, State { x, v }, scratch, loads, h, substeps);
            self.report = Some(ContactReport::default());
            return;
        };
        let m = patch.points.len();
        let inv_mass = |k: u32| net.inv_mass.get(k as usize).copied().unwrap_or(0.0);
        self.solve.lcp.reset(m);
        self.solve.matrix_lumped(&patch, inv_mass, h * h);
        self.a.clear();
        self.a.extend_from_slice(self.solve.lcp.matrix());
        let mut report = ContactReport::default();
        for _ in 0..substeps {
            let s = State {
                x: &mut *x,
                v: &mut *v,
            };
            integrate(net, s, scratch, loads, h, 1);
            self.solve.begin(&patch, |k| {
                x.get(k as usize).copied().unwrap_or([f64::NAN; 3])
            });
            self.solve.lcp.matrix().copy_from_slice(&self.a);
            if !self.solve.solve(&patch) {
                report = ContactReport::default();
                continue;
            }
            let lambda = self.solve.lcp.lambda();
            for (p, &l) in patch.points.iter().zip(lambda) {
                if l == 0.0 {
                    continue;
                }
                for (&k, &w) in p.nodes.iter().zip(&p.weights) {
                    let dv = scale(p.normal, h * inv_mass(k) * w * l);
                    if let (Some(xk), Some(vk)) = (x.get_mut(k as usize), v.get_mut(k as usize)) {
                        *vk = add(*vk, dv);
                        *xk = add(*xk, scale(dv, h));
                    }
                }
            }
            // The grabs' forces (`crate::grasp`), spread over their nodes by their weights.
            for (i, hold) in patch.holds.iter().enumerate() {
                let f = self.solve.holds.force(i);
                for (k, w) in hold.terms() {
                    let dv = scale(f, h * inv_mass(k) * w);
                    if let (Some(xk), Some(vk)) = (x.get_mut(k as usize), v.get_mut(k as usize)) {
                        *vk = add(*vk, dv);
                        *xk = add(*xk, scale(dv, h));
                    }
                }
            }
            report = self.solve.report(&patch, 0);
        }
        self.report = Some(report);
    }
}
