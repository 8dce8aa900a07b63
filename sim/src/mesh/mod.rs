//! Tetrahedral meshes: the in-memory form, readers, validation and surface extraction.
//!
//! A [`TetMesh`] is the volume mesh of one organ: node positions, positively oriented linear
//! tetrahedra, the outward-wound boundary surface extracted from them, and the fixed
//! (Dirichlet) nodes. Every constructor validates its input, so code that holds a `TetMesh` can
//! rely on the invariants documented on its fields. Nothing here panics on bad input: a
//! malformed file gives a [`MeshReadError`] that names the file, the line and the offending
//! value.
//!
//! # Reading
//!
//! [`read_mesh`] recognises the format by the path for TetGen and by the file's content
//! otherwise (extensions are compared case-insensitively):
//!
//! | recognised by | format | reader |
//! |---|---|---|
//! | path `X.node`, `X.ele`, or `X` with `X.node` beside it | TetGen | [`read_tetgen`] |
//! | first line `$MeshFormat` or `$NOD` | Gmsh ASCII 1, 2.2 or 4.1 | [`read_gmsh`] |
//! | first line `# vtk DataFile ...` | legacy VTK `UNSTRUCTURED_GRID`, ASCII or binary (file versions up to 5.1) | [`read_vtk`] |
//! | first line `<?xml ...` or `<VTKFile ...` | VTK XML `UnstructuredGrid` (`.vtu`) | [`read_vtk_xml`] |
//! | otherwise the extension `*.msh` / `*.vtk` / `*.vtu` | (the reader then says what is wrong) | |
//!
//! So a Gmsh file named `liver.txt` or a VTK file named `liver.dat` reads. A file that is
//! none of these is a [`MeshReadError::UnsupportedFormat`] that quotes its first line.
//!
//! Triangle surfaces (STL ASCII and binary, OBJ, PLY ASCII and binary, VTK legacy `POLYDATA`
//! and XML `PolyData`) are read by [`read_surface`] into a [`SurfaceMesh`]; see there for what
//! is read of each. They are not
//! volume meshes: `read_mesh` does not read them.
//!
//! Coordinates are taken as they are written: they are metres by convention, and no unit
//! conversion is done.
//!
//! ## TetGen (`X.node`, `X.ele`, optional `X.face`, optional `X.bnd`)
//!
//! `#` starts a comment anywhere on a line; blank lines are ignored; fields are separated by
//! whitespace or commas (as TetGen itself accepts).
//!
//! - `.node`: header `<#points> [<dimension = 3> [<#attributes> [<boundary markers 0|1>]]]`,
//!   then one line per point, `<number> <x> <y> <z> [attributes...] [marker]`, with exactly the
//!   declared number of fields. The number of the first point (0 or 1) is the file's *first
//!   number*; the points must then be numbered consecutively. Attributes and markers are checked
//!   to be numbers and otherwise ignored.
//! - `.ele`: header `<#tetrahedra> <nodes per tetrahedron: 4 or 10> [<#attributes>]`, then
//!   `<number> <n1> ... <n4|n10> [attributes...]`. Node numbers use the first number of the
//!   `.node` file; a number outside `[first, first + #points)` is an
//!   [`MeshReadError::IndexOutOfRange`] that says how the nodes are numbered, so a 1-based
//!   `.ele` beside a 0-based `.node` (or the reverse) is caught. Of a 10-node (quadratic)
//!   tetrahedron only the four corners are used. Tetrahedron numbers are read but not checked.
//! - `.face` (optional): header `<#faces> [<boundary marker 0|1>]`, then
//!   `<number> <a> <b> <c> [marker]`. It is only checked to parse and to refer to existing
//!   nodes: the surface is always extracted from the tetrahedra, which cannot disagree with them.
//! - `.bnd` (optional): the fixed nodes, see below.
//!
//! ## Gmsh (`*.msh`, or any name with Gmsh content)
//!
//! ASCII files of format 2.x (`$MeshFormat 2.2 0 8`) and 4.1 are read, and so is the legacy
//! format 1 (what `gmsh -format msh1` writes): no `$MeshFormat`, the nodes in `$NOD` ...
//! `$ENDNOD` (`<count>`, then `<node number> <x> <y> <z>`), the elements in `$ELM` ...
//! `$ENDELM` (`<count>`, then `<element number> <type> <physical region> <elementary region>
//! <#nodes> <node numbers...>`; an element whose node list is not as long as it says is an
//! error).
//!
//! Of the elements, only type 4 (4-node tetrahedron) is kept; all other element types (points,
//! lines, triangles, quadratic tetrahedra, ...) are skipped, and an error for a file with no
//! tetrahedra says how many were skipped. Sections other than `$MeshFormat`, `$Nodes` and
//! `$Elements` (e.g. `$PhysicalNames`, `$Entities`, `$NodeData`) are skipped. Node tags
//! (format 1: node numbers) may be sparse and in any order: node `i` of the mesh is the `i`-th
//! node listed in `$Nodes` (`$NOD`). Binary files and format 4.0 are rejected with
//! [`MeshReadError::UnsupportedFormat`] (re-export with `gmsh -format msh22` or `msh41`,
//! ASCII).
//!
//! ## VTK (`*.vtk`, `*.vtu`, or any name with VTK content)
//!
//! Legacy `DATASET UNSTRUCTURED_GRID`, ASCII or binary (`BINARY` on line 3: the arrays are
//! big-endian, as the legacy format specifies), with `POINTS` (any numeric type), `CELLS`
//! (either the classic `<count> <ids...>` list or the 5.1 `OFFSETS`/`CONNECTIVITY` arrays)
//! and `CELL_TYPES`. `FIELD` and `METADATA` blocks are skipped and reading stops at
//! `POINT_DATA` / `CELL_DATA`.
//!
//! VTK XML `UnstructuredGrid` (`.vtu`, or XML inside a `.vtk`): `DataArray`s in `ascii`,
//! `binary` (base64) or `appended` (`raw` or `base64`) format, uncompressed or with
//! `vtkZLibDataCompressor`, either `byte_order`, `header_type` `UInt32` or `UInt64`, several
//! `<Piece>`s joined; other compressors are [`MeshReadError::UnsupportedFormat`]. Every count
//! and size in a header is checked against the bytes in the file before anything is allocated
//! for it.
//!
//! Only cells of type 10 (`VTK_TETRA`) are kept; the others are skipped, and an error for a
//! file with no tetrahedra says how many were. Points are numbered from 0. Errors give the
//! line in text and the byte offset in binary data (raw appended data, binary legacy arrays).
//! A `POLYDATA` / `PolyData` file is a surface: read it with [`read_surface`].
//!
//! ## Fixed nodes: the boundary file (`.bnd`)
//!
//! lop's own format for the "additional file specifying the boundary constraints" of the
//! thesis. It sits beside the mesh: `X.bnd` for TetGen base `X`, `<stem>.bnd` for
//! `<stem>.msh` / `<stem>.vtk` / `<stem>.vtu`. If it is absent, no node is fixed.
//!
//! ```text
//! # comments start with '#', anywhere on a line; blank lines are ignored
//! 3        # first data line: the number N of fixed nodes
//! 1        # then N lines with one node number each
//! 2
//! 7
//! ```
//!
//! Node numbers are in the numbering of the mesh file they belong to: TetGen's first number
//! (the same base as the `.node` file), Gmsh node tags, VTK 0-based point ids. A number that
//! names no node is an error ([`MeshReadError::BadBoundary`], or
//! [`MeshReadError::UnknownNodeTag`] for Gmsh); a node listed twice is fixed once.
//! [`write_bnd`] writes one.
//!
//! # Validation
//!
//! - Every coordinate is finite; every node index names a node; at least one tetrahedron.
//! - **Degenerate**: a tetrahedron with `|6V| <= 1e-12 · (longest edge)³` (including one that
//!   repeats a node) is an error.
//! - **Duplicate**: two tetrahedra over the same set of four nodes are an error naming both.
//! - **Orientation**: files differ in their orientation convention. If all tetrahedra have the
//!   same sign of `(b-a)·((c-a)×(d-a))`, they are accepted and, if negative, normalised to
//!   positive by swapping their 2nd and 3rd nodes. If the signs are mixed, the tetrahedra of
//!   the minority sign are inverted (on a tie: the negative ones) and the first of them is
//!   reported as [`MeshReadError::InvertedTet`].
//! - **Surface**: the boundary surface is the set of faces that belong to exactly one
//!   tetrahedron, wound counter-clockwise seen from outside (so `(b-a)×(c-a)` points out), in
//!   the order of the tetrahedra. A face shared by more than two tetrahedra is an error
//!   ([`MeshReadError::NonManifoldFace`]), and so are two tetrahedra on the same side of the
//!   face they share ([`MeshReadError::OverlappingTets`]): both mean the mesh is broken.
//! - Nodes that no tetrahedron uses are kept (TetGen writes them unless run with `-j`, and
//!   they keep node numbers equal to the file's); [`MeshInfo::unused_nodes`] counts them.
//!
//! # Writing
//!
//! [`write_tetgen`] writes `X.node`, `X.ele`, `X.face` (the surface) and `X.bnd` numbered
//! from 1, as TetGen itself does; [`write_tetgen_numbered`] chooses 0 or 1. [`write_vtk`]
//! writes a legacy VTK file (points numbered from 0; fixed nodes are not part of VTK, write
//! them with [`write_bnd`] if needed). Coordinates are written so that they read back bit for
//! bit.

mod bnd;
mod cut;
mod embed;
mod error;
mod gmsh;
mod obj;
mod ply;
mod quality;
mod select;
mod stl;
mod surface;
mod surface_check;
mod surface_io;
mod tetgen;
mod text;
mod validate;
mod vtk;
mod vtk_binary;
mod vtk_cells;
mod vtk_xml;

use std::fmt;
use std::path::{Path, PathBuf};

pub use bnd::write_bnd;
pub use cut::{CutRefused, MeshCut, MIN_PIECE_TETS};
pub use embed::{EmbedError, Embedding, MAX_OUTSIDE_FRACTION};
pub use error::MeshReadError;
pub use gmsh::read_gmsh;
pub use select::{vertex_normals, NodeSelector, FACING_ANGLE_DEFAULT_DEG};
pub use surface_check::{
    check_surface, close_holes, DefectKind, HoleClosing, SurfaceDefect, SurfaceReport, TriangleRef,
    DEFECTS_LISTED,
};
pub use surface_io::{read_surface, SurfaceMesh};
pub use tetgen::{read_tetgen, write_tetgen, write_tetgen_numbered};
pub use vtk::{read_vtk, write_vtk};
pub use vtk_xml::read_vtk_xml;

/// A validated linear tetrahedral mesh.
#[derive(Debug, Clone, PartialEq)]
pub struct TetMesh {
    /// Node positions, metres (whatever the file says; no unit conversion). All finite.
    pub nodes: Vec<[f64; 3]>,
    /// Tetrahedra, 0-based node indices, every one positively oriented:
    /// `(b-a)·((c-a)×(d-a)) > 0`. No two use the same four nodes.
    pub tets: Vec<[u32; 4]>,
    /// Boundary surface: triangles wound counter-clockwise seen from outside (normal points
    /// out), 0-based.
    pub surface: Vec<[u32; 3]>,
    /// Fixed (Dirichlet) nodes, 0-based, sorted, unique.
    pub fixed: Vec<u32>,
    /// File the mesh was read from (for messages).
    pub source: PathBuf,
}

impl TetMesh {
    /// Builds a mesh from raw parts, validating them (indices in range, finite coordinates, no
    /// duplicate or degenerate tetrahedra, consistent orientation, manifold faces) and
    /// extracting the surface. Tetrahedra may all be negatively oriented; they are then flipped.
    /// `fixed` may be unsorted and repeat nodes. Errors name tetrahedra and nodes by their
    /// 0-based index and have no line numbers.
    ///
    /// # Errors
    /// [`MeshReadError::IndexOutOfRange`], [`MeshReadError::BadBoundary`] (a fixed node out of
    /// range), [`MeshReadError::NonFiniteCoordinate`], [`MeshReadError::NoTets`],
    /// [`MeshReadError::DegenerateTet`], [`MeshReadError::DuplicateTet`],
    /// [`MeshReadError::InvertedTet`], [`MeshReadError::NonManifoldFace`],
    /// [`MeshReadError::OverlappingTets`], [`MeshReadError::TooManyNodes`].
    pub fn from_parts(
        nodes: Vec<[f64; 3]>,
        tets: Vec<[u32; 4]>,
        fixed: Vec<u32>,
        source: PathBuf,
    ) -> Result<TetMesh, MeshReadError> {
        let origin = validate::Origin::in_memory(source.clone());
        validate::build(nodes, tets, fixed, source, &origin)
    }

    /// Counts, bounding box, volume and quality.
    #[must_use]
    pub fn info(&self) -> MeshInfo {
        let (mut bbox_min, mut bbox_max) = bounds(&self.nodes);
        if self.nodes.is_empty() {
            bbox_min = [0.0; 3];
            bbox_max = [0.0; 3];
        }
        let mut volume = 0.0;
        let mut quality_min = f64::INFINITY;
        let mut quality_sum = 0.0;
        let mut used = vec![false; self.nodes.len()];
        for (i, tet) in self.tets.iter().enumerate() {
            volume += self.tet_volume(i);
            let q = quality::mean_ratio(&self.corners(i));
            quality_min = quality_min.min(q);
            quality_sum += q;
            for &n in tet {
                if let Some(u) = used.get_mut(n as usize) {
                    *u = true;
                }
            }
        }
        let (quality_min, quality_mean) = if self.tets.is_empty() {
            (0.0, 0.0)
        } else {
            (quality_min, quality_sum / self.tets.len() as f64)
        };
        MeshInfo {
            nodes: self.nodes.len(),
            tets: self.tets.len(),
            surface_triangles: self.surface.len(),
            fixed_nodes: self.fixed.len(),
            unused_nodes: used.iter().filter(|&&u| !u).count(),
            bbox_min,
            bbox_max,
            volume,
            quality_min,
            quality_mean,
        }
    }

    /// Unique undirected edges of the tetrahedra, each `[lo, hi]` with `lo < hi`, sorted.
    #[must_use]
    pub fn edges(&self) -> Vec<[u32; 2]> {
        surface::edges(&self.tets)
    }

    /// Signed volume of tetrahedron `i` (positive for a validated mesh).
    ///
    /// # Panics
    /// If `i` or one of its node indices is out of range.
    pub fn tet_volume(&self, i: usize) -> f64 {
        quality::volume6(&self.corners(i)) / 6.0
    }

    /// Nodes that appear in the surface, sorted unique.
    #[must_use]
    pub fn surface_nodes(&self) -> Vec<u32> {
        let mut nodes: Vec<u32> = self.surface.iter().flatten().copied().collect();
        nodes.sort_unstable();
        nodes.dedup();
        nodes
    }

    fn corners(&self, i: usize) -> [[f64; 3]; 4] {
        self.tets[i].map(|n| self.nodes[n as usize])
    }
}

/// Summary of a mesh, from [`TetMesh::info`]. Its `Display` is a multi-line human summary.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeshInfo {
    pub nodes: usize,
    pub tets: usize,
    pub surface_triangles: usize,
    pub fixed_nodes: usize,
    /// Nodes used by no tetrahedron (kept to preserve the file's numbering).
    pub unused_nodes: usize,
    pub bbox_min: [f64; 3],
    pub bbox_max: [f64; 3],
    /// Total volume, m³.
    pub volume: f64,
    /// Mean-ratio quality `12 (3V)^(2/3) / Σ l²` over the six edges: 1 for a regular
    /// tetrahedron, towards 0 for a degenerate one. Worst over all tetrahedra.
    pub quality_min: f64,
    /// Mean-ratio quality averaged over all tetrahedra.
    pub quality_mean: f64,
}

impl fmt::Display for MeshInfo {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let size = [0, 1, 2].map(|k| self.bbox_max[k] - self.bbox_min[k]);
        writeln!(f, "nodes:             {}", self.nodes)?;
        writeln!(f, "  fixed:           {}", self.fixed_nodes)?;
        if self.unused_nodes > 0 {
            writeln!(f, "  unused:          {}", self.unused_nodes)?;
        }
        writeln!(f, "tetrahedra:        {}", self.tets)?;
        writeln!(f, "surface triangles: {}", self.surface_triangles)?;
        writeln!(
            f,
            "bounding box:      [{:.6}, {:.6}, {:.6}] .. [{:.6}, {:.6}, {:.6}] m",
            self.bbox_min[0],
            self.bbox_min[1],
            self.bbox_min[2],
            self.bbox_max[0],
            self.bbox_max[1],
            self.bbox_max[2]
        )?;
        writeln!(
            f,
            "size:              {:.6} x {:.6} x {:.6} m",
            size[0], size[1], size[2]
        )?;
        writeln!(f, "volume:            {:.6e} m^3", self.volume)?;
        write!(
            f,
            "quality:           min {:.4}, mean {:.4} (mean ratio; 1 = regular tetrahedron)",
            self.quality_min, self.quality_mean
        )
    }
}

/// Axis-aligned bounding box `(min, max)` of `points`, m (infinite and inverted when empty).
pub fn bounds(points: &[[f64; 3]]) -> ([f64; 3], [f64; 3]) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in points {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    (lo, hi)
}

/// Extent of the bounding box of `points` along each axis, m.
pub fn extents(points: &[[f64; 3]]) -> [f64; 3] {
    let (lo, hi) = bounds(points);
    [0, 1, 2].map(|k| hi[k] - lo[k])
}

/// Smallest extent of the bounding box of `points`, m: the "smallest dimension" that errors
/// and jumps are measured against.
pub fn smallest_extent(points: &[[f64; 3]]) -> f64 {
    extents(points).into_iter().fold(f64::INFINITY, f64::min)
}

/// Reads any supported mesh, recognising the format (see the [module docs](self)):
/// `X.node` / `X.ele` / a base `X` with `X.node` beside it → TetGen; otherwise by the file's
/// first line: `$MeshFormat` or `$NOD` → Gmsh, `# vtk DataFile` → VTK, whatever the extension;
/// a file whose first line is neither falls back to its extension (`.msh`, `.vtk`), so that the
/// reader for that format reports what is wrong with it.
///
/// # Errors
/// [`MeshReadError::Io`] if the file (or, for TetGen, `X.node`) does not exist,
/// [`MeshReadError::UnsupportedFormat`] for a file of no known format (the message quotes its
/// first line), and whatever the reader for the format reports.
pub fn read_mesh(path: &Path) -> Result<TetMesh, MeshReadError> {
    let ext = text::extension(path);
    match ext.as_deref() {
        Some("node" | "ele" | "face") => return read_tetgen(path),
        _ if text::with_suffix(path, "node").is_file() => return read_tetgen(path),
        _ if !path.exists() => {
            return Err(MeshReadError::Io {
                path: path.to_owned(),
                source: std::io::Error::new(
                    std::io::ErrorKind::NotFound,
                    format!(
                        "no such file, and no TetGen mesh {} beside it",
                        text::with_suffix(path, "node").display()
                    ),
                ),
            })
        }
        _ => {}
    }
    let first = text::first_line(path)?;
    match sniff(&first) {
        Some(Format::Gmsh) => read_gmsh(path),
        Some(Format::Vtk) => read_vtk(path),
        Some(Format::VtkXml) => read_vtk_xml(path),
        None => match ext.as_deref() {
            Some("msh") => read_gmsh(path),
            Some("vtk") => read_vtk(path),
            Some("vtu") => read_vtk_xml(path),
            _ => {
                let surface = matches!(ext.as_deref(), Some("stl" | "obj" | "ply" | "vtp"))
                    || first == "ply"
                    || first.starts_with("solid");
                Err(MeshReadError::UnsupportedFormat {
                    path: path.to_owned(),
                    reason: format!(
                        "expected a TetGen mesh (.node/.ele), a Gmsh .msh file (first line \
                         `$MeshFormat` or `$NOD`), a legacy VTK .vtk file (first line \
                         `# vtk DataFile Version ...`) or a VTK XML .vtu file (first line \
                         `<?xml ...` or `<VTKFile ...`), but the first line is {}{}",
                        if first.is_empty() {
                            "empty (or the file is)".to_owned()
                        } else {
                            text::quote(&first)
                        },
                        if surface {
                            " (this looks like a triangle surface: it has no tetrahedra; \
                             mesh its inside, e.g. with TetGen or gmsh)"
                        } else {
                            ""
                        }
                    ),
                })
            }
        },
    }
}

/// Volume mesh formats recognised by their first line.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Format {
    Gmsh,
    Vtk,
    VtkXml,
}

/// The format a file's first non-blank line announces, if any.
fn sniff(first: &str) -> Option<Format> {
    match first {
        "$MeshFormat" | "$NOD" => Some(Format::Gmsh),
        t if t
            .get(..14)
            .is_some_and(|head| head.eq_ignore_ascii_case("# vtk DataFile")) =>
        {
            Some(Format::Vtk)
        }
        t if t.starts_with("<?xml") || t.starts_with("<VTKFile") => Some(Format::VtkXml),
        _ => None,
    }
}
