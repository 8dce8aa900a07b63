//! Programmatic meshes for tests and benchmarks.

use std::path::PathBuf;

use crate::mesh::TetMesh;

/// A box `[0, size]` split into `cells` hexahedra per axis, each cut into 6 tetrahedra around
/// its main diagonal (Kuhn / Freudenthal split: every cell is cut the same way, so the faces
/// of neighbouring cells match). Nodes for which `fixed(position)` is true are fixed.
///
/// # Panics
/// If a cell count is zero or the mesh does not validate (non-positive size).
#[doc(hidden)]
pub fn box_mesh(size: [f64; 3], cells: [usize; 3], fixed: impl Fn([f64; 3]) -> bool) -> TetMesh {
    assert!(cells.iter().all(|&c| c > 0), "box_mesh: cells must be > 0");
    let [nx, ny, nz] = cells.map(|c| c + 1);
    let id = |i: usize, j: usize, k: usize| (i + nx * (j + ny * k)) as u32;
    let mut nodes = Vec::with_capacity(nx * ny * nz);
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                nodes.push([
                    size[0] * i as f64 / cells[0] as f64,
                    size[1] * j as f64 / cells[1] as f64,
                    size[2] * k as f64 / cells[2] as f64,
                ]);
            }
        }
    }
    // The 6 monotone paths from corner 000 to 111, one per axis permutation.
    const PERMS: [[usize; 3]; 6] = [
        [0, 1, 2],
        [0, 2, 1],
        [1, 0, 2],
        [1, 2, 0],
        [2, 0, 1],
        [2, 1, 0],
    ];
    let mut tets = Vec::with_capacity(6 * cells.iter().product::<usize>());
    for k in 0..cells[2] {
        for j in 0..cells[1] {
            for i in 0..cells[0] {
                for p in PERMS {
                    let mut c = [i, j, k];
                    let mut t = [id(c[0], c[1], c[2]); 4];
                    for (s, &axis) in p.iter().enumerate() {
                        c[axis] += 1;
                        t[s + 1] = id(c[0], c[1], c[2]);
                    }
                    // Orient positively.
                    let x = t.map(|n| nodes[n as usize]);
                    let e = |a: usize| [0, 1, 2].map(|r| x[a][r] - x[0][r]);
                    let (a, b, cc) = (e(1), e(2), e(3));
                    let det = a[0] * (b[1] * cc[2] - b[2] * cc[1])
                        - a[1] * (b[0] * cc[2] - b[2] * cc[0])
                        + a[2] * (b[0] * cc[1] - b[1] * cc[0]);
                    if det < 0.0 {
                        t.swap(1, 2);
                    }
                    tets.push(t);
                }
            }
        }
    }
    let fixed_nodes: Vec<u32> = nodes
        .iter()
        .enumerate()
        .filter(|(_, p)| fixed(**p))
        .map(|(i, _)| i as u32)
        .collect();
    TetMesh::from_parts(nodes, tets, fixed_nodes, PathBuf::from("box_mesh"))
        .expect("box_mesh builds a valid mesh")
}
