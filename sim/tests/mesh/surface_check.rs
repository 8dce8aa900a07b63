//! Surface checks before tetrahedralisation (`check_surface`, `close_holes`).
//!
//! Invariant guarded: every defect that stops a mesher — a hole, a non-manifold edge or vertex,
//! a triangle wound the wrong way, two triangles crossing — is reported with exactly the
//! triangles involved, a sound closed surface is reported clean (no false positives on a fine
//! sphere or on nested shells), and an inward-wound surface is a note, not a defect.

use lop_sim::mesh::{check_surface, close_holes, DefectKind, SurfaceMesh, DEFECTS_LISTED};

/// Octahedron of radius `r` centred at `c`: 6 vertices, 8 outward triangles.
fn octahedron(c: [f64; 3], r: f64) -> SurfaceMesh {
    let d = [
        [r, 0.0, 0.0],
        [-r, 0.0, 0.0],
        [0.0, r, 0.0],
        [0.0, -r, 0.0],
        [0.0, 0.0, r],
        [0.0, 0.0, -r],
    ];
    let vertices = d
        .iter()
        .map(|v| [c[0] + v[0], c[1] + v[1], c[2] + v[2]])
        .collect();
    let triangles = vec![
        [0, 2, 4],
        [2, 1, 4],
        [1, 3, 4],
        [3, 0, 4],
        [2, 0, 5],
        [1, 2, 5],
        [3, 1, 5],
        [0, 3, 5],
    ];
    SurfaceMesh {
        vertices,
        triangles,
    }
}

/// A UV sphere: `rings` latitude bands, `segments` around, outward.
fn uv_sphere(r: f64, rings: u32, segments: u32) -> SurfaceMesh {
    let mut vertices = vec![[0.0, 0.0, r]];
    for i in 1..rings {
        let th = std::f64::consts::PI * i as f64 / rings as f64;
        for j in 0..segments {
            let ph = 2.0 * std::f64::consts::PI * j as f64 / segments as f64;
            vertices.push([
                r * th.sin() * ph.cos(),
                r * th.sin() * ph.sin(),
                r * th.cos(),
            ]);
        }
    }
    vertices.push([0.0, 0.0, -r]);
    let south = vertices.len() as u32 - 1;
    let at = |i: u32, j: u32| 1 + (i - 1) * segments + j % segments;
    let mut triangles = Vec::new();
    for j in 0..segments {
        triangles.push([0, at(1, j), at(1, j + 1)]);
        triangles.push([south, at(rings - 1, j + 1), at(rings - 1, j)]);
    }
    for i in 1..rings - 1 {
        for j in 0..segments {
            let (a, b, c, d) = (at(i, j), at(i, j + 1), at(i + 1, j), at(i + 1, j + 1));
            triangles.push([a, c, d]);
            triangles.push([a, d, b]);
        }
    }
    SurfaceMesh {
        vertices,
        triangles,
    }
}

fn union(a: SurfaceMesh, b: SurfaceMesh) -> SurfaceMesh {
    let off = a.vertices.len() as u32;
    let mut m = a;
    m.vertices.extend(b.vertices);
    m.triangles
        .extend(b.triangles.iter().map(|t| t.map(|v| v + off)));
    m
}

fn indices(report: &lop_sim::mesh::SurfaceReport, kind: DefectKind) -> Vec<Vec<u32>> {
    report
        .of(kind)
        .map(|d| d.triangles.iter().map(|t| t.index).collect())
        .collect()
}

#[test]
fn sound_surfaces_are_clean() {
    let o = check_surface(&octahedron([0.0; 3], 1.0));
    assert!(o.is_ok(), "{o}");
    assert!(!o.inverted);
    // Volume of the octahedron: 4/3 r³.
    assert!((o.volume - 4.0 / 3.0).abs() < 1e-12, "{}", o.volume);
    let s = check_surface(&uv_sphere(0.05, 24, 48));
    assert!(s.is_ok(), "{s}");
    // Nested shells do not intersect: no false positive from the grid or the test.
    let nested = check_surface(&union(uv_sphere(0.05, 12, 24), uv_sphere(0.04, 12, 24)));
    assert!(nested.is_ok(), "{nested}");
}

#[test]
fn inward_surface_is_a_note_and_flips() {
    let mut m = octahedron([0.0; 3], 1.0);
    m.flip();
    let r = check_surface(&m);
    assert!(r.is_ok() && r.inverted && r.volume < 0.0, "{r}");
    assert!(r.to_string().contains("wound inward"), "{r}");
    m.flip();
    assert!(!check_surface(&m).inverted);
}

#[test]
fn hole_is_reported_with_its_neighbours_and_closed() {
    let mut m = octahedron([0.0; 3], 1.0);
    m.triangles.remove(0); // [0, 2, 4]
    let r = check_surface(&m);
    assert_eq!(r.count(DefectKind::OpenEdge), 3, "{r}");
    assert_eq!(r.counts.iter().sum::<usize>(), 3, "{r}");
    // Edges 0-2, 0-4, 2-4 of the removed triangle, each now in one neighbour: after the
    // removal, [2,0,5] is triangle 3, [3,0,4] is 2 and [2,1,4] is 0.
    let edges: Vec<[u32; 2]> = r
        .of(DefectKind::OpenEdge)
        .map(|d| d.edge.unwrap())
        .collect();
    assert_eq!(edges, vec![[0, 2], [0, 4], [2, 4]]);
    assert_eq!(
        indices(&r, DefectKind::OpenEdge),
        vec![vec![3], vec![2], vec![0]]
    );
    // The message names the triangle, its vertices and their coordinates.
    let text = r.to_string();
    assert!(
        text.contains("edge 0-2: triangle 3 (vertices 2 (0, 1, 0) 0 (1, 0, 0) 5 (0, 0, -1))"),
        "{text}"
    );
    let closing = close_holes(&mut m, 3);
    assert_eq!(closing.closed, vec![3]);
    let r = check_surface(&m);
    assert!(r.is_ok() && !r.inverted, "{r}");
}

#[test]
fn larger_hole_closes_with_a_fan_only_when_allowed() {
    let mut m = uv_sphere(1.0, 8, 12);
    // Remove the north cap: a 12-edge hole.
    m.triangles.retain(|t| !t.contains(&0));
    let before = check_surface(&m);
    assert_eq!(before.count(DefectKind::OpenEdge), 12, "{before}");
    assert!(before.to_string().contains("... and 4 more"), "{before}");
    assert_eq!(before.of(DefectKind::OpenEdge).count(), DEFECTS_LISTED);
    let mut small = m.clone();
    let c = close_holes(&mut small, 8);
    assert_eq!((c.closed.len(), c.left_open.clone()), (0, vec![12]));
    let c = close_holes(&mut m, 12);
    assert_eq!(c.closed, vec![12]);
    let after = check_surface(&m);
    assert!(after.is_ok() && !after.inverted, "{after}");
}

#[test]
fn flipped_triangle_is_reported_on_each_of_its_edges() {
    let mut m = octahedron([0.0; 3], 1.0);
    m.triangles[5].swap(1, 2);
    let r = check_surface(&m);
    assert_eq!(r.count(DefectKind::Misoriented), 3, "{r}");
    assert_eq!(r.counts.iter().sum::<usize>(), 3, "{r}");
    for pair in indices(&r, DefectKind::Misoriented) {
        assert_eq!(pair.len(), 2);
        assert!(pair.contains(&5), "{pair:?}");
    }
}

#[test]
fn fin_on_an_edge_is_non_manifold() {
    let mut m = octahedron([0.0; 3], 1.0);
    m.vertices.push([1.0, 1.0, 1.0]);
    m.triangles.push([0, 2, 6]); // on edge 0-2, shared by triangles 0 and 4
    let r = check_surface(&m);
    assert_eq!(r.count(DefectKind::NonManifoldEdge), 1, "{r}");
    let d = r.of(DefectKind::NonManifoldEdge).next().unwrap();
    assert_eq!(d.edge, Some([0, 2]));
    let mut t: Vec<u32> = d.triangles.iter().map(|t| t.index).collect();
    t.sort_unstable();
    assert_eq!(t, vec![0, 4, 8]);
    // The fin's two other edges are open; its vertices are not reported again.
    assert_eq!(r.count(DefectKind::OpenEdge), 2, "{r}");
    assert_eq!(r.count(DefectKind::NonManifoldVertex), 0, "{r}");
}

#[test]
fn shells_touching_at_a_vertex_are_non_manifold_there() {
    let a = octahedron([0.0; 3], 1.0);
    let b = octahedron([2.0, 0.0, 0.0], 1.0);
    // b's vertex 1 is (1, 0, 0): weld it to a's vertex 0.
    let mut m = union(a, b);
    for t in m.triangles.iter_mut().skip(8) {
        for v in t.iter_mut() {
            if *v == 6 + 1 {
                *v = 0;
            }
        }
    }
    let r = check_surface(&m);
    assert_eq!(r.count(DefectKind::NonManifoldVertex), 1, "{r}");
    assert_eq!(
        r.of(DefectKind::NonManifoldVertex).next().unwrap().vertex,
        Some(0)
    );
}

#[test]
fn overlapping_shells_intersect_pairwise() {
    let m = union(octahedron([0.0; 3], 1.0), octahedron([0.5, 0.2, 0.1], 1.0));
    let r = check_surface(&m);
    let pairs = indices(&r, DefectKind::SelfIntersection);
    assert!(r.count(DefectKind::SelfIntersection) > 0, "{r}");
    assert_eq!(
        r.counts.iter().sum::<usize>(),
        r.count(DefectKind::SelfIntersection)
    );
    for p in pairs {
        // One triangle of each shell.
        assert!(p[0] < 8 && p[1] >= 8, "{p:?}");
    }
}

#[test]
fn a_vertex_pushed_through_the_far_side_crosses_it() {
    let mut m = uv_sphere(1.0, 8, 12);
    // Push the north pole through the south cap: the north fan now crosses the south fan.
    m.vertices[0] = [0.05, 0.03, -1.5];
    let r = check_surface(&m);
    assert!(r.count(DefectKind::SelfIntersection) > 0, "{r}");
    for d in r.of(DefectKind::SelfIntersection) {
        let [a, b] = [&d.triangles[0], &d.triangles[1]];
        // Every pair involves a triangle of the north fan (vertex 0).
        assert!(a.vertices.contains(&0) || b.vertices.contains(&0), "{d}");
    }
}

#[test]
fn degenerate_triangle_is_named() {
    let mut m = octahedron([0.0; 3], 1.0);
    m.vertices.push([0.5, 0.5, 0.0]); // on the segment 0-2
    m.triangles.push([0, 6, 2]);
    let r = check_surface(&m);
    assert_eq!(r.count(DefectKind::Degenerate), 1, "{r}");
    assert_eq!(indices(&r, DefectKind::Degenerate), vec![vec![8]]);
}
