//! Legacy VTK (`.vtk`) files: `UNSTRUCTURED_GRID` volume meshes and `POLYDATA` surfaces,
//! ASCII (read here) and binary (read by [`super::vtk_binary`]); writing ASCII. An XML file
//! handed to [`read_vtk`] goes to [`super::vtk_xml`].

use std::io::Write;
use std::path::Path;

use super::text::{self, quote};
use super::vtk_cells::{self, Cells, Loc, VTK_TETRA};
use super::{vtk_binary, vtk_xml, MeshReadError, SurfaceMesh, TetMesh};

/// Section keywords: meeting one where a number is due means the count was too large.
const KEYWORDS: [&str; 14] = [
    "DATASET",
    "POINTS",
    "CELLS",
    "OFFSETS",
    "CONNECTIVITY",
    "CELL_TYPES",
    "POINT_DATA",
    "CELL_DATA",
    "FIELD",
    "METADATA",
    "VERTICES",
    "LINES",
    "POLYGONS",
    "TRIANGLE_STRIPS",
];

/// Reads a legacy VTK `UNSTRUCTURED_GRID`, ASCII or binary (cells of type 10 only), and the
/// fixed nodes from a sibling `<stem>.bnd` (0-based point ids) if there is one. A VTK XML file
/// (first line `<?xml` or `<VTKFile`) is read as [`super::read_vtk_xml`] does. See the
/// [module docs](super).
///
/// # Errors
/// Any [`MeshReadError`] naming the `.vtk` or `.bnd` file at fault; datasets other than
/// `UNSTRUCTURED_GRID` are [`MeshReadError::UnsupportedFormat`].
pub fn read_vtk(path: &Path) -> Result<TetMesh, MeshReadError> {
    let bytes = std::fs::read(path).map_err(|source| MeshReadError::Io {
        path: path.to_owned(),
        source,
    })?;
    if vtk_xml::is_xml(&bytes) {
        return vtk_xml::read_volume(path, &bytes);
    }
    let legacy = read_legacy(path, bytes)?;
    if legacy.dataset != Dataset::UnstructuredGrid {
        return Err(MeshReadError::UnsupportedFormat {
            path: path.to_owned(),
            reason: "VTK dataset POLYDATA is a surface, not a volume mesh: it holds no \
                     tetrahedra (read it with read_surface)"
                .to_owned(),
        });
    }
    let points = legacy.points.len();
    let tets = vtk_cells::tets(path, points, &legacy.cells)?;
    let lines = vtk_cells::line_numbers(&legacy.cells, &tets.labels);
    vtk_cells::tet_mesh(path, legacy.points, tets, lines)
}

/// Reads a legacy VTK `POLYDATA` (ASCII or binary) or a VTK XML `PolyData` as a triangle
/// surface: `bytes` are the file's. An unstructured grid of triangles and quadrilaterals (as
/// meshio writes surfaces) is read too.
pub(super) fn read_vtk_surface(path: &Path, bytes: Vec<u8>) -> Result<SurfaceMesh, MeshReadError> {
    if vtk_xml::is_xml(&bytes) {
        return vtk_xml::read_surface(path, &bytes);
    }
    let mut legacy = read_legacy(path, bytes)?;
    if legacy.dataset == Dataset::UnstructuredGrid {
        legacy.polys = vtk_cells::surface_cells(path, &legacy.cells)?;
    }
    let points = legacy.points.len();
    let triangles = vtk_cells::triangles(path, points, &legacy.polys)?;
    Ok(SurfaceMesh {
        vertices: legacy.points,
        triangles,
    })
}

/// The dataset types read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Dataset {
    UnstructuredGrid,
    PolyData,
}

/// A legacy VTK dataset as read, before its cells are turned into tetrahedra or triangles.
pub(super) struct Legacy {
    pub dataset: Dataset,
    pub points: Vec<[f64; 3]>,
    /// `CELLS` and `CELL_TYPES` (an unstructured grid).
    pub cells: Cells,
    /// `POLYGONS` (a polydata).
    pub polys: Cells,
}

/// Reads the header and hands the body to the ASCII or the binary reader.
fn read_legacy(path: &Path, bytes: Vec<u8>) -> Result<Legacy, MeshReadError> {
    // The header is ASCII even in binary files: look at it before the UTF-8 check.
    if header_line(&bytes, 2).eq_ignore_ascii_case("BINARY")
        && header_line(&bytes, 0)
            .to_ascii_lowercase()
            .starts_with("# vtk datafile")
    {
        return vtk_binary::read(path, &bytes);
    }
    let text = text::bytes_to_text(path, bytes)?;
    if text.trim().is_empty() {
        return Err(text::eof_error(path, 1, "`# vtk DataFile Version ...`"));
    }
    let mut header = text.lines();
    let first = header.next().unwrap_or("").trim();
    if !first.to_ascii_lowercase().starts_with("# vtk datafile") {
        return Err(MeshReadError::UnsupportedFormat {
            path: path.to_owned(),
            reason: format!(
                "not a legacy VTK file: the first line is {} instead of `# vtk DataFile Version ...`",
                quote(first)
            ),
        });
    }
    let _title = header.next();
    match header.next().map(str::trim) {
        Some(t) if t.eq_ignore_ascii_case("ASCII") => {}
        Some(t) => return Err(text::parse_error(path, 3, "`ASCII` or `BINARY`", quote(t))),
        None => return Err(text::eof_error(path, 3, "`ASCII` or `BINARY`")),
    }

    let mut r = Reader::new(path, &text);
    let dataset = r.dataset()?;
    let grid = r.grid(dataset)?;
    Ok(Legacy {
        dataset,
        points: grid.points,
        cells: grid.cells,
        polys: grid.polys,
    })
}

/// Writes `mesh` as a legacy VTK 3.0 ASCII unstructured grid of tetrahedra (type 10), points
/// numbered from 0. Fixed nodes are not written (see [`super::write_bnd`]).
///
/// # Errors
/// Any I/O error from creating or writing the file.
pub fn write_vtk(mesh: &TetMesh, path: &Path) -> std::io::Result<()> {
    let mut out = std::io::BufWriter::new(std::fs::File::create(path)?);
    writeln!(out, "# vtk DataFile Version 3.0")?;
    // The title is one line of at most 255 characters.
    let title: String = format!("lop-sim tetrahedral mesh from {}", mesh.source.display())
        .chars()
        .filter(|c| *c != '\n' && *c != '\r')
        .take(255)
        .collect();
    writeln!(out, "{title}")?;
    writeln!(out, "ASCII")?;
    writeln!(out, "DATASET UNSTRUCTURED_GRID")?;
    writeln!(out, "POINTS {} double", mesh.nodes.len())?;
    for [x, y, z] in &mesh.nodes {
        writeln!(out, "{x:?} {y:?} {z:?}")?;
    }
    writeln!(out, "CELLS {} {}", mesh.tets.len(), 5 * mesh.tets.len())?;
    for [a, b, c, d] in &mesh.tets {
        writeln!(out, "4 {a} {b} {c} {d}")?;
    }
    writeln!(out, "CELL_TYPES {}", mesh.tets.len())?;
    for _ in &mesh.tets {
        writeln!(out, "{VTK_TETRA}")?;
    }
    out.flush()
}

/// Line `i` (0-based) of raw bytes, trimmed, lossily decoded.
pub(super) fn header_line(bytes: &[u8], i: usize) -> String {
    bytes
        .split(|&b| b == b'\n')
        .nth(i)
        .map(|l| String::from_utf8_lossy(l).trim().to_owned())
        .unwrap_or_default()
}

/// A legacy ASCII dataset as read.
#[derive(Default)]
struct Grid {
    points: Vec<[f64; 3]>,
    cells: Cells,
    polys: Cells,
}

/// A declared count being read, for [`MeshReadError::CountMismatch`].
#[derive(Clone, Copy)]
struct Counted {
    line: usize,
    what: &'static str,
    declared: usize,
    /// Tokens per record (3 for points).
    per: usize,
}

/// Whitespace-separated tokens with their line numbers (data starts on line 4).
struct Reader<'a> {
    path: &'a Path,
    lines: std::iter::Skip<std::iter::Enumerate<std::str::Lines<'a>>>,
    line_no: usize,
    current: std::str::SplitWhitespace<'a>,
    peeked: Option<(usize, &'a str)>,
    /// Bytes of the whole text: no header may reserve more records than it can hold.
    bytes: usize,
}

impl<'a> Reader<'a> {
    fn new(path: &'a Path, text: &'a str) -> Self {
        Self {
            path,
            lines: text.lines().enumerate().skip(3),
            line_no: 3,
            current: "".split_whitespace(),
            peeked: None,
            bytes: text.len(),
        }
    }

    /// Room for `declared` records of `per` numbers each, but never more than the text can
    /// hold (a number and its separator take at least two bytes): a header claiming 10¹²
    /// points in a small file reserves what the file could hold.
    fn capacity(&self, declared: usize, per: usize) -> usize {
        text::capacity_within(declared, self.bytes, 2 * per)
    }

    fn next(&mut self) -> Option<(usize, &'a str)> {
        if let Some(t) = self.peeked.take() {
            return Some(t);
        }
        loop {
            if let Some(t) = self.current.next() {
                return Some((self.line_no, t));
            }
            let (i, line) = self.lines.next()?;
            self.line_no = i + 1;
            self.current = line.split_whitespace();
        }
    }

    fn peek(&mut self) -> Option<(usize, &'a str)> {
        if self.peeked.is_none() {
            self.peeked = self.next();
        }
        self.peeked
    }

    /// Skips a `METADATA` block: everything up to the next blank line.
    fn skip_metadata(&mut self) {
        self.peeked = None;
        self.current = "".split_whitespace();
        for (i, line) in self.lines.by_ref() {
            self.line_no = i + 1;
            if line.trim().is_empty() {
                break;
            }
        }
    }

    fn eof(&self, expected: impl Into<String>) -> MeshReadError {
        text::eof_error(self.path, self.line_no, expected)
    }

    /// The next token, which must exist.
    fn token(&mut self, expected: &str) -> Result<(usize, &'a str), MeshReadError> {
        self.next().ok_or_else(|| self.eof(expected))
    }

    fn count(&mut self, what: &str) -> Result<(usize, usize), MeshReadError> {
        let (line, t) = self.token(what)?;
        Ok((line, text::parse_count(self.path, line, t, what)?))
    }

    /// The next value of a counted list: a section keyword or the end of the file instead
    /// means the list is shorter than declared.
    fn value(&mut self, counted: Counted, read: usize) -> Result<(usize, &'a str), MeshReadError> {
        match self.next() {
            Some((line, t)) if !is_keyword(t) => Ok((line, t)),
            _ => Err(MeshReadError::CountMismatch {
                path: self.path.to_owned(),
                line: counted.line,
                what: counted.what,
                declared: counted.declared,
                found: read / counted.per.max(1),
            }),
        }
    }

    fn int_value(
        &mut self,
        counted: Counted,
        read: usize,
        what: std::fmt::Arguments<'_>,
    ) -> Result<(usize, i64), MeshReadError> {
        let (line, t) = self.value(counted, read)?;
        Ok((line, text::parse_i64(self.path, line, t, what)?))
    }

    /// `DATASET UNSTRUCTURED_GRID` or `DATASET POLYDATA`.
    fn dataset(&mut self) -> Result<Dataset, MeshReadError> {
        let (line, t) = self.token("`DATASET UNSTRUCTURED_GRID`")?;
        if !t.eq_ignore_ascii_case("DATASET") {
            return Err(text::parse_error(
                self.path,
                line,
                "`DATASET UNSTRUCTURED_GRID`",
                quote(t),
            ));
        }
        let (_, kind) = self.token("`UNSTRUCTURED_GRID`")?;
        dataset(self.path, kind)
    }

    fn grid(&mut self, dataset: Dataset) -> Result<Grid, MeshReadError> {
        let mut grid = Grid::default();
        let mut cells: Option<(usize, usize)> = None; // (line, count)
        let mut types_seen = false;
        let mut last: Option<Counted> = None;
        while let Some((line, t)) = self.next() {
            let keyword = t.to_ascii_uppercase();
            match keyword.as_str() {
                "POINTS" => {
                    let (_, n) = self.count("the number of points")?;
                    self.token("the point data type")?;
                    let counted = Counted {
                        line,
                        what: "points",
                        declared: n,
                        per: 3,
                    };
                    grid.points = Vec::with_capacity(self.capacity(n, 3));
                    for i in 0..n {
                        let mut p = [0.0; 3];
                        for (k, axis) in ["x", "y", "z"].iter().enumerate() {
                            let (l, t) = self.value(counted, 3 * i + k)?;
                            let what = format_args!("the {axis} coordinate of point {i}");
                            let v = text::parse_f64(self.path, l, t, what)?;
                            if !v.is_finite() {
                                return Err(MeshReadError::NonFiniteCoordinate {
                                    path: self.path.to_owned(),
                                    line: Some(l),
                                    node: i64::try_from(i).unwrap_or(i64::MAX),
                                    value: v,
                                });
                            }
                            p[k] = v;
                        }
                        grid.points.push(p);
                    }
                    last = Some(counted);
                }
                "CELLS" | "POLYGONS" | "VERTICES" | "LINES" | "TRIANGLE_STRIPS" => {
                    let (_, n) = self.count("the number of cells")?;
                    let (_, size) = self.count("the size of the cell list")?;
                    let is_v51 = self
                        .peek()
                        .is_some_and(|(_, t)| t.eq_ignore_ascii_case("OFFSETS"));
                    let mut list = Cells::default();
                    last = Some(if is_v51 {
                        self.cells_v51(line, n, size, &mut list)?
                    } else {
                        self.cells_legacy(line, n, size, &mut list)?
                    });
                    match keyword.as_str() {
                        "CELLS" => {
                            cells = Some((line, list.len()));
                            grid.cells = list;
                        }
                        "POLYGONS" => grid.polys = list,
                        "TRIANGLE_STRIPS" if list.len() > 0 && dataset == Dataset::PolyData => {
                            return Err(text::parse_error(
                                self.path,
                                line,
                                "POLYGONS (triangle strips are not read; save the surface \
                                 as triangles)",
                                format!("{} triangle strips", list.len()),
                            ))
                        }
                        _ => {} // points and lines are no part of a surface
                    }
                }
                "CELL_TYPES" => {
                    let (_, n) = self.count("the number of cell types")?;
                    let counted = Counted {
                        line,
                        what: "cell types",
                        declared: n,
                        per: 1,
                    };
                    grid.cells.types = Vec::with_capacity(self.capacity(n, 1));
                    for i in 0..n {
                        let (_, kind) =
                            self.int_value(counted, i, format_args!("the type of cell {i}"))?;
                        grid.cells.types.push(kind);
                    }
                    let cell_count = cells.map_or(0, |(_, c)| c);
                    if n != cell_count {
                        return Err(MeshReadError::CountMismatch {
                            path: self.path.to_owned(),
                            line,
                            what: "cell types",
                            declared: n,
                            found: cell_count,
                        });
                    }
                    types_seen = true;
                    last = Some(counted);
                }
                "METADATA" => self.skip_metadata(),
                "FIELD" => {
                    self.skip_field()?;
                    last = None;
                }
                "POINT_DATA" | "CELL_DATA" => break,
                _ if t.parse::<f64>().is_ok() && last.is_some() => {
                    let counted = last.unwrap_or(Counted {
                        line,
                        what: "values",
                        declared: 0,
                        per: 1,
                    });
                    let mut extra = 1usize;
                    while self.peek().is_some_and(|(_, t)| !is_keyword(t)) {
                        self.next();
                        extra += 1;
                    }
                    return Err(MeshReadError::CountMismatch {
                        path: self.path.to_owned(),
                        line: counted.line,
                        what: counted.what,
                        declared: counted.declared,
                        found: counted
                            .declared
                            .saturating_add(extra.div_ceil(counted.per.max(1))),
                    });
                }
                _ => return Err(text::parse_error(
                    self.path,
                    line,
                    "a section keyword (POINTS, CELLS, CELL_TYPES, POLYGONS, POINT_DATA, CELL_DATA, FIELD)",
                    quote(t),
                )),
            }
        }
        if let Some((line, _)) = cells {
            if !types_seen {
                return Err(text::eof_error(
                    self.path,
                    self.line_no.max(line),
                    "a `CELL_TYPES` section after `CELLS`",
                ));
            }
        }
        Ok(grid)
    }

    /// `CELLS <n> <size>` followed by `n` lists `<k> <id 1> ... <id k>`.
    fn cells_legacy(
        &mut self,
        line: usize,
        n: usize,
        size: usize,
        grid: &mut Cells,
    ) -> Result<Counted, MeshReadError> {
        let counted = Counted {
            line,
            what: "cells",
            declared: n,
            per: 1,
        };
        let sized = Counted {
            line,
            what: "numbers in the CELLS list",
            declared: size,
            per: 1,
        };
        grid.offsets = Vec::with_capacity(self.capacity(n, 1) + 1);
        grid.offsets.push(0);
        let mut used = 0usize;
        for i in 0..n {
            let (cell_line, k) = self.value(counted, i)?;
            let k = text::parse_count(
                self.path,
                cell_line,
                k,
                format_args!("the number of points of cell {i}"),
            )?;
            used = used.saturating_add(k).saturating_add(1);
            if used > size {
                return Err(MeshReadError::CountMismatch {
                    path: self.path.to_owned(),
                    line,
                    what: sized.what,
                    declared: size,
                    found: used,
                });
            }
            for j in 0..k {
                let (_, id) = self.int_value(
                    sized,
                    used - k - 1 + j,
                    format_args!("point {j} of cell {i}"),
                )?;
                grid.conn.push(id);
            }
            grid.offsets.push(grid.conn.len());
            grid.locs.push(Loc::Line(cell_line));
        }
        if used != size {
            return Err(MeshReadError::CountMismatch {
                path: self.path.to_owned(),
                line,
                what: sized.what,
                declared: size,
                found: used,
            });
        }
        Ok(counted)
    }

    /// VTK 5.1: `CELLS <#offsets> <#connectivity>`, `OFFSETS <type>` with the offsets,
    /// `CONNECTIVITY <type>` with the point ids.
    fn cells_v51(
        &mut self,
        line: usize,
        n_offsets: usize,
        n_conn: usize,
        grid: &mut Cells,
    ) -> Result<Counted, MeshReadError> {
        self.next(); // OFFSETS
        self.token("the offsets data type")?;
        let counted = Counted {
            line,
            what: "offsets",
            declared: n_offsets,
            per: 1,
        };
        let mut offsets = Vec::with_capacity(self.capacity(n_offsets, 1));
        for i in 0..n_offsets {
            let (l, v) = self.int_value(counted, i, format_args!("offset {i}"))?;
            let prev = offsets.last().copied().unwrap_or(0);
            let ok = usize::try_from(v)
                .ok()
                .filter(|&v| v >= prev && (i > 0 || v == 0) && v <= n_conn);
            let Some(v) = ok else {
                return Err(text::parse_error(
                    self.path,
                    l,
                    format!("offset {i} to be 0 for the first cell, non-decreasing and at most {n_conn}"),
                    quote(&v.to_string()),
                ));
            };
            offsets.push(v);
        }
        match self.token("`CONNECTIVITY`")? {
            (_, t) if t.eq_ignore_ascii_case("CONNECTIVITY") => {}
            (l, t) => {
                if t.parse::<f64>().is_ok() {
                    // More offsets than declared.
                    return Err(MeshReadError::CountMismatch {
                        path: self.path.to_owned(),
                        line,
                        what: "offsets",
                        declared: n_offsets,
                        found: n_offsets + 1,
                    });
                }
                return Err(text::parse_error(self.path, l, "`CONNECTIVITY`", quote(t)));
            }
        }
        self.token("the connectivity data type")?;
        let counted_conn = Counted {
            line,
            what: "connectivity entries",
            declared: n_conn,
            per: 1,
        };
        let mut conn_lines = Vec::with_capacity(self.capacity(n_conn, 1));
        for i in 0..n_conn {
            let (l, id) =
                self.int_value(counted_conn, i, format_args!("connectivity entry {i}"))?;
            grid.conn.push(id);
            conn_lines.push(l);
        }
        if offsets.last().is_some_and(|&last| last != n_conn) {
            return Err(text::parse_error(
                self.path,
                line,
                format!("the last offset to equal the connectivity size {n_conn}"),
                quote(&offsets.last().copied().unwrap_or(0).to_string()),
            ));
        }
        grid.locs = offsets
            .iter()
            .take(offsets.len().saturating_sub(1))
            .map(|&o| Loc::Line(conn_lines.get(o).copied().unwrap_or(line)))
            .collect();
        grid.offsets = offsets;
        if grid.offsets.is_empty() {
            grid.offsets.push(0);
        }
        Ok(counted_conn)
    }

    /// `FIELD <name> <#arrays>`, each array `<name> <#components> <#tuples> <type>` followed by
    /// its values (and possibly a METADATA block): skipped.
    fn skip_field(&mut self) -> Result<(), MeshReadError> {
        self.token("the field name")?;
        let (line, arrays) = self.count("the number of field arrays")?;
        for a in 0..arrays {
            while self
                .peek()
                .is_some_and(|(_, t)| t.eq_ignore_ascii_case("METADATA"))
            {
                self.skip_metadata();
            }
            self.token("the field array name")?;
            let (_, comps) = self.count("the number of components")?;
            let (_, tuples) = self.count("the number of tuples")?;
            self.token("the field array data type")?;
            let values = comps.saturating_mul(tuples);
            let counted = Counted {
                line,
                what: "field array values",
                declared: values,
                per: 1,
            };
            for i in 0..values {
                self.value(counted, i)?;
            }
            let _ = a;
        }
        while self
            .peek()
            .is_some_and(|(_, t)| t.eq_ignore_ascii_case("METADATA"))
        {
            self.skip_metadata();
        }
        Ok(())
    }
}

/// The dataset a `DATASET <kind>` line names, if it is one that is read.
pub(super) fn dataset(path: &Path, kind: &str) -> Result<Dataset, MeshReadError> {
    if kind.eq_ignore_ascii_case("UNSTRUCTURED_GRID") {
        Ok(Dataset::UnstructuredGrid)
    } else if kind.eq_ignore_ascii_case("POLYDATA") {
        Ok(Dataset::PolyData)
    } else {
        Err(MeshReadError::UnsupportedFormat {
            path: path.to_owned(),
            reason: format!(
                "VTK dataset {}: only UNSTRUCTURED_GRID (tetrahedra) and POLYDATA (surfaces) \
                 are read",
                quote(kind)
            ),
        })
    }
}

fn is_keyword(token: &str) -> bool {
    KEYWORDS.iter().any(|k| token.eq_ignore_ascii_case(k))
}
