//! The explicit integrators: `substeps` sub-steps of size `h` each, allocation-free (every
//! buffer comes from [`Scratch`]). Fixed and massless nodes have zero inverse mass, so their
//! acceleration is zero and, starting at rest, they never move.

use super::forces::{Loads, Network};
use super::Scratch;
use crate::contact::{add, scale};

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
