//! A render surface embedded in a tetrahedral mesh: each of its vertices follows one
//! tetrahedron of the simulation mesh by fixed barycentric weights, so the organ is drawn as it
//! was segmented (a fine surface) while a coarser mesh is simulated.
//!
//! - A vertex inside the mesh takes the tetrahedron that contains it; its four weights are
//!   its barycentric coordinates there (each in 0..=1, summing to 1).
//! - A vertex outside the mesh (a segmented surface and the mesh made from it never match
//!   exactly: the mesher smooths, a coarse mesh cuts corners) is projected onto the mesh: the
//!   tetrahedron nearest to it is the one it follows. Its weights are still its own barycentric
//!   coordinates in that tetrahedron (some negative), so at rest every vertex is drawn exactly
//!   where the input put it, and under deformation it moves as the tetrahedron's affine map
//!   carries it.
//! - A vertex farther from the mesh than [`MAX_OUTSIDE_FRACTION`] of the mesh's smallest extent
//!   is refused: the surface does not belong to this mesh (other units, another organ).
//!
//! Placing the surface is `Σ wᵢ xᵢ` over four nodes per vertex ([`Embedding::place`]): cheap
//! enough for every frame on the renderer's side.

use super::TetMesh;
use crate::contact::{bary_point, closest_point_on_triangle};
use crate::vec3::{cross, dot, sub, v};

/// The farthest a render vertex may lie outside the mesh, as a fraction of the mesh's smallest
/// extent.
pub const MAX_OUTSIDE_FRACTION: f64 = 0.1;

/// Where each vertex of a render surface sits in the simulation mesh.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Embedding {
    /// The four nodes each vertex follows (the mesh's 0-based node indices).
    pub nodes: Vec<[u32; 4]>,
    /// The vertex's weights on those nodes (sum 1; negative only for a vertex outside the mesh).
    pub weights: Vec<[f64; 4]>,
    /// Vertices that lie outside every tetrahedron.
    pub outside: usize,
    /// The largest distance of a vertex from the mesh, m (0 when every vertex is inside).
    pub max_outside: f64,
}

/// A render surface that cannot be embedded.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EmbedError {
    /// A vertex lies too far outside the mesh.
    #[error(
        "render vertex {vertex} at ({x:.4}, {y:.4}, {z:.4}) lies {distance:.4} m outside the \
         mesh, more than {limit:.4} m ({percent} % of the mesh's smallest extent): is the \
         surface in the mesh's units and frame?",
        x = point[0], y = point[1], z = point[2], percent = MAX_OUTSIDE_FRACTION * 100.0
    )]
    TooFar {
        /// 0-based vertex index.
        vertex: usize,
        /// Its position.
        point: [f64; 3],
        /// Its distance from the mesh.
        distance: f64,
        /// The limit.
        limit: f64,
    },
    /// A vertex coordinate is NaN or infinite.
    #[error("render vertex {vertex} has a coordinate that is not finite: {point:?}")]
    NotFinite {
        /// 0-based vertex index.
        vertex: usize,
        /// Its position.
        point: [f64; 3],
    },
}

impl Embedding {
    /// Embeds `points` in `mesh` (see the module docs).
    ///
    /// # Errors
    /// [`EmbedError::TooFar`] for a vertex beyond [`MAX_OUTSIDE_FRACTION`] of the mesh's smallest
    /// extent, [`EmbedError::NotFinite`].
    pub fn new(mesh: &TetMesh, points: &[[f64; 3]]) -> Result<Embedding, EmbedError> {
        let grid = Grid::new(mesh);
        let limit = MAX_OUTSIDE_FRACTION * super::smallest_extent(&mesh.nodes);
        let mut out = Embedding {
            nodes: Vec::with_capacity(points.len()),
            weights: Vec::with_capacity(points.len()),
            ..Embedding::default()
        };
        for (vertex, &point) in points.iter().enumerate() {
            if !point.iter().all(|c| c.is_finite()) {
                return Err(EmbedError::NotFinite { vertex, point });
            }
            let (tet, distance) = grid.nearest(mesh, point, limit);
            if distance > limit {
                return Err(EmbedError::TooFar {
                    vertex,
                    point,
                    distance,
                    limit,
                });
            }
            if distance > 0.0 {
                out.outside += 1;
                out.max_outside = out.max_outside.max(distance);
            }
            let t = mesh.tets[tet];
            out.nodes.push(t);
            out.weights.push(barycentric(corners(mesh, tet), point));
        }
        Ok(out)
    }

    /// Vertices embedded.
    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    /// No vertices.
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// Each vertex's position given the mesh's node positions `nodes` (`out` is cleared first).
    pub fn place(&self, nodes: &[[f64; 3]], out: &mut Vec<[f64; 3]>) {
        out.clear();
        out.extend(self.nodes.iter().zip(&self.weights).map(|(n, w)| {
            let mut p = [0.0; 3];
            for (&k, &wk) in n.iter().zip(w) {
                let x = nodes[k as usize];
                for d in 0..3 {
                    p[d] += wk * x[d];
                }
            }
            p
        }));
    }
}

fn corners(mesh: &TetMesh, tet: usize) -> [[f64; 3]; 4] {
    mesh.tets[tet].map(|k| mesh.nodes[k as usize])
}

/// Barycentric coordinates of `p` in the tetrahedron `c` (any sign; they sum to 1).
fn barycentric(c: [[f64; 3]; 4], p: [f64; 3]) -> [f64; 4] {
    let (e1, e2, e3, q) = (
        sub(c[1], c[0]),
        sub(c[2], c[0]),
        sub(c[3], c[0]),
        sub(p, c[0]),
    );
    let volume = dot(e1, cross(e2, e3));
    let w1 = dot(q, cross(e2, e3)) / volume;
    let w2 = dot(e1, cross(q, e3)) / volume;
    let w3 = dot(e1, cross(e2, q)) / volume;
    [1.0 - w1 - w2 - w3, w1, w2, w3]
}

/// Distance from `p` to the solid tetrahedron `c` (0 inside).
fn distance_to_tet(c: [[f64; 3]; 4], p: [f64; 3]) -> f64 {
    let w = barycentric(c, p);
    // Inside up to rounding: a vertex on a shared face belongs to either neighbour.
    if w.iter().all(|&x| x >= -1e-12) {
        return 0.0;
    }
    const FACES: [[usize; 3]; 4] = [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]];
    FACES
        .iter()
        .map(|f| {
            let (a, b, e) = (c[f[0]], c[f[1]], c[f[2]]);
            let w = closest_point_on_triangle(p, a, b, e);
            v(p).distance_squared(bary_point(v(a), v(b), v(e), w))
        })
        .fold(f64::INFINITY, f64::min)
        .sqrt()
}

/// A uniform grid of the tetrahedra's bounding boxes.
struct Grid {
    lo: [f64; 3],
    cell: f64,
    dims: [usize; 3],
    /// Start of each cell's list in `items` (one more than the cells).
    starts: Vec<u32>,
    items: Vec<u32>,
}

impl Grid {
    fn new(mesh: &TetMesh) -> Grid {
        let (lo, hi) = super::bounds(&mesh.nodes);
        let volume: f64 = (0..3).map(|d| (hi[d] - lo[d]).max(1e-12)).product();
        // About one tetrahedron per cell, capped so that a thin body's grid stays small.
        let cell = (volume / mesh.tets.len().max(1) as f64).cbrt().max(1e-9);
        let dims = [0, 1, 2].map(|d| (((hi[d] - lo[d]) / cell).ceil() as usize).clamp(1, 256));
        let mut grid = Grid {
            lo,
            cell,
            dims,
            starts: Vec::new(),
            items: Vec::new(),
        };
        let cells = dims[0] * dims[1] * dims[2];
        let ranges: Vec<([usize; 3], [usize; 3])> = (0..mesh.tets.len())
            .map(|t| {
                let c = corners(mesh, t);
                let a = grid.cell_of(
                    c.iter()
                        .fold(c[0], |m, p| [0, 1, 2].map(|d| m[d].min(p[d]))),
                );
                let b = grid.cell_of(
                    c.iter()
                        .fold(c[0], |m, p| [0, 1, 2].map(|d| m[d].max(p[d]))),
                );
                (a, b)
            })
            .collect();
        let mut counts = vec![0u32; cells + 1];
        for (a, b) in &ranges {
            grid.each_cell(*a, *b, |k| counts[k + 1] += 1);
        }
        for k in 0..cells {
            counts[k + 1] += counts[k];
        }
        let mut fill = counts.clone();
        let mut items = vec![0u32; counts[cells] as usize];
        for (t, (a, b)) in ranges.iter().enumerate() {
            grid.each_cell(*a, *b, |k| {
                items[fill[k] as usize] = t as u32;
                fill[k] += 1;
            });
        }
        grid.starts = counts;
        grid.items = items;
        grid
    }

    fn cell_of(&self, p: [f64; 3]) -> [usize; 3] {
        [0, 1, 2].map(|d| {
            let i = ((p[d] - self.lo[d]) / self.cell).floor();
            (i.max(0.0) as usize).min(self.dims[d] - 1)
        })
    }

    fn index(&self, c: [usize; 3]) -> usize {
        (c[2] * self.dims[1] + c[1]) * self.dims[0] + c[0]
    }

    fn each_cell(&self, a: [usize; 3], b: [usize; 3], mut f: impl FnMut(usize)) {
        for z in a[2]..=b[2] {
            for y in a[1]..=b[1] {
                for x in a[0]..=b[0] {
                    f(self.index([x, y, z]));
                }
            }
        }
    }

    /// The tetrahedron nearest to `p` and its distance (0 inside). Searches rings of cells
    /// around `p`'s cell until no unvisited cell can hold a nearer one, or past `limit` (then
    /// the best found so far, or `(0, ∞)`).
    fn nearest(&self, mesh: &TetMesh, p: [f64; 3], limit: f64) -> (usize, f64) {
        let home = self.cell_of(p);
        // How far `p` lies outside the grid: cells are clamped, so rings count from there.
        let outside = (0..3)
            .map(|d| {
                let hi = self.lo[d] + self.dims[d] as f64 * self.cell;
                (self.lo[d] - p[d]).max(p[d] - hi).max(0.0)
            })
            .fold(0.0f64, |a, b| a.hypot(b));
        let mut best = (0usize, f64::INFINITY);
        let max_ring = self.dims.iter().copied().max().unwrap_or(1);
        for ring in 0..=max_ring {
            let lo = [0, 1, 2].map(|d| home[d].saturating_sub(ring));
            let hi = [0, 1, 2].map(|d| (home[d] + ring).min(self.dims[d] - 1));
            for z in lo[2]..=hi[2] {
                for y in lo[1]..=hi[1] {
                    for x in lo[0]..=hi[0] {
                        let shell = [x, y, z]
                            .iter()
                            .zip(&home)
                            .any(|(&c, &h)| c.abs_diff(h) == ring);
                        if !shell {
                            continue;
                        }
                        let k = self.index([x, y, z]);
                        for &t in &self.items[self.starts[k] as usize..self.starts[k + 1] as usize]
                        {
                            let d = distance_to_tet(corners(mesh, t as usize), p);
                            if d < best.1 || (d == best.1 && (t as usize) < best.0) {
                                best = (t as usize, d);
                            }
                        }
                    }
                }
            }
            // Every cell beyond this ring is at least `ring · cell` from p along one axis, and
            // at least `outside` from it along the axes where p lies outside the grid.
            let reach = outside.hypot(ring as f64 * self.cell);
            if best.1 <= reach || reach > limit {
                break;
            }
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    /// A unit cube of six tetrahedra (Kuhn's split), scaled by `s`.
    fn cube(s: f64) -> TetMesh {
        let nodes: Vec<[f64; 3]> = (0..8)
            .map(|i| {
                [
                    (i & 1) as f64 * s,
                    ((i >> 1) & 1) as f64 * s,
                    ((i >> 2) & 1) as f64 * s,
                ]
            })
            .collect();
        let tets = vec![
            [0, 1, 3, 7],
            [0, 3, 2, 7],
            [0, 2, 6, 7],
            [0, 6, 4, 7],
            [0, 4, 5, 7],
            [0, 5, 1, 7],
        ];
        TetMesh::from_parts(nodes, tets, vec![], PathBuf::from("cube")).unwrap()
    }

    #[test]
    fn rest_positions_are_reproduced_inside_and_outside() {
        let mesh = cube(0.02);
        let points = [
            [0.01, 0.01, 0.01],
            [0.005, 0.015, 0.002],
            [0.0, 0.0, 0.0],
            [0.021, 0.01, 0.01],    // 1 mm outside +x
            [-0.001, -0.001, 0.03], // outside a corner region, 10 mm above
        ];
        let e = Embedding::new(&mesh, &points[..4]).unwrap();
        assert_eq!(e.outside, 1);
        assert!((e.max_outside - 0.001).abs() < 1e-12, "{}", e.max_outside);
        let mut placed = Vec::new();
        e.place(&mesh.nodes, &mut placed);
        for (p, q) in points.iter().zip(&placed) {
            for d in 0..3 {
                assert!((p[d] - q[d]).abs() < 1e-15, "{p:?} {q:?}");
            }
        }
        for w in &e.weights[..3] {
            assert!(
                w.iter().all(|&x| (-1e-12..=1.0 + 1e-12).contains(&x)),
                "{w:?}"
            );
            assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        }
        // 10 mm from a 20 mm cube: beyond 10 % of its extent (2 mm).
        let err = Embedding::new(&mesh, &points).unwrap_err();
        assert!(matches!(err, EmbedError::TooFar { vertex: 4, .. }), "{err}");
        assert!(err.to_string().contains("render vertex 4"), "{err}");
    }

    #[test]
    fn an_affine_motion_of_the_nodes_moves_every_vertex_by_it() {
        let mesh = cube(0.02);
        let points: Vec<[f64; 3]> = (0..50)
            .map(|i| {
                let t = i as f64 * 0.37;
                [
                    0.01 + 0.0105 * t.sin(),
                    0.01 + 0.009 * (1.3 * t).cos(),
                    0.02 * (i as f64 / 49.0),
                ]
            })
            .collect();
        let e = Embedding::new(&mesh, &points).unwrap();
        let a = [[1.1, 0.2, 0.0], [-0.1, 0.9, 0.3], [0.05, 0.0, 1.2]];
        let b = [0.003, -0.002, 0.01];
        let map = |p: [f64; 3]| [0, 1, 2].map(|r| dot(a[r], p) + b[r]);
        let moved: Vec<[f64; 3]> = mesh.nodes.iter().map(|&p| map(p)).collect();
        let mut placed = Vec::new();
        e.place(&moved, &mut placed);
        for (p, q) in points.iter().zip(&placed) {
            let m = map(*p);
            for d in 0..3 {
                assert!((m[d] - q[d]).abs() < 1e-14, "{m:?} {q:?}");
            }
        }
    }

    #[test]
    fn a_non_finite_vertex_is_named() {
        let err = Embedding::new(&cube(1.0), &[[0.5; 3], [f64::NAN, 0.0, 0.0]]).unwrap_err();
        assert!(
            matches!(err, EmbedError::NotFinite { vertex: 1, .. }),
            "{err}"
        );
    }
}
