//! fTetWild through PyPI `pytetwild` (run by `python3`, `ftetwild.py` beside this file): it
//! meshes the space inside an envelope of width ε around the input triangles and keeps the
//! tetrahedra inside by winding number, so crossing triangles, holes and gaps do not stop
//! it. The boundary it makes lies within ε of the input (where the input has a surface:
//! across a hole it is the patch the winding number chose).
//!
//! Like gmsh, it is given the surface in millimetres.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

use lop_sim::mesh::{read_surface, read_tetgen, SurfaceMesh, TetMesh};

use super::{run_in, scratch_dir, MesherError};

/// The script that calls pytetwild.
const SCRIPT: &str = include_str!("ftetwild.py");

/// Millimetres per metre.
const MM: f64 = 1000.0;

/// fTetWild's own default envelope: 1e-3 of the bounding box diagonal.
pub const EPSILON: f64 = 1e-3;

/// A Python with pytetwild: `$LOP_PYTHON` if set (and then only that), else `python3` on
/// `PATH`, else `/usr/bin/python3`.
pub fn find_python() -> Result<PathBuf, MesherError> {
    let candidates: Vec<PathBuf> = match std::env::var_os("LOP_PYTHON").filter(|p| !p.is_empty()) {
        Some(p) => vec![PathBuf::from(p)],
        None => vec!["python3".into(), "/usr/bin/python3".into()],
    };
    for python in &candidates {
        let ok = Command::new(python)
            .args(["-c", "import pytetwild"])
            .output()
            .is_ok_and(|o| o.status.success());
        if ok {
            return Ok(python.clone());
        }
    }
    Err(MesherError::Missing {
        what: "Python package pytetwild (fTetWild)".to_owned(),
        tried: candidates
            .iter()
            .map(|p| format!("`{} -c 'import pytetwild'`", p.display()))
            .collect::<Vec<_>>()
            .join(", "),
        install: "python3 -m pip install --user pytetwild pyvista".to_owned(),
        env: ", or point LOP_PYTHON at a Python that has it".to_owned(),
    })
}

/// Meshes `surface` (metres; need not be closed or free of crossings) with tetrahedra of edge
/// about `edge` metres inside an envelope of `epsilon` × the bounding box diagonal.
pub fn mesh(surface: &SurfaceMesh, edge: f64, epsilon: f64) -> Result<TetMesh, MesherError> {
    let python = find_python()?;
    let work = scratch_dir("ftetwild")?;
    let result = run_script(&python, surface, edge, epsilon, &work, "volume").and_then(|()| {
        read_tetgen(&work.join("volume")).map_err(|e| MesherError::BadResult {
            mesher: "fTetWild",
            reason: e.to_string(),
        })
    });
    let _ = std::fs::remove_dir_all(&work);
    let mut mesh = result?;
    for p in &mut mesh.nodes {
        *p = p.map(|c| c / MM);
    }
    Ok(mesh)
}

/// The boundary of fTetWild's (unoptimised) mesh of `surface` (metres): closed and
/// outward-wound by construction, within `epsilon` × the diagonal of the input where the
/// input has a surface. The repair.
pub fn boundary(
    surface: &SurfaceMesh,
    edge: f64,
    epsilon: f64,
) -> Result<SurfaceMesh, MesherError> {
    let python = find_python()?;
    let work = scratch_dir("ftetwild")?;
    let result = run_script(&python, surface, edge, epsilon, &work, "surface").and_then(|()| {
        read_surface(&work.join("volume.obj")).map_err(|e| MesherError::BadResult {
            mesher: "fTetWild",
            reason: e.to_string(),
        })
    });
    let _ = std::fs::remove_dir_all(&work);
    let mut s = result?;
    s.scale(1.0 / MM);
    Ok(s)
}

fn run_script(
    python: &Path,
    surface: &SurfaceMesh,
    edge: f64,
    epsilon: f64,
    work: &Path,
    mode: &str,
) -> Result<(), MesherError> {
    let write = |name: &str, text: &str| {
        let p = work.join(name);
        std::fs::write(&p, text).map_err(|e| MesherError::Io(format!("{}: {e}", p.display())))
    };
    write("ftetwild.py", SCRIPT)?;
    let mut t = format!("{} {}\n", surface.vertices.len(), surface.triangles.len());
    for p in &surface.vertices {
        let [x, y, z] = p.map(|c| c * MM);
        writeln!(t, "{x:?} {y:?} {z:?}").ok();
    }
    for [a, b, c] in &surface.triangles {
        writeln!(t, "{a} {b} {c}").ok();
    }
    write("surface.txt", &t)?;
    let expect = if mode == "volume" {
        "volume.ele"
    } else {
        "volume.obj"
    };
    run_in(
        Command::new(python)
            .arg("ftetwild.py")
            .arg("surface.txt")
            .arg(format!("{:?}", edge * MM))
            .arg(format!("{epsilon:?}"))
            .arg("volume")
            .arg(mode),
        work,
        &work.join(expect),
    )?;
    Ok(())
}
