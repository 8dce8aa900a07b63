//! Boundary surface and edge extraction from a positively oriented tetrahedral mesh.

use super::validate::Origin;
use super::MeshReadError;

/// The four faces of a positively oriented tetrahedron `[a, b, c, d]`, each wound
/// counter-clockwise seen from outside the tetrahedron (the face opposite a corner is wound so
/// that its normal points away from that corner).
pub(crate) fn outward_faces([a, b, c, d]: [u32; 4]) -> [[u32; 3]; 4] {
    [[a, c, b], [a, b, d], [a, d, c], [b, c, d]]
}

fn sorted(mut f: [u32; 3]) -> [u32; 3] {
    f.sort_unstable();
    f
}

/// Whether two triangles over the same three nodes have the same winding (one is a rotation
/// of the other).
fn same_winding(f: [u32; 3], g: [u32; 3]) -> bool {
    g == f || g == [f[1], f[2], f[0]] || g == [f[2], f[0], f[1]]
}

/// Triangles that belong to exactly one tetrahedron, wound outward, in the order of the
/// tetrahedra. Fails if a face belongs to three or more tetrahedra, or if two tetrahedra lie on
/// the same side of a face they share; of several such problems, the one found at the earliest
/// tetrahedron is reported.
pub(crate) fn extract(tets: &[[u32; 4]], origin: &Origin) -> Result<Vec<[u32; 3]>, MeshReadError> {
    // Every face of every tetrahedron, keyed by its sorted nodes; sorting groups shared faces
    // (and is faster and more predictable than hashing).
    let mut faces: Vec<([u32; 3], usize, usize)> = Vec::with_capacity(tets.len() * 4);
    for (t, &tet) in tets.iter().enumerate() {
        for (k, face) in outward_faces(tet).into_iter().enumerate() {
            faces.push((sorted(face), t, k));
        }
    }
    faces.sort_unstable();

    let face = |t: usize, k: usize| outward_faces(tets[t])[k];
    let mut boundary = vec![false; tets.len() * 4];
    // (offending tet, error) with the smallest offending tet.
    let mut first_problem: Option<(usize, MeshReadError)> = None;
    for group in faces.chunk_by(|a, b| a.0 == b.0) {
        let problem = match *group {
            [(_, t, k)] => {
                boundary[4 * t + k] = true;
                None
            }
            [(_, t1, k1), (_, t2, k2)] if same_winding(face(t1, k1), face(t2, k2)) => {
                Some((t2, overlapping(origin, t2, t1, face(t2, k2))))
            }
            [_, _] => None,
            [_, _, (_, t3, k3), ..] => Some((t3, non_manifold(origin, t3, face(t3, k3)))),
            [] => None,
        };
        if let Some((t, err)) = problem {
            if first_problem.as_ref().is_none_or(|(first, _)| t < *first) {
                first_problem = Some((t, err));
            }
        }
    }
    if let Some((_, err)) = first_problem {
        return Err(err);
    }
    Ok(tets
        .iter()
        .enumerate()
        .flat_map(|(t, &tet)| {
            let boundary = &boundary;
            outward_faces(tet)
                .into_iter()
                .enumerate()
                .filter(move |&(k, _)| boundary[4 * t + k])
                .map(|(_, f)| f)
        })
        .collect())
}

fn overlapping(origin: &Origin, t: usize, other: usize, face: [u32; 3]) -> MeshReadError {
    MeshReadError::OverlappingTets {
        path: origin.tet_file.clone(),
        line: origin.line(t),
        tet: origin.tet_label(t),
        other_line: origin.line(other),
        other_tet: origin.tet_label(other),
        face: origin.face_labels(face),
    }
}

fn non_manifold(origin: &Origin, t: usize, face: [u32; 3]) -> MeshReadError {
    MeshReadError::NonManifoldFace {
        path: origin.tet_file.clone(),
        line: origin.line(t),
        tet: origin.tet_label(t),
        face: origin.face_labels(face),
    }
}

/// Unique undirected edges `[lo, hi]`, sorted.
pub(crate) fn edges(tets: &[[u32; 4]]) -> Vec<[u32; 2]> {
    let mut edges: Vec<[u32; 2]> = tets
        .iter()
        .flat_map(|t| {
            super::quality::EDGES.map(|[i, j]| {
                let (a, b) = (t[i], t[j]);
                [a.min(b), a.max(b)]
            })
        })
        .collect();
    edges.sort_unstable();
    edges.dedup();
    edges
}

#[cfg(test)]
mod tests {
    use super::super::quality::{cross, dot, sub};
    use super::*;

    #[test]
    fn faces_of_a_positive_tet_point_outward() {
        let p = [[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        let centroid = [0.25; 3];
        for f in outward_faces([0, 1, 2, 3]) {
            let [a, b, c] = f.map(|i| p[i as usize]);
            let n = cross(sub(b, a), sub(c, a));
            assert!(dot(n, sub(a, centroid)) > 0.0, "face {f:?} points inward");
        }
    }

    #[test]
    fn winding() {
        assert!(same_winding([1, 2, 3], [3, 1, 2]));
        assert!(same_winding([1, 2, 3], [2, 3, 1]));
        assert!(!same_winding([1, 2, 3], [1, 3, 2]));
    }
}
