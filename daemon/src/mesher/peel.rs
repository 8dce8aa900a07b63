//! Boundary slivers peeled off a mesh.
//!
//! A Delaunay fill of a re-meshed surface can leave a flat tetrahedron lying on the boundary:
//! its four vertices on the surface, two of its faces on the boundary, all four nearly in one
//! plane. The optimisers cannot fix it, because the surface vertices must stay on the surface
//! (gmsh kept a 3.1° one on the `kidney` surface at 5,000 tetrahedra through four meshings).
//! Such a sliver only fills a dent between two surface triangles, so removing it makes its two
//! inner faces the boundary. The surface moves by at most the sliver's height, no vertex
//! moves, and the mesh stays a closed manifold if two conditions hold:
//! - the edge the two inner faces share is not already a boundary edge (else four boundary
//!   faces would meet there);
//! - the vertices of the two boundary faces' shared edge are still used by other tetrahedra.
//!
//! A sliver inside the volume, or one with one or three faces on the boundary, is left alone.

use glam::DVec3;
use lop_sim::mesh::TetMesh;
use std::collections::{HashMap, HashSet};

use super::shape::tet_dihedrals;

/// Most slivers peeled from one mesh: each rebuilds the mesh, and a mesh with more has a
/// problem that peeling does not solve.
const MAX_PEELED: usize = 64;

/// What [`peel_boundary_slivers`] removed.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Peeled {
    /// Tetrahedra removed.
    pub count: usize,
    /// Their volume, in the mesh's units cubed.
    pub volume: f64,
}

/// Removes every boundary sliver (module docs) whose smallest dihedral angle is under
/// `min_degrees`, the flattest first. The mesh is rebuilt (validated, its surface extracted
/// again) after each removal; a removal the rebuild refuses ends the peeling and leaves the
/// mesh as it was before that removal.
pub fn peel_boundary_slivers(mesh: &mut TetMesh, min_degrees: f64) -> Peeled {
    let mut peeled = Peeled::default();
    while peeled.count < MAX_PEELED {
        let Some(t) = peelable(mesh, min_degrees) else {
            break;
        };
        let volume = mesh.tet_volume(t);
        let mut tets = mesh.tets.clone();
        tets.remove(t);
        match TetMesh::from_parts(
            mesh.nodes.clone(),
            tets,
            mesh.fixed.clone(),
            mesh.source.clone(),
        ) {
            Ok(m) => *mesh = m,
            Err(_) => break,
        }
        peeled.count += 1;
        peeled.volume += volume;
    }
    peeled
}

/// The flattest boundary sliver under `min_degrees` that can be peeled, if any.
fn peelable(mesh: &TetMesh, min_degrees: f64) -> Option<usize> {
    let mut slivers: Vec<(f64, usize)> = mesh
        .tets
        .iter()
        .enumerate()
        .filter_map(|(i, t)| {
            let a = tet_dihedrals(t.map(|n| DVec3::from(mesh.nodes[n as usize])));
            let lo = a.iter().copied().fold(f64::INFINITY, f64::min);
            (lo < min_degrees).then_some((lo, i))
        })
        .collect();
    if slivers.is_empty() {
        return None;
    }
    slivers.sort_by(|a, b| a.0.total_cmp(&b.0));
    let sorted3 = |mut f: [u32; 3]| {
        f.sort_unstable();
        f
    };
    let edge = |a: u32, b: u32| (a.min(b), a.max(b));
    let faces: HashSet<[u32; 3]> = mesh.surface.iter().map(|&f| sorted3(f)).collect();
    let edges: HashSet<(u32, u32)> = mesh
        .surface
        .iter()
        .flat_map(|f| [edge(f[0], f[1]), edge(f[1], f[2]), edge(f[2], f[0])])
        .collect();
    let mut uses: HashMap<u32, usize> = HashMap::new();
    for t in &mesh.tets {
        for &n in t {
            *uses.entry(n).or_default() += 1;
        }
    }
    slivers.into_iter().map(|(_, i)| i).find(|&i| {
        let t = mesh.tets[i];
        // Face k leaves out corner k.
        let on_boundary: Vec<usize> = (0..4)
            .filter(|&k| {
                let f = [0, 1, 2, 3]
                    .into_iter()
                    .filter(|&j| j != k)
                    .map(|j| t[j])
                    .collect::<Vec<_>>();
                faces.contains(&sorted3([f[0], f[1], f[2]]))
            })
            .collect();
        if on_boundary.len() != 2 {
            return false;
        }
        // The boundary faces leave out corners p and q: they share the edge of the other two
        // corners, and the inner faces share the edge p-q.
        let (p, q) = (t[on_boundary[0]], t[on_boundary[1]]);
        let shared: Vec<u32> = t.iter().copied().filter(|&n| n != p && n != q).collect();
        !edges.contains(&edge(p, q)) && shared.iter().all(|n| uses.get(n).copied() > Some(1))
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    /// Positively oriented.
    fn oriented(nodes: &[[f64; 3]], mut t: [u32; 4]) -> [u32; 4] {
        let p = t.map(|i| DVec3::from(nodes[i as usize]));
        if (p[1] - p[0]).dot((p[2] - p[0]).cross(p[3] - p[0])) < 0.0 {
            t.swap(2, 3);
        }
        t
    }

    /// A flat square (one corner lifted) as a sliver on top of two tetrahedra that hang from it.
    fn roof(lift: f64) -> TetMesh {
        let nodes = vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, lift],
            [0.5, 0.5, -1.0],
        ];
        let tets = [[0, 1, 2, 3], [0, 1, 2, 4], [0, 2, 3, 4]]
            .map(|t| oriented(&nodes, t))
            .to_vec();
        TetMesh::from_parts(nodes, tets, vec![], PathBuf::from("roof")).unwrap()
    }

    #[test]
    fn a_flat_tetrahedron_with_two_boundary_faces_is_peeled() {
        let mut mesh = roof(0.05);
        let before: f64 = (0..mesh.tets.len()).map(|i| mesh.tet_volume(i)).sum();
        let sliver = mesh.tet_volume(0);
        let peeled = peel_boundary_slivers(&mut mesh, 10.0);
        assert_eq!(peeled.count, 1);
        assert!((peeled.volume - sliver).abs() < 1e-15);
        assert_eq!(mesh.tets.len(), 2);
        // Still closed: every edge of the surface is in exactly two of its triangles.
        let mut count: HashMap<(u32, u32), usize> = HashMap::new();
        for f in &mesh.surface {
            for (a, b) in [(f[0], f[1]), (f[1], f[2]), (f[2], f[0])] {
                *count.entry((a.min(b), a.max(b))).or_default() += 1;
            }
        }
        assert!(count.values().all(|&c| c == 2), "{count:?}");
        let after: f64 = (0..mesh.tets.len()).map(|i| mesh.tet_volume(i)).sum();
        assert!((before - after - sliver).abs() < 1e-12);
    }

    #[test]
    fn a_well_shaped_mesh_and_an_inner_sliver_are_left_alone() {
        // Lifted by half the square: no angle under 10°.
        let mut mesh = roof(0.5);
        assert_eq!(peel_boundary_slivers(&mut mesh, 10.0), Peeled::default());
        assert_eq!(mesh.tets.len(), 3);
        // The sliver with a tetrahedron on each of its boundary faces too: no face of it on
        // the boundary any more.
        let mut mesh = roof(0.05);
        let mut nodes = mesh.nodes.clone();
        nodes.push([0.5, 0.5, 1.0]);
        let mut tets = mesh.tets.clone();
        tets.push(oriented(&nodes, [0, 1, 3, 5]));
        tets.push(oriented(&nodes, [1, 2, 3, 5]));
        mesh = TetMesh::from_parts(nodes, tets, vec![], PathBuf::from("capped")).unwrap();
        assert_eq!(peel_boundary_slivers(&mut mesh, 10.0), Peeled::default());
        assert_eq!(mesh.tets.len(), 5);
    }
}
