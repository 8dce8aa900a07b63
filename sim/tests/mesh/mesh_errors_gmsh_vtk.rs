//! Mesh module, Gmsh and VTK readers: every kind of malformed input gives its own error
//! variant, and the message names the file, the line and the offending value.

use crate::mesh_text;

use lop_sim::mesh::{read_mesh, MeshReadError};
use mesh_text::*;

// ---------------------------------------------------------------------------------------------
// Gmsh

#[test]
fn gmsh_fixture_is_valid() {
    let dir = scratch("msh-valid");
    let mesh = read_mesh(&write(&dir, "m.msh", MSH22)).unwrap();
    assert_eq!(mesh.tets, cube_tets());
}

#[test]
fn gmsh41_fixture_is_valid_and_checks_block_counts() {
    let dir = scratch("msh41-valid");
    let mesh = read_mesh(&write(&dir, "m.msh", MSH41)).unwrap();
    assert_eq!(mesh.tets, cube_tets());

    // Block of 4 nodes declared as 5: it runs into the coordinates' count.
    let (_, err) = read_msh("msh41-block", replace_line(MSH41, 6, "2 1 0 5"));
    says(&err, &["m.msh:"]);
    // Header total disagrees with the blocks.
    let (_, err) = read_msh("msh41-total", replace_line(MSH41, 5, "2 9 1 8"));
    assert!(matches!(
        err,
        MeshReadError::CountMismatch {
            line: 5,
            declared: 9,
            found: 8,
            ..
        }
    ));
    let (_, err) = read_msh("msh41-elements", replace_line(MSH41, 26, "2 7 1 6"));
    assert!(matches!(
        err,
        MeshReadError::CountMismatch {
            line: 26,
            declared: 7,
            found: 6,
            ..
        }
    ));
    let (_, err) = read_msh("msh41-param", replace_line(MSH41, 11, "0 0 0 0.5"));
    says(&err, &["m.msh:11:", "3 fields", "4 fields"]);
}

#[test]
fn gmsh_unknown_node_tag() {
    let (_, err) = read_msh("msh-tag", replace_line(MSH22, 20, "4 4 2 0 1 1 5 6 70"));
    assert!(matches!(
        err,
        MeshReadError::UnknownNodeTag {
            line: 20,
            tag: 70,
            ..
        }
    ));
    says(&err, &["m.msh:20:", "node tag 70", "$Nodes"]);
}

#[test]
fn gmsh_counts() {
    let (_, err) = read_msh("msh-more", replace_line(MSH22, 5, "9"));
    assert!(matches!(
        err,
        MeshReadError::CountMismatch {
            line: 5,
            declared: 9,
            found: 8,
            ..
        }
    ));
    says(&err, &["m.msh:5:", "declares 9 nodes", "has 8"]);

    let (_, err) = read_msh("msh-fewer", replace_line(MSH22, 16, "5"));
    assert!(matches!(
        err,
        MeshReadError::CountMismatch {
            line: 16,
            declared: 5,
            found: 6,
            ..
        }
    ));

    let truncated: String = MSH22.lines().take(19).map(|l| format!("{l}\n")).collect();
    let (_, err) = read_msh("msh-trunc", truncated);
    assert!(matches!(
        err,
        MeshReadError::CountMismatch {
            declared: 6,
            found: 3,
            ..
        }
    ));
}

#[test]
fn gmsh_garbage_and_structure() {
    let (_, err) = read_msh("msh-garbage", replace_line(MSH22, 8, "3 0 1,5 0"));
    assert!(matches!(err, MeshReadError::Parse { line: 8, .. }));
    says(&err, &["m.msh:8:", "y coordinate of node 3", "`1,5`"]);

    let (_, err) = read_msh("msh-dup", replace_line(MSH22, 8, "2 0 1 0"));
    says(&err, &["m.msh:8:", "tag 2 again (first on line 7)"]);

    let (_, err) = read_msh("msh-nan", replace_line(MSH22, 8, "3 0 NaN 0"));
    assert!(matches!(
        err,
        MeshReadError::NonFiniteCoordinate {
            line: Some(8),
            node: 3,
            ..
        }
    ));

    let (_, err) = read_msh("msh-tetfields", replace_line(MSH22, 19, "3 4 2 0 1 3 1 4"));
    says(&err, &["m.msh:19:", "9 fields"]);

    let (_, err) = read_msh("msh-noend", MSH22.replace("$EndElements\n", ""));
    says(&err, &["`$EndElements`", "end of file"]);

    // Format 1 is read (see mesh_gmsh_v1.rs): nodes without an element section.
    let (_, err) = read_msh("msh-v1", "$NOD\n1\n1 0 0 0\n$ENDNOD\n");
    assert!(
        matches!(err, MeshReadError::NoTets { skipped: 0, .. }),
        "{err}"
    );
}

#[test]
fn gmsh_unsupported_versions_and_binary() {
    let (_, err) = read_msh("msh-40", MSH22.replace("2.2 0 8", "4 0 8"));
    assert!(matches!(err, MeshReadError::UnsupportedFormat { .. }));
    says(&err, &["m.msh", "Gmsh format 4", "re-export"]);

    let mut binary = b"$MeshFormat\n4.1 1 8\n".to_vec();
    binary.extend_from_slice(&1i32.to_le_bytes());
    binary.extend_from_slice(b"\n$EndMeshFormat\n$Nodes\n");
    binary.extend_from_slice(&[0xff, 0x00, 0x80, 0xc3, 0x28, 0x0a]);
    let (_, err) = read_msh("msh-binary", binary);
    assert!(matches!(err, MeshReadError::UnsupportedFormat { .. }));
    says(&err, &["m.msh", "binary"]);

    // A binary flag with an all-ASCII payload is caught too.
    let (_, err) = read_msh("msh-binary2", MSH22.replace("2.2 0 8", "2.2 1 8"));
    says(&err, &["binary"]);
}

#[test]
fn gmsh_without_tetrahedra() {
    let text: String = MSH22
        .lines()
        .enumerate()
        .filter(|&(i, _)| !(18..=22).contains(&(i + 1)))
        .map(|(_, l)| format!("{l}\n"))
        .collect::<String>()
        .replace("$Elements\n6\n", "$Elements\n1\n");
    let (_, err) = read_msh("msh-notets", text);
    assert!(matches!(err, MeshReadError::NoTets { skipped: 1, .. }));
    says(
        &err,
        &["m.msh", "no tetrahedra", "1 elements of other types"],
    );
}

#[test]
fn gmsh_boundary_unknown_tag() {
    let dir = scratch("msh-bnd");
    let path = write(&dir, "m.msh", MSH22);
    write(&dir, "m.bnd", "2\n1\n42\n");
    let err = read_mesh(&path).unwrap_err();
    assert!(
        matches!(&err, MeshReadError::UnknownNodeTag { path, line: 3, tag: 42, .. } if path == &dir.join("m.bnd"))
    );
    says(&err, &["m.bnd:3:", "node tag 42", "m.msh"]);
}

// ---------------------------------------------------------------------------------------------
// VTK

#[test]
fn vtk_fixture_is_valid() {
    let dir = scratch("vtk-valid");
    let mesh = read_mesh(&write(&dir, "m.vtk", VTK)).unwrap();
    assert_eq!(mesh.tets, cube_tets());
}

#[test]
fn vtk_errors() {
    let (_, err) = read_vtk_text("vtk-oor", replace_line(VTK, 17, "4 7 3 5 8"));
    assert!(matches!(
        err,
        MeshReadError::IndexOutOfRange {
            line: Some(17),
            index: 8,
            count: 8,
            first_index: 0,
            ..
        }
    ));
    says(
        &err,
        &[
            "m.vtk:17:",
            "node index 8",
            "m.vtk has 8 nodes, numbered from 0",
        ],
    );

    let (_, err) = read_vtk_text("vtk-points", replace_line(VTK, 5, "POINTS 9 double"));
    assert!(matches!(
        err,
        MeshReadError::CountMismatch {
            line: 5,
            what: "points",
            declared: 9,
            found: 8,
            ..
        }
    ));
    says(&err, &["m.vtk:5:", "declares 9 points", "has 8"]);

    let (_, err) = read_vtk_text("vtk-points7", replace_line(VTK, 5, "POINTS 7 double"));
    assert!(matches!(
        err,
        MeshReadError::CountMismatch {
            declared: 7,
            found: 8,
            ..
        }
    ));

    let (_, err) = read_vtk_text("vtk-types", replace_line(VTK, 20, "CELL_TYPES 4"));
    assert!(matches!(err, MeshReadError::CountMismatch { line: 20, .. }));

    let (_, err) = read_vtk_text("vtk-nan", replace_line(VTK, 8, "0 nan 0"));
    assert!(matches!(
        err,
        MeshReadError::NonFiniteCoordinate {
            line: Some(8),
            node: 2,
            ..
        }
    ));
    says(&err, &["m.vtk:8:", "NaN", "node 2"]);

    let (_, err) = read_vtk_text("vtk-garbage", replace_line(VTK, 8, "0 one 0"));
    assert!(matches!(err, MeshReadError::Parse { line: 8, .. }));
    says(&err, &["m.vtk:8:", "y coordinate of point 2", "`one`"]);

    let (_, err) = read_vtk_text("vtk-tri", replace_line(VTK, 16, "3 7 3 5"));
    says(&err, &["m.vtk"]);

    let (_, err) = read_vtk_text("vtk-polydata", VTK.replace("UNSTRUCTURED_GRID", "POLYDATA"));
    assert!(matches!(err, MeshReadError::UnsupportedFormat { .. }));

    // BINARY with ASCII data: the binary reader takes the text as big-endian doubles and
    // reports where the data stops making sense, by byte offset.
    let (_, err) = read_vtk_text("vtk-binary", VTK.replace("ASCII", "BINARY"));
    assert!(err.offset().is_some(), "{err}");
    says(&err, &["m.vtk: byte "]);

    let (_, err) = read_vtk_text(
        "vtk-header",
        VTK.replace("# vtk DataFile", "# vtx DataFile"),
    );
    assert!(matches!(err, MeshReadError::UnsupportedFormat { .. }));

    let types: String = VTK.lines().take(19).map(|l| format!("{l}\n")).collect();
    let (_, err) = read_vtk_text("vtk-notypes", types);
    says(&err, &["CELL_TYPES", "end of file"]);

    let dir = scratch("vtk-bnd");
    let path = write(&dir, "m.vtk", VTK);
    write(&dir, "m.bnd", "1\n8\n");
    let err = read_mesh(&path).unwrap_err();
    assert!(matches!(
        err,
        MeshReadError::BadBoundary {
            line: Some(2),
            index: 8,
            first_index: 0,
            ..
        }
    ));
    says(&err, &["m.bnd:2:", "boundary node 8"]);
}
