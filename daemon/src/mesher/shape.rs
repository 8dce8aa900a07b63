//! What a mesh is worth: the dihedral angles of its tetrahedra (slivers — flat tetrahedra with
//! a dihedral near 0° or 180° — make the implicit FEM step in contact need many more CG
//! iterations) and how far its boundary strays from the surface it was made from.

use std::fmt;

use glam::DVec3;
use lop_sim::mesh::{SurfaceMesh, TetMesh};

/// The smallest dihedral angle of each tetrahedron, summarised.
#[derive(Debug, Clone, PartialEq)]
pub struct Dihedrals {
    /// Smallest and largest dihedral angle over the mesh, degrees.
    pub min: f64,
    /// Largest dihedral angle, degrees.
    pub max: f64,
    /// Percentiles 1, 5 and 50 of the tetrahedra's smallest dihedral angle, degrees.
    pub p1_p5_p50: [f64; 3],
    /// How many tetrahedra have their smallest dihedral angle in each of [`BINS`].
    pub histogram: [usize; 6],
}

/// The bins of [`Dihedrals::histogram`]: lower bounds, degrees (the last is open).
pub const BINS: [f64; 6] = [0.0, 5.0, 10.0, 15.0, 20.0, 30.0];

/// The six dihedral angles of a tetrahedron, degrees.
pub fn tet_dihedrals(p: [DVec3; 4]) -> [f64; 6] {
    let pairs = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)];
    pairs.map(|(i, j)| {
        // The edge i-j; the two other corners k, l projected on its normal plane.
        let (k, l) = match (i, j) {
            (0, 1) => (2, 3),
            (0, 2) => (1, 3),
            (0, 3) => (1, 2),
            (1, 2) => (0, 3),
            (1, 3) => (0, 2),
            _ => (0, 1),
        };
        let e = (p[j] - p[i]).normalize_or_zero();
        let u = p[k] - p[i];
        let v = p[l] - p[i];
        let (u, v) = (u - e * u.dot(e), v - e * v.dot(e));
        let c = (u.dot(v) / (u.length() * v.length())).clamp(-1.0, 1.0);
        c.acos().to_degrees()
    })
}

impl Dihedrals {
    /// Over every tetrahedron of `mesh` (which has at least one).
    pub fn of(mesh: &TetMesh) -> Dihedrals {
        let mut mins = Vec::with_capacity(mesh.tets.len());
        let mut max = 0.0f64;
        let mut histogram = [0usize; 6];
        for t in &mesh.tets {
            let a = tet_dihedrals(t.map(|i| DVec3::from(mesh.nodes[i as usize])));
            let lo = a.iter().copied().fold(f64::INFINITY, f64::min);
            max = a.iter().copied().fold(max, f64::max);
            mins.push(lo);
            let bin = BINS.iter().rposition(|&b| lo >= b).unwrap_or(0);
            histogram[bin] += 1;
        }
        mins.sort_by(f64::total_cmp);
        let at = |q: f64| mins[((mins.len() - 1) as f64 * q).round() as usize];
        Dihedrals {
            min: mins.first().copied().unwrap_or(0.0),
            max,
            p1_p5_p50: [at(0.01), at(0.05), at(0.5)],
            histogram,
        }
    }
}

impl fmt::Display for Dihedrals {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let [p1, p5, p50] = self.p1_p5_p50;
        writeln!(
            f,
            "dihedral angles:   {:.1} .. {:.1} degrees; smallest per tetrahedron: 1 % under \
             {p1:.1}, 5 % under {p5:.1}, median {p50:.1}",
            self.min, self.max
        )?;
        write!(f, "smallest dihedral:")?;
        for (i, n) in self.histogram.iter().enumerate() {
            match BINS.get(i + 1) {
                Some(hi) => write!(f, " {:.0}-{hi:.0}°: {n}", BINS[i])?,
                None => write!(f, " {:.0}°+: {n}", BINS[i])?,
            }
            if i + 1 < BINS.len() {
                write!(f, ",")?;
            }
        }
        Ok(())
    }
}

/// How far the mesh's boundary vertices are from the input surface, in the input's units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceDistance {
    /// Largest distance of a boundary vertex from the nearest input triangle.
    pub max: f64,
    /// Mean over the boundary vertices.
    pub mean: f64,
    /// Boundary vertices nearest to a patch over a hole (not counted in `max` and `mean`),
    /// and the largest distance among them.
    pub over_holes: (usize, f64),
}

/// The distance of every boundary vertex of `mesh` to the nearest triangle of `input` (both
/// in the same units): the one-sided Hausdorff distance at the vertices. Triangles from
/// `patches_from` on are patches closing holes: a vertex nearest to one is counted apart,
/// since a hole's patch is a guess. Exhaustive over the triangles with a bounding-box
/// cut-off: a few million point-triangle tests for an organ.
pub fn surface_distance(
    mesh: &TetMesh,
    input: &SurfaceMesh,
    patches_from: usize,
) -> SurfaceDistance {
    let tris: Vec<[DVec3; 3]> = input
        .triangles
        .iter()
        .map(|t| t.map(|i| DVec3::from(input.vertices[i as usize])))
        .collect();
    let boxes: Vec<(DVec3, DVec3)> = tris
        .iter()
        .map(|[a, b, c]| (a.min(*b).min(*c), a.max(*b).max(*c)))
        .collect();
    let nodes = mesh.surface_nodes();
    let mut max = 0.0f64;
    let mut sum = 0.0;
    let mut counted = 0usize;
    let mut over_holes = (0usize, 0.0f64);
    for &n in &nodes {
        let p = DVec3::from(mesh.nodes[n as usize]);
        let mut best = f64::INFINITY;
        let mut nearest = 0;
        for (i, (t, (lo, hi))) in tris.iter().zip(&boxes).enumerate() {
            let outside = (*lo - p).max(p - *hi).max(DVec3::ZERO);
            if outside.length_squared() >= best {
                continue;
            }
            let d = point_triangle2(p, *t);
            if d < best {
                best = d;
                nearest = i;
            }
        }
        let d = best.sqrt();
        if nearest >= patches_from {
            over_holes = (over_holes.0 + 1, over_holes.1.max(d));
        } else {
            max = max.max(d);
            sum += d;
            counted += 1;
        }
    }
    SurfaceDistance {
        max,
        mean: sum / counted.max(1) as f64,
        over_holes,
    }
}

/// Squared distance from `p` to the triangle `[a, b, c]` (closest point by regions, as in
/// Ericson, Real-Time Collision Detection, 5.1.5).
fn point_triangle2(p: DVec3, [a, b, c]: [DVec3; 3]) -> f64 {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return ap.length_squared();
    }
    let bp = p - b;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return bp.length_squared();
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return (p - (a + ab * v)).length_squared();
    }
    let cp = p - c;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
    if d6 >= 0.0 && d5 <= d6 {
        return cp.length_squared();
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return (p - (a + ac * w)).length_squared();
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (p - (b + (c - b) * w)).length_squared();
    }
    let denom = 1.0 / (va + vb + vc);
    if !denom.is_finite() {
        // A degenerate triangle: its edges.
        return [(a, b), (b, c), (c, a)]
            .map(|(s, e)| {
                let d = e - s;
                let t = if d.length_squared() > 0.0 {
                    ((p - s).dot(d) / d.length_squared()).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                (p - (s + d * t)).length_squared()
            })
            .into_iter()
            .fold(f64::INFINITY, f64::min);
    }
    let v = vb * denom;
    let w = vc * denom;
    (p - (a + ab * v + ac * w)).length_squared()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regular_tet_has_dihedrals_of_70_5_degrees() {
        let s = 1.0 / 2f64.sqrt();
        let p = [
            DVec3::new(1.0, 0.0, -s),
            DVec3::new(-1.0, 0.0, -s),
            DVec3::new(0.0, 1.0, s),
            DVec3::new(0.0, -1.0, s),
        ];
        for a in tet_dihedrals(p) {
            assert!((a - (1.0f64 / 3.0).acos().to_degrees()).abs() < 1e-9, "{a}");
        }
    }

    #[test]
    fn distance_to_a_triangle_by_region() {
        let t = [DVec3::ZERO, DVec3::X, DVec3::Y];
        // Above the face, beyond an edge, beyond a corner.
        assert!((point_triangle2(DVec3::new(0.2, 0.2, 3.0), t) - 9.0).abs() < 1e-12);
        assert!((point_triangle2(DVec3::new(0.5, -2.0, 0.0), t) - 4.0).abs() < 1e-12);
        assert!((point_triangle2(DVec3::new(2.0, 0.0, 0.0), t) - 1.0).abs() < 1e-12);
        assert!((point_triangle2(DVec3::new(1.0, 1.0, 0.0), t) - 0.5).abs() < 1e-12);
    }
}
