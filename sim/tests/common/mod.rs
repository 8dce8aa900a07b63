//! Fixtures shared by the mass-spring integration tests.
#![allow(dead_code)] // each test file uses a subset

use lop_sim::fem::{FemMode, FemParameters};
use lop_sim::mesh::{read_mesh, TetMesh};
use lop_test_support::fixtures::mesh_path;

/// A mesh from `assets/meshes`.
pub fn shipped_mesh(name: &str) -> TetMesh {
    read_mesh(&mesh_path(name)).unwrap_or_else(|e| panic!("shipped mesh {name}: {e}"))
}

/// The shipped §6.1 cylinder (base fixed).
pub fn cylinder() -> TetMesh {
    shipped_mesh("cylinder")
}

/// Table 6.1's FEM column (the §6.1 cylinders), corotational.
pub fn cylinder_fem_params() -> FemParameters {
    FemParameters {
        young: 600.0,
        poisson: 0.0023,
        density: 30.0,
        damping: 1.0,
        dt: 0.02,
        mode: FemMode::Corotational,
    }
}

/// Sum of spring forces acting on the fixed nodes (recomputed from positions).
pub fn support_reaction(mesh: &TetMesh, x: &[[f64; 3]], k: f64) -> [f64; 3] {
    let fixed: std::collections::HashSet<u32> = mesh.fixed.iter().copied().collect();
    let mut r = [0.0; 3];
    for [a, b] in mesh.edges() {
        let (pa, pb) = (mesh.nodes[a as usize], mesh.nodes[b as usize]);
        let rest =
            ((pb[0] - pa[0]).powi(2) + (pb[1] - pa[1]).powi(2) + (pb[2] - pa[2]).powi(2)).sqrt();
        let (xa, xb) = (x[a as usize], x[b as usize]);
        let d = [xb[0] - xa[0], xb[1] - xa[1], xb[2] - xa[2]];
        let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        let f = k * (len - rest) / len; // force on a along d
        for kk in 0..3 {
            if fixed.contains(&a) {
                r[kk] += f * d[kk];
            }
            if fixed.contains(&b) {
                r[kk] -= f * d[kk];
            }
        }
    }
    r
}
