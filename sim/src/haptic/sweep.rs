//! When a sphere moving along a segment first touches a triangle: the segment against the
//! triangle's Minkowski sum with the sphere — the triangle's plane pushed out by the radius on
//! its outward side, three capsules around the edges, three balls around the corners.

use glam::DVec3;

use crate::contact::{closest_bary, unit_normal};
use crate::vec3::v;

/// First contact of a moving sphere with a triangle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Impact {
    /// Fraction of the motion done at first contact, in `[0, 1]`.
    pub s: f64,
    /// Unit normal of the contact, from the triangle towards the sphere's centre.
    pub normal: [f64; 3],
}

/// Smallest root in `[0, 1]` of `a s² + b s + c = 0` entered from outside (`c ≥ 0` means the
/// start is outside the quadric); `Some(0)` when starting inside and moving inwards.
fn enter(a: f64, b: f64, c: f64) -> Option<f64> {
    if c <= 0.0 {
        // Starting on or inside: a contact now if the motion goes deeper.
        return (b < 0.0).then_some(0.0);
    }
    if !(a > 0.0) || b >= 0.0 {
        return None;
    }
    let disc = b * b - 4.0 * a * c;
    if disc < 0.0 {
        return None;
    }
    let s = (-b - disc.sqrt()) / (2.0 * a);
    (0.0..=1.0).contains(&s).then_some(s)
}

/// First contact of a sphere of radius `r` whose centre moves from `x` by `d` with triangle
/// `[a, b, c]` (counter-clockwise seen from outside). Only contacts the motion runs into count
/// (a sphere sliding along or leaving the triangle is free to go); the face is one-sided — a
/// sphere behind the triangle's plane passes through it, since it can only be there inside the
/// body.
pub fn sweep_sphere_triangle(
    x: [f64; 3],
    d: [f64; 3],
    r: f64,
    [a, b, c]: [[f64; 3]; 3],
) -> Option<Impact> {
    sweep(v(x), v(d), r, [v(a), v(b), v(c)]).map(|(s, normal)| Impact {
        s,
        normal: normal.to_array(),
    })
}

/// [`sweep_sphere_triangle`] on `DVec3`s: the fraction and the contact normal.
pub(crate) fn sweep(x: DVec3, d: DVec3, r: f64, [a, b, c]: [DVec3; 3]) -> Option<(f64, DVec3)> {
    let mut best: Option<(f64, DVec3)> = None;
    let mut consider = |s: f64, normal: DVec3| {
        if d.dot(normal) < 0.0 && best.is_none_or(|b| s < b.0) {
            best = Some((s, normal));
        }
    };
    // Face: the plane offset by r.
    let n = unit_normal(a, b, c);
    if n.length() > 0.0 {
        let h0 = (x - a).dot(n);
        let dn = d.dot(n);
        if h0 >= 0.0 && dn < 0.0 {
            let s = ((h0 - r) / -dn).max(0.0);
            if s <= 1.0 {
                let p = x + d * s;
                let q = p - n * (p - a).dot(n);
                let w = closest_bary(q, a, b, c);
                if w.iter().all(|&v| v > 0.0) {
                    consider(s, n);
                }
            }
        }
    }
    // Edges: capsules (the cylinder part; the ends are the corner balls).
    for (p0, p1) in [(a, b), (b, c), (c, a)] {
        let e = p1 - p0;
        let len = e.length();
        if !(len > 0.0) {
            continue;
        }
        let e = e * (1.0 / len);
        let m = x - p0;
        let mp = m - e * m.dot(e);
        let dp = d - e * d.dot(e);
        let (qa, qb, qc) = (dp.dot(dp), 2.0 * mp.dot(dp), mp.dot(mp) - r * r);
        if let Some(s) = enter(qa, qb, qc) {
            let p = x + d * s;
            let t = (p - p0).dot(e);
            if t > 0.0 && t < len {
                let axis = p0 + e * t;
                let off = p - axis;
                let l = off.length();
                if l > 0.0 {
                    consider(s, off * (1.0 / l));
                }
            }
        }
    }
    // Corners.
    for corner in [a, b, c] {
        let m = x - corner;
        if let Some(s) = enter(d.dot(d), 2.0 * m.dot(d), m.dot(m) - r * r) {
            let p = x + d * s;
            let off = p - corner;
            let l = off.length();
            if l > 0.0 {
                consider(s, off * (1.0 / l));
            }
        }
    }
    best
}

/// Direction of the line where two planes with unit normals `n1`, `n2` meet (zero if parallel).
pub(crate) fn crease(n1: DVec3, n2: DVec3) -> DVec3 {
    let u = n1.cross(n2);
    let l = u.length();
    if l > 1e-9 {
        u * (1.0 / l)
    } else {
        DVec3::ZERO
    }
}
