//! 3-vector helpers on `[f64; 3]` for the code whose storage is plain arrays (models, meshes,
//! the world), computed with [`glam::DVec3`]: the geometry modules (contact, haptic, collide)
//! use `DVec3` directly and convert at their boundaries with [`v`] and `to_array`.
//!
//! Bit-for-bit the plain-array arithmetic they replace: glam's `f64` vectors are scalar
//! structs, `+ - *` are per component, `dot` is `(x·x') + (y·y') + (z·z')` left to right,
//! `cross` is the usual formula (products commute exactly), and no `mul_add` is used.
//! `normalize()` multiplies by `1 / length`: callers that divide write `v * (1.0 / l)` or
//! `v / l` explicitly, as the original code did.

use glam::DVec3;

/// `[f64; 3]` → `DVec3`.
#[inline(always)]
pub(crate) fn v(a: [f64; 3]) -> DVec3 {
    DVec3::from_array(a)
}

#[inline]
pub(crate) fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    (v(a) - v(b)).to_array()
}
#[inline]
pub(crate) fn add(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    (v(a) + v(b)).to_array()
}
#[inline]
pub(crate) fn scale(a: [f64; 3], s: f64) -> [f64; 3] {
    (v(a) * s).to_array()
}
#[inline]
pub(crate) fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    v(a).dot(v(b))
}
#[inline]
pub(crate) fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    v(a).cross(v(b)).to_array()
}
#[inline]
pub(crate) fn norm(a: [f64; 3]) -> f64 {
    v(a).length()
}
