//! `read_mesh` recognises Gmsh and VTK files by their first line, whatever their extension,
//! and names the file and its first line when it recognises nothing.

use crate::mesh_text;

use lop_sim::mesh::{read_mesh, MeshReadError};
use mesh_text::*;

#[test]
fn gmsh_and_vtk_read_under_any_extension() {
    let dir = scratch("detect");
    for (name, text) in [
        ("cube.txt", MSH22),
        ("cube", MSH41),
        ("cube.dat", MSH1),
        ("cube.vtk.bak", MSH22),
        ("cube.dat2", VTK),
        ("CUBE.MSH", VTK),
        ("cube.msh", VTK),
        ("cube.vtk", MSH1),
    ] {
        let path = write(&dir, name, text);
        let mesh = read_mesh(&path).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(mesh.tets, cube_tets(), "{name}");
        std::fs::remove_file(&path).unwrap();
    }
    // Leading blank lines and a byte-order mark do not hide the first line.
    let path = write(&dir, "bom.txt", format!("\u{feff}\n\n{MSH22}"));
    assert_eq!(read_mesh(&path).unwrap().tets, cube_tets());
}

#[test]
fn recognised_format_errors_come_from_its_reader() {
    let dir = scratch("detect-err");
    // A Gmsh file named .dat with a bad coordinate: the Gmsh reader's error, with the line.
    let path = write(&dir, "m.dat", replace_line(MSH1, 5, "103 0 abc 0"));
    let err = read_mesh(&path).unwrap_err();
    says(&err, &["m.dat:5:", "`abc`"]);
    // A .msh file that is not Gmsh falls back to the Gmsh reader, which says so.
    let path = write(&dir, "n.msh", "hello\n");
    let err = read_mesh(&path).unwrap_err();
    assert!(matches!(err, MeshReadError::UnsupportedFormat { .. }));
    says(&err, &["n.msh", "`hello`"]);
}

#[test]
fn unknown_content_names_the_file_and_its_first_line() {
    let dir = scratch("detect-unknown");
    let err = read_mesh(&write(&dir, "organ.dat", "\n  solid liver  \nfacet\n")).unwrap_err();
    assert!(matches!(err, MeshReadError::UnsupportedFormat { .. }));
    says(
        &err,
        &[
            "organ.dat",
            "the first line is `solid liver`",
            "$NOD",
            "# vtk DataFile",
        ],
    );

    // Long and binary first lines are shortened and escaped.
    let mut junk = vec![b'x'; 300];
    junk.extend_from_slice(&[0, 1, 0xff, b'\t', 7]);
    let err = read_mesh(&write(&dir, "long.bin", &junk)).unwrap_err();
    let msg = err.to_string();
    assert!(msg.contains("long.bin") && msg.contains("xxx...`"), "{msg}");
    assert!(msg.len() < 600, "{msg}");
    let err = read_mesh(&write(&dir, "ctl.bin", [0u8, 1, 0xff, b'\t', 7])).unwrap_err();
    let msg = err.to_string();
    assert!(msg.contains("\\u{0}\\u{1}\u{fffd}"), "{msg}");
    assert!(!msg.chars().any(|c| c.is_control() && c != '\n'), "{msg:?}");

    let err = read_mesh(&write(&dir, "empty.dat", "")).unwrap_err();
    says(&err, &["empty.dat", "empty"]);
}
