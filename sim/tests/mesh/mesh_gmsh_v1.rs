//! Gmsh's legacy format 1 (`$NOD` / `$ELM`): meshes written by gmsh itself in formats 1, 2.2
//! and 4.1 from one geometry read to the same mesh, and malformed format-1 files give errors
//! that name the file, the line and the value.

use crate::mesh_text;

use std::collections::BTreeSet;

use lop_sim::mesh::{read_gmsh, read_mesh, MeshReadError, TetMesh};
use mesh_text::*;

/// A box with a hole-free but not trivial mesh (a few hundred nodes).
const GEO: &str = "SetFactory(\"OpenCASCADE\");
Box(1) = {0, 0, 0, 0.04, 0.03, 0.02};
Mesh.CharacteristicLengthMax = 0.008;
";

/// The mesh as sets of coordinates (exact bits), independent of the numbering.
fn shape(mesh: &TetMesh) -> (BTreeSet<[u64; 3]>, BTreeSet<[[u64; 3]; 4]>) {
    let bits = |n: u32| mesh.nodes[n as usize].map(f64::to_bits);
    let nodes = mesh.nodes.iter().map(|p| p.map(f64::to_bits)).collect();
    let tets = mesh
        .tets
        .iter()
        .map(|t| {
            let mut c = t.map(bits);
            c.sort_unstable();
            c
        })
        .collect();
    (nodes, tets)
}

#[test]
fn gmsh_writes_formats_1_22_41_that_read_to_the_same_mesh() {
    let dir = scratch("v1-gmsh");
    let geo = write(&dir, "box.geo", GEO);
    let mut shapes = Vec::new();
    for format in ["msh1", "msh22", "msh41"] {
        let out = dir.join(format!("box-{format}.msh"));
        gmsh("-3", &geo, format, &[], &out);
        let text = std::fs::read_to_string(&out).unwrap();
        if format == "msh1" {
            assert!(text.starts_with("$NOD"), "gmsh wrote {}", &text[..20]);
        }
        let mesh = read_mesh(&out).unwrap_or_else(|e| panic!("{format}: {e}"));
        assert!(mesh.tets.len() > 100, "{format}: {} tets", mesh.tets.len());
        let info = mesh.info();
        assert!(
            (info.volume - 0.04 * 0.03 * 0.02).abs() < 1e-12,
            "{}",
            info.volume
        );
        shapes.push((format, mesh.nodes.len(), shape(&mesh)));
    }
    let (_, n1, s1) = &shapes[0];
    for (format, n, s) in &shapes[1..] {
        assert_eq!(n1, n, "node count of msh1 vs {format}");
        assert!(s1.0 == s.0, "node coordinates of msh1 and {format} differ");
        assert!(s1.1 == s.1, "tetrahedra of msh1 and {format} differ");
    }
}

#[test]
fn format1_fixture_maps_node_numbers_and_skips_other_elements() {
    let dir = scratch("v1-valid");
    let mesh = read_mesh(&write(&dir, "m.msh", MSH1)).unwrap();
    assert_eq!(mesh.nodes, cube_nodes());
    assert_eq!(mesh.tets, cube_tets());
    // Fixed nodes are named by the file's node numbers.
    write(&dir, "m.bnd", "2\n101\n108\n");
    let mesh = read_gmsh(&dir.join("m.msh")).unwrap();
    assert_eq!(mesh.fixed, vec![0, 7]);
    // Only points and triangles: no tetrahedra, and the message says two were skipped.
    let only = MSH1.replace(" 4 1 1 4 ", " 5 1 1 4 ");
    let (_, err) = read_msh("v1-none", only);
    assert!(
        matches!(err, MeshReadError::NoTets { skipped: 7, .. }),
        "{err}"
    );
}

#[test]
fn format1_counts() {
    let (_, err) = read_msh("v1-nod-more", replace_line(MSH1, 2, "9"));
    assert!(
        matches!(
            err,
            MeshReadError::CountMismatch {
                line: 2,
                declared: 9,
                found: 8,
                ..
            }
        ),
        "{err}"
    );
    says(&err, &["m.msh:2:", "declares 9 nodes", "has 8"]);
    let (_, err) = read_msh("v1-nod-fewer", replace_line(MSH1, 2, "7"));
    says(&err, &["m.msh:2:", "declares 7 nodes", "has 8"]);
    let (_, err) = read_msh("v1-elm-more", replace_line(MSH1, 13, "8"));
    says(&err, &["m.msh:13:", "declares 8 elements", "has 7"]);
    let (_, err) = read_msh("v1-elm-fewer", replace_line(MSH1, 13, "6"));
    says(&err, &["m.msh:13:", "declares 6 elements", "has 7"]);
    // The element's own node count disagrees with its node list.
    let (_, err) = read_msh("v1-elm-n", replace_line(MSH1, 16, "3 4 1 1 4 101 102 104"));
    says(
        &err,
        &[
            "m.msh:16:",
            "says it has 4 nodes",
            "`3 4 1 1 4 101 102 104`",
        ],
    );
    // A tetrahedron with other than 4 nodes.
    let (_, err) = read_msh(
        "v1-tet-5",
        replace_line(MSH1, 16, "3 4 1 1 5 101 102 104 106 107"),
    );
    says(&err, &["m.msh:16:", "4 nodes for element 3", "`5`"]);
    let (_, err) = read_msh("v1-bad-count", replace_line(MSH1, 2, "-8"));
    says(&err, &["m.msh:2:", "number of nodes", "`-8`"]);
}

#[test]
fn format1_missing_end_markers() {
    let (_, err) = read_msh("v1-no-endnod", replace_line(MSH1, 11, ""));
    says(&err, &["m.msh:12:", "`$ENDNOD`", "`$ELM`"]);
    let no_endelm = MSH1.replace("$ENDELM\n", "");
    let (_, err) = read_msh("v1-no-endelm", no_endelm);
    says(&err, &["m.msh:20:", "`$ENDELM`", "end of file"]);
    // A second node section.
    let (_, err) = read_msh("v1-nod-twice", "$NOD\n0\n$ENDNOD\n$ELM\n0\n$ENDELM\n$NOD\n");
    says(&err, &["m.msh:7:", "a single `$NOD` section"]);
}

#[test]
fn format1_unknown_node() {
    let (_, err) = read_msh("v1-tag", replace_line(MSH1, 17, "4 4 1 1 4 103 101 104 7"));
    assert!(
        matches!(
            err,
            MeshReadError::UnknownNodeTag {
                line: 17,
                tag: 7,
                ..
            }
        ),
        "{err}"
    );
    says(&err, &["m.msh:17:", "node tag 7", "$NOD"]);
    // Node numbers used twice.
    let (_, err) = read_msh("v1-twice", replace_line(MSH1, 4, "101 1 0 0"));
    says(&err, &["m.msh:4:", "tag 101 again (first on line 3)"]);
}

#[test]
fn format1_non_numeric_values() {
    let (_, err) = read_msh("v1-x", replace_line(MSH1, 5, "103 0 abc 0"));
    says(&err, &["m.msh:5:", "y coordinate of node 103", "`abc`"]);
    let (_, err) = read_msh("v1-nan", replace_line(MSH1, 5, "103 0 nan 0"));
    assert!(matches!(
        err,
        MeshReadError::NonFiniteCoordinate {
            line: Some(5),
            node: 103,
            ..
        }
    ));
    let (_, err) = read_msh(
        "v1-type",
        replace_line(MSH1, 18, "5 tet 1 1 4 101 105 106 107"),
    );
    says(&err, &["m.msh:18:", "element type", "`tet`"]);
    let (_, err) = read_msh(
        "v1-node",
        replace_line(MSH1, 18, "5 4 1 1 4 101 105 1x6 107"),
    );
    says(&err, &["m.msh:18:", "node 3 of element 5", "`1x6`"]);
    let (_, err) = read_msh("v1-fields", replace_line(MSH1, 6, "104 1 1"));
    says(&err, &["m.msh:6:", "4 fields", "`104 1 1`"]);
}

#[test]
fn format1_truncated() {
    // Cut anywhere after the first line: always an error with a line number.
    for cut in (5..MSH1.len() - 1).step_by(7) {
        let (_, err) = read_msh("v1-cut", &MSH1[..cut]);
        let msg = err.to_string();
        assert!(msg.contains("m.msh:"), "{msg}");
        assert!(err.line().is_some(), "cut at {cut}: {msg}");
    }
    let (_, err) = read_msh("v1-cut-0", "");
    says(
        &err,
        &["m.msh:1:", "`$MeshFormat` (or `$NOD`", "end of file"],
    );
    let (_, err) = read_msh("v1-cut-elm", &MSH1[..MSH1.find("$ELM").unwrap() + 5]);
    says(&err, &["m.msh:12:", "number of elements", "end of file"]);
    let (_, err) = read_msh("v1-cut-line", &MSH1[..MSH1.find("104 1 1 0").unwrap() + 6]);
    says(&err, &["m.msh:6:", "`104 1`"]);
}
