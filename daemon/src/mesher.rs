//! The tetrahedral meshers behind `lopd mesh tetrahedralize`, each run as a separate program
//! in a scratch directory and read back with lop's own readers (which refuse inverted,
//! degenerate or duplicate tetrahedra):
//!
//! - [`gmsh`]: the `gmsh` program (Debian package `gmsh`). Re-meshes the surface at the target
//!   edge length (its vertices stay on the input surface), fills it by Delaunay and optimises
//!   the tetrahedra. The default for a surface that passes the checks.
//! - [`ftetwild`]: fTetWild through PyPI `pytetwild`, run by `python3`. Meshes inside an
//!   envelope around the input, so crossing triangles, holes and gaps do not stop it: the
//!   mesher of `--repair`.
//! - [`tetgen`]: the `tetgen` program (Debian package `tetgen`; AGPL, so never linked). Keeps
//!   the surface's triangles (split, never moved) and fills exactly its volume, but its quality
//!   refinement, not the size asked for, sets the count.
//!
//! Why this split is in the [`crate::tetrahedralize`] module docs, the figures in
//! `docs/benchmarks.md` ("Meshing").

pub mod ftetwild;
pub mod gmsh;
pub mod peel;
pub mod shape;
pub mod tetgen;

use std::path::{Path, PathBuf};
use std::process::Command;

/// Which program fills the surface.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Mesher {
    /// gmsh: re-meshed surface, Delaunay fill, optimised tetrahedra.
    Gmsh,
    /// fTetWild (PyPI pytetwild): meshes inside an envelope; repairs defects.
    Ftetwild,
    /// TetGen: keeps the surface's triangles.
    Tetgen,
}

impl Mesher {
    /// As written on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Mesher::Gmsh => "gmsh",
            Mesher::Ftetwild => "ftetwild",
            Mesher::Tetgen => "tetgen",
        }
    }
}

/// Why a mesher did not give a mesh.
#[derive(Debug, thiserror::Error)]
pub enum MesherError {
    /// The program (or the Python package) is not on this machine.
    #[error(
        "{what} not found ({tried}): install it with `bash scripts/setup.sh` ({install}){env}"
    )]
    Missing {
        /// The program or package.
        what: String,
        /// Where it was looked for.
        tried: String,
        /// The package that provides it.
        install: String,
        /// The environment variable that points at it, as a hint.
        env: String,
    },
    /// The program ran and failed.
    #[error("`{command}` failed ({status}); its last output:\n{tail}")]
    Failed {
        /// The command line.
        command: String,
        /// Exit status.
        status: String,
        /// The last lines of its output.
        tail: String,
    },
    /// The program's result does not read, or is not what was asked.
    #[error("{mesher}'s result is not a valid mesh: {reason}")]
    BadResult {
        /// Which mesher.
        mesher: &'static str,
        /// What is wrong.
        reason: String,
    },
    /// Reading or writing the scratch files.
    #[error("{0}")]
    Io(String),
}

/// A scratch directory for one run, unique per process and call.
pub(crate) fn scratch_dir(tag: &str) -> Result<PathBuf, MesherError> {
    static CALLS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let n = CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.subsec_nanos())
        .unwrap_or_default();
    let dir = std::env::temp_dir().join(format!("lopd-{tag}-{}-{n}-{nanos}", std::process::id()));
    std::fs::create_dir_all(&dir)
        .map_err(|e| MesherError::Io(format!("temporary directory {}: {e}", dir.display())))?;
    Ok(dir)
}

/// A program: `$env_var` if set (and then only that), else `name` on `PATH`, else
/// `/usr/bin/name`.
pub(crate) fn find_program(
    name: &str,
    env_var: &str,
    install: &str,
) -> Result<PathBuf, MesherError> {
    let missing = |tried: String| MesherError::Missing {
        what: name.to_owned(),
        tried,
        install: install.to_owned(),
        env: format!(", or point {env_var} at the program"),
    };
    if let Some(p) = std::env::var_os(env_var).filter(|p| !p.is_empty()) {
        let p = PathBuf::from(p);
        if p.is_file() {
            return Ok(p);
        }
        return Err(missing(format!("{env_var}={}", p.display())));
    }
    let mut tried = Vec::new();
    if let Some(path) = std::env::var_os("PATH") {
        for dir in std::env::split_paths(&path) {
            let p = dir.join(name);
            if p.is_file() {
                return Ok(p);
            }
        }
        tried.push(format!("{name} on PATH"));
    }
    let usr = Path::new("/usr/bin").join(name);
    if usr.is_file() {
        return Ok(usr);
    }
    tried.push(usr.display().to_string());
    Err(missing(tried.join(", ")))
}

/// Runs `command` in `work`; its combined output, or [`MesherError::Failed`] with the last
/// lines when it fails or `expect` is not written.
pub(crate) fn run_in(
    command: &mut Command,
    work: &Path,
    expect: &Path,
) -> Result<String, MesherError> {
    let shown = format!("{command:?}").replace('"', "");
    let out = command
        .current_dir(work)
        .output()
        .map_err(|e| MesherError::Io(format!("running {shown}: {e}")))?;
    let output = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    if !out.status.success() || !expect.is_file() {
        let lines: Vec<&str> = output.lines().filter(|l| !l.trim().is_empty()).collect();
        let tail = lines[lines.len().saturating_sub(12)..].join("\n");
        return Err(MesherError::Failed {
            command: shown,
            status: out.status.to_string(),
            tail,
        });
    }
    Ok(output)
}
