//! VTK XML files: `UnstructuredGrid` (`.vtu`) volume meshes and `PolyData` (`.vtp`) surfaces,
//! recognised by content (`<?xml` or `<VTKFile`), whatever the extension.
//!
//! A `DataArray` is `format="ascii"` (numbers in the text), `"binary"` (base64 in the text) or
//! `"appended"` (at `offset` in `<AppendedData>`, whose `encoding` is `"raw"`, bytes as they are
//! after the `_` marker, or `"base64"`). Binary data is a header of `header_type` words
//! (`UInt32`, the default, or `UInt64`) then the values: uncompressed, one word with the byte
//! count; with `compressor="vtkZLibDataCompressor"`, the block count, the block size, the size
//! of the last block and each block's compressed size, then the zlib streams. Base64 writers
//! differ in whether the header is encoded apart from the data (VTK, meshio) or with it; both
//! are read. `byte_order` `LittleEndian` and `BigEndian`; any numeric `type` for points,
//! integer types for ids, offsets and cell types.
//!
//! Raw appended data is not XML: the file is split at the `_` marker and only the part before
//! it is parsed. Every count and size (`NumberOfPoints`, `NumberOfCells`, header words) is
//! checked against the bytes actually in the file before anything is allocated for it; a zlib
//! block may not claim to expand more than deflate can (1032:1).
//!
//! Crates, with their compile time in a clean `cargo build -p lop-sim --timings` (dev profile,
//! dependencies at opt-level 3, 2 shared cores): `roxmltree` 5.3 s plus `memchr` 3.1 s (XML;
//! no DTD support, so no entity expansion), `base64` 1.0 s, `flate2` 1.2 s plus its default
//! pure-Rust backend `miniz_oxide` 4.0 s, `crc32fast` 1.3 s and `adler2` 0.2 s: about 16 s of
//! crate builds, partly in parallel.
//!
//! This file reads the document (the `<VTKFile>` layout, datasets, pieces, `DataArray`s and
//! their ascii values); `binary.rs` decodes binary and appended arrays (header words, base64,
//! zlib blocks).

use std::borrow::Cow;
use std::path::Path;

use roxmltree::{Document, Node};

use super::text::{self, quote};
use super::vtk_cells::{self, error_at, Cells, Loc, Scalar};
use super::{MeshReadError, SurfaceMesh, TetMesh};

mod binary;

/// Whether `bytes` look like a VTK XML file: the first non-blank text is `<?xml` or
/// `<VTKFile`.
pub(super) fn is_xml(bytes: &[u8]) -> bool {
    let bytes = bytes.strip_prefix(b"\xef\xbb\xbf").unwrap_or(bytes);
    let start = bytes
        .iter()
        .position(|b| !b.is_ascii_whitespace())
        .unwrap_or(bytes.len());
    let head = &bytes[start..];
    head.starts_with(b"<?xml") || head.starts_with(b"<VTKFile")
}

/// Reads a VTK XML `UnstructuredGrid` (`.vtu`: cells of type 10 only) and the fixed nodes from
/// a sibling `<stem>.bnd` (0-based point ids) if there is one. See the [module docs](super).
///
/// # Errors
/// Any [`MeshReadError`] naming the file at fault and the line (XML) or byte offset (raw
/// appended data); a `PolyData` or other dataset is [`MeshReadError::UnsupportedFormat`].
pub fn read_vtk_xml(path: &Path) -> Result<TetMesh, MeshReadError> {
    let bytes = std::fs::read(path).map_err(|source| MeshReadError::Io {
        path: path.to_owned(),
        source,
    })?;
    read_volume(path, &bytes)
}

pub(super) fn read_volume(path: &Path, bytes: &[u8]) -> Result<TetMesh, MeshReadError> {
    let (text, appended) = split(path, bytes)?;
    let doc = parse(path, &text)?;
    let file = File::new(path, bytes, &doc, appended)?;
    let grid = file.dataset("UnstructuredGrid")?;
    let mut points = Vec::new();
    let mut cells = Cells::default();
    for piece in grid.children().filter(|n| n.has_tag_name("Piece")) {
        file.grid_piece(piece, &mut points, &mut cells)?;
    }
    let tets = vtk_cells::tets(path, points.len(), &cells)?;
    let lines = vtk_cells::line_numbers(&cells, &tets.labels);
    vtk_cells::tet_mesh(path, points, tets, lines)
}

pub(super) fn read_surface(path: &Path, bytes: &[u8]) -> Result<SurfaceMesh, MeshReadError> {
    let (text, appended) = split(path, bytes)?;
    let doc = parse(path, &text)?;
    let file = File::new(path, bytes, &doc, appended)?;
    let kind = doc.root_element().attribute("type");
    let mut points = Vec::new();
    let mut polys = Cells::default();
    if kind == Some("UnstructuredGrid") {
        // meshio writes triangle surfaces as unstructured grids of triangles.
        let grid = file.dataset("UnstructuredGrid")?;
        let mut cells = Cells::default();
        for piece in grid.children().filter(|n| n.has_tag_name("Piece")) {
            file.grid_piece(piece, &mut points, &mut cells)?;
        }
        polys = vtk_cells::surface_cells(path, &cells)?;
    } else {
        let data = file.dataset("PolyData")?;
        for piece in data.children().filter(|n| n.has_tag_name("Piece")) {
            file.poly_piece(piece, &mut points, &mut polys)?;
        }
    }
    let triangles = vtk_cells::triangles(path, points.len(), &polys)?;
    Ok(SurfaceMesh {
        vertices: points,
        triangles,
    })
}

/// Where `<AppendedData>`'s data is in the file.
#[derive(Clone, Copy, Debug)]
struct Appended {
    /// Offset of the first byte after the `_` marker (appended offsets count from here).
    start: usize,
    /// Offset of `</AppendedData>` (or the end of the file).
    end: usize,
}

fn find(hay: &[u8], needle: &[u8], from: usize) -> Option<usize> {
    hay.get(from..)?
        .windows(needle.len())
        .position(|w| w == needle)
        .map(|i| i + from)
}

/// The XML part of the file as text, and where the appended data is if there is some: a file
/// with `<AppendedData>` is cut after that element's start tag (raw data is not XML) and the
/// XML closed there.
fn split(path: &Path, bytes: &[u8]) -> Result<(String, Option<Appended>), MeshReadError> {
    let Some(tag) = find(bytes, b"<AppendedData", 0) else {
        return Ok((text::bytes_to_text(path, bytes.to_vec())?, None));
    };
    let Some(gt) = find(bytes, b">", tag) else {
        return Err(error_at(
            path,
            Loc::byte(tag),
            "the end `>` of the `<AppendedData ...>` tag",
            "end of file",
        ));
    };
    let mut underscore = gt + 1;
    while bytes.get(underscore).is_some_and(u8::is_ascii_whitespace) {
        underscore += 1;
    }
    if bytes.get(underscore) != Some(&b'_') || bytes[gt - 1] == b'/' {
        return Err(error_at(
            path,
            Loc::byte(underscore),
            "the `_` that starts the appended data",
            match bytes.get(underscore) {
                Some(b) => format!("the byte 0x{b:02x}"),
                None => "end of file".to_owned(),
            },
        ));
    }
    let start = underscore + 1;
    let end = bytes
        .windows(b"</AppendedData>".len())
        .rposition(|w| w == b"</AppendedData>")
        .filter(|&e| e >= start)
        .ok_or_else(|| {
            error_at(
                path,
                Loc::byte(bytes.len()),
                "`</AppendedData>` after the appended data",
                "end of file",
            )
        })?;
    let mut xml = bytes[..=gt].to_vec();
    xml.extend_from_slice(b"</AppendedData></VTKFile>");
    Ok((
        text::bytes_to_text(path, xml)?,
        Some(Appended { start, end }),
    ))
}

fn parse<'t>(path: &Path, text: &'t str) -> Result<Document<'t>, MeshReadError> {
    Document::parse(text).map_err(|e| MeshReadError::Parse {
        path: path.to_owned(),
        line: e.pos().row as usize,
        expected: "well-formed XML".to_owned(),
        found: e.to_string(),
    })
}

/// How binary data is laid out, from the `<VTKFile>` attributes.
#[derive(Clone, Copy, Debug)]
struct Layout {
    big: bool,
    /// `UInt32` or `UInt64`.
    header: Scalar,
    zlib: bool,
}

/// A parsed file: the document, the raw bytes (for appended data) and the binary layout.
struct File<'a, 'd> {
    path: &'a Path,
    bytes: &'a [u8],
    doc: &'d Document<'d>,
    appended: Option<Appended>,
    /// `encoding="base64"` on `<AppendedData>` (else raw).
    appended_base64: bool,
    layout: Layout,
}

/// The decoded bytes of a binary `DataArray` and where it is.
struct Binary<'b> {
    data: Cow<'b, [u8]>,
    loc: Loc,
}

impl<'a, 'd> File<'a, 'd> {
    fn new(
        path: &'a Path,
        bytes: &'a [u8],
        doc: &'d Document<'d>,
        appended: Option<Appended>,
    ) -> Result<Self, MeshReadError> {
        let root = doc.root_element();
        let mut file = File {
            path,
            bytes,
            doc,
            appended,
            appended_base64: false,
            layout: Layout {
                big: false,
                header: Scalar::U32,
                zlib: false,
            },
        };
        if !root.has_tag_name("VTKFile") {
            return Err(MeshReadError::UnsupportedFormat {
                path: path.to_owned(),
                reason: format!(
                    "an XML file whose root element is <{}>, not a VTK XML file (<VTKFile>)",
                    root.tag_name().name()
                ),
            });
        }
        file.layout.big = match root.attribute("byte_order") {
            None | Some("LittleEndian") => false,
            Some("BigEndian") => true,
            Some(other) => {
                return Err(file.attr_error(
                    root,
                    "byte_order",
                    "`LittleEndian` or `BigEndian`",
                    other,
                ))
            }
        };
        file.layout.header = match root.attribute("header_type") {
            None | Some("UInt32") => Scalar::U32,
            Some("UInt64") => Scalar::U64,
            Some(other) => {
                return Err(file.attr_error(root, "header_type", "`UInt32` or `UInt64`", other))
            }
        };
        file.layout.zlib = match root.attribute("compressor") {
            None | Some("") => false,
            Some("vtkZLibDataCompressor") => true,
            Some(other) => {
                return Err(MeshReadError::UnsupportedFormat {
                    path: path.to_owned(),
                    reason: format!(
                        "compressor {} (line {}): only vtkZLibDataCompressor is read; save \
                         the file uncompressed or with zlib",
                        quote(other),
                        file.line(root)
                    ),
                })
            }
        };
        if let Some(data) = root.children().find(|n| n.has_tag_name("AppendedData")) {
            file.appended_base64 = match data.attribute("encoding") {
                Some("raw") => false,
                None | Some("base64") => true,
                Some(other) => {
                    return Err(file.attr_error(data, "encoding", "`raw` or `base64`", other))
                }
            };
        }
        Ok(file)
    }

    fn line(&self, node: Node<'_, '_>) -> usize {
        self.doc.text_pos_at(node.range().start).row as usize
    }

    fn at(&self, node: Node<'_, '_>) -> Loc {
        Loc::Line(self.line(node))
    }

    fn attr_error(
        &self,
        node: Node<'_, '_>,
        name: &str,
        expected: &str,
        found: &str,
    ) -> MeshReadError {
        text::parse_error(
            self.path,
            self.line(node),
            format!("{expected} for `{name}` of <{}>", node.tag_name().name()),
            quote(found),
        )
    }

    /// The dataset element `<kind>` under `<VTKFile type="kind">`.
    fn dataset(&self, kind: &str) -> Result<Node<'d, 'd>, MeshReadError> {
        let root = self.doc.root_element();
        let found = root.attribute("type").unwrap_or("");
        if found != kind {
            let hint = match found {
                "UnstructuredGrid" => " (a volume mesh: read it with read_mesh)",
                "PolyData" => " (a surface: read it with read_surface)",
                _ => "",
            };
            return Err(MeshReadError::UnsupportedFormat {
                path: self.path.to_owned(),
                reason: format!(
                    "VTK XML type {} on line {}, expected {kind}{hint}",
                    quote(found),
                    self.line(root)
                ),
            });
        }
        root.children()
            .find(|n| n.has_tag_name(kind))
            .ok_or_else(|| {
                text::parse_error(
                    self.path,
                    self.line(root),
                    format!("a <{kind}> element"),
                    "none",
                )
            })
    }

    fn count(&self, node: Node<'_, '_>, name: &str) -> Result<usize, MeshReadError> {
        let Some(v) = node.attribute(name) else {
            return Err(text::parse_error(
                self.path,
                self.line(node),
                format!("a `{name}` attribute on <{}>", node.tag_name().name()),
                "none",
            ));
        };
        v.trim()
            .parse::<usize>()
            .map_err(|_| self.attr_error(node, name, "a non-negative integer", v))
    }

    fn child(&self, node: Node<'d, 'd>, name: &str) -> Result<Node<'d, 'd>, MeshReadError> {
        node.children()
            .find(|n| n.has_tag_name(name))
            .ok_or_else(|| {
                text::parse_error(
                    self.path,
                    self.line(node),
                    format!("a <{name}> element in <{}>", node.tag_name().name()),
                    "none",
                )
            })
    }

    /// The `DataArray` named `name` in `parent`.
    fn array(&self, parent: Node<'d, 'd>, name: &str) -> Result<Node<'d, 'd>, MeshReadError> {
        parent
            .children()
            .find(|n| n.has_tag_name("DataArray") && n.attribute("Name") == Some(name))
            .ok_or_else(|| {
                text::parse_error(
                    self.path,
                    self.line(parent),
                    format!(
                        "a <DataArray Name=\"{name}\"> in <{}>",
                        parent.tag_name().name()
                    ),
                    "none",
                )
            })
    }

    /// `<Points>`: `n` points of three components.
    fn points(
        &self,
        piece: Node<'d, 'd>,
        n: usize,
        out: &mut Vec<[f64; 3]>,
    ) -> Result<(), MeshReadError> {
        let da = self
            .child(piece, "Points")?
            .children()
            .find(|c| c.has_tag_name("DataArray"))
            .ok_or_else(|| {
                text::parse_error(
                    self.path,
                    self.line(piece),
                    "a <DataArray> in <Points>",
                    "none",
                )
            })?;
        let comps = da.attribute("NumberOfComponents").unwrap_or("1");
        if comps.trim() != "3" {
            return Err(self.attr_error(da, "NumberOfComponents", "3", comps));
        }
        let what = format!("NumberOfPoints=\"{n}\" × 3 coordinates");
        let values = self.reals(da, n.saturating_mul(3), &what)?;
        for (i, p) in values.chunks_exact(3).enumerate() {
            if let Some(k) = p.iter().position(|v| !v.is_finite()) {
                return Err(error_at(
                    self.path,
                    self.at(da),
                    format!("a finite {} coordinate of point {i}", ["x", "y", "z"][k]),
                    format!("{}", p[k]),
                ));
            }
            out.push([p[0], p[1], p[2]]);
        }
        Ok(())
    }

    /// `connectivity` and `offsets` (end offsets, one per cell) in `parent`, appended to
    /// `cells` with point ids shifted by `base`.
    fn cell_arrays(
        &self,
        parent: Node<'d, 'd>,
        n: usize,
        count_name: &str,
        base: usize,
        cells: &mut Cells,
    ) -> Result<(), MeshReadError> {
        let off_da = self.array(parent, "offsets")?;
        let offsets = self.ints(off_da, n, &format!("{count_name}=\"{n}\""))?;
        let mut ends = Vec::with_capacity(offsets.len());
        for (i, &o) in offsets.iter().enumerate() {
            let prev = ends.last().copied().unwrap_or(0);
            match usize::try_from(o).ok().filter(|&o| o >= prev) {
                Some(o) => ends.push(o),
                None => {
                    return Err(error_at(
                        self.path,
                        self.at(off_da),
                        format!(
                            "offset {i} to be non-negative and at least the one before ({prev})"
                        ),
                        format!("`{o}`"),
                    ))
                }
            }
        }
        let conn_da = self.array(parent, "connectivity")?;
        let total = ends.last().copied().unwrap_or(0);
        let conn = self.ints(conn_da, total, &format!("the last offset, {total}"))?;
        let shift = i64::try_from(base).unwrap_or(i64::MAX);
        let first = cells.conn.len();
        if cells.offsets.is_empty() {
            cells.offsets.push(0);
        }
        cells.conn.extend(
            conn.iter()
                .map(|&id| if id < 0 { id } else { id.saturating_add(shift) }),
        );
        cells.offsets.extend(ends.iter().map(|&e| first + e));
        let loc = self.at(conn_da);
        cells.locs.extend(std::iter::repeat_n(loc, n));
        Ok(())
    }

    fn grid_piece(
        &self,
        piece: Node<'d, 'd>,
        points: &mut Vec<[f64; 3]>,
        cells: &mut Cells,
    ) -> Result<(), MeshReadError> {
        let np = self.count(piece, "NumberOfPoints")?;
        let nc = self.count(piece, "NumberOfCells")?;
        let base = points.len();
        self.points(piece, np, points)?;
        let cells_node = self.child(piece, "Cells")?;
        self.cell_arrays(cells_node, nc, "NumberOfCells", base, cells)?;
        let what = format!("NumberOfCells=\"{nc}\"");
        let types = self.ints(self.array(cells_node, "types")?, nc, &what)?;
        cells.types.extend(types);
        Ok(())
    }

    fn poly_piece(
        &self,
        piece: Node<'d, 'd>,
        points: &mut Vec<[f64; 3]>,
        polys: &mut Cells,
    ) -> Result<(), MeshReadError> {
        let np = self.count(piece, "NumberOfPoints")?;
        let strips = match piece.attribute("NumberOfStrips") {
            Some(_) => self.count(piece, "NumberOfStrips")?,
            None => 0,
        };
        if strips > 0 {
            return Err(text::parse_error(
                self.path,
                self.line(piece),
                "no triangle strips (they are not read; save the surface as triangles)",
                format!("NumberOfStrips=\"{strips}\""),
            ));
        }
        let base = points.len();
        self.points(piece, np, points)?;
        let n = match piece.attribute("NumberOfPolys") {
            Some(_) => self.count(piece, "NumberOfPolys")?,
            None => 0,
        };
        if n > 0 {
            let node = self.child(piece, "Polys")?;
            self.cell_arrays(node, n, "NumberOfPolys", base, polys)?;
        }
        Ok(())
    }

    fn scalar(&self, da: Node<'_, '_>) -> Result<Scalar, MeshReadError> {
        let t = da.attribute("type").unwrap_or("");
        Scalar::from_xml(t).ok_or_else(|| {
            self.attr_error(
                da,
                "type",
                "a numeric type (Int32, Int64, Float32, Float64, ...)",
                t,
            )
        })
    }

    /// `count` real values of a `DataArray`; `what` says where the count comes from.
    fn reals(&self, da: Node<'_, '_>, count: usize, what: &str) -> Result<Vec<f64>, MeshReadError> {
        let scalar = self.scalar(da)?;
        if self.format(da)? == "ascii" {
            return self.ascii(da, count, what, |t| t.parse::<f64>().ok());
        }
        let bin = self.binary(da, scalar, count, what)?;
        Ok(bin
            .data
            .chunks_exact(scalar.size())
            .map(|v| scalar.real(v, self.layout.big))
            .collect())
    }

    /// `count` integer values of a `DataArray` (ids, offsets, types).
    fn ints(&self, da: Node<'_, '_>, count: usize, what: &str) -> Result<Vec<i64>, MeshReadError> {
        let scalar = self.scalar(da)?;
        if !scalar.is_integer() {
            return Err(self.attr_error(
                da,
                "type",
                "an integer type (Int32, Int64, UInt8, ...)",
                da.attribute("type").unwrap_or(""),
            ));
        }
        if self.format(da)? == "ascii" {
            return self.ascii(da, count, what, |t| t.parse::<i64>().ok());
        }
        let bin = self.binary(da, scalar, count, what)?;
        bin.data
            .chunks_exact(scalar.size())
            .enumerate()
            .map(|(i, v)| {
                scalar.int(v, self.layout.big).ok_or_else(|| {
                    error_at(
                        self.path,
                        bin.loc,
                        format!("an integer below 2^63 for value {i} of {}", self.name(da)),
                        "a larger one",
                    )
                })
            })
            .collect()
    }

    fn name(&self, da: Node<'_, '_>) -> String {
        match da.attribute("Name") {
            Some(n) => format!("DataArray `{n}`"),
            None => "the DataArray".to_owned(),
        }
    }

    fn format(&self, da: Node<'_, '_>) -> Result<&'static str, MeshReadError> {
        match da.attribute("format").unwrap_or("ascii") {
            "ascii" => Ok("ascii"),
            "binary" => Ok("binary"),
            "appended" => Ok("appended"),
            other => Err(self.attr_error(da, "format", "`ascii`, `binary` or `appended`", other)),
        }
    }

    /// The `count` whitespace-separated numbers of an ASCII `DataArray`, each error naming its
    /// line.
    fn ascii<T>(
        &self,
        da: Node<'_, '_>,
        count: usize,
        what: &str,
        parse: impl Fn(&str) -> Option<T>,
    ) -> Result<Vec<T>, MeshReadError> {
        let (text, start) = match da.first_child().filter(|c| c.is_text()) {
            Some(t) => (t.text().unwrap_or(""), t.range().start),
            None => ("", da.range().end),
        };
        // A number takes a character and a separator: refuse a count the text cannot hold
        // before allocating for it.
        if count > text.len().div_ceil(2) {
            return Err(text::parse_error(
                self.path,
                self.line(da),
                format!("{count} values in {} ({what})", self.name(da)),
                format!(
                    "{} characters of text, room for at most {}",
                    text.len(),
                    text.len().div_ceil(2)
                ),
            ));
        }
        let first_line = self.doc.text_pos_at(start).row as usize;
        let mut out = Vec::with_capacity(count);
        for (k, line) in text.split('\n').enumerate() {
            for token in line.split_whitespace() {
                let i = out.len();
                if i == count {
                    return Err(text::parse_error(
                        self.path,
                        first_line + k,
                        format!("{count} values in {} ({what})", self.name(da)),
                        format!("more: {}", quote(token)),
                    ));
                }
                let v = parse(token).ok_or_else(|| {
                    text::parse_error(
                        self.path,
                        first_line + k,
                        format!("a number for value {i} of {}", self.name(da)),
                        quote(token),
                    )
                })?;
                out.push(v);
            }
        }
        if out.len() != count {
            return Err(text::parse_error(
                self.path,
                self.line(da),
                format!("{count} values in {} ({what})", self.name(da)),
                format!("{}", out.len()),
            ));
        }
        Ok(out)
    }
}
