//! Cages: the [`Cage`] type, the box cages of the thesis, and the validation that
//! [`GreenCoordinates::new`](super::GreenCoordinates::new) runs.

use super::CageError;
use crate::vec3::{cross, dot, norm, sub};

/// A closed, outward-wound triangle cage.
///
/// `triangles` index into `vertices`; each triangle lists its corners counter-clockwise as seen
/// from outside, so that `(v_b − v_a) × (v_c − v_a)` points out of the cage. Nothing is checked
/// when a `Cage` is built: [`GreenCoordinates::from_cage`](super::GreenCoordinates::from_cage)
/// (or [`GreenCoordinates::new`](super::GreenCoordinates::new)) validates it.
#[derive(Debug, Clone, PartialEq)]
pub struct Cage {
    /// Vertex positions (m).
    pub vertices: Vec<[f64; 3]>,
    /// Triangles as indices into `vertices`, counter-clockwise seen from outside.
    pub triangles: Vec<[usize; 3]>,
}

/// The thesis' cage: the axis-aligned bounding box of `points` grown by `padding` (m, > 0) on
/// every side; 8 vertices, 12 triangles (two per face), wound outward.
///
/// It is [`subdivided_box_cage`] with `n = 1`; see there for the vertex and triangle order and
/// for what happens with unusual input (no points, a non-finite point, `padding` ≤ 0 or NaN).
/// Every point of `points` is at least `padding` away from every face of the box.
pub fn box_cage(points: &[[f64; 3]], padding: f64) -> Cage {
    subdivided_box_cage(points, padding, 1)
}

/// The box of [`box_cage`] with each edge divided into `n` ≥ 1 equal segments: every face is an
/// `n × n` grid of squares, each split into two triangles along the same diagonal. The result
/// has `6n² + 2` vertices and `12n²` triangles, is wound outward, and has no duplicate
/// vertices; `n = 1` is [`box_cage`].
///
/// Vertex order: the surface points of the `(n+1)³` lattice `(i, j, k)` of the box, with `i`
/// (along x) running fastest and `k` (along z) slowest. Triangle order: the faces −x, +x, −y,
/// +y, −z, +z, two triangles per grid square. Lattice coordinates are
/// `lo + (hi − lo)·i/n`, with the far side exactly `hi`.
///
/// This function never panics and never fails; input it cannot make sense of gives a cage that
/// [`GreenCoordinates::new`](super::GreenCoordinates::new) rejects with a precise error:
/// - `n = 0` gives an empty cage ([`CageError::TooFewVertices`]);
/// - a NaN or infinite point, or a NaN or infinite `padding`, gives non-finite vertices
///   ([`CageError::NonFiniteVertex`]);
/// - no points at all gives the box of half-width `padding` around the origin;
/// - `padding` ≤ 0 is used as given: a flat point set then gives a degenerate cage, and a box
///   that does not enclose the points makes [`GreenCoordinates::bind`] reject them.
///
/// [`GreenCoordinates::bind`]: super::GreenCoordinates::bind
pub fn subdivided_box_cage(points: &[[f64; 3]], padding: f64, n: usize) -> Cage {
    grid_box_cage(points, padding, [n, n, n])
}

/// The box of [`box_cage`] with its x, y and z edges divided into `cells[0]`, `cells[1]` and
/// `cells[2]` equal segments: [`subdivided_box_cage`] with a resolution per axis, so that a long
/// body gets cells of about the same size along its length as across it. Vertex and triangle
/// order and the handling of unusual input are those of [`subdivided_box_cage`]; any zero in
/// `cells` gives an empty cage.
pub fn grid_box_cage(points: &[[f64; 3]], padding: f64, cells: [usize; 3]) -> Cage {
    if cells.contains(&0) {
        return Cage {
            vertices: Vec::new(),
            triangles: Vec::new(),
        };
    }
    let (lo, hi) = padded_bounds(points, padding);
    // Lattice coordinate along axis `a`.
    let coord = |a: usize, i: usize| -> f64 {
        if i == cells[a] {
            hi[a]
        } else {
            lo[a] + (hi[a] - lo[a]) * (i as f64 / cells[a] as f64)
        }
    };
    // Index of each lattice point on the surface, usize::MAX inside.
    let m = cells.map(|c| c + 1);
    let mut index = vec![usize::MAX; m[0] * m[1] * m[2]];
    let mut vertices = Vec::new();
    for k in 0..m[2] {
        for j in 0..m[1] {
            for i in 0..m[0] {
                let on_surface = [i, j, k].iter().zip(cells).any(|(&c, n)| c == 0 || c == n);
                if on_surface {
                    index[i + m[0] * (j + m[1] * k)] = vertices.len();
                    vertices.push([coord(0, i), coord(1, j), coord(2, k)]);
                }
            }
        }
    }
    let at = |l: [usize; 3]| index[l[0] + m[0] * (l[1] + m[1] * l[2])];
    let mut triangles = Vec::new();
    for axis in 0..3 {
        // (axis, b, c) is a cyclic permutation of (x, y, z), so e_b × e_c = e_axis.
        let (b, c) = ((axis + 1) % 3, (axis + 2) % 3);
        for side in [0, cells[axis]] {
            for v in 0..cells[c] {
                for u in 0..cells[b] {
                    let corner = |du: usize, dv: usize| {
                        let mut l = [0; 3];
                        l[axis] = side;
                        l[b] = u + du;
                        l[c] = v + dv;
                        at(l)
                    };
                    let (p00, p10, p11, p01) =
                        (corner(0, 0), corner(1, 0), corner(1, 1), corner(0, 1));
                    if side == cells[axis] {
                        // Counter-clockwise seen from +axis.
                        triangles.push([p00, p10, p11]);
                        triangles.push([p00, p11, p01]);
                    } else {
                        triangles.push([p00, p11, p10]);
                        triangles.push([p00, p01, p11]);
                    }
                }
            }
        }
    }
    Cage {
        vertices,
        triangles,
    }
}

/// The bounding box of `points` grown by `padding`; NaN anywhere propagates to the result.
fn padded_bounds(points: &[[f64; 3]], padding: f64) -> ([f64; 3], [f64; 3]) {
    if points.is_empty() {
        return ([-padding; 3], [padding; 3]);
    }
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in points {
        for a in 0..3 {
            // Not f64::min/max: they would drop a NaN.
            if p[a] < lo[a] || p[a].is_nan() {
                lo[a] = p[a];
            }
            if p[a] > hi[a] || p[a].is_nan() {
                hi[a] = p[a];
            }
        }
    }
    // A NaN, once recorded, stays: every comparison with it is false.
    (lo.map(|l| l - padding), hi.map(|h| h + padding))
}

/// Relative size below which a triangle counts as degenerate: `|u × v| ≤ TOL · (longest edge)²`,
/// i.e. the sine of its largest angle is negligible.
const DEGENERATE_TOL: f64 = 1e-12;

/// Relative size below which the enclosed volume counts as zero: `|V| ≤ TOL · diagonal³`.
const VOLUME_TOL: f64 = 1e-12;

/// Checks that `vertices` / `triangles` form a closed, oriented, outward-wound 2-manifold cage.
///
/// Order: counts, indices, finite vertices, degenerate triangles, edges (non-manifold, then
/// open, then winding), unused vertices, volume. Every check only relies on the ones before it.
pub(crate) fn validate(vertices: &[[f64; 3]], triangles: &[[usize; 3]]) -> Result<(), CageError> {
    if vertices.len() < 4 {
        return Err(CageError::TooFewVertices {
            count: vertices.len(),
        });
    }
    if triangles.len() < 4 {
        return Err(CageError::TooFewTriangles {
            count: triangles.len(),
        });
    }
    for (t, tri) in triangles.iter().enumerate() {
        if let Some(&index) = tri.iter().find(|&&i| i >= vertices.len()) {
            return Err(CageError::IndexOutOfRange {
                triangle: t,
                index,
                vertex_count: vertices.len(),
            });
        }
    }
    if let Some(vertex) = vertices
        .iter()
        .position(|v| !v.iter().all(|c| c.is_finite()))
    {
        return Err(CageError::NonFiniteVertex {
            vertex,
            position: vertices[vertex],
        });
    }
    for (t, tri) in triangles.iter().enumerate() {
        let [a, b, c] = tri.map(|i| vertices[i]);
        let (u, v, w) = (sub(b, a), sub(c, a), sub(c, b));
        let twice_area = norm(cross(u, v));
        let longest = dot(u, u).max(dot(v, v)).max(dot(w, w));
        if !(twice_area > DEGENERATE_TOL * longest) {
            return Err(CageError::DegenerateTriangle {
                triangle: t,
                vertices: *tri,
                area: 0.5 * twice_area,
            });
        }
    }
    check_edges(triangles)?;
    let mut used = vec![false; vertices.len()];
    for tri in triangles {
        for &i in tri {
            used[i] = true;
        }
    }
    if let Some(vertex) = used.iter().position(|&u| !u) {
        return Err(CageError::UnusedVertex { vertex });
    }
    let volume = signed_volume(vertices, triangles);
    let (lo, hi) = padded_bounds(vertices, 0.0);
    let diagonal = norm(sub(hi, lo));
    if !(volume.abs() > VOLUME_TOL * diagonal.powi(3)) {
        return Err(CageError::NoVolume { volume });
    }
    if volume < 0.0 {
        return Err(CageError::InwardWinding { volume });
    }
    Ok(())
}

/// Every undirected edge must be used by exactly two triangles, once in each direction.
fn check_edges(triangles: &[[usize; 3]]) -> Result<(), CageError> {
    // (smaller vertex, larger vertex, triangle, traversed from smaller to larger?)
    let mut edges: Vec<(usize, usize, usize, bool)> = Vec::with_capacity(3 * triangles.len());
    for (t, tri) in triangles.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            edges.push((a.min(b), a.max(b), t, a < b));
        }
    }
    edges.sort_unstable();
    let groups: Vec<&[(usize, usize, usize, bool)]> =
        edges.chunk_by(|x, y| (x.0, x.1) == (y.0, y.1)).collect();
    // Non-manifold first: an extra triangle on an edge also leaves its other edges open.
    if let Some(g) = groups.iter().find(|g| g.len() > 2) {
        return Err(CageError::NonManifoldEdge {
            edge: [g[0].0, g[0].1],
            triangles: g.iter().map(|e| e.2).collect(),
        });
    }
    if let Some(g) = groups.iter().find(|g| g.len() == 1) {
        let (lo, hi, triangle, forward) = g[0];
        let edge = if forward { [lo, hi] } else { [hi, lo] };
        return Err(CageError::OpenEdge { edge, triangle });
    }
    if let Some(g) = groups.iter().find(|g| g[0].3 == g[1].3) {
        let (lo, hi, t0, forward) = g[0];
        let edge = if forward { [lo, hi] } else { [hi, lo] };
        return Err(CageError::InconsistentWinding {
            edge,
            triangles: [t0, g[1].2],
        });
    }
    Ok(())
}

/// Signed volume enclosed by the closed surface (> 0 for outward winding), summed about the
/// vertex centroid to keep the digits of a cage far from the origin.
pub(crate) fn signed_volume(vertices: &[[f64; 3]], triangles: &[[usize; 3]]) -> f64 {
    let mut c = [0.0; 3];
    for v in vertices {
        for a in 0..3 {
            c[a] += v[a];
        }
    }
    let c = c.map(|s| s / vertices.len() as f64);
    let six_v: f64 = triangles
        .iter()
        .map(|tri| {
            let [a, b, d] = tri.map(|i| sub(vertices[i], c));
            dot(a, cross(b, d))
        })
        .sum();
    six_v / 6.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_counts_and_validity() {
        for n in 1..5 {
            let cage = subdivided_box_cage(&[[0.0, 0.0, 0.0], [1.0, 2.0, 3.0]], 0.1, n);
            assert_eq!(cage.vertices.len(), 6 * n * n + 2);
            assert_eq!(cage.triangles.len(), 12 * n * n);
            validate(&cage.vertices, &cage.triangles).unwrap();
            let v = signed_volume(&cage.vertices, &cage.triangles);
            assert!((v - 1.2 * 2.2 * 3.2).abs() < 1e-12, "{v}");
        }
    }

    #[test]
    fn nan_point_propagates_into_the_box() {
        let cage = box_cage(&[[0.0; 3], [f64::NAN, 1.0, 1.0], [2.0; 3]], 0.1);
        assert!(cage.vertices.iter().any(|v| v[0].is_nan()));
        assert!(matches!(
            validate(&cage.vertices, &cage.triangles),
            Err(CageError::NonFiniteVertex { .. })
        ));
    }

    #[test]
    fn flat_cage_has_no_volume() {
        // A closed tetrahedron-shaped surface whose apex lies in the base triangle's plane
        // (inside the base): no triangle is degenerate, but it encloses nothing.
        let v = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.3, 0.3, 0.0],
        ];
        let t = [[0, 2, 1], [0, 1, 3], [1, 2, 3], [2, 0, 3]];
        assert!(matches!(validate(&v, &t), Err(CageError::NoVolume { .. })));
    }
}
