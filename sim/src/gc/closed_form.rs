//! The closed form of one triangle's Green-coordinate integrals (reference §3), and the
//! per-triangle scale factor `s_j` of the deformation (reference §2).

use std::f64::consts::PI;

use super::dd;
use crate::vec3::{add, cross, dot, norm, scale, sub};

/// `1 / (4π)`.
const INV_4PI: f64 = 0.25 / PI;

/// One rest-cage triangle with everything the closed form and `s_j` need that does not depend
/// on the evaluation point.
///
/// Corner `k` is `x[k]`; the edge *opposite* corner `k` runs from `x[k+1]` to `x[k+2]` (indices
/// mod 3).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct RestTriangle {
    /// The three corners, counter-clockwise seen from outside.
    x: [[f64; 3]; 3],
    /// Outward unit normal.
    pub(crate) normal: [f64; 3],
    /// Area.
    pub(crate) area: f64,
    /// `1 / (2 A)`.
    inv_two_area: f64,
    /// `L_k = |x[k+1] − x[k+2]|`, the length of the edge opposite corner `k`.
    len: [f64; 3],
    /// `1 / (4π L_k)`.
    inv_4pi_len: [f64; 3],
    /// `n × d_k` with `d_k = x[k+1] − x[k+2]`.
    n_cross_d: [[f64; 3]; 3],
    /// `|u|²`, `|v|²`, `u·v` of the rest edges `u = x1 − x0`, `v = x2 − x0`.
    uu: f64,
    vv: f64,
    uv: f64,
    /// `1 / (√8 A)`.
    inv_sqrt8_area: f64,
}

/// What one triangle contributes at one point: `φ` of its three corners (to be summed over the
/// triangles around each cage vertex) and its `ψ`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct TriangleIntegrals {
    /// Contribution to `φ` of corners 0, 1, 2.
    pub(crate) phi: [f64; 3],
    /// `ψ` of the triangle.
    pub(crate) psi: f64,
}

impl RestTriangle {
    /// Precomputes the triangle `x` (outward, counter-clockwise). The caller has checked that it
    /// is finite and not degenerate.
    pub(crate) fn new(x: [[f64; 3]; 3]) -> RestTriangle {
        let u = sub(x[1], x[0]);
        let v = sub(x[2], x[0]);
        let c = cross(u, v);
        let two_area = norm(c);
        let normal = scale(c, 1.0 / two_area);
        let mut len = [0.0; 3];
        let mut inv_4pi_len = [0.0; 3];
        let mut n_cross_d = [[0.0; 3]; 3];
        for k in 0..3 {
            let d = sub(x[(k + 1) % 3], x[(k + 2) % 3]);
            len[k] = norm(d);
            inv_4pi_len[k] = INV_4PI / len[k];
            n_cross_d[k] = cross(normal, d);
        }
        let area = 0.5 * two_area;
        RestTriangle {
            x,
            normal,
            area,
            inv_two_area: 1.0 / two_area,
            len,
            inv_4pi_len,
            n_cross_d,
            uu: dot(u, u),
            vv: dot(v, v),
            uv: dot(u, v),
            inv_sqrt8_area: 1.0 / (8f64.sqrt() * area),
        }
    }

    /// The closed form (reference §3) of `ψ_t(η) = ∫_t 1/(4π|ξ−η|) dσ` and of the three corner
    /// contributions `∫_t Γ_k(ξ) (ξ−η)·n / (4π|ξ−η|³) dσ` to `φ`, for a point `η` not on the
    /// triangle.
    ///
    /// No step divides by the distance of `η` to the triangle's plane or to an edge line, so a
    /// point whose projection lands on an edge line (the centre of a box) is fine, and points
    /// very close to the triangle, an edge or a corner keep their digits (see the comments).
    #[inline]
    pub(crate) fn integrals(&self, eta: [f64; 3]) -> TriangleIntegrals {
        let n = self.normal;
        let e = [
            sub(self.x[0], eta),
            sub(self.x[1], eta),
            sub(self.x[2], eta),
        ];
        let r = [norm(e[0]), norm(e[1]), norm(e[2])];
        let d01 = dot(e[0], e[1]);
        let d12 = dot(e[1], e[2]);
        let d20 = dot(e[2], e[0]);

        // Signed solid angle (Van Oosterom & Strackee 1983): atan2, never clamped or zeroed
        // below a threshold. It is > 0 for a point behind the outward normal and sums to 4π
        // inside the cage. Next to an edge its arguments are recomputed exactly (NEAR_EDGE).
        let mut triple = dot(e[0], cross(e[1], e[2]));
        let r012 = r[0] * r[1] * r[2];
        let mut denom = r012 + d01 * r[2] + d20 * r[1] + d12 * r[0];
        if triple * triple + denom * denom <= (NEAR_EDGE * r012) * (NEAR_EDGE * r012) {
            (triple, denom) = solid_angle_terms_dd(e);
        }
        let omega_4pi = 2.0 * triple.atan2(denom) * INV_4PI; // Ω / 4π

        let h = dot(e[0], n);
        let mut psi = -omega_4pi * h;
        let mut p = scale(n, -omega_4pi);
        let mut j = [[0.0; 3]; 3];
        // Edge opposite corner k: between e_a = e[k+1] and e_b = e[k+2].
        let dots = [d12, d20, d01];
        for k in 0..3 {
            let (a, b) = ((k + 1) % 3, (k + 2) % 3);
            let (ea, eb, ra, rb, ab) = (e[a], e[b], r[a], r[b], dots[k]);
            let big_r = ra + rb;
            let l = self.len[k];
            // R − L without subtraction: (R − L)(R + L) = R² − L² = 2 (r_a r_b + e_a·e_b)
            //   = 2 |e_a × e_b|² / (r_a r_b − e_a·e_b).
            // The second form (reference §4) keeps its digits near the edge, where
            // e_a·e_b → −r_a r_b; the first is the same number and keeps its digits where
            // e_a·e_b ≥ 0 (it also avoids 0/0 on the edge's line beyond its ends).
            let r_minus_l = if ab >= 0.0 {
                2.0 * (ra * rb + ab) / (big_r + l)
            } else {
                let c = cross(ea, eb);
                2.0 * dot(c, c) / ((ra * rb - ab) * (big_r + l))
            };
            // ln((R + L)/(R − L)) = ln(1 + 2L/(R − L)): ln_1p keeps the digits of a far edge.
            let ck = (2.0 * l / r_minus_l).ln_1p() * self.inv_4pi_len[k];
            let jk = cross(eb, ea); // J_k = e_{k+2} × e_{k+1}
            psi -= ck * dot(jk, n);
            p = add(p, scale(self.n_cross_d[k], ck));
            j[k] = jk;
        }
        TriangleIntegrals {
            phi: [
                dot(p, j[0]) * self.inv_two_area,
                dot(p, j[1]) * self.inv_two_area,
                dot(p, j[2]) * self.inv_two_area,
            ],
            psi,
        }
    }

    /// `s_j n(t'_j)` for the deformed corners `y` (reference §2):
    /// `s_j = sqrt(|u'|²|v|² − 2 (u'·v')(u·v) + |v'|²|u|²) / (√8 A)`.
    ///
    /// A deformed triangle of zero area has no normal: its term is the zero vector. Non-finite
    /// corners give non-finite components.
    #[inline]
    pub(crate) fn scaled_normal(&self, y: [[f64; 3]; 3]) -> [f64; 3] {
        let u = sub(y[1], y[0]);
        let v = sub(y[2], y[0]);
        let q = dot(u, u) * self.vv - 2.0 * dot(u, v) * self.uv + dot(v, v) * self.uu;
        // q ≥ 0 in exact arithmetic; rounding can make a collapsed triangle's q slightly
        // negative. Written so that NaN passes through.
        let q = if q < 0.0 { 0.0 } else { q };
        let s = q.sqrt() * self.inv_sqrt8_area;
        let c = cross(u, v);
        let len = norm(c);
        if len == 0.0 {
            return [0.0; 3];
        }
        scale(c, s / len)
    }
}

/// Below this value of `|(N, D)| / (r_0 r_1 r_2)` (the two arguments of the solid angle's
/// `atan2` relative to the size of their terms) they are recomputed in double-double.
///
/// `N` and `D` are sums of terms of size `r_0 r_1 r_2` that cancel to `O(δ/ℓ)` of it when the
/// point is at a distance `δ` from an edge of the triangle (length scale `ℓ`), and only there.
/// In `f64` the solid angle then carries an error of `~ε ℓ/δ`; the solid angles of the two
/// triangles at that edge no longer add up to what they should, and `Σφ = 1` and the identity
/// fail by ~1e-8 at `δ = 1e-9 ℓ`. With `N`, `D` exact for the rounded `e_k` (and the
/// double-double `r_k = |e_k|` consistent with them), the errors of neighbouring triangles are
/// consistent and cancel, and the results keep ~15 digits. Above the threshold plain `f64`
/// loses at most `~ε/NEAR_EDGE`.
const NEAR_EDGE: f64 = 1.0 / 16.0;

/// `N = e_0·(e_1×e_2)` and `D = r_0 r_1 r_2 + (e_0·e_1) r_2 + (e_0·e_2) r_1 + (e_1·e_2) r_0`
/// in double-double arithmetic from the `f64` vectors `e_k`, rounded to `f64` at the end.
#[cold]
fn solid_angle_terms_dd(e: [[f64; 3]; 3]) -> (f64, f64) {
    let r = e.map(|v| dd::dot(v, v).sqrt());
    let c = dd::cross(e[1], e[2]);
    let n = c[0]
        .mul_f64(e[0][0])
        .add(c[1].mul_f64(e[0][1]))
        .add(c[2].mul_f64(e[0][2]));
    let d = r[0]
        .mul(r[1])
        .mul(r[2])
        .add(dd::dot(e[0], e[1]).mul(r[2]))
        .add(dd::dot(e[0], e[2]).mul(r[1]))
        .add(dd::dot(e[1], e[2]).mul(r[0]));
    (n.hi, d.hi)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri() -> RestTriangle {
        RestTriangle::new([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.5, 1.5, 0.0]])
    }

    #[test]
    fn precomputed_geometry() {
        let t = tri();
        assert_eq!(t.normal, [0.0, 0.0, 1.0]);
        assert!((t.area - 1.5).abs() < 1e-15);
        assert!((t.len[2] - 2.0).abs() < 1e-15);
    }

    #[test]
    fn phi_of_one_triangle_sums_to_its_solid_angle() {
        // Σ_k φ_k = Ω/4π for any point: the edge terms cancel (Σ_k J_k = −2A n).
        let t = tri();
        for eta in [
            [0.3, 0.4, -0.7],
            [5.0, -3.0, -0.01],
            [0.6, 0.5, -1e-7],
            [1.0, 0.0, -2.0],
        ] {
            let ti = t.integrals(eta);
            let e: Vec<_> = t.x.iter().map(|&x| sub(x, eta)).collect();
            let r: Vec<_> = e.iter().map(|&v| norm(v)).collect();
            let omega = 2.0
                * dot(e[0], cross(e[1], e[2])).atan2(
                    r[0] * r[1] * r[2]
                        + dot(e[0], e[1]) * r[2]
                        + dot(e[0], e[2]) * r[1]
                        + dot(e[1], e[2]) * r[0],
                );
            let sum: f64 = ti.phi.iter().sum();
            assert!((sum - omega / (4.0 * PI)).abs() < 1e-14, "{eta:?}: {sum}");
            assert!(ti.psi > 0.0);
        }
    }

    #[test]
    fn double_double_solid_angle_agrees_with_f64_where_both_are_accurate() {
        // 1e-3 from the edge x0–x1: f64 still keeps ~12 digits of the angle.
        let t = tri();
        let eta = [0.7, 1e-3, -1e-3];
        let e = t.x.map(|x| sub(x, eta));
        let r = e.map(norm);
        let n = dot(e[0], cross(e[1], e[2]));
        let d = r[0] * r[1] * r[2]
            + dot(e[0], e[1]) * r[2]
            + dot(e[2], e[0]) * r[1]
            + dot(e[1], e[2]) * r[0];
        let (ndd, ddd) = solid_angle_terms_dd(e);
        assert!((n.atan2(d) - ndd.atan2(ddd)).abs() < 1e-11);
        assert!(
            n.hypot(d) < NEAR_EDGE * r[0] * r[1] * r[2],
            "takes the double-double path"
        );
    }

    #[test]
    fn point_on_the_line_of_an_edge_beyond_its_end_is_finite() {
        // e_a ∥ e_b, same direction: the cross-product form of R − L would be 0/0.
        let t = tri();
        let ti = t.integrals([3.0, 0.0, 0.0]);
        assert!(ti.phi.iter().all(|p| p.is_finite()) && ti.psi.is_finite());
    }

    #[test]
    fn scale_factor_of_rigid_scaled_and_collapsed_triangles() {
        let t = tri();
        let rot = |p: [f64; 3]| [-p[1] + 1.0, p[0] - 2.0, p[2] + 3.0]; // 90° about z + shift
        let y = t.x.map(rot);
        let sn = t.scaled_normal(y);
        assert!((norm(sn) - 1.0).abs() < 1e-14);
        let y = t.x.map(|p| scale(p, 3.0));
        assert!((norm(t.scaled_normal(y)) - 3.0).abs() < 1e-14);
        let flat = [[0.0; 3], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]];
        assert_eq!(t.scaled_normal(flat), [0.0; 3]);
        let nan = [[f64::NAN, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        assert!(t.scaled_normal(nan).iter().all(|c| c.is_nan()));
    }
}
