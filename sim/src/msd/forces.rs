//! Forces of the mass-spring model shared by every integrator: springs, gravity and external
//! loads (position-only), and the tool's penalty contact.

use crate::contact::{add, dot, norm, scale, sub};
pub(super) use crate::interaction::{touch, Touch};
use crate::interaction::{ContactSpring, ToolContact};

/// A spring between nodes `a < b`.
#[derive(Debug, Clone, Copy)]
pub(super) struct Spring {
    pub a: u32,
    pub b: u32,
    /// Rest length, m.
    pub rest: f64,
}

/// The body's fixed description: springs, masses and rest shape.
#[derive(Debug, Clone)]
pub(super) struct Network {
    /// Sorted by `(a, b)`, unique.
    pub springs: Vec<Spring>,
    /// N/m.
    pub stiffness: f64,
    /// γ, N·s/m.
    pub damping: f64,
    /// kg, one per node.
    pub mass: Vec<f64>,
    /// 1/kg; 0 for fixed and massless nodes, so the explicit integrators never move them.
    pub inv_mass: Vec<f64>,
    pub rest: Vec<[f64; 3]>,
}

/// What acts on the body during a step besides its springs.
pub(super) struct Loads<'a, 'c> {
    pub gravity: [f64; 3],
    /// N, one per node; missing entries are zero.
    pub external: &'a [[f64; 3]],
    pub contact: Option<&'a ToolContact<'c>>,
    /// Organ-to-organ contact springs.
    pub springs: &'a [ContactSpring],
}

impl Network {
    /// `out = M g + f_ext + f_spring(x)`: every force that depends on positions only.
    pub fn conservative_forces(&self, x: &[[f64; 3]], loads: &Loads<'_, '_>, out: &mut [[f64; 3]]) {
        for (i, f) in out.iter_mut().enumerate() {
            let ext = loads.external.get(i).copied().unwrap_or([0.0; 3]);
            *f = add(scale(loads.gravity, self.mass[i]), ext);
        }
        let k = self.stiffness;
        for s in &self.springs {
            let (a, b) = (s.a as usize, s.b as usize);
            let d = sub(x[b], x[a]);
            let len = norm(d);
            if len <= 0.0 {
                continue;
            }
            // Hooke's law along the spring (eq. 4.1).
            let f = scale(d, k * (len - s.rest) / len);
            out[a] = add(out[a], f);
            out[b] = sub(out[b], f);
        }
    }

    /// Adds the tool's penalty force at positions `x` into `force` (which holds the
    /// conservative forces), spread to the touched triangle's nodes by the barycentric weights,
    /// and makes its normal part implicit for the sub-step `h`: with `K = w² dF/dd` the node's
    /// stiffness along the normal `n`, the normal force `f_n` (damping at velocity `v`
    /// included) becomes `(f_n − h K v_n) / (1 + h² K / m)`, its linearised backward-Euler
    /// value, so the stiff tool cannot destabilise an explicit integrator.
    pub fn add_contact_explicit(
        &self,
        c: &ToolContact<'_>,
        x: &[[f64; 3]],
        v: &[[f64; 3]],
        force: &mut [[f64; 3]],
        h: f64,
    ) {
        if let Some(t) = touch(c, x) {
            self.add_touch_explicit(&t, v, force, h);
        }
    }

    /// [`Network::add_contact_explicit`] for a touch already found.
    pub fn add_touch_explicit(&self, t: &Touch, v: &[[f64; 3]], force: &mut [[f64; 3]], h: f64) {
        // Implicit along the normal; along every axis for a grab's isotropic spring.
        let axes = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        let dirs: &[[f64; 3]] = if t.isotropic {
            &axes
        } else {
            std::slice::from_ref(&t.normal)
        };
        for k in 0..3 {
            let i = t.tri[k] as usize;
            let w = t.weights[k];
            force[i] = add(force[i], scale(t.on_tissue, w));
            let inv_m = self.inv_mass[i];
            if inv_m == 0.0 {
                continue;
            }
            let kn = t.stiffness * w * w;
            for &n in dirs {
                let f_n = dot(sub(force[i], scale(v[i], self.damping)), n);
                let v_n = dot(v[i], n);
                let implicit = (f_n - h * kn * v_n) / (1.0 + h * h * kn * inv_m);
                force[i] = add(force[i], scale(n, implicit - f_n));
            }
        }
    }

    /// All forces at `(x, v)` except damping, for an explicit integrator with sub-step `h`:
    /// conservative forces plus the (normal-implicit) contact.
    pub fn forces(
        &self,
        x: &[[f64; 3]],
        v: &[[f64; 3]],
        loads: &Loads<'_, '_>,
        h: f64,
        out: &mut [[f64; 3]],
    ) {
        self.conservative_forces(x, loads, out);
        if let Some(c) = loads.contact {
            self.add_contact_explicit(c, x, v, out, h);
        }
        for s in loads.springs {
            if let Some(t) = s.touch(x) {
                self.add_touch_explicit(&t, v, out, h);
            }
        }
    }

    /// Acceleration of a node of inverse mass `inv_mass` under force `f`, damping at velocity
    /// `v` added; zero for fixed and massless nodes (`inv_mass == 0`).
    #[inline]
    pub fn accel(&self, f: [f64; 3], v: [f64; 3], inv_mass: f64) -> [f64; 3] {
        scale(sub(f, scale(v, self.damping)), inv_mass)
    }

    /// `Σ ½ k (l − L)²`, J.
    pub fn elastic_energy(&self, x: &[[f64; 3]]) -> f64 {
        self.springs
            .iter()
            .map(|s| {
                let stretch = norm(sub(x[s.b as usize], x[s.a as usize])) - s.rest;
                0.5 * self.stiffness * stretch * stretch
            })
            .sum()
    }
}
