//! Shared by the mesh tests: scratch directories, the valid fixture texts of every format,
//! readers that expect an error, and the runs of the Python scripts whose files other
//! libraries write (`mesh_meshio.rs`, `mesh_vtk_writers.rs`).
#![allow(dead_code)] // each test binary uses what it needs

use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;

use lop_sim::mesh::{read_gmsh, read_tetgen, read_vtk, MeshReadError};

/// A scratch directory, removed when dropped (unique per process, so concurrent runs of the
/// suite don't clash).
pub struct Scratch(pub PathBuf);

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

pub fn scratch(name: &str) -> Scratch {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("lop-sim-mesh-err-{}-{name}", std::process::id()));
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(&dir).unwrap();
    Scratch(dir)
}

/// The unit cube, nodes numbered from 1 (node n = corner n-1, corner = x + 2y + 4z).
/// Node n sits on line n + 1.
pub const NODE1: &str = "8 3 0 0
1 0 0 0
2 1 0 0
3 0 1 0
4 1 1 0
5 0 0 1
6 1 0 1
7 0 1 1
8 1 1 1
";

/// Five positively oriented tetrahedra; tetrahedron k sits on line k + 1.
pub const ELE1: &str = "5 4 0
1 1 2 4 6
2 3 1 4 7
3 1 5 6 7
4 8 4 6 7
5 4 1 6 7
";

/// Writes `name.node` / `name.ele` (and `.bnd` if given) and returns the base path.
pub fn tetgen(dir: &Path, node: &str, ele: &str, bnd: Option<&str>) -> PathBuf {
    let base = dir.join("m");
    fs::write(dir.join("m.node"), node).unwrap();
    fs::write(dir.join("m.ele"), ele).unwrap();
    if let Some(bnd) = bnd {
        fs::write(dir.join("m.bnd"), bnd).unwrap();
    }
    base
}

/// Reads a TetGen mesh made of the given texts in a fresh directory.
pub fn read_tg(name: &str, node: &str, ele: &str, bnd: Option<&str>) -> (Scratch, MeshReadError) {
    let dir = scratch(name);
    let base = tetgen(&dir, node, ele, bnd);
    let err = read_tetgen(&base).expect_err("the mesh should be rejected");
    (dir, err)
}

pub fn write(dir: &Path, name: &str, text: impl AsRef<[u8]>) -> PathBuf {
    let path = dir.join(name);
    fs::write(&path, text).unwrap();
    path
}

/// Asserts the message contains every needle, and prints it for the test log.
pub fn says(err: &MeshReadError, needles: &[&str]) {
    let msg = err.to_string();
    println!("{msg}");
    for needle in needles {
        assert!(msg.contains(needle), "{needle:?} missing from: {msg}");
    }
}

pub fn cube_nodes() -> Vec<[f64; 3]> {
    (0..8)
        .map(|i| [(i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64])
        .collect()
}

/// The 0-based tetrahedra of `ELE1`.
pub fn cube_tets() -> Vec<[u32; 4]> {
    vec![
        [0, 1, 3, 5],
        [2, 0, 3, 6],
        [0, 4, 5, 6],
        [7, 3, 5, 6],
        [3, 0, 5, 6],
    ]
}

pub fn replace_line(text: &str, line: usize, with: &str) -> String {
    text.lines()
        .enumerate()
        .map(|(i, l)| if i + 1 == line { with } else { l })
        .collect::<Vec<_>>()
        .join("\n")
        + "\n"
}

// Gmsh

pub const MSH22: &str = "$MeshFormat
2.2 0 8
$EndMeshFormat
$Nodes
8
1 0 0 0
2 1 0 0
3 0 1 0
4 1 1 0
5 0 0 1
6 1 0 1
7 0 1 1
8 1 1 1
$EndNodes
$Elements
6
1 2 2 0 1 1 2 4
2 4 2 0 1 1 2 4 6
3 4 2 0 1 3 1 4 7
4 4 2 0 1 1 5 6 7
5 4 2 0 1 8 4 6 7
6 4 2 0 1 4 1 6 7
$EndElements
";

/// The same cube in format 4.1, with a triangle block to skip.
pub const MSH41: &str = "$MeshFormat
4.1 0 8
$EndMeshFormat
$Nodes
2 8 1 8
2 1 0 4
1
2
3
4
0 0 0
1 0 0
0 1 0
1 1 0
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
2 6 1 6
2 1 2 1
1 1 2 4
3 1 4 5
2 1 2 4 6
3 3 1 4 7
4 1 5 6 7
5 8 4 6 7
6 4 1 6 7
$EndElements
";

/// The same cube in the legacy format 1, nodes numbered from 101 (node 100 + n on line n + 2),
/// with a point and a triangle to skip; element k sits on line k + 13.
pub const MSH1: &str = "$NOD
8
101 0 0 0
102 1 0 0
103 0 1 0
104 1 1 0
105 0 0 1
106 1 0 1
107 0 1 1
108 1 1 1
$ENDNOD
$ELM
7
1 15 0 1 1 101
2 2 0 1 3 101 102 104
3 4 1 1 4 101 102 104 106
4 4 1 1 4 103 101 104 107
5 4 1 1 4 101 105 106 107
6 4 1 1 4 108 104 106 107
7 4 1 1 4 104 101 106 107
$ENDELM
";

pub fn read_msh(name: &str, text: impl AsRef<[u8]>) -> (Scratch, MeshReadError) {
    let dir = scratch(name);
    let path = write(&dir, "m.msh", text);
    (
        dir,
        read_gmsh(&path).expect_err("the mesh should be rejected"),
    )
}

// VTK

pub const VTK: &str = "# vtk DataFile Version 3.0
cube
ASCII
DATASET UNSTRUCTURED_GRID
POINTS 8 double
0 0 0
1 0 0
0 1 0
1 1 0
0 0 1
1 0 1
0 1 1
1 1 1
CELLS 5 25
4 0 1 3 5
4 2 0 3 6
4 0 4 5 6
4 7 3 5 6
4 3 0 5 6
CELL_TYPES 5
10
10
10
10
10
";

pub fn read_vtk_text(name: &str, text: impl AsRef<[u8]>) -> (Scratch, MeshReadError) {
    let dir = scratch(name);
    let path = write(&dir, "m.vtk", text);
    (
        dir,
        read_vtk(&path).expect_err("the mesh should be rejected"),
    )
}

/// Runs gmsh on `geo`, writing `out` in `format` (`-3` for a volume mesh). Fails the test,
/// saying how to install gmsh, if gmsh is missing.
pub fn gmsh(dim: &str, geo: &Path, format: &str, extra: &[&str], out: &Path) {
    let result = Command::new("gmsh")
        .arg(dim)
        .arg(geo)
        .arg("-format")
        .arg(format)
        .args(extra)
        .arg("-o")
        .arg(out)
        .output();
    let output = match result {
        Ok(output) => output,
        Err(e) => panic!(
            "cannot run gmsh ({e}): these tests need the real gmsh; install it with \
             `scripts/setup.sh` (or `apt-get install gmsh`)"
        ),
    };
    assert!(
        output.status.success() && out.is_file(),
        "gmsh {dim} {} -format {format} failed: {}\n{}",
        geo.display(),
        output.status,
        String::from_utf8_lossy(&output.stderr)
    );
}

/// A Python interpreter that can import `module`, as a program and its leading arguments:
/// `python3` on the PATH, else `/usr/bin/python3` (a pyenv shim may hide the system one, or the
/// reverse), else `/usr/bin/python3 -s`: Debian's own packages without the user's site, where a
/// NumPy 2 that pip installed for other packages breaks Debian's meshio (built for Debian's
/// NumPy 1). Panics naming `package` and `scripts/setup.sh` when none can: these tests fail,
/// they do not skip.
pub fn python_with(module: &str, package: &str) -> (&'static str, &'static [&'static str]) {
    const CANDIDATES: [(&str, &[&str]); 3] = [
        ("python3", &[]),
        ("/usr/bin/python3", &[]),
        ("/usr/bin/python3", &["-s"]),
    ];
    for (python, args) in CANDIDATES {
        let ok = Command::new(python)
            .args(args)
            .args(["-c", &format!("import {module}")])
            .output()
            .is_ok_and(|o| o.status.success());
        if ok {
            return (python, args);
        }
    }
    panic!(
        "Python's {module} is missing: this test reads files written by it; install it with \
         `bash scripts/setup.sh` ({package})"
    );
}

/// Runs `tests/data/<script>` (which needs `module`, from `package`) on `dir` and returns its
/// standard output: the script writes its files into `dir` and prints what it computed, one
/// `key value…` line each.
pub fn run_writer(script: &str, module: &str, package: &str, dir: &Path) -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(script);
    let (python, args) = python_with(module, package);
    let out = Command::new(python)
        .args(args)
        .arg(&path)
        .arg(dir)
        .output()
        .unwrap_or_else(|e| panic!("run {script}: {e}"));
    assert!(
        out.status.success(),
        "{script} failed: {}\n{}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}
