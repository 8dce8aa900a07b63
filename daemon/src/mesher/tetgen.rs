//! TetGen (`tetgen`, a separate program: it is AGPL and never linked): the surface as a
//! `.smesh`, `-p` (fill it), `-q` (radius-edge bound), `-a` (largest volume), `-Y` (keep the
//! surface's triangles whole).

use std::fmt::Write as _;
use std::path::Path;
use std::process::Command;

use lop_sim::mesh::{read_tetgen, SurfaceMesh, TetMesh};

use super::{find_program, run_in, scratch_dir, MesherError};

/// TetGen's switches.
#[derive(Debug, Clone, Copy)]
pub struct TetgenSwitches {
    /// Radius-edge ratio bound (`-q`), > 1.
    pub quality: f64,
    /// Largest tetrahedron volume, m³ (`-a`).
    pub max_volume: Option<f64>,
    /// No points added on the surface (`-Y`).
    pub keep_surface: bool,
}

impl TetgenSwitches {
    /// As passed to TetGen, e.g. `-pq1.4a1.2e-7`.
    pub fn text(&self) -> String {
        let mut s = format!("-pq{}", self.quality);
        if let Some(v) = self.max_volume {
            write!(s, "a{v:e}").ok();
        }
        if self.keep_surface {
            s.push('Y');
        }
        s
    }
}

/// Fills `surface` (metres, closed and outward-wound) with TetGen.
pub fn mesh(surface: &SurfaceMesh, switches: &TetgenSwitches) -> Result<TetMesh, MesherError> {
    let tetgen = find_program("tetgen", "LOP_TETGEN", "Debian package tetgen")?;
    let work = scratch_dir("tetgen")?;
    let result = mesh_in(&tetgen, surface, switches, &work);
    let _ = std::fs::remove_dir_all(&work);
    result
}

fn mesh_in(
    tetgen: &Path,
    surface: &SurfaceMesh,
    switches: &TetgenSwitches,
    work: &Path,
) -> Result<TetMesh, MesherError> {
    let smesh = work.join("surface.smesh");
    std::fs::write(&smesh, smesh_text(surface))
        .map_err(|e| MesherError::Io(format!("{}: {e}", smesh.display())))?;
    run_in(
        Command::new(tetgen)
            .arg(switches.text())
            .arg("surface.smesh"),
        work,
        &work.join("surface.1.ele"),
    )?;
    read_tetgen(&work.join("surface.1")).map_err(|e| MesherError::BadResult {
        mesher: "TetGen",
        reason: e.to_string(),
    })
}

/// A TetGen `.smesh`: the surface's vertices (numbered from 1) and triangles, no holes, no
/// regions. Coordinates as Rust prints them, which read back bit for bit.
fn smesh_text(s: &SurfaceMesh) -> String {
    let mut t = String::new();
    writeln!(t, "# lopd mesh tetrahedralize: surface in metres").ok();
    writeln!(t, "{} 3 0 0", s.vertices.len()).ok();
    for (i, [x, y, z]) in s.vertices.iter().enumerate() {
        writeln!(t, "{} {x:?} {y:?} {z:?}", i + 1).ok();
    }
    writeln!(t, "{} 0", s.triangles.len()).ok();
    for [a, b, c] in &s.triangles {
        writeln!(t, "3 {} {} {}", a + 1, b + 1, c + 1).ok();
    }
    t.push_str("0\n0\n");
    t
}
