//! Mesh module: building, surface extraction, info, and round trips through every format.

use std::collections::HashMap;
use std::fs;
use std::path::{Path, PathBuf};

use lop_sim::mesh::{
    read_gmsh, read_mesh, read_tetgen, read_vtk, write_bnd, write_tetgen, write_tetgen_numbered,
    write_vtk, TetMesh,
};
use lop_test_support::fixtures::meshes_dir;
use lop_test_support::vec3::{cross, dot, sub};

// ---------------------------------------------------------------------------------------------
// helpers

/// A scratch directory, removed when dropped (unique per process, so concurrent runs of the
/// suite don't clash).
struct Scratch(PathBuf);

impl std::ops::Deref for Scratch {
    type Target = Path;

    fn deref(&self) -> &Path {
        &self.0
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = fs::remove_dir_all(&self.0);
    }
}

fn scratch(name: &str) -> Scratch {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("lop-sim-mesh-io-{}-{name}", std::process::id()));
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(&dir).unwrap();
    Scratch(dir)
}

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name)
}

fn vol6(p: &[[f64; 3]], t: [u32; 4]) -> f64 {
    let [a, b, c, d] = t.map(|i| p[i as usize]);
    let u = sub(b, a);
    let v = sub(c, a);
    let w = sub(d, a);
    dot(u, cross(v, w))
}

/// Swaps two corners of every negatively oriented tetrahedron.
fn orient_positive(nodes: &[[f64; 3]], tets: &mut [[u32; 4]]) {
    for t in tets {
        if vol6(nodes, *t) < 0.0 {
            t.swap(0, 1);
        }
    }
}

/// Corners of the unit cube; corner `x + 2y + 4z`.
fn cube_nodes(size: f64) -> Vec<[f64; 3]> {
    (0..8)
        .map(|i| {
            [
                (i & 1) as f64 * size,
                ((i >> 1) & 1) as f64 * size,
                ((i >> 2) & 1) as f64 * size,
            ]
        })
        .collect()
}

/// The cube split into four corner tetrahedra and a central one.
fn cube5_tets() -> Vec<[u32; 4]> {
    let mut tets = vec![
        [1, 0, 3, 5],
        [2, 0, 3, 6],
        [4, 0, 5, 6],
        [7, 3, 5, 6],
        [0, 3, 5, 6],
    ];
    orient_positive(&cube_nodes(1.0), &mut tets);
    tets
}

/// The cube split into six tetrahedra around the diagonal 0-7 (Kuhn / Freudenthal).
fn cube6_tets(corner: impl Fn(u32) -> u32) -> Vec<[u32; 4]> {
    let perms = [
        [1, 2, 4],
        [1, 4, 2],
        [2, 1, 4],
        [2, 4, 1],
        [4, 1, 2],
        [4, 2, 1],
    ];
    perms
        .iter()
        .map(|p| [0, p[0], p[0] + p[1], 7].map(&corner))
        .collect()
}

fn cube5() -> TetMesh {
    TetMesh::from_parts(
        cube_nodes(1.0),
        cube5_tets(),
        vec![2, 0, 1, 3, 0],
        "cube5".into(),
    )
    .unwrap()
}

/// An n×n×n block of Kuhn-split cubes of edge `h`.
fn block(n: u32, h: f64) -> TetMesh {
    let id = |x: u32, y: u32, z: u32| x + (n + 1) * (y + (n + 1) * z);
    let mut nodes = Vec::new();
    for z in 0..=n {
        for y in 0..=n {
            for x in 0..=n {
                nodes.push([x as f64 * h, y as f64 * h, z as f64 * h]);
            }
        }
    }
    let mut tets = Vec::new();
    for z in 0..n {
        for y in 0..n {
            for x in 0..n {
                tets.extend(cube6_tets(|c| {
                    id(x + (c & 1), y + ((c >> 1) & 1), z + ((c >> 2) & 1))
                }));
            }
        }
    }
    orient_positive(&nodes, &mut tets);
    let fixed = (0..=n)
        .flat_map(|y| (0..=n).map(move |x| id(x, y, 0)))
        .collect();
    TetMesh::from_parts(nodes, tets, fixed, "block".into()).unwrap()
}

/// The surface is closed and consistently wound: every directed edge appears exactly once and
/// its reverse exactly once.
fn assert_closed(mesh: &TetMesh) {
    let mut directed: HashMap<(u32, u32), usize> = HashMap::new();
    for t in &mesh.surface {
        for k in 0..3 {
            *directed.entry((t[k], t[(k + 1) % 3])).or_default() += 1;
        }
    }
    for (&(a, b), &n) in &directed {
        assert_eq!(n, 1, "directed edge {a}->{b} used {n} times");
        assert_eq!(
            directed.get(&(b, a)),
            Some(&1),
            "edge {a}-{b} is not shared by exactly two triangles with opposite winding"
        );
    }
}

/// Divergence theorem: V = Σ (centroid · area normal) / 3 over the outward surface.
fn surface_volume(mesh: &TetMesh) -> f64 {
    mesh.surface
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| mesh.nodes[i as usize]);
            let centroid = [0, 1, 2].map(|k| (a[k] + b[k] + c[k]) / 3.0);
            let n2 = cross(sub(b, a), sub(c, a)); // twice the area normal
            dot(centroid, n2) / 6.0
        })
        .sum()
}

/// Everything a valid mesh promises, plus the surface checks.
fn assert_valid(mesh: &TetMesh) {
    let n = mesh.nodes.len() as u32;
    for (i, t) in mesh.tets.iter().enumerate() {
        assert!(t.iter().all(|&v| v < n));
        assert!(mesh.tet_volume(i) > 0.0, "tet {i} not positive");
    }
    assert!(mesh.fixed.windows(2).all(|w| w[0] < w[1]));
    assert!(mesh.fixed.iter().all(|&v| v < n));
    assert_closed(mesh);
    let volume = mesh.info().volume;
    assert!(
        (surface_volume(mesh) - volume).abs() <= 1e-12 * volume.max(1.0),
        "divergence theorem: {} vs {volume}",
        surface_volume(mesh)
    );
}

/// Same mesh apart from `source`.
fn assert_same(a: &TetMesh, b: &TetMesh) {
    assert_eq!(a.nodes, b.nodes);
    assert_eq!(a.tets, b.tets);
    assert_eq!(a.surface, b.surface);
    assert_eq!(a.fixed, b.fixed);
}

// ---------------------------------------------------------------------------------------------
// building, surface, info

#[test]
fn cube5_counts_surface_and_volume() {
    let mesh = cube5();
    let info = mesh.info();
    assert_eq!(info.nodes, 8);
    assert_eq!(info.tets, 5);
    assert_eq!(info.surface_triangles, 12);
    assert_eq!(info.fixed_nodes, 4);
    assert_eq!(info.unused_nodes, 0);
    assert_eq!(mesh.fixed, vec![0, 1, 2, 3]);
    assert!((info.volume - 1.0).abs() < 1e-12);
    assert_eq!(info.bbox_min, [0.0; 3]);
    assert_eq!(info.bbox_max, [1.0; 3]);
    // 12 cube edges + 6 face diagonals.
    assert_eq!(mesh.edges().len(), 18);
    assert!(mesh.edges().windows(2).all(|w| w[0] < w[1]));
    assert!(mesh.edges().iter().all(|[a, b]| a < b));
    assert_eq!(mesh.surface_nodes(), (0..8).collect::<Vec<u32>>());
    assert!((mesh.tet_volume(4) - 1.0 / 3.0).abs() < 1e-15);
    assert_valid(&mesh);
    // Every surface triangle lies in a face of the cube and its normal points out of it.
    for t in &mesh.surface {
        let [a, b, c] = t.map(|i| mesh.nodes[i as usize]);
        let n = cross(sub(b, a), sub(c, a));
        let centroid = [0, 1, 2].map(|k| (a[k] + b[k] + c[k]) / 3.0 - 0.5);
        assert!(dot(n, centroid) > 0.0, "triangle {t:?} points inward");
    }
}

#[test]
fn cube6_counts() {
    let mut tets = cube6_tets(|c| c);
    orient_positive(&cube_nodes(1.0), &mut tets);
    let mesh = TetMesh::from_parts(cube_nodes(1.0), tets, vec![], "cube6".into()).unwrap();
    assert_eq!(mesh.surface.len(), 12);
    assert_eq!(mesh.edges().len(), 19); // + the main diagonal
    assert!((mesh.info().volume - 1.0).abs() < 1e-12);
    assert!(mesh.fixed.is_empty());
    assert_valid(&mesh);
}

#[test]
fn block_surface_is_closed_and_outward() {
    let mesh = block(3, 0.01);
    let info = mesh.info();
    assert_eq!(info.nodes, 64);
    assert_eq!(info.tets, 6 * 27);
    assert_eq!(info.surface_triangles, 6 * 9 * 2);
    assert_eq!(info.fixed_nodes, 16);
    assert_eq!(mesh.surface_nodes().len(), 64 - 8); // all but the 2×2×2 interior nodes
    assert!((info.volume - 2.7e-5).abs() < 1e-18);
    assert_valid(&mesh);
}

#[test]
fn consistently_negative_tets_are_flipped() {
    let mut tets = cube5_tets();
    for t in &mut tets {
        t.swap(2, 3);
    }
    let mesh = TetMesh::from_parts(cube_nodes(2.0), tets.clone(), vec![], "neg".into()).unwrap();
    for (i, (got, orig)) in mesh.tets.iter().zip(&tets).enumerate() {
        let mut a = *got;
        let mut b = *orig;
        a.sort_unstable();
        b.sort_unstable();
        assert_eq!(a, b, "tet {i} changed its nodes");
    }
    assert!((mesh.info().volume - 8.0).abs() < 1e-12);
    assert_valid(&mesh);
}

#[test]
fn regular_tet_quality_is_one() {
    let s = 1.0 / 2f64.sqrt();
    let nodes = vec![
        [1.0, 0.0, -s],
        [-1.0, 0.0, -s],
        [0.0, 1.0, s],
        [0.0, -1.0, s],
    ];
    let mut tets = vec![[0, 1, 2, 3]];
    orient_positive(&nodes, &mut tets);
    let mesh = TetMesh::from_parts(nodes, tets, vec![], "regular".into()).unwrap();
    let info = mesh.info();
    assert!(
        (info.quality_min - 1.0).abs() < 1e-12,
        "{}",
        info.quality_min
    );
    assert!((info.quality_mean - 1.0).abs() < 1e-12);
    assert_eq!(info.surface_triangles, 4);
    assert!((info.volume - 8.0 / (6.0 * 2f64.sqrt())).abs() < 1e-12);
    assert_valid(&mesh);
}

#[test]
fn cube_quality_is_below_one() {
    let info = cube5().info();
    // Corner tets: 12 (1/2)^(2/3) / 9; central (regular, edge sqrt 2): 1.
    let corner = 12.0 * 0.5f64.powf(2.0 / 3.0) / 9.0;
    assert!((info.quality_min - corner).abs() < 1e-12);
    assert!((info.quality_mean - (4.0 * corner + 1.0) / 5.0).abs() < 1e-12);
}

#[test]
fn info_display_is_a_readable_summary() {
    let text = cube5().info().to_string();
    for needle in [
        "nodes:             8",
        "fixed:           4",
        "tetrahedra:        5",
        "surface triangles: 12",
        "volume:            1.000000e0 m^3",
        "quality:",
    ] {
        assert!(text.contains(needle), "missing {needle:?} in\n{text}");
    }
    assert!(text.lines().count() >= 6);
}

#[test]
fn unused_nodes_are_kept_and_counted() {
    let mut nodes = cube_nodes(1.0);
    nodes.push([5.0, 5.0, 5.0]);
    let mesh = TetMesh::from_parts(nodes, cube5_tets(), vec![8], "extra".into()).unwrap();
    let info = mesh.info();
    assert_eq!(info.nodes, 9);
    assert_eq!(info.unused_nodes, 1);
    assert_eq!(info.bbox_max, [5.0; 3]);
    assert!(info.to_string().contains("unused:          1"));
    assert_eq!(mesh.surface_nodes().len(), 8);
}

// ---------------------------------------------------------------------------------------------
// TetGen

#[test]
fn tetgen_fixture_is_read_and_normalised() {
    let mesh = read_mesh(&data("cube.node")).unwrap();
    assert_eq!(mesh.source, data("cube.node"));
    let info = mesh.info();
    assert_eq!((info.nodes, info.tets, info.surface_triangles), (8, 5, 12));
    assert_eq!(mesh.fixed, vec![0, 1, 2, 3]);
    assert!((info.volume - 1.0).abs() < 1e-12);
    assert_eq!(mesh.nodes[7], [1.0, 1.0, 1.0]);
    // The file lists every tet negatively; the first one is 2 1 4 6 (1-based).
    let mut first = mesh.tets[0];
    first.sort_unstable();
    assert_eq!(first, [0, 1, 3, 5]);
    assert_valid(&mesh);
    // All the ways to name it give the same mesh.
    for p in [data("cube"), data("cube.ele"), data("cube.face")] {
        assert_same(&read_mesh(&p).unwrap(), &mesh);
    }
    assert_same(&read_tetgen(&data("cube")).unwrap(), &mesh);
}

#[test]
fn tetgen_round_trip_one_based() {
    let dir = scratch("tetgen1");
    let mesh = block(2, 0.1);
    write_tetgen(&mesh, &dir.join("block")).unwrap();
    let node = fs::read_to_string(dir.join("block.node")).unwrap();
    assert!(
        node.lines().any(|l| l.starts_with("1 0.0 0.0 0.0")),
        "{node}"
    );
    let bnd = fs::read_to_string(dir.join("block.bnd")).unwrap();
    assert!(bnd.lines().any(|l| l == "9"));
    let back = read_mesh(&dir.join("block")).unwrap();
    assert_same(&mesh, &back);
    assert_eq!(back.source, dir.join("block.node"));
    assert_valid(&back);
}

#[test]
fn tetgen_round_trip_zero_based() {
    let dir = scratch("tetgen0");
    // Awkward coordinates must come back bit for bit.
    let mut mesh = cube5();
    let nodes: Vec<[f64; 3]> = mesh
        .nodes
        .iter()
        .map(|p| p.map(|v| v * 0.1 + 1e-7 / 3.0))
        .collect();
    mesh = TetMesh::from_parts(nodes, mesh.tets, mesh.fixed, "odd".into()).unwrap();
    write_tetgen_numbered(&mesh, &dir.join("odd.v2"), 0).unwrap();
    let node = fs::read_to_string(dir.join("odd.v2.node")).unwrap();
    assert!(node.lines().any(|l| l.starts_with("0 ")), "{node}");
    let back = read_tetgen(&dir.join("odd.v2.ele")).unwrap();
    assert_same(&mesh, &back);
    assert!(write_tetgen_numbered(&mesh, &dir.join("x"), 2).is_err());
}

#[test]
fn tetgen_ten_node_tets_and_commas() {
    let dir = scratch("tet10");
    let base = dir.join("t10");
    // One tetrahedron with its six edge midpoints; fields separated by commas too.
    fs::write(
        base.with_extension("node"),
        "10 3 0 0\n\
         0, 0 0 0\n1, 1 0 0\n2, 0 1 0\n3, 0 0 1\n\
         4, 0.5 0 0\n5, 0 0.5 0\n6, 0 0 0.5\n7, 0.5 0.5 0\n8, 0 0.5 0.5\n9, 0.5 0 0.5\n",
    )
    .unwrap();
    fs::write(base.with_extension("ele"), "1 10\n0 0 1 2 3 4 5 6 7 8 9\n").unwrap();
    let mesh = read_tetgen(&base).unwrap();
    assert_eq!(mesh.tets, vec![[0, 1, 2, 3]]);
    assert_eq!(mesh.info().unused_nodes, 6);
    assert!((mesh.info().volume - 1.0 / 6.0).abs() < 1e-15);
}

// ---------------------------------------------------------------------------------------------
// VTK

#[test]
fn vtk_round_trip() {
    let dir = scratch("vtk");
    let mesh = block(2, 0.05);
    let path = dir.join("block.vtk");
    write_vtk(&mesh, &path).unwrap();
    write_bnd(&mesh.fixed, 0, &dir.join("block.bnd")).unwrap();
    let back = read_mesh(&path).unwrap();
    assert_same(&mesh, &back);
    assert_eq!(back.source, path);
    // Without the .bnd there are no fixed nodes.
    fs::remove_file(dir.join("block.bnd")).unwrap();
    let back = read_vtk(&path).unwrap();
    assert!(back.fixed.is_empty());
    assert_eq!(back.tets, mesh.tets);
}

#[test]
fn vtk_51_fixture_with_metadata_and_mixed_cells() {
    let mesh = read_mesh(&data("cube_v51.vtk")).unwrap();
    let info = mesh.info();
    assert_eq!((info.nodes, info.tets, info.surface_triangles), (8, 5, 12));
    assert_eq!(mesh.fixed, vec![4, 5, 6, 7]);
    assert!((info.volume - 1.0).abs() < 1e-12);
    assert_valid(&mesh);
    // Same tets as the hand-built cube.
    let mut a: Vec<[u32; 4]> = mesh.tets.iter().map(|t| sorted4(*t)).collect();
    let mut b: Vec<[u32; 4]> = cube5_tets().into_iter().map(sorted4).collect();
    a.sort_unstable();
    b.sort_unstable();
    assert_eq!(a, b);
}

fn sorted4(mut t: [u32; 4]) -> [u32; 4] {
    t.sort_unstable();
    t
}

#[test]
fn vtk_legacy_layout_with_other_cells() {
    let dir = scratch("vtk-legacy");
    let path = dir.join("mixed.vtk");
    fs::write(
        &path,
        "# vtk DataFile Version 2.0\n\
         mixed cells\n\
         ASCII\n\
         \n\
         DATASET UNSTRUCTURED_GRID\n\
         POINTS 5 float\n\
         0 0 0  1 0 0  0 1 0  0 0 1  1 1 1\n\
         CELLS 3 14\n\
         3 0 1 2\n\
         4 0 1 2 3\n\
         4 1 2 3 4\n\
         CELL_TYPES 3\n\
         5 10 10\n\
         POINT_DATA 5\n\
         SCALARS t float 1\n\
         LOOKUP_TABLE default\n\
         0 0 0 0 0\n",
    )
    .unwrap();
    let mesh = read_vtk(&path).unwrap();
    assert_eq!(mesh.tets.len(), 2);
    assert_eq!(mesh.surface.len(), 6);
    assert_valid(&mesh);
}

// ---------------------------------------------------------------------------------------------
// Gmsh

/// The cube of `cube5()` with sparse node tags `10 * (i + 1)` listed in reverse order.
const CUBE_MSH22: &str = "\
$MeshFormat
2.2 0 8
$EndMeshFormat
$PhysicalNames
2
2 1 \"bottom\"
3 2 \"tissue\"
$EndPhysicalNames
$Nodes
8
80 1 1 1
70 0 1 1
60 1 0 1
50 0 0 1
40 1 1 0
30 0 1 0
20 1 0 0
10 0 0 0
$EndNodes
$Elements
9
1 15 2 0 1 10
2 1 2 0 1 10 20
3 2 2 1 1 10 40 20
4 2 2 1 1 10 30 40
100 4 2 2 1 20 10 40 60
101 4 2 2 1 30 40 10 70
102 4 2 2 1 60 50 10 70
103 4 2 2 1 40 80 60 70
104 4 2 2 1 60 10 40 70
$EndElements
$NodeData
1
\"temperature\"
0
$EndNodeData
";

#[test]
fn gmsh22_with_sparse_tags_and_other_elements() {
    let dir = scratch("msh22");
    let path = dir.join("cube.msh");
    fs::write(&path, CUBE_MSH22).unwrap();
    fs::write(dir.join("cube.bnd"), "# gmsh tags\n4\n10\n20\n30\n40\n").unwrap();
    let mesh = read_mesh(&path).unwrap();
    let info = mesh.info();
    assert_eq!((info.nodes, info.tets, info.surface_triangles), (8, 5, 12));
    assert!((info.volume - 1.0).abs() < 1e-12);
    // Node i of the mesh is the i-th listed: tag 80 first.
    assert_eq!(mesh.nodes[0], [1.0, 1.0, 1.0]);
    assert_eq!(mesh.nodes[7], [0.0, 0.0, 0.0]);
    assert_eq!(mesh.fixed, vec![4, 5, 6, 7]);
    assert_valid(&mesh);
}

const CUBE_MSH41: &str = "\
$MeshFormat
4.1 0 8
$EndMeshFormat
$Entities
1 0 0 1
1 0 0 0 0
1 0 0 0 1 1 1 0 0
$EndEntities
$Nodes
3 8 1 8
0 1 0 1
1
0 0 0
2 1 1 3
2
3
4
1 0 0 0.5 0
0 1 0 0 0.5
1 1 0 0.5 0.5
3 1 0 4
5
6
7
8
0 0 1
1 0 1
0 1 1
1 1 1
$EndNodes
$Elements
2 7 1 7
2 1 2 2
1 1 4 2
2 1 3 4
3 1 4 5
3 1 2 4 6
4 3 1 4 7
5 1 5 6 7
6 8 4 6 7
7 4 1 6 7
$EndElements
";

#[test]
fn gmsh41_blocks_and_parametric_nodes() {
    let dir = scratch("msh41");
    let path = dir.join("cube41.msh");
    fs::write(&path, CUBE_MSH41).unwrap();
    let mesh = read_gmsh(&path).unwrap();
    let info = mesh.info();
    assert_eq!((info.nodes, info.tets, info.surface_triangles), (8, 5, 12));
    assert!((info.volume - 1.0).abs() < 1e-12);
    assert!(mesh.fixed.is_empty());
    assert_eq!(mesh.nodes, cube_nodes(1.0));
    let mut a: Vec<[u32; 4]> = mesh.tets.iter().map(|t| sorted4(*t)).collect();
    let mut b: Vec<[u32; 4]> = cube5_tets().into_iter().map(sorted4).collect();
    a.sort_unstable();
    b.sort_unstable();
    assert_eq!(a, b);
    assert_valid(&mesh);
}

/// The same mesh read from every format agrees.
#[test]
fn all_formats_agree() {
    let dir = scratch("agree");
    let mesh = cube5();
    write_tetgen(&mesh, &dir.join("c")).unwrap();
    write_vtk(&mesh, &dir.join("c.vtk")).unwrap();
    let t = read_mesh(&dir.join("c.node")).unwrap();
    let v = read_mesh(&dir.join("c.vtk")).unwrap();
    assert_eq!(t.nodes, v.nodes);
    assert_eq!(t.tets, v.tets);
    assert_eq!(t.surface, v.surface);
    assert_eq!(t.fixed, mesh.fixed);
    // c.bnd was written 1-based for TetGen; the VTK reader shares the sibling name and reads it
    // 0-based, which is why lop's boundary file follows the numbering of its mesh file.
    assert_eq!(v.fixed, vec![1, 2, 3, 4]);
}

/// Every TetGen mesh shipped in `assets/meshes` reads, is closed and outward, and its
/// `.face` file (TetGen's own boundary) has as many triangles as the extracted surface.
#[test]
fn shipped_assets_are_valid() {
    let dir = meshes_dir();
    // The assets are part of the repository: a missing directory is a failure, not a skip.
    let entries = fs::read_dir(&dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
    let mut bases: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "node"))
        .map(|p| p.with_extension(""))
        .collect();
    bases.sort();
    for base in bases {
        let mesh = read_mesh(&base).unwrap_or_else(|e| panic!("{e}"));
        assert_valid(&mesh);
        let face = base.with_extension("face");
        if let Ok(text) = fs::read_to_string(&face) {
            let declared: usize = text
                .lines()
                .map(|l| l.split('#').next().unwrap_or("").trim())
                .find(|l| !l.is_empty())
                .and_then(|l| l.split_whitespace().next())
                .and_then(|t| t.parse().ok())
                .unwrap();
            assert_eq!(declared, mesh.surface.len(), "{}", face.display());
        }
    }
}
