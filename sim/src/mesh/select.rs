//! Node selectors: which nodes of a mesh a geometric region picks, e.g. the nodes to hold fixed
//! where an organ is attached. A scene names them in its own coordinates (`[[body.fix]]`), so a
//! selector is evaluated on positions already placed in the scene; `lopd mesh info --select`
//! evaluates one on a mesh file's own coordinates.
//!
//! With the `serde` feature a selector reads and writes as a scene's `[[body.fix]]` table:
//! `kind = "box" | "sphere" | "slab" | "facing"` and the keys of its variant (`lop-config`
//! validates what a user writes, and writes selectors back through this representation).

use glam::DVec3;

/// A region of space (or of the surface) whose nodes are selected.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(
    feature = "serde",
    serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)
)]
pub enum NodeSelector {
    /// Nodes inside the axis-aligned box `min ..= max`.
    Box {
        /// Lowest corner.
        min: [f64; 3],
        /// Highest corner.
        max: [f64; 3],
    },
    /// Nodes within `radius` of `center`.
    Sphere {
        /// Centre.
        center: [f64; 3],
        /// Radius (> 0).
        radius: f64,
    },
    /// Nodes on the back side of the plane through `point` with normal `normal` — with
    /// `n̂ = normal / |normal|`, those with `(p − point)·n̂ <= 0` — and, with a `thickness`,
    /// at most that far behind it.
    Slab {
        /// A point of the plane.
        point: [f64; 3],
        /// The plane's normal (need not be unit; not zero): the slab lies against it.
        normal: [f64; 3],
        /// Depth of the slab behind the plane; `None`: the whole half-space.
        #[cfg_attr(
            feature = "serde",
            serde(default, skip_serializing_if = "Option::is_none")
        )]
        thickness: Option<f64>,
    },
    /// Surface nodes whose outward normal (the area-weighted mean of their triangles' normals)
    /// is within `angle_deg` of `direction`, optionally only those `within` another region.
    Facing {
        /// The direction the patch faces (need not be unit; not zero).
        direction: [f64; 3],
        /// Largest angle between a node's normal and `direction`, degrees (0 < angle <= 180;
        /// [`FACING_ANGLE_DEFAULT_DEG`] when a scene leaves it out).
        #[cfg_attr(feature = "serde", serde(default = "facing_angle_default"))]
        angle_deg: f64,
        /// Further limits the patch to the nodes this selector picks.
        #[cfg_attr(
            feature = "serde",
            serde(default, skip_serializing_if = "Option::is_none")
        )]
        within: Option<Box<NodeSelector>>,
    },
}

/// A facing selector's `angle_deg` when a scene leaves it out, degrees.
pub const FACING_ANGLE_DEFAULT_DEG: f64 = 45.0;

#[cfg(feature = "serde")]
fn facing_angle_default() -> f64 {
    FACING_ANGLE_DEFAULT_DEG
}

impl NodeSelector {
    /// The nodes (0-based, ascending) this selector picks among `nodes`, whose boundary surface
    /// (outward-wound, as [`super::TetMesh::surface`]) is `surface`.
    pub fn select(&self, nodes: &[[f64; 3]], surface: &[[u32; 3]]) -> Vec<u32> {
        let mut keep = vec![true; nodes.len()];
        self.mark(nodes, surface, &mut keep);
        (0..nodes.len() as u32)
            .filter(|&i| keep[i as usize])
            .collect()
    }

    /// Clears `keep[i]` for every node `i` this selector does not pick.
    fn mark(&self, nodes: &[[f64; 3]], surface: &[[u32; 3]], keep: &mut [bool]) {
        let p = |i: usize| DVec3::from_array(nodes[i]);
        match self {
            NodeSelector::Box { min, max } => {
                let (lo, hi) = (DVec3::from_array(*min), DVec3::from_array(*max));
                for (i, k) in keep.iter_mut().enumerate() {
                    *k &= p(i).cmpge(lo).all() && p(i).cmple(hi).all();
                }
            }
            NodeSelector::Sphere { center, radius } => {
                let c = DVec3::from_array(*center);
                for (i, k) in keep.iter_mut().enumerate() {
                    *k &= p(i).distance(c) <= *radius;
                }
            }
            NodeSelector::Slab {
                point,
                normal,
                thickness,
            } => {
                let (o, n) = (
                    DVec3::from_array(*point),
                    DVec3::from_array(*normal).normalize_or_zero(),
                );
                let depth = thickness.unwrap_or(f64::INFINITY);
                for (i, k) in keep.iter_mut().enumerate() {
                    let h = (p(i) - o).dot(n);
                    *k &= h <= 0.0 && h >= -depth;
                }
            }
            NodeSelector::Facing {
                direction,
                angle_deg,
                within,
            } => {
                let d = DVec3::from_array(*direction).normalize_or_zero();
                let cos = angle_deg.to_radians().cos();
                let normals = vertex_normals(nodes, surface);
                for (i, k) in keep.iter_mut().enumerate() {
                    let n = DVec3::from_array(normals[i]);
                    // Interior nodes have no normal: never facing anything.
                    *k &= n != DVec3::ZERO && n.normalize().dot(d) >= cos - 1e-12;
                }
                if let Some(w) = within {
                    w.mark(nodes, surface, keep);
                }
            }
        }
    }
}

/// Area-weighted outward normal of every node: the sum of `(b−a)×(c−a)` over the surface
/// triangles at it (twice their area times their unit normal); zero for interior nodes.
pub fn vertex_normals(nodes: &[[f64; 3]], surface: &[[u32; 3]]) -> Vec<[f64; 3]> {
    let mut out = vec![DVec3::ZERO; nodes.len()];
    for t in surface {
        let [a, b, c] = t.map(|i| DVec3::from_array(nodes[i as usize]));
        let n = (b - a).cross(c - a);
        for &i in t {
            out[i as usize] += n;
        }
    }
    out.iter().map(DVec3::to_array).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit cube's 8 corners and its 12 outward triangles.
    fn cube() -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
        let nodes = (0..8)
            .map(|i| [(i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64])
            .collect();
        let quads = [
            [0, 2, 3, 1], // z = 0, facing -z
            [4, 5, 7, 6], // z = 1
            [0, 1, 5, 4], // y = 0
            [2, 6, 7, 3], // y = 1
            [0, 4, 6, 2], // x = 0
            [1, 3, 7, 5], // x = 1
        ];
        let tris = quads
            .iter()
            .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
            .collect();
        (nodes, tris)
    }

    #[test]
    fn selectors_pick_the_corners_they_cover() {
        let (n, s) = cube();
        let b = NodeSelector::Box {
            min: [-0.1, -0.1, -0.1],
            max: [1.1, 0.5, 1.1],
        };
        assert_eq!(b.select(&n, &s), vec![0, 1, 4, 5]);
        let sp = NodeSelector::Sphere {
            center: [0.0; 3],
            radius: 1.01,
        };
        assert_eq!(sp.select(&n, &s), vec![0, 1, 2, 4]);
        let slab = NodeSelector::Slab {
            point: [0.0, 0.0, 0.5],
            normal: [0.0, 0.0, 2.0],
            thickness: None,
        };
        assert_eq!(slab.select(&n, &s), vec![0, 1, 2, 3]);
        let thin = NodeSelector::Slab {
            point: [0.0, 0.0, 1.5],
            normal: [0.0, 0.0, 1.0],
            thickness: Some(0.6),
        };
        assert_eq!(thin.select(&n, &s), vec![4, 5, 6, 7]);
        // Corner normals are area-weighted over the triangles at each corner, so they depend
        // on the diagonals: corner 3 is 35.3° from -z, corner 0 54.7°, corners 1 and 2 65.9°,
        // the top corners more than 90°.
        let facing = |angle_deg: f64, within: Option<Box<NodeSelector>>| NodeSelector::Facing {
            direction: [0.0, 0.0, -1.0],
            angle_deg,
            within,
        };
        assert_eq!(facing(70.0, None).select(&n, &s), vec![0, 1, 2, 3]);
        assert_eq!(facing(60.0, None).select(&n, &s), vec![0, 3]);
        assert_eq!(facing(50.0, None).select(&n, &s), vec![3]);
        let limited = facing(70.0, Some(Box::new(b)));
        assert_eq!(limited.select(&n, &s), vec![0, 1]);
    }
}
