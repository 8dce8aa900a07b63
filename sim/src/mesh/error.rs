//! [`MeshReadError`]: everything that can go wrong while reading or validating a mesh.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Why a mesh could not be read or built.
///
/// Every variant names the file it is about (`path`). Where the problem sits on one line, `line`
/// is that 1-based line number; it is an `Option` in the variants that [`TetMesh::from_parts`]
/// can also produce, because a mesh built in memory has no lines (the `Display` text then names
/// the tetrahedron or node by its index instead).
///
/// Node and tetrahedron numbers in the fields and messages (`tet`, `nodes`, `face`, `node`,
/// `index`, `tag`) are the ones the file uses: TetGen numbers from the file's first number
/// (0 or 1), Gmsh uses node and element tags, VTK uses 0-based point and cell ids. For a mesh
/// built with [`TetMesh::from_parts`] they are 0-based indices into `nodes` / `tets`.
///
/// [`TetMesh::from_parts`]: super::TetMesh::from_parts
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum MeshReadError {
    /// The file could not be opened or read (missing `.ele`, permissions, ...).
    #[error("{}: cannot read: {source}", show(.path))]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },

    /// A token or line does not have the expected form: not a number, wrong number of
    /// fields, invalid UTF-8, unexpected end of file, a missing section marker ...
    #[error("{}:{line}: expected {expected}, found {found}", show(.path))]
    Parse {
        path: PathBuf,
        line: usize,
        /// What the reader expected, e.g. "a number for the y coordinate of node 7".
        expected: String,
        /// What it found: the offending token or line in backticks, or "end of file".
        found: String,
    },

    /// Like [`MeshReadError::Parse`], in a binary file (or its binary part): `offset` is the
    /// 0-based byte offset of the offending value from the start of the file.
    #[error("{}: byte {offset}: expected {expected}, found {found}", show(.path))]
    BinaryParse {
        path: PathBuf,
        offset: u64,
        /// What the reader expected, e.g. "the x coordinate of vertex 3 of triangle 7".
        expected: String,
        /// What it found: the value, or "end of file".
        found: String,
    },

    /// The file is not in a format this module reads (unknown extension, binary Gmsh,
    /// Gmsh 4.0, a VTK dataset or compressor that is not read, ...).
    #[error("{}: unsupported mesh format: {reason}", show(.path))]
    UnsupportedFormat { path: PathBuf, reason: String },

    /// A header (or section header) declares a different number of records than follow it.
    /// `line` is the line of the declaration.
    #[error(
        "{}:{line}: the header declares {declared} {}, but the file has {found}",
        show(.path),
        counted(.what, *.declared)
    )]
    CountMismatch {
        path: PathBuf,
        line: usize,
        /// What is counted, e.g. "nodes", "tetrahedra", "boundary nodes".
        what: &'static str,
        declared: usize,
        found: usize,
    },

    /// A tetrahedron or face refers to a node number that does not exist.
    #[error(
        "{}: node index {index} out of range ({})",
        at(.path, *.line),
        node_range(.node_file, *.count, *.first_index)
    )]
    IndexOutOfRange {
        path: PathBuf,
        line: Option<usize>,
        /// The offending node number, as written in the file.
        index: i64,
        /// How many nodes there are.
        count: usize,
        /// The number of the first node (TetGen: 0 or 1; VTK and in-memory meshes: 0).
        first_index: i64,
        /// The file that defines the nodes (the `.node` file for TetGen).
        node_file: PathBuf,
    },

    /// A Gmsh element or a boundary file refers to a node tag not defined in `$Nodes` (`$NOD`).
    #[error(
        "{}:{line}: node tag {tag} is not defined in the $Nodes section ($NOD in format 1) of {}",
        show(.path),
        file_name(.mesh_file)
    )]
    UnknownNodeTag {
        path: PathBuf,
        line: usize,
        tag: i64,
        mesh_file: PathBuf,
    },

    /// A node coordinate is NaN or infinite.
    #[error("{}: coordinate {value} of node {node} is not finite", at(.path, *.line))]
    NonFiniteCoordinate {
        path: PathBuf,
        line: Option<usize>,
        node: i64,
        value: f64,
    },

    /// Two tetrahedra use the same four nodes.
    #[error(
        "{}: tetrahedron {tet} uses the same four nodes as tetrahedron {first_tet}{}",
        at(.path, *.line),
        on_line(*.first_line)
    )]
    DuplicateTet {
        path: PathBuf,
        line: Option<usize>,
        tet: i64,
        first_line: Option<usize>,
        first_tet: i64,
    },

    /// A tetrahedron is flat: `|6V| <= 1e-12 * (longest edge)^3` (or its volume is not finite).
    #[error(
        "{}: tetrahedron {tet} (nodes {}) is degenerate: volume {volume:.3e} with longest \
         edge {longest_edge:.3e}",
        at(.path, *.line),
        list(.nodes)
    )]
    DegenerateTet {
        path: PathBuf,
        line: Option<usize>,
        tet: i64,
        nodes: [i64; 4],
        /// Signed volume as listed, `(b-a)·((c-a)×(d-a)) / 6`.
        volume: f64,
        longest_edge: f64,
    },

    /// The tetrahedra do not all have the same orientation: this one has the minority sign
    /// (on a tie, the negatively oriented ones are the inverted ones).
    #[error(
        "{}: tetrahedron {tet} (nodes {}) is inverted: signed volume {volume:.3e}, while {} of \
         the {total} tetrahedra have the opposite orientation",
        at(.path, *.line),
        list(.nodes),
        .total.saturating_sub(*.inverted)
    )]
    InvertedTet {
        path: PathBuf,
        line: Option<usize>,
        tet: i64,
        nodes: [i64; 4],
        /// Signed volume as listed, `(b-a)·((c-a)×(d-a)) / 6`.
        volume: f64,
        /// How many tetrahedra have the minority orientation.
        inverted: usize,
        total: usize,
    },

    /// Two tetrahedra share a face but lie on the same side of it: the mesh folds over itself.
    #[error(
        "{}: tetrahedron {tet} lies on the same side of face {} as tetrahedron {other_tet}{}: the \
         tetrahedra overlap",
        at(.path, *.line),
        list(.face),
        on_line(*.other_line)
    )]
    OverlappingTets {
        path: PathBuf,
        line: Option<usize>,
        tet: i64,
        other_line: Option<usize>,
        other_tet: i64,
        face: [i64; 3],
    },

    /// A triangle is a face of more than two tetrahedra.
    #[error(
        "{}: tetrahedron {tet} is the third tetrahedron on face {}: the mesh is not a manifold",
        at(.path, *.line),
        list(.face)
    )]
    NonManifoldFace {
        path: PathBuf,
        line: Option<usize>,
        tet: i64,
        face: [i64; 3],
    },

    /// The file holds no tetrahedra.
    #[error("{}: no tetrahedra in the mesh{}", show(.path), skipped_note(*.skipped))]
    NoTets {
        path: PathBuf,
        /// Elements/cells of other types that were skipped.
        skipped: usize,
    },

    /// A boundary (fixed node) entry refers to a node that does not exist.
    #[error(
        "{}: boundary node {index} out of range ({})",
        at(.path, *.line),
        node_range(.node_file, *.count, *.first_index)
    )]
    BadBoundary {
        path: PathBuf,
        line: Option<usize>,
        index: i64,
        count: usize,
        first_index: i64,
        node_file: PathBuf,
    },

    /// More nodes than 32-bit indices can address.
    #[error("{}: {count} nodes is more than a mesh can index (at most 2^32 - 1)", show(.path))]
    TooManyNodes { path: PathBuf, count: usize },
}

impl MeshReadError {
    /// The file the error is about.
    pub fn path(&self) -> &Path {
        match self {
            Self::Io { path, .. }
            | Self::Parse { path, .. }
            | Self::BinaryParse { path, .. }
            | Self::UnsupportedFormat { path, .. }
            | Self::CountMismatch { path, .. }
            | Self::IndexOutOfRange { path, .. }
            | Self::UnknownNodeTag { path, .. }
            | Self::NonFiniteCoordinate { path, .. }
            | Self::DuplicateTet { path, .. }
            | Self::DegenerateTet { path, .. }
            | Self::InvertedTet { path, .. }
            | Self::OverlappingTets { path, .. }
            | Self::NonManifoldFace { path, .. }
            | Self::NoTets { path, .. }
            | Self::BadBoundary { path, .. }
            | Self::TooManyNodes { path, .. } => path,
        }
    }

    /// The 0-based byte offset the error is about, if it is about a value in a binary file.
    pub fn offset(&self) -> Option<u64> {
        match self {
            Self::BinaryParse { offset, .. } => Some(*offset),
            _ => None,
        }
    }

    /// The 1-based line the error is about, if it is about one line.
    pub fn line(&self) -> Option<usize> {
        match self {
            Self::Parse { line, .. }
            | Self::CountMismatch { line, .. }
            | Self::UnknownNodeTag { line, .. } => Some(*line),
            Self::IndexOutOfRange { line, .. }
            | Self::NonFiniteCoordinate { line, .. }
            | Self::DuplicateTet { line, .. }
            | Self::DegenerateTet { line, .. }
            | Self::InvertedTet { line, .. }
            | Self::OverlappingTets { line, .. }
            | Self::NonManifoldFace { line, .. }
            | Self::BadBoundary { line, .. } => *line,
            Self::Io { .. }
            | Self::BinaryParse { .. }
            | Self::UnsupportedFormat { .. }
            | Self::NoTets { .. }
            | Self::TooManyNodes { .. } => None,
        }
    }
}

/// A path for messages; an in-memory mesh may have an empty one.
fn show(path: &Path) -> String {
    if path.as_os_str().is_empty() {
        "(in-memory mesh)".to_owned()
    } else {
        path.display().to_string()
    }
}

/// `path:line`, or just `path` when there is no line.
fn at(path: &Path, line: Option<usize>) -> String {
    match line {
        Some(line) => format!("{}:{line}", show(path)),
        None => show(path),
    }
}

/// Just the file name, for a second file in a message.
fn file_name(path: &Path) -> String {
    path.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| show(path))
}

/// `what` (a plural noun phrase) in the singular when there is one.
fn counted(what: &str, n: usize) -> String {
    if n != 1 {
        return what.to_owned();
    }
    let singular = match what {
        "tetrahedra" => "tetrahedron",
        "connectivity entries" => "connectivity entry",
        "numbers in the CELLS list" => "number in the CELLS list",
        "nodes in the block" => "node in the block",
        "elements in the block" => "element in the block",
        other => other.strip_suffix('s').unwrap_or(other),
    };
    singular.to_owned()
}

fn on_line(line: Option<usize>) -> String {
    line.map(|l| format!(" (line {l})")).unwrap_or_default()
}

fn node_range(node_file: &Path, count: usize, first: i64) -> String {
    let noun = if count == 1 { "node" } else { "nodes" };
    match node_file.file_name() {
        Some(name) if !node_file.as_os_str().is_empty() => format!(
            "{} has {count} {noun}, numbered from {first}",
            name.to_string_lossy()
        ),
        _ => format!("the mesh has {count} {noun}, numbered from {first}"),
    }
}

fn list(numbers: &[i64]) -> String {
    let mut out = String::new();
    for (i, n) in numbers.iter().enumerate() {
        if i > 0 {
            out.push(' ');
        }
        let _ = write!(out, "{n}");
    }
    out
}

fn skipped_note(skipped: usize) -> String {
    match skipped {
        0 => String::new(),
        n => format!(
            " ({n} elements of other types were skipped; only linear 4-node tetrahedra are read)"
        ),
    }
}
