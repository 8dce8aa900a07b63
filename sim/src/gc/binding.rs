//! [`GcBinding`]: the coefficients of many points, laid out for the hot path.

/// Points per panel. Eight `f64` accumulators per coordinate (24 in all) measured fastest on
/// x86-64 with SSE2 only (2, 4, 16 per panel and plain column-major or row-major storage were
/// all slower).
pub(crate) const LANES: usize = 8;

/// Precomputed Green coordinates of a fixed set of points (e.g. every node of an organ's mesh)
/// with respect to one rest cage, made by
/// [`GreenCoordinates::bind`](super::GreenCoordinates::bind).
///
/// Deforming all points is then one small dense product, [`GcBinding::deform_into`]:
/// `η'_p = Σ_i φ_i(η_p) v'_i + Σ_j ψ_j(η_p) s_j n(t'_j)`.
///
/// # Layout
/// The points are grouped into panels of eight consecutive points (the last panel is padded with
/// zero coefficients). A panel stores its coefficient columns one after the other — the
/// `vertex_count` φ columns, then the `triangle_count` ψ columns — and each column holds the
/// eight points' values contiguously. So the hot loop streams one contiguous block of memory
/// and keeps 3 × 8 accumulators in registers while it runs over the columns. Use
/// [`GcBinding::phi`] and [`GcBinding::psi`] to read single coefficients.
#[derive(Debug, Clone, PartialEq)]
pub struct GcBinding {
    /// Number of bound points.
    points: usize,
    /// Number of cage vertices (φ columns).
    vertices: usize,
    /// Number of cage triangles (ψ columns).
    triangles: usize,
    /// `points.div_ceil(LANES)` panels of `(vertices + triangles) · LANES` values.
    coef: Vec<f64>,
}

impl GcBinding {
    /// An all-zero binding of `points` points to a cage of `vertices` vertices and `triangles`
    /// triangles; [`GcBinding::set`] fills it.
    pub(crate) fn zeroed(points: usize, vertices: usize, triangles: usize) -> GcBinding {
        let panels = points.div_ceil(LANES);
        GcBinding {
            points,
            vertices,
            triangles,
            coef: vec![0.0; panels * (vertices + triangles) * LANES],
        }
    }

    /// Position in `coef` of column `column` of point `point`.
    #[inline]
    fn at(&self, point: usize, column: usize) -> usize {
        let columns = self.vertices + self.triangles;
        (point / LANES) * columns * LANES + column * LANES + point % LANES
    }

    /// Stores the coordinates of point `point`.
    pub(crate) fn set(&mut self, point: usize, phi: &[f64], psi: &[f64]) {
        for (i, &v) in phi.iter().enumerate() {
            let k = self.at(point, i);
            self.coef[k] = v;
        }
        for (j, &v) in psi.iter().enumerate() {
            let k = self.at(point, self.vertices + j);
            self.coef[k] = v;
        }
    }

    /// Number of bound points.
    pub fn point_count(&self) -> usize {
        self.points
    }

    /// Number of cage vertices (φ coefficients per point).
    pub fn vertex_count(&self) -> usize {
        self.vertices
    }

    /// Number of cage triangles (ψ coefficients per point).
    pub fn triangle_count(&self) -> usize {
        self.triangles
    }

    /// `φ_vertex` of point `point` (both 0-based, in the order given to
    /// [`GreenCoordinates::bind`](super::GreenCoordinates::bind) and
    /// [`GreenCoordinates::new`](super::GreenCoordinates::new)).
    ///
    /// # Panics
    /// If `point ≥ point_count()` or `vertex ≥ vertex_count()`.
    pub fn phi(&self, point: usize, vertex: usize) -> f64 {
        assert!(
            point < self.points && vertex < self.vertices,
            "GcBinding::phi({point}, {vertex}): {} points, {} cage vertices",
            self.points,
            self.vertices
        );
        self.coef[self.at(point, vertex)]
    }

    /// `ψ_triangle` of point `point` (both 0-based).
    ///
    /// # Panics
    /// If `point ≥ point_count()` or `triangle ≥ triangle_count()`.
    pub fn psi(&self, point: usize, triangle: usize) -> f64 {
        assert!(
            point < self.points && triangle < self.triangles,
            "GcBinding::psi({point}, {triangle}): {} points, {} cage triangles",
            self.points,
            self.triangles
        );
        self.coef[self.at(point, self.vertices + triangle)]
    }

    /// Deformed positions of all bound points: `out[p] = Σ_i φ_i(p) v'_i + Σ_j ψ_j(p) s_j n(t'_j)`.
    ///
    /// `deformed_cage_vertices` are the cage vertices `v'_i` in their current positions (same
    /// order as the rest cage) and `scaled_normals` the `s_j n(t'_j)` of the same deformed cage,
    /// from [`GreenCoordinates::scaled_normals`](super::GreenCoordinates::scaled_normals).
    /// Allocation-free; this is the hot path (a few microseconds for ~550 points and a box
    /// cage). Non-finite input gives non-finite output, never a panic.
    ///
    /// # Panics
    /// If `deformed_cage_vertices.len() != vertex_count()`,
    /// `scaled_normals.len() != triangle_count()` or `out.len() != point_count()`.
    pub fn deform_into(
        &self,
        deformed_cage_vertices: &[[f64; 3]],
        scaled_normals: &[[f64; 3]],
        out: &mut [[f64; 3]],
    ) {
        assert_eq!(
            deformed_cage_vertices.len(),
            self.vertices,
            "deform_into: one deformed position per cage vertex"
        );
        assert_eq!(
            scaled_normals.len(),
            self.triangles,
            "deform_into: one scaled normal per cage triangle"
        );
        assert_eq!(
            out.len(),
            self.points,
            "deform_into: one output per bound point"
        );
        let panel_len = (self.vertices + self.triangles) * LANES;
        for (panel, coef) in self.coef.chunks_exact(panel_len).enumerate() {
            let (phi, psi) = coef.split_at(self.vertices * LANES);
            let mut x = [0.0; LANES];
            let mut y = [0.0; LANES];
            let mut z = [0.0; LANES];
            accumulate(phi, deformed_cage_vertices, &mut x, &mut y, &mut z);
            accumulate(psi, scaled_normals, &mut x, &mut y, &mut z);
            // Indexed writes: zipping the panels with `out.chunks_mut(LANES)` measured 30 %
            // slower (the accumulators no longer stayed in registers).
            let base = panel * LANES;
            let valid = out.len().saturating_sub(base).min(LANES);
            for k in 0..valid {
                out[base + k] = [x[k], y[k], z[k]];
            }
        }
    }
}

/// `x/y/z[k] += Σ_c columns[c][k] · w[c]` over the columns of one panel.
#[inline(always)]
fn accumulate(
    columns: &[f64],
    w: &[[f64; 3]],
    x: &mut [f64; LANES],
    y: &mut [f64; LANES],
    z: &mut [f64; LANES],
) {
    let (columns, _) = columns.as_chunks::<LANES>();
    for (c, w) in columns.iter().zip(w) {
        for k in 0..LANES {
            x[k] += c[k] * w[0];
            y[k] += c[k] * w[1];
            z[k] += c[k] * w[2];
        }
    }
}
