//! Removing tetrahedra from a mesh: the topology half of a cut ([`TetMesh::without_tets`]).
//!
//! The nodes keep their numbers. A node no kept tetrahedron uses stays in the mesh, unused
//! (every model holds such a node still and gives it no mass), so positions, velocities,
//! temperatures and the renderers' per-node buffers keep their layout from one topology to
//! the next; only the tetrahedra and the surface change.
//!
//! **Pieces.** What is left falls apart into pieces: sets of tetrahedra joined through shared
//! faces. Two tetrahedra that share only an edge or a node are not joined (a hinge of no area
//! holds no tissue). Which pieces stay:
//!
//! - a mesh with fixed nodes keeps every piece that holds a fixed node and has at least
//!   [`MIN_PIECE_TETS`] tetrahedra; a piece cut loose from every fixed node is taken out with
//!   the cut (in surgery: the specimen, lifted out), so nothing falls free through the scene;
//! - a mesh without fixed nodes keeps its largest piece by volume (the first, by tetrahedron
//!   order, of equal ones), if it has at least [`MIN_PIECE_TETS`] tetrahedra;
//! - a piece of fewer than [`MIN_PIECE_TETS`] tetrahedra never stays: a shred that small has a
//!   sliver's stiffness without the mass around it that steadies it.
//!
//! A cut that would leave no piece is refused ([`CutRefused::WholeBody`]): a body is never
//! cut away whole, and a cut through every fixed node's tissue is the same case.

use std::fmt;

use super::surface::{extract, outward_faces};
use super::validate::Origin;
use super::TetMesh;

/// The fewest tetrahedra a piece left by a cut keeps (module docs).
pub const MIN_PIECE_TETS: usize = 4;

/// A mesh after a cut, and what the cut took.
#[derive(Debug, Clone)]
pub struct MeshCut {
    /// The mesh left: the same nodes (unused ones included), the kept tetrahedra in their old
    /// order, their surface, the same fixed nodes.
    pub mesh: TetMesh,
    /// For each tetrahedron of `mesh`, its index in the mesh before the cut.
    pub kept: Vec<u32>,
    /// Tetrahedra removed: those asked for, and those of the pieces taken out.
    pub removed_tets: usize,
    /// Of them, those of pieces taken out (cut loose, or too small).
    pub piece_tets: usize,
    /// Pieces taken out.
    pub pieces_removed: usize,
    /// Pieces left.
    pub pieces_kept: usize,
    /// Nodes used by a tetrahedron before the cut and by none after it.
    pub nodes_freed: usize,
    /// Rest volume removed, m³.
    pub volume_removed: f64,
}

/// Why a cut removes nothing.
#[derive(Debug, Clone, PartialEq)]
pub enum CutRefused {
    /// The mask does not have one entry per tetrahedron.
    WrongLength {
        /// Entries given.
        got: usize,
        /// Tetrahedra of the mesh.
        expected: usize,
    },
    /// No tetrahedron was asked for.
    Nothing,
    /// The cut would leave no piece (module docs): the whole body, or all the tissue around
    /// its fixed nodes.
    WholeBody {
        /// Tetrahedra asked for.
        asked: usize,
        /// Tetrahedra of the mesh.
        tets: usize,
    },
}

impl fmt::Display for CutRefused {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CutRefused::WrongLength { got, expected } => write!(
                f,
                "a cut names {got} tetrahedra where the mesh has {expected}"
            ),
            CutRefused::Nothing => write!(f, "the cut removes no tetrahedron"),
            CutRefused::WholeBody { asked, tets } => write!(
                f,
                "the cut ({asked} of {tets} tetrahedra) would leave no piece held by a fixed \
                 node of at least {MIN_PIECE_TETS} tetrahedra: a body is never cut away whole"
            ),
        }
    }
}

impl std::error::Error for CutRefused {}

impl TetMesh {
    /// The mesh without the tetrahedra `remove` marks (one entry per tetrahedron), and without
    /// the pieces that cut leaves loose or too small (module docs).
    ///
    /// # Errors
    /// [`CutRefused`]: a mask of the wrong length, one that marks nothing, or a cut that
    /// would leave no piece. The mesh is unchanged either way (`self` is not modified).
    pub fn without_tets(&self, remove: &[bool]) -> Result<MeshCut, CutRefused> {
        let n_tets = self.tets.len();
        if remove.len() != n_tets {
            return Err(CutRefused::WrongLength {
                got: remove.len(),
                expected: n_tets,
            });
        }
        let asked = remove.iter().filter(|&&r| r).count();
        if asked == 0 {
            return Err(CutRefused::Nothing);
        }
        let refused = CutRefused::WholeBody {
            asked,
            tets: n_tets,
        };
        let pieces = Pieces::of(&self.tets, remove);
        let mut fixed = vec![false; self.nodes.len()];
        for &f in &self.fixed {
            fixed[f as usize] = true;
        }
        // Per piece: tetrahedra, volume, whether it holds a fixed node.
        let n = pieces.count;
        let (mut size, mut volume, mut held) = (vec![0usize; n], vec![0.0f64; n], vec![false; n]);
        for (t, tet) in self.tets.iter().enumerate() {
            if let Some(p) = pieces.of_tet[t] {
                size[p] += 1;
                volume[p] += self.tet_volume(t);
                held[p] |= tet.iter().any(|&k| fixed[k as usize]);
            }
        }
        let keep: Vec<bool> = if self.fixed.is_empty() {
            let largest = (0..n).fold(None, |best: Option<usize>, p| match best {
                Some(b) if volume[b] >= volume[p] => Some(b),
                _ => Some(p),
            });
            (0..n)
                .map(|p| Some(p) == largest && size[p] >= MIN_PIECE_TETS)
                .collect()
        } else {
            (0..n)
                .map(|p| held[p] && size[p] >= MIN_PIECE_TETS)
                .collect()
        };
        if !keep.iter().any(|&k| k) {
            return Err(refused);
        }
        let mut tets = Vec::with_capacity(n_tets - asked);
        let mut kept = Vec::with_capacity(n_tets - asked);
        let mut volume_removed = 0.0;
        for (t, tet) in self.tets.iter().enumerate() {
            match pieces.of_tet[t] {
                Some(p) if keep[p] => {
                    tets.push(*tet);
                    kept.push(t as u32);
                }
                _ => volume_removed += self.tet_volume(t),
            }
        }
        let mut used_before = vec![false; self.nodes.len()];
        let mut used_after = vec![false; self.nodes.len()];
        for tet in &self.tets {
            tet.iter().for_each(|&k| used_before[k as usize] = true);
        }
        for tet in &tets {
            tet.iter().for_each(|&k| used_after[k as usize] = true);
        }
        let nodes_freed = used_before
            .iter()
            .zip(&used_after)
            .filter(|(b, a)| **b && !**a)
            .count();
        // A subset of a valid mesh's tetrahedra has no face of three tetrahedra and no two on
        // one side of a face: extraction cannot fail.
        let surface = extract(&tets, &Origin::in_memory(self.source.clone()))
            .expect("a subset of a valid mesh has a valid surface");
        let removed_tets = n_tets - tets.len();
        let pieces_kept = keep.iter().filter(|&&k| k).count();
        Ok(MeshCut {
            mesh: TetMesh {
                nodes: self.nodes.clone(),
                tets,
                surface,
                fixed: self.fixed.clone(),
                source: self.source.clone(),
            },
            kept,
            removed_tets,
            piece_tets: removed_tets - asked,
            pieces_removed: n - pieces_kept,
            pieces_kept,
            nodes_freed,
            volume_removed,
        })
    }
}

/// The pieces of the tetrahedra a mask keeps: components joined through shared faces.
struct Pieces {
    /// Per tetrahedron: its piece, `None` for a removed one.
    of_tet: Vec<Option<usize>>,
    count: usize,
}

impl Pieces {
    fn of(tets: &[[u32; 4]], remove: &[bool]) -> Pieces {
        let mut parent: Vec<usize> = (0..tets.len()).collect();
        fn root(parent: &mut [usize], mut i: usize) -> usize {
            while parent[i] != i {
                parent[i] = parent[parent[i]];
                i = parent[i];
            }
            i
        }
        // Faces of the kept tetrahedra keyed by their sorted nodes; a face appears at most
        // twice (the mesh is manifold), so neighbours are adjacent entries after the sort.
        let mut faces: Vec<([u32; 3], usize)> = Vec::with_capacity(tets.len() * 4);
        for (t, &tet) in tets.iter().enumerate() {
            if !remove[t] {
                for mut f in outward_faces(tet) {
                    f.sort_unstable();
                    faces.push((f, t));
                }
            }
        }
        faces.sort_unstable();
        for pair in faces.windows(2) {
            if pair[0].0 == pair[1].0 {
                let (a, b) = (root(&mut parent, pair[0].1), root(&mut parent, pair[1].1));
                if a != b {
                    parent[a.max(b)] = a.min(b);
                }
            }
        }
        let mut id = vec![usize::MAX; tets.len()];
        let mut count = 0;
        let of_tet = (0..tets.len())
            .map(|t| {
                if remove[t] {
                    return None;
                }
                let r = root(&mut parent, t);
                if id[r] == usize::MAX {
                    id[r] = count;
                    count += 1;
                }
                Some(id[r])
            })
            .collect();
        Pieces { of_tet, count }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::vec3::{cross, norm, sub};

    /// A bar of `n` unit cubes along x, each cut into 6 tetrahedra (`box_mesh`: cube `i`'s
    /// are tetrahedra `6i..6i + 6`), nodes fixed at x = 0 if `fixed`.
    fn bar(n: usize, fixed: bool) -> TetMesh {
        crate::fem::box_mesh([n as f64, 1.0, 1.0], [n, 1, 1], |p| fixed && p[0] < 1e-9)
    }

    fn cube(mesh: &TetMesh, i: usize) -> Vec<bool> {
        (0..mesh.tets.len()).map(|t| t / 6 == i).collect()
    }

    #[test]
    fn a_cut_through_a_clamped_bar_takes_the_loose_end_out() {
        let mesh = bar(5, true);
        let cut = mesh.without_tets(&cube(&mesh, 2)).expect("a cut");
        // Cubes 0 and 1 stay (held at x = 0); 3 and 4 are cut loose and go with the cut.
        assert_eq!(cut.mesh.tets.len(), 12);
        assert_eq!(cut.kept, (0..12).collect::<Vec<u32>>());
        assert_eq!((cut.removed_tets, cut.piece_tets), (18, 12));
        assert_eq!((cut.pieces_kept, cut.pieces_removed), (1, 1));
        assert!((cut.volume_removed - 3.0).abs() < 1e-12);
        // Nodes at x = 3, 4, 5 are used by nothing now (those at x = 2 still close cube 1).
        assert_eq!(cut.nodes_freed, 12);
        assert_eq!(cut.mesh.nodes.len(), mesh.nodes.len());
        // The new surface closes the stump: a 2 × 1 × 1 box, two ends of 1 and four sides of 2.
        let area: f64 = cut
            .mesh
            .surface
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|k| cut.mesh.nodes[k as usize]);
                0.5 * norm(cross(sub(b, a), sub(c, a)))
            })
            .sum();
        assert!((area - (2.0 + 4.0 * 2.0)).abs() < 1e-12, "area {area}");
    }

    #[test]
    fn a_free_bar_keeps_its_larger_piece() {
        let mesh = bar(5, false);
        let cut = mesh.without_tets(&cube(&mesh, 1)).expect("a cut");
        // Cube 0 alone (6 tetrahedra) against cubes 2–4 (18): the larger stays.
        assert_eq!(cut.kept, (12..30).collect::<Vec<u32>>());
        assert_eq!(cut.pieces_removed, 1);
    }

    #[test]
    fn a_cut_never_takes_the_whole_body() {
        let mesh = bar(3, true);
        let all = vec![true; mesh.tets.len()];
        assert_eq!(
            mesh.without_tets(&all).unwrap_err(),
            CutRefused::WholeBody {
                asked: 18,
                tets: 18
            }
        );
        // Through the clamped cube: every piece left is loose.
        assert!(matches!(
            mesh.without_tets(&cube(&mesh, 0)),
            Err(CutRefused::WholeBody { asked: 6, .. })
        ));
        assert_eq!(
            mesh.without_tets(&[false; 18]).unwrap_err(),
            CutRefused::Nothing
        );
        assert!(matches!(
            mesh.without_tets(&[true]),
            Err(CutRefused::WrongLength {
                got: 1,
                expected: 18
            })
        ));
    }

    #[test]
    fn a_shred_of_tissue_goes_with_the_cut() {
        let mesh = bar(2, true);
        // All of cube 1 but one tetrahedron: one that shares a face with the clamped cube
        // joins its piece and stays; one that touches it only along an edge or at a node is a
        // piece of one tetrahedron and goes with the cut.
        let (mut joined, mut shreds) = (0, 0);
        for keep in 0..6 {
            let mut remove = cube(&mesh, 1);
            remove[6 + keep] = false;
            let cut = mesh.without_tets(&remove).expect("a cut");
            match cut.mesh.tets.len() {
                7 => joined += 1,
                6 => {
                    assert_eq!((cut.pieces_removed, cut.piece_tets), (1, 1));
                    shreds += 1;
                }
                n => panic!("{n} tetrahedra left"),
            }
        }
        // Kuhn cubes meet in two triangles: two tetrahedra of cube 1 hold one each.
        assert_eq!((joined, shreds), (2, 4));
    }
}
