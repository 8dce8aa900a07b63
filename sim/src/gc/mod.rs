//! 3D Green coordinates: smooth, shape-preserving cage deformation of everything inside a
//! closed triangle cage.
//!
//! An organ that nobody touches is not simulated: its mesh follows a coarse *cage* — a closed
//! triangle surface around it — through Green coordinates (Lipman, Levin & Cohen-Or, "Green
//! Coordinates", ACM SIGGRAPH 2008, section 4 and appendix; analysed in Lipman & Levin,
//! "Derivation and Analysis of Green Coordinates", Computational Methods and Function Theory,
//! 2010): this module implements their closed form and guards its numerical traps (points near
//! the cage's faces and edges), as the notes below describe.
//!
//! # Definition
//! For a cage with vertices `v_i` and triangles `t_j` (unit outward normals `n(t_j)`), a point
//! `η` strictly inside it has one coordinate `φ_i(η)` per vertex and one `ψ_j(η)` per triangle:
//!
//! ```text
//! φ_i(η) = Σ_{t ∋ v_i} ∫_t Γ_i(ξ) (ξ−η)·n(t) / (4π|ξ−η|³) dσ     (Γ_i: hat function of v_i)
//! ψ_j(η) = ∫_{t_j} 1 / (4π|ξ−η|) dσ                                 (> 0)
//! η      = Σ_i φ_i(η) v_i + Σ_j ψ_j(η) n(t_j)
//! ```
//!
//! When the cage is deformed to `v'_i`, the point moves to
//!
//! ```text
//! η' = Σ_i φ_i(η) v'_i + Σ_j ψ_j(η) s_j n(t'_j)
//! s_j = sqrt(|u'|²|v|² − 2 (u'·v')(u·v) + |v'|²|u|²) / (√8 · area(t_j))
//! ```
//!
//! with `φ`, `ψ` of the rest cage, `u = v_b − v_a`, `v = v_c − v_a` the rest edges of
//! `t_j = (a, b, c)` and `u'`, `v'` the deformed ones. `s_j = sqrt((σ₁² + σ₂²)/2)` of the
//! triangle's rest-to-deformed map: 1 for a rigid motion, `k` for a uniform scale by `k`.
//!
//! Properties (all checked by the tests): the undeformed cage reproduces every interior point;
//! `Σ_i φ_i = 1` inside; a similarity transform of the cage (rotation, uniform scale,
//! translation) moves interior points by the same transform; `ψ_j > 0`, and `φ_i > 0` in a
//! convex cage. General affine maps are *not* reproduced: Green coordinates preserve shape
//! (they are conformal in 2D, quasi-conformal in 3D), so a stretch of the cage deforms the
//! interior less than an affine map would, by design.
//!
//! # Closed form
//! The integrals are evaluated per triangle in closed form — Urago's form, as given in the
//! appendix of Ben-Chen, Weber & Gotsman, "Variational Harmonic Maps for Space Deformation",
//! ACM SIGGRAPH 2009 — with the solid angle of Van Oosterom & Strackee (1983). For a triangle
//! `x_0, x_1, x_2` (outward, counter-clockwise), area `A`, unit normal `n`, indices mod 3:
//!
//! ```text
//! e_k = x_k − η,   r_k = |e_k|
//! Ω   = 2·atan2( e_0·(e_1×e_2),  r_0 r_1 r_2 + (e_0·e_1) r_2 + (e_0·e_2) r_1 + (e_1·e_2) r_0 )
//! h   = e_0 · n
//! edge opposite x_k:  d_k = x_{k+1} − x_{k+2},  L_k = |d_k|,  R_k = r_{k+1} + r_{k+2}
//! C_k = ln( (R_k + L_k) / (R_k − L_k) ) / (4π L_k)
//! J_k = e_{k+2} × e_{k+1}
//! ψ_t      = −(Ω/4π) h − Σ_k C_k (J_k · n)
//! P_t      = −(Ω/4π) n + Σ_k C_k (n × d_k)
//! φ_{x_k} += (P_t · J_k) / (2A)           for k = 0, 1, 2
//! ```
//!
//! Numerics, as the reference demands:
//! - `R_k − L_k` is never formed by subtraction (which loses every digit near a cage edge):
//!   it is `2|e_a×e_b|² / ((r_a r_b − e_a·e_b)(R + L))`, or the equal
//!   `2(r_a r_b + e_a·e_b) / (R + L)` where `e_a·e_b ≥ 0` (both free of cancellation), and the
//!   logarithm is taken as `ln_1p(2L / (R − L))`;
//! - the solid angle is a plain `atan2`, with no threshold that would depend on the cage's
//!   scale or drop its sign;
//! - nothing divides by the distance of `η` to a triangle's plane or to an edge line, unlike
//!   the paper's pseudocode (`GCTriInt`): the centre of a box, whose projection lands on the
//!   diagonal of every face, is an ordinary point;
//! - within a few percent of a triangle's edge (relative to the triangle), the two arguments
//!   of the solid angle's `atan2` are sums that cancel; there they are recomputed in
//!   double-double arithmetic from the same rounded `e_k`, so that the solid angles of the two
//!   triangles at the edge stay consistent. (In plain `f64` they are off by `~ε ℓ/δ` at a
//!   distance `δ`, which breaks `Σφ = 1` and the identity by ~10⁻⁸ at `δ = 10⁻⁹ ℓ`.)
//!
//! With these, points 10⁻⁹ (relative to the cage) from a face, an edge or a vertex keep the
//! identity and the partition of unity to ~10⁻¹⁵, as everywhere else inside.
//!
//! # Cages
//! A cage is a closed, oriented 2-manifold triangle surface wound outward: each triangle lists
//! its corners counter-clockwise seen from outside. [`GreenCoordinates::new`] checks, in this
//! order: at least 4 vertices and 4 triangles; vertex indices in range; finite vertices; no
//! degenerate (zero-area) triangle; every edge shared by exactly two triangles, traversed once
//! in each direction; no unused vertex; a positive enclosed volume (a negative one means the
//! cage is wound inward, which would make `Σφ = −1` and every deformation wrong). Each failure
//! is a [`CageError`] naming the element at fault. Self-intersection is not checked.
//!
//! Points on or outside the cage are not extrapolated (`Σφ = 0` outside, ½ on a face):
//! [`GreenCoordinates::bind`] rejects them, so pad the cage such that no mesh vertex lies on
//! it. [`box_cage`] (the thesis' cage), [`subdivided_box_cage`] and [`grid_box_cage`] build
//! padded boxes.
//!
//! # Use
//! Bind the mesh nodes once; per frame compute the deformed cage's scaled normals and deform
//! all nodes in one allocation-free product ([`GcBinding::deform_into`], a few microseconds for
//! ~550 nodes and a box cage):
//!
//! ```
//! use lop_sim::gc::{box_cage, GreenCoordinates};
//!
//! let nodes = vec![[0.0, 0.0, 0.0], [0.1, 0.02, 0.0], [0.05, 0.08, 0.03]];
//! let cage = box_cage(&nodes, 0.01);
//! let gc = GreenCoordinates::new(&cage.vertices, &cage.triangles)?;
//! let binding = gc.bind(&nodes)?;
//!
//! // Per frame: move the cage (here a translation), then the nodes follow.
//! let moved: Vec<[f64; 3]> = cage.vertices.iter().map(|v| [v[0] + 0.5, v[1], v[2]]).collect();
//! let mut normals = vec![[0.0; 3]; gc.triangle_count()];
//! let mut out = vec![[0.0; 3]; nodes.len()];
//! gc.scaled_normals(&moved, &mut normals);
//! binding.deform_into(&moved, &normals, &mut out);
//! assert!((out[1][0] - 0.6).abs() < 1e-12);
//! # Ok::<(), lop_sim::gc::CageError>(())
//! ```

mod binding;
mod cage;
mod closed_form;
mod dd;
mod error;

pub use binding::GcBinding;
pub use cage::{box_cage, grid_box_cage, subdivided_box_cage, Cage};
pub use error::CageError;

use closed_form::RestTriangle;

/// Tolerance of [`GreenCoordinates::bind`] on `|Σφ − 1|`. Inside, the sum is 1 to rounding
/// (~10⁻¹⁵); outside it is 0.
const INSIDE_TOL: f64 = 1e-6;

/// Green coordinates of a validated rest cage: computes `φ`, `ψ` of interior points, deforms
/// them, and binds many points for fast repeated deformation ([`GcBinding`]).
///
/// Holds the rest cage and, per triangle, its outward unit normal, its area and the rest edge
/// data of the scale factor `s_j`. See the [module docs](self) for the definitions.
#[derive(Debug, Clone, PartialEq)]
pub struct GreenCoordinates {
    /// Rest cage vertices, as given.
    vertices: Vec<[f64; 3]>,
    /// Cage triangles, as given.
    triangles: Vec<[usize; 3]>,
    /// Per-triangle precomputation, same order as `triangles`.
    rest: Vec<RestTriangle>,
}

impl GreenCoordinates {
    /// Validates the rest cage and precomputes its per-triangle data.
    ///
    /// `cage_vertices` are positions (m); `cage_triangles` index into them, each
    /// counter-clockwise seen from outside the cage.
    ///
    /// # Errors
    /// A [`CageError`] naming the first problem found, checked in this order: too few vertices
    /// or triangles, an index out of range, a non-finite vertex, a degenerate triangle, a
    /// non-manifold edge, an open edge, inconsistent winding, an unused vertex, no enclosed
    /// volume, inward winding. See the [module docs](self#cages).
    pub fn new(
        cage_vertices: &[[f64; 3]],
        cage_triangles: &[[usize; 3]],
    ) -> Result<GreenCoordinates, CageError> {
        cage::validate(cage_vertices, cage_triangles)?;
        let rest = cage_triangles
            .iter()
            .map(|t| RestTriangle::new(t.map(|i| cage_vertices[i])))
            .collect();
        Ok(GreenCoordinates {
            vertices: cage_vertices.to_vec(),
            triangles: cage_triangles.to_vec(),
            rest,
        })
    }

    /// [`GreenCoordinates::new`] of a [`Cage`].
    ///
    /// # Errors
    /// As [`GreenCoordinates::new`].
    pub fn from_cage(cage: &Cage) -> Result<GreenCoordinates, CageError> {
        GreenCoordinates::new(&cage.vertices, &cage.triangles)
    }

    /// The rest cage's vertices, as given to [`GreenCoordinates::new`].
    pub fn vertices(&self) -> &[[f64; 3]] {
        &self.vertices
    }

    /// The cage's triangles, as given to [`GreenCoordinates::new`].
    pub fn triangles(&self) -> &[[usize; 3]] {
        &self.triangles
    }

    /// Number of cage vertices (length of `φ`).
    pub fn vertex_count(&self) -> usize {
        self.vertices.len()
    }

    /// Number of cage triangles (length of `ψ`).
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// Outward unit normal of rest triangle `triangle`.
    ///
    /// # Panics
    /// If `triangle ≥ triangle_count()`.
    pub fn normal(&self, triangle: usize) -> [f64; 3] {
        self.rest[triangle].normal
    }

    /// Area of rest triangle `triangle` (m²).
    ///
    /// # Panics
    /// If `triangle ≥ triangle_count()`.
    pub fn area(&self, triangle: usize) -> f64 {
        self.rest[triangle].area
    }

    /// The Green coordinates of `point`: `φ` per cage vertex and `ψ` per cage triangle, in the
    /// order of the cage given to [`GreenCoordinates::new`].
    ///
    /// Meaningful for points strictly inside the cage. Outside it the same integrals are
    /// returned (`Σφ = 0` there), which do not reproduce the point; on the cage some values are
    /// infinite or NaN. Use [`GreenCoordinates::bind`] to have points checked.
    pub fn coordinates(&self, point: [f64; 3]) -> (Vec<f64>, Vec<f64>) {
        let mut phi = vec![0.0; self.vertex_count()];
        let mut psi = vec![0.0; self.triangle_count()];
        self.coordinates_into(point, &mut phi, &mut psi);
        (phi, psi)
    }

    /// [`GreenCoordinates::coordinates`] without allocation: overwrites `phi` (one entry per
    /// cage vertex) and `psi` (one per cage triangle).
    ///
    /// # Panics
    /// If `phi.len() != vertex_count()` or `psi.len() != triangle_count()`.
    pub fn coordinates_into(&self, point: [f64; 3], phi: &mut [f64], psi: &mut [f64]) {
        assert_eq!(
            phi.len(),
            self.vertex_count(),
            "phi: one entry per cage vertex"
        );
        assert_eq!(
            psi.len(),
            self.triangle_count(),
            "psi: one entry per cage triangle"
        );
        phi.fill(0.0);
        for ((tri, rest), psi) in self.triangles.iter().zip(&self.rest).zip(psi) {
            let ti = rest.integrals(point);
            for (&i, p) in tri.iter().zip(ti.phi) {
                phi[i] += p;
            }
            *psi = ti.psi;
        }
    }

    /// The deformed position `η' = Σ_i φ_i v'_i + Σ_j ψ_j s_j n(t'_j)` of the rest-space point
    /// `point`, with `φ`, `ψ` taken from the rest cage.
    ///
    /// Allocation-free (each triangle's contribution is applied as it is computed), but it
    /// evaluates the closed form: to move many points every frame, [`bind`](Self::bind) them
    /// once and use [`GcBinding::deform_into`]. For a point not strictly inside the rest cage
    /// the result is meaningless (see [`coordinates`](Self::coordinates)).
    ///
    /// # Panics
    /// If `deformed_cage_vertices.len() != vertex_count()`.
    pub fn deform(&self, point: [f64; 3], deformed_cage_vertices: &[[f64; 3]]) -> [f64; 3] {
        assert_eq!(
            deformed_cage_vertices.len(),
            self.vertex_count(),
            "deform: one deformed position per cage vertex"
        );
        let mut out = [0.0; 3];
        for (tri, rest) in self.triangles.iter().zip(&self.rest) {
            let ti = rest.integrals(point);
            let y = tri.map(|i| deformed_cage_vertices[i]);
            let sn = rest.scaled_normal(y);
            for a in 0..3 {
                out[a] += ti.phi[0] * y[0][a]
                    + ti.phi[1] * y[1][a]
                    + ti.phi[2] * y[2][a]
                    + ti.psi * sn[a];
            }
        }
        out
    }

    /// `s_j n(t'_j)` of every triangle of the deformed cage (same order as the triangles), for
    /// [`GcBinding::deform_into`]. Allocation-free.
    ///
    /// `n(t'_j)` is the deformed triangle's unit normal (same winding as at rest) and `s_j` its
    /// scale factor (module docs). A deformed triangle of zero area has no normal: its entry is
    /// the zero vector. Non-finite vertices give non-finite entries, never a panic.
    ///
    /// # Panics
    /// If `deformed_cage_vertices.len() != vertex_count()` or `out.len() != triangle_count()`.
    pub fn scaled_normals(&self, deformed_cage_vertices: &[[f64; 3]], out: &mut [[f64; 3]]) {
        assert_eq!(
            deformed_cage_vertices.len(),
            self.vertex_count(),
            "scaled_normals: one deformed position per cage vertex"
        );
        assert_eq!(
            out.len(),
            self.triangle_count(),
            "scaled_normals: one output per cage triangle"
        );
        for ((tri, rest), o) in self.triangles.iter().zip(&self.rest).zip(out) {
            *o = rest.scaled_normal(tri.map(|i| deformed_cage_vertices[i]));
        }
    }

    /// Precomputes `φ` and `ψ` of every point of `points` (e.g. all nodes of a mesh) into a
    /// [`GcBinding`], whose [`deform_into`](GcBinding::deform_into) moves them all at once.
    ///
    /// A point exactly on a face of the cage is a limit case: the solid angle of that face is
    /// `±2π` by the sign of a rounded zero, so the point is either rejected (`Σφ = 0`) or gets
    /// the limit of its coordinates from inside, which reproduce it. On an edge or a vertex
    /// some coordinates are infinite and the point is rejected. Pad the cage.
    ///
    /// # Errors
    /// [`CageError::PointNotInside`] for the first point that is not strictly inside the cage:
    /// its coordinates are not all finite, or `|Σφ − 1| > 10⁻⁶` (the sum is 1 inside to
    /// rounding, 0 outside). The error names the point's index, its coordinates and `Σφ`.
    pub fn bind(&self, points: &[[f64; 3]]) -> Result<GcBinding, CageError> {
        let mut binding =
            GcBinding::zeroed(points.len(), self.vertex_count(), self.triangle_count());
        let mut phi = vec![0.0; self.vertex_count()];
        let mut psi = vec![0.0; self.triangle_count()];
        for (p, &point) in points.iter().enumerate() {
            self.coordinates_into(point, &mut phi, &mut psi);
            let sum: f64 = phi.iter().sum();
            let finite = sum.is_finite() && psi.iter().all(|v| v.is_finite());
            if !(finite && (sum - 1.0).abs() <= INSIDE_TOL) {
                return Err(CageError::PointNotInside {
                    point: p,
                    position: point,
                    phi_sum: if finite { sum } else { f64::NAN },
                });
            }
            binding.set(p, &phi, &psi);
        }
        Ok(binding)
    }
}
