//! When a sphere moving along a segment first touches a triangle: the segment against the
//! triangle's Minkowski sum with the sphere — the triangle's plane pushed out by the radius on
//! its outward side, three capsules around the edges, three balls around the corners.

use crate::contact::{closest_point_on_triangle, triangle_normal};
use crate::vec3::{add, cross, dot, norm, scale, sub};

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
    let mut best: Option<Impact> = None;
    let mut consider = |s: f64, normal: [f64; 3]| {
        if dot(d, normal) < 0.0 && best.is_none_or(|b| s < b.s) {
            best = Some(Impact { s, normal });
        }
    };
    // Face: the plane offset by r.
    let n = triangle_normal(a, b, c);
    if norm(n) > 0.0 {
        let h0 = dot(sub(x, a), n);
        let dn = dot(d, n);
        if h0 >= 0.0 && dn < 0.0 {
            let s = ((h0 - r) / -dn).max(0.0);
            if s <= 1.0 {
                let p = add(x, scale(d, s));
                let q = sub(p, scale(n, dot(sub(p, a), n)));
                let w = closest_point_on_triangle(q, a, b, c);
                if w.iter().all(|&v| v > 0.0) {
                    consider(s, n);
                }
            }
        }
    }
    // Edges: capsules (the cylinder part; the ends are the corner balls).
    for (p0, p1) in [(a, b), (b, c), (c, a)] {
        let e = sub(p1, p0);
        let len = norm(e);
        if !(len > 0.0) {
            continue;
        }
        let e = scale(e, 1.0 / len);
        let m = sub(x, p0);
        let mp = sub(m, scale(e, dot(m, e)));
        let dp = sub(d, scale(e, dot(d, e)));
        let (qa, qb, qc) = (dot(dp, dp), 2.0 * dot(mp, dp), dot(mp, mp) - r * r);
        if let Some(s) = enter(qa, qb, qc) {
            let p = add(x, scale(d, s));
            let t = dot(sub(p, p0), e);
            if t > 0.0 && t < len {
                let axis = add(p0, scale(e, t));
                let off = sub(p, axis);
                let l = norm(off);
                if l > 0.0 {
                    consider(s, scale(off, 1.0 / l));
                }
            }
        }
    }
    // Corners.
    for v in [a, b, c] {
        let m = sub(x, v);
        if let Some(s) = enter(dot(d, d), 2.0 * dot(m, d), dot(m, m) - r * r) {
            let p = add(x, scale(d, s));
            let off = sub(p, v);
            let l = norm(off);
            if l > 0.0 {
                consider(s, scale(off, 1.0 / l));
            }
        }
    }
    best
}

/// Direction of the line where two planes with unit normals `n1`, `n2` meet (zero if parallel).
pub(crate) fn crease(n1: [f64; 3], n2: [f64; 3]) -> [f64; 3] {
    let u = cross(n1, n2);
    let l = norm(u);
    if l > 1e-9 {
        scale(u, 1.0 / l)
    } else {
        [0.0; 3]
    }
}
