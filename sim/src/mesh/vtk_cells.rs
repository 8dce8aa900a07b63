//! What the VTK readers share: where an error sits (a line or a byte offset), the scalar types
//! of binary arrays (the PLY reader decodes its binary properties with them too), and turning
//! VTK cells into tetrahedra (volume meshes) or triangles (surfaces).

use std::path::Path;

use super::validate::{self, NodeLabels, Origin};
use super::{bnd, MeshReadError, TetMesh};

/// VTK cell type of the linear tetrahedron (`VTK_TETRA`).
pub(super) const VTK_TETRA: i64 = 10;

/// Where a value sits in a file, for messages: a 1-based line of text, or a 0-based byte offset
/// in binary data.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Loc {
    Line(usize),
    Byte(u64),
}

impl Loc {
    pub(super) fn byte(offset: usize) -> Self {
        Loc::Byte(offset as u64)
    }
}

/// [`MeshReadError::Parse`] or [`MeshReadError::BinaryParse`], depending on `loc`.
pub(super) fn error_at(
    path: &Path,
    loc: Loc,
    expected: impl Into<String>,
    found: impl Into<String>,
) -> MeshReadError {
    match loc {
        Loc::Line(line) => MeshReadError::Parse {
            path: path.to_owned(),
            line,
            expected: expected.into(),
            found: found.into(),
        },
        Loc::Byte(offset) => MeshReadError::BinaryParse {
            path: path.to_owned(),
            offset,
            expected: expected.into(),
            found: found.into(),
        },
    }
}

/// A scalar type of binary VTK data.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    I64,
    U64,
    F32,
    F64,
}

impl Scalar {
    /// A VTK XML `type` attribute (`Int32`, `Float64`, ...).
    pub(super) fn from_xml(name: &str) -> Option<Self> {
        Some(match name {
            "Int8" | "Char" => Scalar::I8,
            "UInt8" => Scalar::U8,
            "Int16" => Scalar::I16,
            "UInt16" => Scalar::U16,
            "Int32" => Scalar::I32,
            "UInt32" => Scalar::U32,
            "Int64" => Scalar::I64,
            "UInt64" => Scalar::U64,
            "Float32" => Scalar::F32,
            "Float64" => Scalar::F64,
            _ => return None,
        })
    }

    /// A legacy VTK data type (`float`, `double`, `int`, `vtktypeint64`, ...). `long` is taken
    /// as 8 bytes, as VTK on 64-bit Linux writes it.
    pub(super) fn from_legacy(name: &str) -> Option<Self> {
        Some(match name.to_ascii_lowercase().as_str() {
            "char" | "vtktypeint8" => Scalar::I8,
            "unsigned_char" | "vtktypeuint8" => Scalar::U8,
            "short" | "vtktypeint16" => Scalar::I16,
            "unsigned_short" | "vtktypeuint16" => Scalar::U16,
            "int" | "vtktypeint32" => Scalar::I32,
            "unsigned_int" | "vtktypeuint32" => Scalar::U32,
            "long" | "vtktypeint64" | "vtkidtype" => Scalar::I64,
            "unsigned_long" | "vtktypeuint64" => Scalar::U64,
            "float" | "vtktypefloat32" => Scalar::F32,
            "double" | "vtktypefloat64" => Scalar::F64,
            _ => return None,
        })
    }

    /// A PLY property type (`char`, `uchar`, …, `double`, or `int8` … `float64`).
    pub(super) fn from_ply(name: &str) -> Option<Self> {
        Some(match name {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    /// The range of an integer type (all of `i64` for the others).
    pub(super) fn range(self) -> (i64, i64) {
        match self {
            Scalar::I8 => (i8::MIN.into(), i8::MAX.into()),
            Scalar::U8 => (0, u8::MAX.into()),
            Scalar::I16 => (i16::MIN.into(), i16::MAX.into()),
            Scalar::U16 => (0, u16::MAX.into()),
            Scalar::I32 => (i32::MIN.into(), i32::MAX.into()),
            Scalar::U32 => (0, u32::MAX.into()),
            Scalar::I64 | Scalar::U64 | Scalar::F32 | Scalar::F64 => (i64::MIN, i64::MAX),
        }
    }

    pub(super) fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::I64 | Scalar::U64 | Scalar::F64 => 8,
        }
    }

    pub(super) fn is_integer(self) -> bool {
        !matches!(self, Scalar::F32 | Scalar::F64)
    }

    /// Value `raw` (exactly `size()` bytes) as an integer; `None` for a float type or a
    /// `UInt64` above `i64::MAX`.
    pub(super) fn int(self, raw: &[u8], big: bool) -> Option<i64> {
        let b = ordered(raw.get(..self.size()).unwrap_or(raw), big);
        Some(match self {
            Scalar::I8 => i64::from(b[7] as i8),
            Scalar::U8 => i64::from(b[7]),
            Scalar::I16 => i64::from(i16::from_be_bytes([b[6], b[7]])),
            Scalar::U16 => i64::from(u16::from_be_bytes([b[6], b[7]])),
            Scalar::I32 => i64::from(i32::from_be_bytes([b[4], b[5], b[6], b[7]])),
            Scalar::U32 => i64::from(u32::from_be_bytes([b[4], b[5], b[6], b[7]])),
            Scalar::I64 => i64::from_be_bytes(b),
            Scalar::U64 => i64::try_from(u64::from_be_bytes(b)).ok()?,
            Scalar::F32 | Scalar::F64 => return None,
        })
    }

    /// Value `raw` (exactly `size()` bytes) as a real number (integers converted).
    pub(super) fn real(self, raw: &[u8], big: bool) -> f64 {
        let b = ordered(raw.get(..self.size()).unwrap_or(raw), big);
        match self {
            Scalar::F32 => f64::from(f32::from_be_bytes([b[4], b[5], b[6], b[7]])),
            Scalar::F64 => f64::from_be_bytes(b),
            Scalar::U64 => u64::from_be_bytes(b) as f64,
            other => other.int(raw, big).unwrap_or(0) as f64,
        }
    }
}

/// `raw` (at most 8 bytes) right-aligned in 8 big-endian bytes.
fn ordered(raw: &[u8], big: bool) -> [u8; 8] {
    let mut b = [0u8; 8];
    let n = raw.len().min(8);
    b[8 - n..].copy_from_slice(&raw[..n]);
    if !big {
        b[8 - n..].reverse();
    }
    b
}

/// Cells as VTK stores them: cell `i` is `conn[offsets[i]..offsets[i + 1]]`, of type
/// `types[i]` (no types for the polygons of a POLYDATA).
#[derive(Debug, Default)]
pub(super) struct Cells {
    /// `#cells + 1` non-decreasing offsets into `conn`, the first 0, the last `conn.len()`.
    pub offsets: Vec<usize>,
    pub conn: Vec<i64>,
    pub types: Vec<i64>,
    /// Where each cell is, for messages.
    pub locs: Vec<Loc>,
}

impl Cells {
    pub(super) fn len(&self) -> usize {
        self.offsets.len().saturating_sub(1)
    }

    /// Where cell `i` is (the last known place if it has none).
    pub(super) fn loc(&self, i: usize) -> Loc {
        self.locs
            .get(i)
            .or(self.locs.last())
            .copied()
            .unwrap_or(Loc::Line(1))
    }

    pub(super) fn cell(&self, i: usize) -> &[i64] {
        let lo = self.offsets.get(i).copied().unwrap_or(0);
        let hi = self.offsets.get(i + 1).copied().unwrap_or(lo);
        self.conn.get(lo..hi).unwrap_or(&[])
    }
}

/// A point id of a cell as a 0-based node index, or an error at `loc`: in text
/// [`MeshReadError::IndexOutOfRange`] (as the other text readers report it), in binary data a
/// [`MeshReadError::BinaryParse`] naming the cell.
fn point(
    path: &Path,
    loc: Loc,
    points: usize,
    id: i64,
    what: std::fmt::Arguments<'_>,
) -> Result<u32, MeshReadError> {
    usize::try_from(id)
        .ok()
        .filter(|&i| i < points)
        .and_then(|i| u32::try_from(i).ok())
        .ok_or_else(|| match loc {
            Loc::Line(line) => MeshReadError::IndexOutOfRange {
                path: path.to_owned(),
                line: Some(line),
                index: id,
                count: points,
                first_index: 0,
                node_file: path.to_owned(),
            },
            Loc::Byte(_) => error_at(
                path,
                loc,
                format!("a point id below {points} (the number of points) for {what}"),
                format!("`{id}`"),
            ),
        })
}

/// The tetrahedra of a file.
pub(super) struct Tets {
    pub tets: Vec<[u32; 4]>,
    /// The cell id of each tetrahedron.
    pub labels: Vec<i64>,
    pub skipped: usize,
}

/// The tetrahedra (type 10) of `cells`; other types are counted as skipped.
pub(super) fn tets(path: &Path, points: usize, cells: &Cells) -> Result<Tets, MeshReadError> {
    let loc = |c| cells.loc(c);
    let mut out = Tets {
        tets: Vec::new(),
        labels: Vec::new(),
        skipped: 0,
    };
    for (c, &kind) in cells.types.iter().enumerate() {
        if kind != VTK_TETRA {
            out.skipped += 1;
            continue;
        }
        let ids = cells.cell(c);
        if ids.len() != 4 {
            return Err(error_at(
                path,
                loc(c),
                format!("4 point ids for cell {c} of type 10 (VTK_TETRA)"),
                format!("{} ids", ids.len()),
            ));
        }
        let mut tet = [0u32; 4];
        for (j, (slot, &id)) in tet.iter_mut().zip(ids).enumerate() {
            *slot = point(
                path,
                loc(c),
                points,
                id,
                format_args!("point {j} of cell {c}"),
            )?;
        }
        out.tets.push(tet);
        out.labels.push(i64::try_from(c).unwrap_or(i64::MAX));
    }
    Ok(out)
}

/// The triangles of the polygons of a POLYDATA: a triangle is kept, a quadrilateral
/// `a b c d` is split into `a b c` and `a c d`, any other polygon is refused (naming it).
pub(super) fn triangles(
    path: &Path,
    points: usize,
    polys: &Cells,
) -> Result<Vec<[u32; 3]>, MeshReadError> {
    let loc = |c| polys.loc(c);
    let mut out = Vec::with_capacity(polys.len().min(1 << 16));
    for c in 0..polys.len() {
        let ids = polys.cell(c);
        if !(3..=4).contains(&ids.len()) {
            return Err(error_at(
                path,
                loc(c),
                format!(
                    "a triangle or a quadrilateral for polygon {c} (other polygons are not read)"
                ),
                format!("a polygon of {} points", ids.len()),
            ));
        }
        let mut p = [0u32; 4];
        for (j, &id) in ids.iter().enumerate() {
            p[j] = point(
                path,
                loc(c),
                points,
                id,
                format_args!("point {j} of polygon {c}"),
            )?;
        }
        out.push([p[0], p[1], p[2]]);
        if ids.len() == 4 {
            out.push([p[0], p[2], p[3]]);
        }
    }
    Ok(out)
}

/// The line of each tetrahedron (by its cell id), if the cells have lines.
pub(super) fn line_numbers(cells: &Cells, labels: &[i64]) -> Vec<usize> {
    labels
        .iter()
        .map_while(
            |&c| match cells.loc(usize::try_from(c).unwrap_or(usize::MAX)) {
                Loc::Line(line) => Some(line),
                Loc::Byte(_) => None,
            },
        )
        .collect()
}

/// The cells of an unstructured grid read as a surface: triangles (type 5) and quadrilaterals
/// (type 9) are kept, vertices and lines (types 1 to 4) skipped, any other cell refused.
pub(super) fn surface_cells(path: &Path, cells: &Cells) -> Result<Cells, MeshReadError> {
    let mut out = Cells {
        offsets: vec![0],
        ..Cells::default()
    };
    for (c, &kind) in cells.types.iter().enumerate() {
        match kind {
            5 | 9 => {
                out.conn.extend_from_slice(cells.cell(c));
                out.offsets.push(out.conn.len());
                out.locs.push(cells.loc(c));
            }
            1..=4 => {}
            _ => {
                return Err(error_at(
                    path,
                    cells.loc(c),
                    format!(
                        "a triangle or quadrilateral (VTK type 5 or 9) for cell {c} of a surface"
                    ),
                    if kind == VTK_TETRA {
                        "type `10`, a tetrahedron (a volume mesh: read it with read_mesh)"
                            .to_owned()
                    } else {
                        format!("type `{kind}`")
                    },
                ))
            }
        }
    }
    Ok(out)
}

/// The checks after reading, shared by the VTK volume readers: no tetrahedra is an error
/// (saying how many cells were skipped); the fixed nodes come from a sibling `<stem>.bnd`
/// (0-based point ids); then validation. `lines` is the line of each tetrahedron if it has one.
pub(super) fn tet_mesh(
    path: &Path,
    points: Vec<[f64; 3]>,
    tets: Tets,
    lines: Vec<usize>,
) -> Result<TetMesh, MeshReadError> {
    if tets.tets.is_empty() {
        return Err(MeshReadError::NoTets {
            path: path.to_owned(),
            skipped: tets.skipped,
        });
    }
    let count = points.len();
    let bnd_path = path.with_extension("bnd");
    let fixed = bnd::read_optional(&bnd_path, |line, id| {
        usize::try_from(id)
            .ok()
            .filter(|&i| i < count)
            .and_then(|i| u32::try_from(i).ok())
            .ok_or_else(|| MeshReadError::BadBoundary {
                path: bnd_path.clone(),
                line: Some(line),
                index: id,
                count,
                first_index: 0,
                node_file: path.to_owned(),
            })
    })?
    .unwrap_or_default();
    let origin = Origin {
        tet_file: path.to_owned(),
        tet_lines: lines,
        tet_labels: tets.labels,
        node_labels: NodeLabels::Offset(0),
    };
    validate::build(points, tets.tets, fixed, path.to_owned(), &origin)
}
