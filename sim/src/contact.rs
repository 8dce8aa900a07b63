//! Tool-to-surface geometry shared by the haptic loop and the deformation process.
//!
//! Everything here is allocation-free and works on borrowed slices, so the 1 kHz loop can call it
//! on the positions it maps straight from shared memory (`f32`) as well as the deformation
//! process on its own state (`f64`).
//!
//! The arithmetic is on [`glam::DVec3`]; the public types stay `[f64; 3]` (they cross into
//! the models, the daemon and the wire), converted at the boundary. Bit for bit the plain-array
//! code it replaced (see `vec3`).
//!
//! # parry3d for tool queries
//! parry3d-f64's `TriMesh` point queries are faster than the god-object's walk plus hierarchy
//! ([`SurfaceSet::closest_in_body`](crate::haptic::SurfaceSet::closest_in_body)), but not
//! adopted: the haptic loop would also have to bring parry's mesh up to date with each new frame,
//! which allocates (with the pseudo-normals its inside test needs) or alone exceeds the tick
//! budget (without them), where [`SurfaceSet`](crate::haptic::SurfaceSet) refits lazily, only
//! bodies in reach, without allocating; and its answers differ from [`closest_on_surface`]'s in
//! the last bits, which would change the shipped trajectories. Measured by `lop-bench collide`;
//! figures in `docs/benchmarks.md`, "Collision and tool queries against parry3d".

/// A position source: `f64` model state or `f32` frame data.
pub trait Positions {
    /// Position of node `i`, m.
    fn at(&self, i: usize) -> [f64; 3];
    /// Number of nodes.
    fn len(&self) -> usize;
    /// True if there are no nodes.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

// The plain-array helpers, for the models that import them from here.
use crate::vec3::v;
pub(crate) use crate::vec3::{add, dot, norm, scale, sub};
use glam::DVec3;

impl Positions for [[f64; 3]] {
    #[inline]
    fn at(&self, i: usize) -> [f64; 3] {
        self[i]
    }
    fn len(&self) -> usize {
        <[[f64; 3]]>::len(self)
    }
}

impl Positions for [[f32; 3]] {
    #[inline]
    fn at(&self, i: usize) -> [f64; 3] {
        let p = self[i];
        [p[0] as f64, p[1] as f64, p[2] as f64]
    }
    fn len(&self) -> usize {
        <[[f32; 3]]>::len(self)
    }
}

/// The closest point of a surface to a query point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceHit {
    /// Index of the closest triangle in the triangle slice searched.
    pub triangle: usize,
    /// The closest point on it, m.
    pub point: [f64; 3],
    /// Barycentric coordinates of `point` on the triangle (sum 1, each in [0, 1]).
    pub barycentric: [f64; 3],
    /// Unit outward normal of the triangle.
    pub normal: [f64; 3],
    /// Distance from the query to `point`, m.
    pub distance: f64,
    /// The query lies behind the closest triangle (inside the body), by the sign of
    /// `(query − point) · normal` as in thesis §5.2.
    pub inside: bool,
}

impl SurfaceHit {
    /// Signed distance: negative inside the body.
    pub fn signed_distance(&self) -> f64 {
        if self.inside {
            -self.distance
        } else {
            self.distance
        }
    }
}

/// Closest point on triangle `(a, b, c)` to `p`, as barycentric coordinates (Voronoi-region
/// walk, Ericson, *Real-Time Collision Detection* §5.1.5). Degenerate triangles fall back to
/// their closest edge or vertex.
pub fn closest_point_on_triangle(p: [f64; 3], a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> [f64; 3] {
    closest_bary(v(p), v(a), v(b), v(c))
}

/// [`closest_point_on_triangle`] on `DVec3`s.
pub(crate) fn closest_bary(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> [f64; 3] {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return [1.0, 0.0, 0.0];
    }
    let bp = p - b;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return [0.0, 1.0, 0.0];
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return [1.0 - v, v, 0.0];
    }
    let cp = p - c;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
    if d6 >= 0.0 && d5 <= d6 {
        return [0.0, 0.0, 1.0];
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return [1.0 - w, 0.0, w];
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return [0.0, 1.0 - w, w];
    }
    let denom = va + vb + vc;
    if !(denom.abs() > 0.0) || !denom.is_finite() {
        // Degenerate (zero-area) triangle: the regions above did not catch it; take vertex a.
        return [1.0, 0.0, 0.0];
    }
    let v = vb / denom;
    let w = vc / denom;
    [1.0 - v - w, v, w]
}

/// The point with barycentric weights `w` on triangle `(a, b, c)`: `a w₀ + b w₁ + c w₂`.
#[inline]
pub(crate) fn bary_point(a: DVec3, b: DVec3, c: DVec3, w: [f64; 3]) -> DVec3 {
    a * w[0] + b * w[1] + c * w[2]
}

/// The barycentric weights of the point of triangle `(a, b, c)` closest to `p`, and `p`'s
/// offset from that point.
#[inline]
pub(crate) fn off_triangle(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> ([f64; 3], DVec3) {
    let w = closest_bary(p, a, b, c);
    (w, p - bary_point(a, b, c, w))
}

/// Unit normal of triangle `(a, b, c)` (counter-clockwise → outward); zero for a degenerate one.
#[inline]
pub fn triangle_normal(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> [f64; 3] {
    unit_normal(v(a), v(b), v(c)).to_array()
}

/// [`triangle_normal`] on `DVec3`s. Divides as `n · (1 / |n|)`, which is what glam's
/// `normalize` does too, but with the zero check.
#[inline]
pub(crate) fn unit_normal(a: DVec3, b: DVec3, c: DVec3) -> DVec3 {
    let n = (b - a).cross(c - a);
    let l = n.length();
    if l > 0.0 {
        n * (1.0 / l)
    } else {
        DVec3::ZERO
    }
}

/// Closest point of a triangle surface to `p` by checking every triangle: exact, O(n), no
/// allocation. `offset` is added to triangle indices when addressing `positions` (so one body's
/// triangles can be searched in a frame that holds every body's nodes).
pub fn closest_on_surface<P: Positions + ?Sized>(
    positions: &P,
    triangles: &[[u32; 3]],
    p: [f64; 3],
) -> Option<SurfaceHit> {
    let mut best: Option<SurfaceHit> = None;
    let mut best_d2 = f64::INFINITY;
    let n = positions.len();
    let p = v(p);
    for (t, tri) in triangles.iter().enumerate() {
        let (ia, ib, ic) = (tri[0] as usize, tri[1] as usize, tri[2] as usize);
        if ia >= n || ib >= n || ic >= n {
            continue;
        }
        let (a, b, c) = (
            v(positions.at(ia)),
            v(positions.at(ib)),
            v(positions.at(ic)),
        );
        let bary = closest_bary(p, a, b, c);
        let q = bary_point(a, b, c, bary);
        let d = p - q;
        let d2 = d.dot(d);
        if d2 < best_d2 {
            best_d2 = d2;
            let normal = unit_normal(a, b, c);
            best = Some(SurfaceHit {
                triangle: t,
                point: q.to_array(),
                barycentric: bary,
                normal: normal.to_array(),
                distance: d2.sqrt(),
                inside: d.dot(normal) < 0.0,
            });
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closest_point_regions() {
        let (a, b, c) = ([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
        // Above the interior: projection.
        let w = closest_point_on_triangle([0.25, 0.25, 1.0], a, b, c);
        assert!((w[0] - 0.5).abs() < 1e-15 && (w[1] - 0.25).abs() < 1e-15);
        // Beyond vertex b.
        assert_eq!(
            closest_point_on_triangle([2.0, -1.0, 0.0], a, b, c),
            [0.0, 1.0, 0.0]
        );
        // Beyond edge bc: closest is its midpoint.
        let w = closest_point_on_triangle([1.0, 1.0, 0.0], a, b, c);
        assert!((w[1] - 0.5).abs() < 1e-15 && (w[2] - 0.5).abs() < 1e-15);
    }

    #[test]
    fn force_laws() {
        let mut tool = ToolSphere {
            center: [0.0; 3],
            radius: 0.003,
            stiffness: 300.0,
            law: ForceLaw::Linear,
        };
        assert!((tool.force_magnitude(0.002) - 0.6).abs() < 1e-12);
        assert_eq!(tool.force_magnitude(-1.0), 0.0);
        assert_eq!(tool.force_magnitude(f64::NAN), 0.0);
        tool.law = ForceLaw::Quadratic;
        tool.stiffness = 1e4;
        assert!((tool.force_magnitude(0.01) - 1.0).abs() < 1e-12);
        assert!((tool.max_stiffness(0.01) - 200.0).abs() < 1e-12);
        // A sphere centred 1 mm above a face (outside) penetrates radius − 1 mm.
        let hit = SurfaceHit {
            triangle: 0,
            point: [0.0; 3],
            barycentric: [1.0, 0.0, 0.0],
            normal: [0.0, 1.0, 0.0],
            distance: 0.001,
            inside: false,
        };
        tool.law = ForceLaw::Linear;
        tool.stiffness = 300.0;
        assert!((tool.depth(&hit) - 0.002).abs() < 1e-15);
        let f = tool.force_on_tool(&hit);
        assert!((f[1] - 0.6).abs() < 1e-12 && f[0] == 0.0 && f[2] == 0.0);
        // Inside by 1 mm: depth radius + 1 mm.
        let inside = SurfaceHit {
            inside: true,
            ..hit
        };
        assert!((tool.depth(&inside) - 0.004).abs() < 1e-15);
    }

    #[test]
    fn inside_outside_of_a_tetrahedron_surface() {
        // Outward-wound unit tetrahedron.
        let pos: Vec<[f64; 3]> = vec![[0., 0., 0.], [1., 0., 0.], [0., 1., 0.], [0., 0., 1.]];
        let tris = [[0u32, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
        let inside = closest_on_surface(pos.as_slice(), &tris, [0.1, 0.1, 0.1]).unwrap();
        assert!(inside.inside);
        assert!((inside.distance - 0.1).abs() < 1e-12);
        let out = closest_on_surface(pos.as_slice(), &tris, [0.2, 0.2, -0.5]).unwrap();
        assert!(!out.inside);
        assert!((out.distance - 0.5).abs() < 1e-12);
        assert_eq!(out.normal, [0.0, 0.0, -1.0]);
    }
}

/// How penetration depth becomes force (thesis §5.2.2); a scene's `[tool] force_law`
/// (`"quadratic"`, `"linear"`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "kebab-case"))]
pub enum ForceLaw {
    /// `F = k d² N` (thesis eq. 5.2); `k` in N/m².
    Quadratic,
    /// `F = k d N`, a linear spring; `k` in N/m. The default.
    #[default]
    Linear,
}

/// The tool tip: a sphere pressed into tissue with a penalty law. The haptic loop and the
/// deformation process evaluate the same law against the same surface, so the force the tissue
/// receives is the force rendered to the hand (up to the multirate delay).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ToolSphere {
    /// Centre, m, scene frame.
    pub center: [f64; 3],
    /// Radius, m.
    pub radius: f64,
    /// Penalty stiffness (units per [`ForceLaw`]).
    pub stiffness: f64,
    /// Penalty law.
    pub law: ForceLaw,
}

impl ToolSphere {
    /// Penetration depth of the sphere behind `hit`'s surface, m (0 when not touching).
    pub fn depth(&self, hit: &SurfaceHit) -> f64 {
        (self.radius - hit.signed_distance()).max(0.0)
    }

    /// Force magnitude at penetration `depth`, N.
    pub fn force_magnitude(&self, depth: f64) -> f64 {
        if !(depth > 0.0) {
            return 0.0;
        }
        match self.law {
            ForceLaw::Linear => self.stiffness * depth,
            ForceLaw::Quadratic => self.stiffness * depth * depth,
        }
    }

    /// Force on the tool (pushing it out along the triangle's outward normal), N.
    pub fn force_on_tool(&self, hit: &SurfaceHit) -> [f64; 3] {
        (v(hit.normal) * self.force_magnitude(self.depth(hit))).to_array()
    }

    /// Largest stiffness `dF/dd` the law reaches at depths up to `max_depth`, N/m: what an
    /// explicit integrator has to stay stable against.
    pub fn max_stiffness(&self, max_depth: f64) -> f64 {
        match self.law {
            ForceLaw::Linear => self.stiffness,
            ForceLaw::Quadratic => 2.0 * self.stiffness * max_depth,
        }
    }
}
