//! Triangle surfaces from files: the [`SurfaceMesh`] and [`read_surface`], which recognises
//! the format by content and hands the file to its reader — one module per format: `stl`,
//! `obj`, `ply`, and the VTK modules (`vtk` for legacy files, with `vtk_binary`; `vtk_xml`).

use std::path::Path;

use super::obj::obj;
use super::ply::ply;
use super::stl::{stl_ascii, stl_binary, stl_count, stl_size};
use super::text;
use super::MeshReadError;

/// A triangle surface: vertex positions and triangles over them (0-based), as the file has
/// them. Nothing is validated beyond "every coordinate is finite" and "every index names a
/// vertex": a surface may be open, non-manifold, or hold degenerate triangles.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SurfaceMesh {
    /// Vertex positions, in the file's units.
    pub vertices: Vec<[f64; 3]>,
    /// Triangles, 0-based indices into `vertices`, in the file's winding.
    pub triangles: Vec<[u32; 3]>,
}

impl SurfaceMesh {
    /// Writes the surface as Wavefront OBJ (`v x y z` at full precision, then `f a b c`,
    /// 1-based), which every surface reader here and every 3D tool reads back.
    pub fn write_obj(&self, path: &Path) -> std::io::Result<()> {
        use std::fmt::Write as _;
        let mut s = String::with_capacity(40 * self.vertices.len() + 24 * self.triangles.len());
        for v in &self.vertices {
            let _ = writeln!(s, "v {:?} {:?} {:?}", v[0], v[1], v[2]);
        }
        for t in &self.triangles {
            let _ = writeln!(s, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1);
        }
        std::fs::write(path, s)
    }
}

/// The surface formats, as recognised from a file's content (the extension only breaks ties).
#[derive(Debug, PartialEq, Eq)]
enum Kind {
    StlAscii,
    StlBinary,
    Obj,
    Ply,
    /// Legacy VTK (`# vtk DataFile ...`) or VTK XML.
    Vtk,
    /// Nothing recognised; the first line, for the message.
    Unknown(String),
}

/// Reads a triangle surface, recognising the format by content:
///
/// - **PLY**: the file starts with the line `ply`. ASCII, `binary_little_endian` and
///   `binary_big_endian`; the `vertex` element's `x`, `y`, `z` (any scalar type) and the
///   `face` element's `vertex_indices` (or `vertex_index`) list, whose polygons are split
///   into triangles as a fan from their first vertex. Other elements and properties are
///   skipped.
/// - **Binary STL**: the file is exactly `84 + 50·n` bytes long, `n` being the triangle count
///   stored at byte 80 (the `solid` that some binary files start with is not trusted). A
///   `.stl` file of another size that is not ASCII STL (or a `solid` file with NUL bytes) is
///   reported as a binary STL whose size does not match its count, before anything is
///   allocated for the count.
/// - **ASCII STL**: the first word is `solid` and there is no NUL byte; `facet normal` /
///   `outer loop` / three
///   `vertex` lines / `endloop` / `endfacet`, in one or more `solid` ... `endsolid` blocks.
/// - **OBJ**: a `.obj` file, or one whose first statement is an OBJ one (`v`, `f`, `o`, ...).
///   `v x y z [w | r g b]` and `f` with `i`, `i/t`, `i//n` or `i/t/n` corners, negative
///   numbers counting back from the last vertex so far; polygons are fanned into triangles.
///   Texture coordinates, normals, groups, materials, lines and points are skipped.
/// - **VTK**: the first line is `# vtk DataFile ...` (legacy, ASCII or binary) or `<?xml` /
///   `<VTKFile` (XML; every encoding [`super::read_vtk_xml`] reads). A `POLYDATA` / `PolyData`
///   with its `POLYGONS` / `<Polys>`, or an unstructured grid of triangles and quadrilaterals
///   (types 5 and 9; as meshio writes surfaces). Triangles are kept; a quadrilateral `a b c d`
///   is split into `a b c` and `a c d`; any other polygon, triangle strips and volume cells
///   are refused naming the cell. Vertices and lines are skipped.
///
/// STL repeats each vertex in every triangle that uses it: vertices with equal coordinates
/// (`-0.0` equal to `0.0`) are merged into one. OBJ and PLY vertices are kept as listed.
///
/// # Errors
/// [`MeshReadError::Parse`] (text: the line) or [`MeshReadError::BinaryParse`] (binary: the
/// byte offset) naming the value at fault, [`MeshReadError::UnsupportedFormat`] for a file of
/// no known surface format (quoting its first line), [`MeshReadError::Io`].
pub fn read_surface(path: &Path) -> Result<SurfaceMesh, MeshReadError> {
    let bytes = std::fs::read(path).map_err(|source| MeshReadError::Io {
        path: path.to_owned(),
        source,
    })?;
    match detect(path, &bytes) {
        Kind::StlBinary => stl_binary(path, &bytes),
        Kind::StlAscii => stl_ascii(path, bytes),
        Kind::Obj => obj(path, bytes),
        Kind::Ply => ply(path, &bytes),
        Kind::Vtk => super::vtk::read_vtk_surface(path, bytes),
        Kind::Unknown(first) => Err(MeshReadError::UnsupportedFormat {
            path: path.to_owned(),
            reason: format!(
                "expected a surface in STL (ASCII or binary), OBJ, PLY or VTK (legacy POLYDATA \
                 or XML PolyData), but the first line is {}",
                if first.is_empty() {
                    "empty (or the file is)".to_owned()
                } else {
                    text::quote(&first)
                }
            ),
        }),
    }
}

fn detect(path: &Path, bytes: &[u8]) -> Kind {
    let ext = text::extension(path);
    let head = String::from_utf8_lossy(&bytes[..bytes.len().min(4096)]);
    let head = head.strip_prefix('\u{feff}').unwrap_or(&head);
    let mut lines = head.lines().map(str::trim).filter(|l| !l.is_empty());
    let first = lines.clone().next().unwrap_or("").to_owned();
    if first == "ply" {
        return Kind::Ply;
    }
    if first
        .get(..14)
        .is_some_and(|head| head.eq_ignore_ascii_case("# vtk DataFile"))
        || super::vtk_xml::is_xml(bytes)
    {
        return Kind::Vtk;
    }
    if stl_count(bytes).is_some_and(|n| stl_size(n) == bytes.len() as u64) {
        return Kind::StlBinary;
    }
    let word = first.split_whitespace().next().unwrap_or("");
    // Binary STL headers may start with "solid" too, but text never holds a NUL byte while
    // binary STL nearly always does (zero attribute bytes, zero coordinates): a "solid" file
    // without NUL is ASCII, and its reader reports any stray byte with its line.
    if word.eq_ignore_ascii_case("solid") && !bytes.contains(&0) {
        return Kind::StlAscii;
    }
    if ext.as_deref() == Some("stl") || word.eq_ignore_ascii_case("solid") {
        return Kind::StlBinary;
    }
    let statement = lines
        .find(|l| !l.starts_with('#'))
        .and_then(|l| l.split_whitespace().next())
        .unwrap_or("");
    let obj_word = matches!(
        statement,
        "v" | "vt" | "vn" | "f" | "o" | "g" | "s" | "mtllib" | "usemtl"
    );
    if ext.as_deref() == Some("obj") || (obj_word && !first.starts_with("# vtk")) {
        return Kind::Obj;
    }
    Kind::Unknown(first)
}

/// A [`MeshReadError::BinaryParse`] at `offset` (shared by the binary STL and PLY readers).
pub(super) fn binary_error(
    path: &Path,
    offset: usize,
    expected: impl Into<String>,
    found: impl Into<String>,
) -> MeshReadError {
    MeshReadError::BinaryParse {
        path: path.to_owned(),
        offset: offset as u64,
        expected: expected.into(),
        found: found.into(),
    }
}
