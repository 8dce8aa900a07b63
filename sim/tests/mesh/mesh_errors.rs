//! Mesh module: every kind of malformed TetGen input and mesh built from parts gives its own
//! error variant, and the message names the file, the line and the offending value. Gmsh and
//! VTK inputs: `mesh_errors_gmsh_vtk.rs`; mutated files of every format: `mesh_fuzz.rs`.

use crate::mesh_text;

use std::fs;

use lop_sim::mesh::{read_gmsh, read_mesh, read_tetgen, read_vtk, MeshReadError, TetMesh};
use mesh_text::*;

// ---------------------------------------------------------------------------------------------
// TetGen: indices and numbering

#[test]
fn the_fixture_texts_are_valid() {
    let dir = scratch("valid");
    let base = tetgen(&dir, NODE1, ELE1, Some("1\n8\n"));
    let mesh = read_tetgen(&base).unwrap();
    assert_eq!(mesh.tets, cube_tets());
    assert_eq!(mesh.fixed, vec![7]);
}

#[test]
fn ele_index_out_of_range() {
    let (dir, err) = read_tg("oor", NODE1, &replace_line(ELE1, 4, "3 1 5 6 905"), None);
    match &err {
        MeshReadError::IndexOutOfRange {
            path,
            line,
            index,
            count,
            first_index,
            node_file,
        } => {
            assert_eq!(path, &dir.join("m.ele"));
            assert_eq!(*line, Some(4));
            assert_eq!((*index, *count, *first_index), (905, 8, 1));
            assert_eq!(node_file, &dir.join("m.node"));
        }
        other => panic!("unexpected {other:?}"),
    }
    assert_eq!(
        err.to_string(),
        format!(
            "{}:4: node index 905 out of range (m.node has 8 nodes, numbered from 1)",
            dir.join("m.ele").display()
        )
    );
    assert_eq!(err.line(), Some(4));
    assert_eq!(err.path(), dir.join("m.ele"));
}

#[test]
fn zero_based_node_file_with_one_based_ele() {
    let node0: String = NODE1
        .lines()
        .enumerate()
        .map(|(i, l)| {
            if i == 0 {
                l.to_owned()
            } else {
                l.replacen(&i.to_string(), &(i - 1).to_string(), 1)
            }
        })
        .collect::<Vec<_>>()
        .join("\n");
    // Tetrahedron 4 (line 5) is the first to use node 8.
    let (_, err) = read_tg("base01", &node0, ELE1, None);
    assert!(matches!(
        err,
        MeshReadError::IndexOutOfRange {
            line: Some(5),
            index: 8,
            count: 8,
            first_index: 0,
            ..
        }
    ));
    says(&err, &["m.ele:5:", "node index 8", "numbered from 0"]);
}

#[test]
fn one_based_node_file_with_zero_based_ele() {
    let ele0 = "5 4 0\n0 0 1 3 5\n1 2 0 3 6\n2 0 4 5 6\n3 7 3 5 6\n4 3 0 5 6\n";
    let (_, err) = read_tg("base10", NODE1, ele0, None);
    assert!(matches!(
        err,
        MeshReadError::IndexOutOfRange {
            line: Some(2),
            index: 0,
            first_index: 1,
            ..
        }
    ));
    says(&err, &["m.ele:2:", "node index 0", "numbered from 1"]);
}

#[test]
fn node_numbers_must_start_at_0_or_1_and_be_consecutive() {
    let (_, err) = read_tg("first2", &replace_line(NODE1, 2, "2 0 0 0"), ELE1, None);
    assert!(matches!(err, MeshReadError::Parse { line: 2, .. }));
    says(&err, &["m.node:2:", "numbered 0 or 1", "`2`"]);

    let (_, err) = read_tg("gap", &replace_line(NODE1, 5, "5 1 1 0"), ELE1, None);
    assert!(matches!(err, MeshReadError::Parse { line: 5, .. }));
    says(&err, &["m.node:5:", "point number 4", "`5`"]);
}

#[test]
fn face_file_index_out_of_range() {
    let dir = scratch("face");
    let base = tetgen(&dir, NODE1, ELE1, None);
    write(&dir, "m.face", "2 0\n1 1 2 4\n2 1 2 9\n");
    let err = read_tetgen(&base).unwrap_err();
    assert!(matches!(
        err,
        MeshReadError::IndexOutOfRange {
            line: Some(3),
            index: 9,
            ..
        }
    ));
    says(&err, &["m.face:3:", "node index 9"]);
}

// ---------------------------------------------------------------------------------------------
// TetGen: geometry

#[test]
fn duplicate_tet() {
    let ele = format!("6 4 0\n{}6 7 6 1 4\n", &ELE1[6..]);
    let (_, err) = read_tg("dup", NODE1, &ele, None);
    assert!(matches!(
        err,
        MeshReadError::DuplicateTet {
            line: Some(7),
            tet: 6,
            first_line: Some(6),
            first_tet: 5,
            ..
        }
    ));
    says(
        &err,
        &["m.ele:7:", "tetrahedron 6", "tetrahedron 5 (line 6)"],
    );
}

#[test]
fn degenerate_tet() {
    let ele = format!("6 4 0\n{}6 1 2 3 4\n", &ELE1[6..]);
    let (_, err) = read_tg("flat", NODE1, &ele, None);
    assert!(matches!(
        err,
        MeshReadError::DegenerateTet {
            line: Some(7),
            tet: 6,
            nodes: [1, 2, 3, 4],
            ..
        }
    ));
    says(
        &err,
        &["m.ele:7:", "tetrahedron 6", "nodes 1 2 3 4", "degenerate"],
    );

    // A repeated node is degenerate too.
    let (_, err) = read_tg("repeat", NODE1, &replace_line(ELE1, 3, "2 3 1 3 7"), None);
    assert!(
        matches!(err, MeshReadError::DegenerateTet { line: Some(3), volume, .. } if volume == 0.0)
    );
}

#[test]
fn degenerate_threshold_is_relative_to_size() {
    for scale in [1.0, 1e-3, 1e3] {
        let tet = |h: f64| {
            let nodes = vec![
                [0.0, 0.0, 0.0],
                [scale, 0.0, 0.0],
                [0.0, scale, 0.0],
                [0.0, 0.0, h * scale],
            ];
            TetMesh::from_parts(nodes, vec![[0, 1, 2, 3]], vec![], "flat".into())
        };
        // 6V = h scale³ against 1e-12 (√2 scale)³ ≈ 2.8e-12 scale³.
        assert!(matches!(
            tet(1e-12),
            Err(MeshReadError::DegenerateTet { .. })
        ));
        assert!(tet(1e-11).is_ok());
    }
}

#[test]
fn mixed_orientation_reports_the_minority() {
    // Tetrahedron 3 flipped.
    let (_, err) = read_tg("inv", NODE1, &replace_line(ELE1, 4, "3 5 1 6 7"), None);
    match &err {
        MeshReadError::InvertedTet {
            line,
            tet,
            nodes,
            volume,
            inverted,
            total,
            ..
        } => {
            assert_eq!((*line, *tet, *nodes), (Some(4), 3, [5, 1, 6, 7]));
            assert!((volume + 1.0 / 6.0).abs() < 1e-15);
            assert_eq!((*inverted, *total), (1, 5));
        }
        other => panic!("unexpected {other:?}"),
    }
    says(
        &err,
        &["m.ele:4:", "tetrahedron 3", "inverted", "4 of the 5"],
    );

    // All flipped but tetrahedron 2: now tetrahedron 2 is the odd one out.
    let mut ele = String::from("5 4 0\n");
    for (k, line) in ELE1.lines().skip(1).enumerate() {
        let f: Vec<&str> = line.split_whitespace().collect();
        if k == 1 {
            ele += &format!("{line}\n");
        } else {
            ele += &format!("{} {} {} {} {}\n", f[0], f[2], f[1], f[3], f[4]);
        }
    }
    let (_, err) = read_tg("inv2", NODE1, &ele, None);
    assert!(matches!(
        err,
        MeshReadError::InvertedTet { line: Some(3), tet: 2, inverted: 1, volume, .. } if volume > 0.0
    ));
}

#[test]
fn non_finite_coordinates() {
    for (token, shown) in [("nan", "NaN"), ("inf", "inf"), ("-1e999", "-inf")] {
        let node = replace_line(NODE1, 4, &format!("3 0 {token} 0"));
        let (_, err) = read_tg(&format!("nan-{token}"), &node, ELE1, None);
        match &err {
            MeshReadError::NonFiniteCoordinate {
                line, node, value, ..
            } => {
                assert_eq!((*line, *node), (Some(4), 3));
                assert!(!value.is_finite());
            }
            other => panic!("unexpected {other:?}"),
        }
        says(&err, &["m.node:4:", shown, "node 3", "not finite"]);
    }
}

#[test]
fn declared_counts_must_match() {
    let cases = [
        (
            "node9",
            replace_line(NODE1, 1, "9 3 0 0"),
            ELE1.to_owned(),
            "m.node:1:",
            9,
            8,
        ),
        (
            "node7",
            replace_line(NODE1, 1, "7 3 0 0"),
            ELE1.to_owned(),
            "m.node:1:",
            7,
            8,
        ),
        (
            "ele6",
            NODE1.to_owned(),
            replace_line(ELE1, 1, "6 4 0"),
            "m.ele:1:",
            6,
            5,
        ),
        (
            "ele4",
            NODE1.to_owned(),
            replace_line(ELE1, 1, "4 4 0"),
            "m.ele:1:",
            4,
            5,
        ),
    ];
    for (name, node, ele, at, d, f) in cases {
        let (_, err) = read_tg(name, &node, &ele, None);
        match &err {
            MeshReadError::CountMismatch {
                line,
                declared,
                found,
                ..
            } => {
                assert_eq!((*line, *declared, *found), (1, d, f), "{name}");
            }
            other => panic!("{name}: unexpected {other:?}"),
        }
        says(&err, &[at, &format!("declares {d}"), &format!("has {f}")]);
    }
}

#[test]
fn garbage_tokens_and_wrong_field_counts() {
    let (_, err) = read_tg("garbage", &replace_line(NODE1, 4, "3 0 1x 0"), ELE1, None);
    assert!(matches!(&err, MeshReadError::Parse { line: 4, found, .. } if found == "`1x`"));
    says(&err, &["m.node:4:", "y coordinate of point 3", "`1x`"]);

    let (_, err) = read_tg(
        "garbage-ele",
        NODE1,
        &replace_line(ELE1, 3, "2 3 one 4 7"),
        None,
    );
    assert!(matches!(err, MeshReadError::Parse { line: 3, .. }));
    says(&err, &["m.ele:3:", "node 2 of tetrahedron 2", "`one`"]);

    let (_, err) = read_tg("short", NODE1, &replace_line(ELE1, 6, "5 4 1 6"), None);
    assert!(matches!(err, MeshReadError::Parse { line: 6, .. }));
    says(&err, &["m.ele:6:", "5 fields", "`5 4 1 6`"]);

    let (_, err) = read_tg("long", &replace_line(NODE1, 9, "8 1 1 1 0"), ELE1, None);
    says(&err, &["m.node:9:", "4 fields", "5 fields"]);

    let (_, err) = read_tg("dim2", &replace_line(NODE1, 1, "8 2 0 0"), ELE1, None);
    says(&err, &["m.node:1:", "dimension 3", "`2`"]);

    let (_, err) = read_tg("npt", NODE1, &replace_line(ELE1, 1, "5 6 0"), None);
    says(&err, &["m.ele:1:", "4 or 10", "`6`"]);
}

#[test]
fn missing_ele_is_an_io_error() {
    let dir = scratch("noele");
    write(&dir, "m.node", NODE1);
    let err = read_mesh(&dir.join("m.node")).unwrap_err();
    match &err {
        MeshReadError::Io { path, source } => {
            assert_eq!(path, &dir.join("m.ele"));
            assert_eq!(source.kind(), std::io::ErrorKind::NotFound);
        }
        other => panic!("unexpected {other:?}"),
    }
    says(&err, &["m.ele", "cannot read"]);
}

#[test]
fn empty_files() {
    let (_, err) = read_tg("empty-node", "", ELE1, None);
    assert!(matches!(&err, MeshReadError::Parse { line: 1, found, .. } if found == "end of file"));
    says(&err, &["m.node:1:", "end of file"]);

    let (_, err) = read_tg("comments-only", "# nothing\n\n# here\n", ELE1, None);
    assert!(matches!(err, MeshReadError::Parse { line: 3, .. }));

    let (_, err) = read_tg("empty-ele", NODE1, "", None);
    says(&err, &["m.ele:1:", "end of file"]);

    let (_, err) = read_tg("zero-tets", NODE1, "0 4 0\n", None);
    assert!(matches!(err, MeshReadError::NoTets { .. }));
    says(&err, &["m.ele", "no tetrahedra"]);

    let dir = scratch("empty-other");
    let err = read_gmsh(&write(&dir, "e.msh", "")).unwrap_err();
    assert!(matches!(err, MeshReadError::Parse { line: 1, .. }));
    says(&err, &["e.msh:1:", "$MeshFormat", "end of file"]);
    let err = read_vtk(&write(&dir, "e.vtk", "")).unwrap_err();
    assert!(matches!(err, MeshReadError::Parse { line: 1, .. }));
    says(&err, &["e.vtk:1:", "end of file"]);
}

#[test]
fn not_utf8() {
    let dir = scratch("utf8");
    let mut node = NODE1.as_bytes().to_vec();
    node.splice(22..22, [0xff, 0xfe]); // inside line 3
    let base = tetgen(&dir, "", ELE1, None);
    fs::write(dir.join("m.node"), &node).unwrap();
    let err = read_tetgen(&base).unwrap_err();
    assert!(matches!(err, MeshReadError::Parse { line: 3, .. }));
    says(&err, &["m.node:3:", "UTF-8", "0xff"]);
}

// ---------------------------------------------------------------------------------------------
// Boundary files

#[test]
fn boundary_index_out_of_range() {
    let (_, err) = read_tg("bnd9", NODE1, ELE1, Some("# fixed\n2\n1\n9\n"));
    assert!(matches!(
        err,
        MeshReadError::BadBoundary {
            line: Some(4),
            index: 9,
            count: 8,
            first_index: 1,
            ..
        }
    ));
    says(
        &err,
        &[
            "m.bnd:4:",
            "boundary node 9 out of range (m.node has 8 nodes, numbered from 1)",
        ],
    );

    let (_, err) = read_tg("bnd0", NODE1, ELE1, Some("1\n0\n"));
    assert!(matches!(err, MeshReadError::BadBoundary { index: 0, .. }));
}

#[test]
fn boundary_count_and_garbage() {
    let (_, err) = read_tg("bndcount", NODE1, ELE1, Some("3\n1\n2\n"));
    assert!(matches!(
        err,
        MeshReadError::CountMismatch {
            line: 1,
            what: "boundary nodes",
            declared: 3,
            found: 2,
            ..
        }
    ));
    says(&err, &["m.bnd:1:", "3 boundary nodes", "has 2"]);

    let (_, err) = read_tg("bndextra", NODE1, ELE1, Some("1\n1\n2\n"));
    assert!(matches!(
        err,
        MeshReadError::CountMismatch {
            declared: 1,
            found: 2,
            ..
        }
    ));

    let (_, err) = read_tg("bndgarbage", NODE1, ELE1, Some("2\n1\nfoo\n"));
    assert!(matches!(err, MeshReadError::Parse { line: 3, .. }));
    says(&err, &["m.bnd:3:", "`foo`"]);

    let (_, err) = read_tg("bndtwo", NODE1, ELE1, Some("2\n1 2\n"));
    says(&err, &["m.bnd:2:", "1 field (one node number)", "2 fields"]);

    let (_, err) = read_tg("bndempty", NODE1, ELE1, Some("# nothing\n"));
    says(&err, &["m.bnd:1:", "number of fixed nodes", "end of file"]);
}

// ---------------------------------------------------------------------------------------------
// from_parts and surfaces

#[test]
fn from_parts_errors_have_no_lines() {
    let mut tets = cube_tets();
    tets[2][1] = 8;
    let err = TetMesh::from_parts(cube_nodes(), tets, vec![], "gen".into()).unwrap_err();
    assert!(matches!(
        err,
        MeshReadError::IndexOutOfRange {
            line: None,
            index: 8,
            count: 8,
            first_index: 0,
            ..
        }
    ));
    assert_eq!(
        err.to_string(),
        "gen: node index 8 out of range (gen has 8 nodes, numbered from 0)"
    );

    let err = TetMesh::from_parts(cube_nodes(), cube_tets(), vec![8], "".into()).unwrap_err();
    assert!(matches!(
        err,
        MeshReadError::BadBoundary {
            line: None,
            index: 8,
            ..
        }
    ));
    assert_eq!(
        err.to_string(),
        "(in-memory mesh): boundary node 8 out of range (the mesh has 8 nodes, numbered from 0)"
    );

    let mut nodes = cube_nodes();
    nodes[5][2] = f64::NAN;
    let err = TetMesh::from_parts(nodes, cube_tets(), vec![], "gen".into()).unwrap_err();
    assert!(matches!(
        err,
        MeshReadError::NonFiniteCoordinate {
            line: None,
            node: 5,
            ..
        }
    ));

    let err = TetMesh::from_parts(cube_nodes(), vec![], vec![], "gen".into()).unwrap_err();
    assert!(matches!(err, MeshReadError::NoTets { skipped: 0, .. }));

    let mut tets = cube_tets();
    tets.push([6, 5, 0, 3]);
    let err = TetMesh::from_parts(cube_nodes(), tets, vec![], "gen".into()).unwrap_err();
    assert!(matches!(
        err,
        MeshReadError::DuplicateTet {
            line: None,
            tet: 5,
            first_tet: 4,
            ..
        }
    ));
    says(
        &err,
        &["gen: tetrahedron 5 uses the same four nodes as tetrahedron 4"],
    );

    let mut tets = cube_tets();
    tets[1].swap(0, 1);
    let err = TetMesh::from_parts(cube_nodes(), tets, vec![], "gen".into()).unwrap_err();
    assert!(matches!(
        err,
        MeshReadError::InvertedTet {
            line: None,
            tet: 1,
            ..
        }
    ));
}

/// Triangle (0, 1, 2) in the plane z = 0 and apexes above and below it.
fn fan(apexes: &[[f64; 3]]) -> Result<TetMesh, MeshReadError> {
    let mut nodes = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    let mut tets = Vec::new();
    for (k, &apex) in apexes.iter().enumerate() {
        nodes.push(apex);
        let apex_index = 3 + k as u32;
        // Orient positively by hand: the apex above the plane needs (0, 1, 2, apex).
        tets.push(if apex[2] > 0.0 {
            [0, 1, 2, apex_index]
        } else {
            [0, 2, 1, apex_index]
        });
    }
    TetMesh::from_parts(nodes, tets, vec![], "fan".into())
}

#[test]
fn two_tets_sharing_a_face_are_fine() {
    let mesh = fan(&[[0.2, 0.2, 1.0], [0.2, 0.2, -1.0]]).unwrap();
    assert_eq!(mesh.surface.len(), 6);
}

#[test]
fn overlapping_tets() {
    let err = fan(&[[0.2, 0.2, 1.0], [0.3, 0.3, 2.0]]).unwrap_err();
    assert!(matches!(
        err,
        MeshReadError::OverlappingTets {
            tet: 1,
            other_tet: 0,
            face: [0, 2, 1],
            ..
        }
    ));
    says(
        &err,
        &[
            "fan: tetrahedron 1",
            "face 0 2 1",
            "tetrahedron 0",
            "overlap",
        ],
    );
}

#[test]
fn non_manifold_face() {
    let err = fan(&[[0.2, 0.2, 1.0], [0.2, 0.2, -1.0], [0.3, 0.3, 2.0]]).unwrap_err();
    assert!(matches!(err, MeshReadError::NonManifoldFace { tet: 2, .. }));
    says(&err, &["fan: tetrahedron 2", "third", "not a manifold"]);
}

#[test]
fn non_manifold_in_a_file_names_the_line() {
    let node = "6 3\n0 0 0 0\n1 1 0 0\n2 0 1 0\n3 0.2 0.2 1\n4 0.2 0.2 -1\n5 0.3 0.3 2\n";
    let ele = "3 4\n0 0 1 2 3\n1 0 2 1 4\n2 0 1 2 5\n";
    let (_, err) = read_tg("nonmanifold", node, ele, None);
    assert!(matches!(
        err,
        MeshReadError::NonManifoldFace {
            line: Some(4),
            tet: 2,
            ..
        }
    ));
    says(&err, &["m.ele:4:", "tetrahedron 2"]);
}

// ---------------------------------------------------------------------------------------------
// dispatch

#[test]
fn read_mesh_dispatch_errors() {
    let dir = scratch("dispatch");
    let err = read_mesh(&dir.join("nothing")).unwrap_err();
    assert!(
        matches!(&err, MeshReadError::Io { source, .. } if source.kind() == std::io::ErrorKind::NotFound)
    );
    says(&err, &["nothing", "nothing.node"]);

    let err = read_mesh(&write(&dir, "liver.obj", "v 0 0 0\n")).unwrap_err();
    assert!(matches!(err, MeshReadError::UnsupportedFormat { .. }));
    says(&err, &["liver.obj", "TetGen", ".msh", ".vtk"]);

    let err = read_mesh(&dir.join("gone.msh")).unwrap_err();
    assert!(matches!(err, MeshReadError::Io { .. }));
}
