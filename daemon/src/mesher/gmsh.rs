//! gmsh (the `gmsh` program, Debian package `gmsh`): the surface is merged as a discrete
//! surface, classified into patches and re-parametrised (`ClassifySurfaces`,
//! `CreateGeometry`), re-meshed at the target edge length, filled by Delaunay and optimised
//! (`Mesh.Optimize`; Debian's gmsh 4.8 has no Netgen optimiser). The new surface vertices lie
//! on the input triangles, so the mesh keeps the input surface up to the chords between them.
//!
//! gmsh works in millimetres here: its geometric tolerances are absolute-ish, and an organ
//! of 0.1 m sits near them in metres.

use std::fmt::Write as _;
use std::path::Path;
use std::process::Command;

use lop_sim::mesh::{read_gmsh, SurfaceMesh, TetMesh};

use super::{find_program, run_in, scratch_dir, MesherError};

/// Millimetres per metre: the scale gmsh is given the surface in.
const MM: f64 = 1000.0;

/// Fills `surface` (metres, closed) with tetrahedra of edge about `edge` metres.
pub fn mesh(surface: &SurfaceMesh, edge: f64) -> Result<TetMesh, MesherError> {
    let gmsh = find_program("gmsh", "LOP_GMSH", "Debian package gmsh")?;
    let work = scratch_dir("gmsh")?;
    let result = mesh_in(&gmsh, surface, edge, &work);
    let _ = std::fs::remove_dir_all(&work);
    result
}

fn mesh_in(
    gmsh: &Path,
    surface: &SurfaceMesh,
    edge: f64,
    work: &Path,
) -> Result<TetMesh, MesherError> {
    let write = |name: &str, text: String| {
        let p = work.join(name);
        std::fs::write(&p, text).map_err(|e| MesherError::Io(format!("{}: {e}", p.display())))
    };
    write("surface.stl", stl_text(surface, MM))?;
    write("volume.geo", geo_text(edge * MM))?;
    let msh = work.join("volume.msh");
    run_in(
        Command::new(gmsh)
            .args(["-3", "-nt", "1", "volume.geo", "-o", "volume.msh"])
            .args(["-format", "msh22"]),
        work,
        &msh,
    )?;
    let mut mesh = read_gmsh(&msh).map_err(|e| MesherError::BadResult {
        mesher: "gmsh",
        reason: e.to_string(),
    })?;
    for p in &mut mesh.nodes {
        *p = p.map(|c| c / MM);
    }
    Ok(mesh)
}

/// The gmsh script: split the merged STL into patches that can be parametrised, at no crease
/// (an organ has none; and on fTetWild's repaired surfaces a 40° crease angle cut patches
/// gmsh then could not mesh), re-parametrise them, one volume inside, sizes between `edge / 2` and `edge`
/// (millimetres), Delaunay (`Algorithm3D = 1`) and gmsh's own optimiser for every tetrahedron
/// of quality below 0.3.
fn geo_text(edge: f64) -> String {
    let mut g = String::new();
    writeln!(g, "// lopd mesh tetrahedralize: surface in mm").ok();
    writeln!(g, "Merge \"surface.stl\";").ok();
    writeln!(g, "ClassifySurfaces{{Pi, 1, 1, Pi}};").ok();
    writeln!(g, "CreateGeometry;").ok();
    writeln!(g, "Surface Loop(1) = Surface{{:}};").ok();
    writeln!(g, "Volume(1) = {{1}};").ok();
    writeln!(g, "Mesh.MeshSizeMax = {edge:?};").ok();
    writeln!(g, "Mesh.MeshSizeMin = {:?};", edge / 2.0).ok();
    writeln!(g, "Mesh.MeshSizeFromCurvature = 0;").ok();
    writeln!(g, "Mesh.Algorithm3D = 1;").ok();
    writeln!(g, "Mesh.Optimize = 1;").ok();
    writeln!(g, "Mesh.OptimizeThreshold = 0.3;").ok();
    g
}

/// An ASCII STL of `s` scaled by `scale`, coordinates as Rust prints them (gmsh reads them
/// as doubles).
fn stl_text(s: &SurfaceMesh, scale: f64) -> String {
    let mut t = String::from("solid lop\n");
    for tri in &s.triangles {
        let [a, b, c] = tri.map(|i| glam::DVec3::from(s.vertices[i as usize]) * scale);
        let n = (b - a).cross(c - a).normalize_or_zero();
        writeln!(t, "facet normal {:?} {:?} {:?}", n.x, n.y, n.z).ok();
        t.push_str("outer loop\n");
        for p in [a, b, c] {
            writeln!(t, "vertex {:?} {:?} {:?}", p.x, p.y, p.z).ok();
        }
        t.push_str("endloop\nendfacet\n");
    }
    t.push_str("endsolid lop\n");
    t
}
