//! Files written by gmsh itself from one geometry: Gmsh formats 1, 2.2 and 4.1 (ASCII) and
//! legacy VTK (ASCII, and binary with `-bin`) all read to the same nodes, tetrahedra and
//! volume. gmsh's binary `.msh` files are not read (lop reads ASCII Gmsh only): they must be
//! refused with a message that says so and how to re-export, not misread.
//!
//! Fails (does not skip) when gmsh is missing: run `scripts/setup.sh`.

use crate::mesh_text;

use std::collections::BTreeSet;

use lop_sim::mesh::{read_mesh, MeshReadError, TetMesh};
use mesh_text::*;

const GEO: &str = "SetFactory(\"OpenCASCADE\");
Sphere(1) = {0.01, -0.02, 0.03, 0.02};
Mesh.CharacteristicLengthMax = 0.008;
";

/// The tetrahedra as sets of corner coordinates, independent of the numbering. Rounded to
/// 0.1 nm: gmsh's ASCII files hold 16 significant digits, its binary VTK the exact doubles.
fn tets(mesh: &TetMesh) -> BTreeSet<[[i64; 3]; 4]> {
    mesh.tets
        .iter()
        .map(|t| {
            let mut c = t.map(|n| mesh.nodes[n as usize].map(|x| (x * 1e10).round() as i64));
            c.sort_unstable();
            c
        })
        .collect()
}

#[test]
fn gmsh_msh_and_vtk_files_read_to_the_same_mesh() {
    let dir = scratch("gmsh-writes");
    let geo = write(&dir, "ball.geo", GEO);
    let mut meshes = Vec::new();
    for (name, format, extra) in [
        ("ball-1.msh", "msh1", &[][..]),
        ("ball-22.msh", "msh22", &[][..]),
        ("ball-41.msh", "msh41", &[][..]),
        ("ball-ascii.vtk", "vtk", &[][..]),
        ("ball-binary.vtk", "vtk", &["-bin"][..]),
    ] {
        let out = dir.join(name);
        gmsh("-3", &geo, format, extra, &out);
        let mesh = read_mesh(&out).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(
            mesh.tets.len() > 300,
            "{name}: {} tetrahedra",
            mesh.tets.len()
        );
        meshes.push((name, mesh));
    }
    let head = std::fs::read(dir.join("ball-binary.vtk")).unwrap();
    assert!(
        head.windows(7).any(|w| w == b"BINARY\n"),
        "gmsh -bin wrote ASCII VTK"
    );
    let (_, first) = &meshes[0];
    let info = first.info();
    // A sphere of radius 0.02 m, meshed with flat faces: a little under 4/3 π r³.
    let sphere = 4.0 / 3.0 * std::f64::consts::PI * 0.02f64.powi(3);
    assert!(
        info.volume < sphere && info.volume > 0.9 * sphere,
        "{}",
        info.volume
    );
    for (name, mesh) in &meshes[1..] {
        let other = mesh.info();
        assert_eq!((other.nodes, other.tets), (info.nodes, info.tets), "{name}");
        assert!(
            (other.volume - info.volume).abs() <= 1e-12 * info.volume,
            "{name}: {}",
            other.volume
        );
        assert!(
            tets(mesh) == tets(first),
            "{name}: other tetrahedra than ball-1.msh"
        );
    }
}

#[test]
fn gmsh_binary_msh_is_refused_with_how_to_reexport() {
    let dir = scratch("gmsh-writes-bin");
    let geo = write(&dir, "ball.geo", GEO);
    for format in ["msh22", "msh41"] {
        let out = dir.join(format!("ball-{format}-bin.msh"));
        gmsh("-3", &geo, format, &["-bin"], &out);
        let err = read_mesh(&out).unwrap_err();
        assert!(
            matches!(err, MeshReadError::UnsupportedFormat { .. }),
            "{err}"
        );
        says(
            &err,
            &[&format!("ball-{format}-bin.msh"), "binary", "-format msh22"],
        );
    }
}
