//! Triangle surfaces from files: STL (ASCII and binary), Wavefront OBJ, PLY (ASCII and
//! binary, either byte order) and VTK (legacy and XML, read by the VTK modules). See
//! [`read_surface`].

use std::collections::hash_map::{Entry, HashMap};
use std::path::Path;

use super::text::{self, DataLines, Line};
use super::vtk_cells::Scalar;
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

// ---------------------------------------------------------------------------------------------
// STL

/// The triangle count of a binary STL (bytes 80..84, little endian), if the header is there.
fn stl_count(bytes: &[u8]) -> Option<u32> {
    let count: [u8; 4] = bytes.get(80..84)?.try_into().ok()?;
    Some(u32::from_le_bytes(count))
}

/// The size of a binary STL with `n` triangles.
fn stl_size(n: u32) -> u64 {
    84 + 50 * u64::from(n)
}

fn binary_error(
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

/// Merges vertices with equal coordinates.
#[derive(Default)]
struct Welder {
    index: HashMap<[u64; 3], u32>,
    vertices: Vec<[f64; 3]>,
}

impl Welder {
    fn add(&mut self, path: &Path, p: [f64; 3]) -> Result<u32, MeshReadError> {
        // Adding 0.0 turns -0.0 into 0.0, so the two weld.
        let key = p.map(|c| (c + 0.0).to_bits());
        match self.index.entry(key) {
            Entry::Occupied(e) => Ok(*e.get()),
            Entry::Vacant(e) => {
                let i = u32::try_from(self.vertices.len()).map_err(|_| {
                    MeshReadError::TooManyNodes {
                        path: path.to_owned(),
                        count: self.vertices.len(),
                    }
                })?;
                self.vertices.push(p);
                Ok(*e.insert(i))
            }
        }
    }
}

fn stl_binary(path: &Path, bytes: &[u8]) -> Result<SurfaceMesh, MeshReadError> {
    let Some(n) = stl_count(bytes) else {
        return Err(binary_error(
            path,
            bytes.len(),
            "a binary STL header: 80 bytes of text, then the triangle count (4 bytes)",
            format!("end of file after {} bytes", bytes.len()),
        ));
    };
    let len = bytes.len() as u64;
    if stl_size(n) != len {
        let fits = len.saturating_sub(84) / 50;
        return Err(binary_error(
            path,
            80,
            format!(
                "a triangle count that fits the file's {len} bytes (84 + 50 per triangle: \
                 {fits} triangles{})",
                if len.saturating_sub(84).is_multiple_of(50) {
                    ""
                } else {
                    " and some bytes left over"
                }
            ),
            format!("{n}, which needs {} bytes", stl_size(n)),
        ));
    }
    let mut welder = Welder::default();
    let mut triangles = Vec::with_capacity(n as usize);
    for t in 0..n as usize {
        let start = 84 + 50 * t;
        let mut tri = [0u32; 3];
        for (k, corner) in tri.iter_mut().enumerate() {
            let mut p = [0.0; 3];
            for (axis, c) in p.iter_mut().enumerate() {
                // Skip the 12-byte normal; then three 12-byte vertices.
                let at = start + 12 + 12 * k + 4 * axis;
                let raw: [u8; 4] = bytes[at..at + 4].try_into().expect("4 bytes");
                let value = f32::from_le_bytes(raw);
                if !value.is_finite() {
                    return Err(binary_error(
                        path,
                        at,
                        format!(
                            "a finite {} coordinate of vertex {} of triangle {}",
                            ["x", "y", "z"][axis],
                            k + 1,
                            t + 1
                        ),
                        format!("{value}"),
                    ));
                }
                *c = f64::from(value);
            }
            *corner = welder.add(path, p)?;
        }
        triangles.push(tri);
    }
    Ok(SurfaceMesh {
        vertices: welder.vertices,
        triangles,
    })
}

fn stl_ascii(path: &Path, bytes: Vec<u8>) -> Result<SurfaceMesh, MeshReadError> {
    let text = text::bytes_to_text(path, bytes)?;
    let mut lines = DataLines::new(&text, false);
    let mut welder = Welder::default();
    let mut triangles = Vec::new();
    let mut in_solid = false;
    while let Some(line) = lines.next() {
        let word = line.text.split_whitespace().next().unwrap_or("");
        let word = word.to_ascii_lowercase();
        match (word.as_str(), in_solid) {
            ("solid", false) => in_solid = true,
            ("endsolid", true) => in_solid = false,
            ("facet", true) => {
                let tri = stl_facet(path, &mut lines, &line, triangles.len() + 1, &mut welder)?;
                triangles.push(tri);
            }
            _ => {
                return Err(text::parse_error(
                    path,
                    line.no,
                    if in_solid {
                        "`facet normal <x> <y> <z>` or `endsolid`"
                    } else {
                        "`solid` (or the end of the file)"
                    },
                    text::quote(line.text),
                ))
            }
        }
    }
    if in_solid {
        return Err(text::eof_error(path, lines.eof_line(), "`endsolid`"));
    }
    Ok(SurfaceMesh {
        vertices: welder.vertices,
        triangles,
    })
}

/// One `facet` ... `endfacet` block, from its `facet normal` line.
fn stl_facet(
    path: &Path,
    lines: &mut DataLines<'_>,
    facet: &Line<'_>,
    number: usize,
    welder: &mut Welder,
) -> Result<[u32; 3], MeshReadError> {
    let fields = facet.fields(false);
    if fields.len() != 5 || !fields[1].eq_ignore_ascii_case("normal") {
        return Err(text::parse_error(
            path,
            facet.no,
            "`facet normal <x> <y> <z>`",
            text::quote(facet.text),
        ));
    }
    for (axis, token) in ["x", "y", "z"].iter().zip(&fields[2..]) {
        let what = format_args!("the normal's {axis} of facet {number}");
        text::parse_f64(path, facet.no, token, what)?;
    }
    let mut next = |expected: &str| match lines.next() {
        Some(line) => Ok(line),
        None => Err(text::eof_error(path, lines.eof_line(), expected)),
    };
    let keyword = |line: &Line<'_>, words: &[&str], expected: &str| {
        let f = line.fields(false);
        if f.len() == words.len() && f.iter().zip(words).all(|(a, b)| a.eq_ignore_ascii_case(b)) {
            Ok(())
        } else {
            Err(text::parse_error(
                path,
                line.no,
                expected,
                text::quote(line.text),
            ))
        }
    };
    let line = next("`outer loop`")?;
    keyword(&line, &["outer", "loop"], "`outer loop`")?;
    let mut tri = [0u32; 3];
    for (k, corner) in tri.iter_mut().enumerate() {
        const VERTEX: &str = "`vertex <x> <y> <z>`";
        let line = next(VERTEX)?;
        let f = line.fields(false);
        if f.len() != 4 || !f[0].eq_ignore_ascii_case("vertex") {
            let expected = if k == 0 {
                VERTEX.to_owned()
            } else {
                format!("{VERTEX} (a facet has 3 vertices, this one {k})")
            };
            return Err(text::parse_error(
                path,
                line.no,
                expected,
                text::quote(line.text),
            ));
        }
        let mut p = [0.0; 3];
        for (axis, (c, token)) in p.iter_mut().zip(&f[1..]).enumerate() {
            let what = format_args!(
                "the {} coordinate of vertex {} of facet {number}",
                ["x", "y", "z"][axis],
                k + 1
            );
            let value = text::parse_f64(path, line.no, token, what)?;
            if !value.is_finite() {
                return Err(text::parse_error(
                    path,
                    line.no,
                    format!(
                        "a finite {} coordinate of vertex {} of facet {number}",
                        ["x", "y", "z"][axis],
                        k + 1
                    ),
                    text::quote(token),
                ));
            }
            *c = value;
        }
        *corner = welder.add(path, p)?;
    }
    let line = next("`endloop`")?;
    keyword(&line, &["endloop"], "`endloop` (a facet has 3 vertices)")?;
    let line = next("`endfacet`")?;
    keyword(&line, &["endfacet"], "`endfacet`")?;
    Ok(tri)
}

// ---------------------------------------------------------------------------------------------
// OBJ

fn obj(path: &Path, bytes: Vec<u8>) -> Result<SurfaceMesh, MeshReadError> {
    let text = text::bytes_to_text(path, bytes)?;
    let mut vertices: Vec<[f64; 3]> = Vec::new();
    let mut triangles = Vec::new();
    for line in DataLines::new(&text, true) {
        let fields = line.fields(false);
        match fields[0] {
            "v" => {
                // x y z, optionally w or an r g b colour.
                if !(4..=7).contains(&fields.len()) {
                    return Err(text::parse_error(
                        path,
                        line.no,
                        "`v <x> <y> <z> [<w> | <r> <g> <b>]`",
                        text::quote(line.text),
                    ));
                }
                let n = vertices.len() + 1;
                let mut p = [0.0; 3];
                for (axis, (c, token)) in p.iter_mut().zip(&fields[1..]).enumerate() {
                    let axis = ["x", "y", "z"][axis];
                    let what = format_args!("the {axis} coordinate of vertex {n}");
                    let value = text::parse_f64(path, line.no, token, what)?;
                    if !value.is_finite() {
                        return Err(text::parse_error(
                            path,
                            line.no,
                            format!("a finite {axis} coordinate of vertex {n}"),
                            text::quote(token),
                        ));
                    }
                    *c = value;
                }
                for token in &fields[4..] {
                    text::parse_f64(path, line.no, token, "a vertex weight or colour")?;
                }
                if vertices.len() == u32::MAX as usize {
                    return Err(MeshReadError::TooManyNodes {
                        path: path.to_owned(),
                        count: vertices.len() + 1,
                    });
                }
                vertices.push(p);
            }
            "f" => {
                if fields.len() < 4 {
                    return Err(text::parse_error(
                        path,
                        line.no,
                        "a face with at least 3 corners",
                        text::quote(line.text),
                    ));
                }
                let mut corners = Vec::with_capacity(fields.len() - 1);
                for token in &fields[1..] {
                    corners.push(obj_corner(path, &line, token, vertices.len())?);
                }
                for k in 1..corners.len() - 1 {
                    triangles.push([corners[0], corners[k], corners[k + 1]]);
                }
            }
            "vt" | "vn" | "vp" | "o" | "g" | "s" | "usemtl" | "mtllib" | "l" | "p" => {}
            other => {
                return Err(text::parse_error(
                    path,
                    line.no,
                    "an OBJ statement (`v`, `f`, or one that is skipped: `vt`, `vn`, `vp`, `o`, \
                     `g`, `s`, `usemtl`, `mtllib`, `l`, `p`)",
                    text::quote(other),
                ))
            }
        }
    }
    Ok(SurfaceMesh {
        vertices,
        triangles,
    })
}

/// One face corner `i`, `i/t`, `i//n` or `i/t/n`: the 0-based vertex index.
fn obj_corner(
    path: &Path,
    line: &Line<'_>,
    token: &str,
    count: usize,
) -> Result<u32, MeshReadError> {
    let mut parts = token.split('/');
    let vertex = parts.next().unwrap_or("");
    let rest: Vec<&str> = parts.collect();
    let bad = || {
        text::parse_error(
            path,
            line.no,
            "a face corner `v`, `v/t`, `v//n` or `v/t/n` (integers)",
            text::quote(token),
        )
    };
    if rest.len() > 2 || (rest.len() == 1 && rest[0].is_empty()) {
        return Err(bad());
    }
    for part in &rest {
        if !part.is_empty() && part.parse::<i64>().is_err() {
            return Err(bad());
        }
    }
    let i = vertex.parse::<i64>().map_err(|_| bad())?;
    let count_i = count as i64;
    let index =
        match i {
            1.. if i <= count_i => i - 1,
            ..=-1 if -i <= count_i => count_i + i,
            _ => {
                return Err(text::parse_error(
                    path,
                    line.no,
                    format!(
                    "a vertex number in 1..={count_i} or -{count_i}..=-1 ({count_i} {} defined \
                     so far)",
                    if count == 1 { "vertex is" } else { "vertices are" }
                ),
                    text::quote(token),
                ))
            }
        };
    // `count` fits in u32 (checked when vertices are added), so does `index`.
    Ok(index as u32)
}

// ---------------------------------------------------------------------------------------------
// PLY

/// A PLY type's name after "a" or "an", for messages.
fn with_article(s: Scalar) -> String {
    match s {
        Scalar::I32 => "an int".to_owned(),
        other => format!("a {}", ply_name(other)),
    }
}

/// A PLY type's name as the header writes it.
fn ply_name(s: Scalar) -> &'static str {
    match s {
        Scalar::I8 => "char",
        Scalar::U8 => "uchar",
        Scalar::I16 => "short",
        Scalar::U16 => "ushort",
        Scalar::I32 => "int",
        Scalar::U32 => "uint",
        Scalar::F32 => "float",
        Scalar::F64 => "double",
        Scalar::I64 => "int64",
        Scalar::U64 => "uint64",
    }
}

#[derive(Debug)]
enum Property {
    Scalar(Scalar),
    /// A list: the type of its length, the type of its items.
    List(Scalar, Scalar),
}

#[derive(Debug)]
struct Element {
    name: String,
    count: usize,
    line: usize,
    properties: Vec<(String, Property)>,
}

#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Encoding {
    Ascii,
    Little,
    Big,
}

struct PlyHeader {
    encoding: Encoding,
    elements: Vec<Element>,
    /// Lines in the header (the body's first line is the next).
    lines: usize,
    /// Byte offset of the body.
    body: usize,
}

fn ply_header(path: &Path, bytes: &[u8]) -> Result<PlyHeader, MeshReadError> {
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    let mut pos = 0usize;
    let mut no = 0usize;
    loop {
        let Some(len) = bytes[pos..].iter().position(|&b| b == b'\n') else {
            return Err(text::eof_error(path, no.max(1), "`end_header`"));
        };
        no += 1;
        let raw = &bytes[pos..pos + len];
        pos += len + 1;
        let Ok(line) = std::str::from_utf8(raw) else {
            return Err(text::parse_error(
                path,
                no,
                "a PLY header line (ASCII text)",
                text::quote(&String::from_utf8_lossy(raw)),
            ));
        };
        let line = line.trim();
        let fields: Vec<&str> = line.split_whitespace().collect();
        let err = |expected: &str| Err(text::parse_error(path, no, expected, text::quote(line)));
        if no == 1 {
            if line != "ply" {
                return err("`ply`");
            }
            continue;
        }
        match fields.first().copied() {
            None | Some("comment" | "obj_info") => {}
            Some("format") if encoding.is_some() => return err("a single `format` line"),
            Some("format") => {
                encoding = Some(match (fields.get(1).copied(), fields.get(2).copied()) {
                    (Some("ascii"), Some("1.0")) if fields.len() == 3 => Encoding::Ascii,
                    (Some("binary_little_endian"), Some("1.0")) if fields.len() == 3 => {
                        Encoding::Little
                    }
                    (Some("binary_big_endian"), Some("1.0")) if fields.len() == 3 => Encoding::Big,
                    _ => {
                        return err("`format ascii 1.0`, `format binary_little_endian 1.0` or \
                             `format binary_big_endian 1.0`")
                    }
                })
            }
            Some("element") => {
                if fields.len() != 3 {
                    return err("`element <name> <count>`");
                }
                let count = text::parse_count(
                    path,
                    no,
                    fields[2],
                    format_args!("the number of {} elements", fields[1]),
                )?;
                elements.push(Element {
                    name: fields[1].to_owned(),
                    count,
                    line: no,
                    properties: Vec::new(),
                });
            }
            Some("property") => {
                let Some(element) = elements.last_mut() else {
                    return err("an `element` line before its properties");
                };
                let property =
                    match fields.as_slice() {
                        ["property", "list", count, item, name] => {
                            match (Scalar::from_ply(count), Scalar::from_ply(item)) {
                                (Some(c), Some(i)) if c.is_integer() => {
                                    (name.to_string(), Property::List(c, i))
                                }
                                _ => return err(
                                    "`property list <integer type> <type> <name>` (types: char, \
                                     uchar, short, ushort, int, uint, float, double)",
                                ),
                            }
                        }
                        ["property", kind, name] => {
                            match Scalar::from_ply(kind) {
                                Some(s) => (name.to_string(), Property::Scalar(s)),
                                None => return err(
                                    "`property <type> <name>` (types: char, uchar, short, ushort, \
                                 int, uint, float, double)",
                                ),
                            }
                        }
                        _ => return err("`property <type> <name>` or `property list ...`"),
                    };
                element.properties.push(property);
            }
            Some("end_header") if fields.len() == 1 => {
                let Some(encoding) = encoding else {
                    return err("a `format` line before `end_header`");
                };
                return Ok(PlyHeader {
                    encoding,
                    elements,
                    lines: no,
                    body: pos,
                });
            }
            Some(_) => {
                return err(
                    "a PLY header line (`format`, `element`, `property`, `comment`, \
                     `end_header`)",
                )
            }
        }
    }
}

/// Where the values of a PLY body come from.
enum Body<'a> {
    Ascii {
        lines: DataLines<'a>,
        fields: Vec<&'a str>,
        next: usize,
        line: usize,
    },
    Binary {
        bytes: &'a [u8],
        pos: usize,
        /// Offset of the last value read (for messages).
        last: usize,
        big: bool,
    },
}

impl<'a> Body<'a> {
    /// Moves to the next element (ASCII: the next line).
    fn start(&mut self, path: &Path, what: &str) -> Result<(), MeshReadError> {
        if let Body::Ascii {
            lines,
            fields,
            next,
            line,
        } = self
        {
            let Some(l) = lines.next() else {
                return Err(text::eof_error(path, lines.eof_line(), what));
            };
            *fields = l.fields(false);
            *next = 0;
            *line = l.no;
        }
        Ok(())
    }

    /// Checks that an element's line has no values left (ASCII).
    fn finish(&self, path: &Path, what: &str) -> Result<(), MeshReadError> {
        match self {
            Body::Ascii {
                fields, next, line, ..
            } if *next < fields.len() => Err(text::parse_error(
                path,
                *line,
                format!("the end of {what}"),
                format!("more values: {}", text::quote(&fields[*next..].join(" "))),
            )),
            _ => Ok(()),
        }
    }

    /// Reads one value of type `s`.
    fn value(&mut self, path: &Path, s: Scalar, what: &str) -> Result<f64, MeshReadError> {
        match self {
            Body::Ascii {
                fields, next, line, ..
            } => {
                let Some(token) = fields.get(*next) else {
                    return Err(text::parse_error(
                        path,
                        *line,
                        format!("{} for {what}", with_article(s)),
                        "the end of the line",
                    ));
                };
                *next += 1;
                let bad = || {
                    text::parse_error(
                        path,
                        *line,
                        format!("{} for {what}", with_article(s)),
                        text::quote(token),
                    )
                };
                if s.is_integer() {
                    let v = token.parse::<i64>().map_err(|_| bad())?;
                    let (lo, hi) = s.range();
                    if v < lo || v > hi {
                        return Err(bad());
                    }
                    Ok(v as f64)
                } else {
                    token.parse::<f64>().map_err(|_| bad())
                }
            }
            Body::Binary {
                bytes,
                pos,
                last,
                big,
            } => {
                let size = s.size();
                let Some(raw) = bytes.get(*pos..*pos + size) else {
                    return Err(binary_error(
                        path,
                        bytes.len(),
                        format!("{} for {what}", with_article(s)),
                        "end of file",
                    ));
                };
                *last = *pos;
                *pos += size;
                Ok(s.real(raw, *big))
            }
        }
    }

    /// An error about the value just read.
    fn error(&self, path: &Path, expected: String, found: String) -> MeshReadError {
        match self {
            Body::Ascii { line, .. } => text::parse_error(path, *line, expected, found),
            Body::Binary { last, .. } => binary_error(path, *last, expected, found),
        }
    }

    /// Bytes left (binary), to refuse counts the file cannot hold before looping over them.
    fn left(&self) -> Option<usize> {
        match self {
            Body::Ascii { .. } => None,
            Body::Binary { bytes, pos, .. } => Some(bytes.len() - *pos),
        }
    }

    fn offset(&self) -> usize {
        match self {
            Body::Ascii { .. } => 0,
            Body::Binary { pos, .. } => *pos,
        }
    }
}

fn ply(path: &Path, bytes: &[u8]) -> Result<SurfaceMesh, MeshReadError> {
    let header = ply_header(path, bytes)?;
    let (vertex_count, vertex_line) = {
        let Some(vertex) = header.elements.iter().find(|e| e.name == "vertex") else {
            return Err(text::parse_error(
                path,
                header.lines,
                "an `element vertex <count>` line in the header",
                "`end_header`",
            ));
        };
        for axis in ["x", "y", "z"] {
            match vertex.properties.iter().find(|(n, _)| n == axis) {
                Some((_, Property::Scalar(_))) => {}
                _ => {
                    return Err(text::parse_error(
                        path,
                        vertex.line,
                        format!("a `property <type> {axis}` of the vertex element"),
                        "none",
                    ))
                }
            }
        }
        (vertex.count, vertex.line)
    };
    let Some(face) = header.elements.iter().find(|e| e.name == "face") else {
        return Err(text::parse_error(
            path,
            header.lines,
            "an `element face <count>` line in the header",
            "`end_header`",
        ));
    };
    let Some(list) = face.properties.iter().position(|(n, p)| {
        matches!(p, Property::List(..)) && (n == "vertex_indices" || n == "vertex_index")
    }) else {
        return Err(text::parse_error(
            path,
            face.line,
            "a `property list <type> <type> vertex_indices` of the face element",
            "none",
        ));
    };
    if let (_, Property::List(_, item)) = &face.properties[list] {
        if !item.is_integer() {
            return Err(text::parse_error(
                path,
                face.line,
                "integer vertex indices",
                format!("`{}`", ply_name(*item)),
            ));
        }
    }
    if u32::try_from(vertex_count).is_err() {
        return Err(text::parse_error(
            path,
            vertex_line,
            "at most 2^32 - 1 vertices (what a mesh can index)",
            vertex_count.to_string(),
        ));
    }

    let text;
    let mut body = match header.encoding {
        Encoding::Ascii => {
            text = text::bytes_to_text(path, bytes.to_vec())?;
            let mut lines = DataLines::new(&text, false);
            // Skip the header (blank header lines are counted by DataLines too).
            while lines.next().is_some_and(|l| l.no < header.lines) {}
            Body::Ascii {
                lines,
                fields: Vec::new(),
                next: 0,
                line: header.lines,
            }
        }
        Encoding::Little | Encoding::Big => Body::Binary {
            bytes,
            pos: header.body,
            last: header.body,
            big: header.encoding == Encoding::Big,
        },
    };

    // A vertex takes at least 2 bytes ("0\n", or a 1-byte binary property).
    let mut vertices = Vec::with_capacity(text::capacity_within(vertex_count, bytes.len(), 2));
    let mut triangles = Vec::new();
    for element in &header.elements {
        // Each element takes at least this many bytes in a binary body.
        let least: usize = element
            .properties
            .iter()
            .map(|(_, p)| match p {
                Property::Scalar(s) | Property::List(s, _) => s.size(),
            })
            .sum();
        if let Some(left) = body.left() {
            if element
                .count
                .checked_mul(least)
                .is_none_or(|need| need > left)
            {
                return Err(binary_error(
                    path,
                    body.offset(),
                    format!(
                        "{} `{}` elements of at least {least} bytes each (header line {})",
                        element.count, element.name, element.line
                    ),
                    format!("{left} bytes left in the file"),
                ));
            }
        }
        let is_vertex = element.name == "vertex";
        let is_face = element.name == "face";
        for i in 0..element.count {
            let what = format!("{} {i}", element.name);
            body.start(
                path,
                &format!("{what} (the header declares {})", element.count),
            )?;
            let mut p = [0.0; 3];
            for (k, (name, property)) in element.properties.iter().enumerate() {
                match property {
                    Property::Scalar(s) => {
                        let v = body.value(path, *s, &format!("`{name}` of {what}"))?;
                        if is_vertex {
                            if let Some(axis) = ["x", "y", "z"].iter().position(|a| a == name) {
                                if !v.is_finite() {
                                    return Err(body.error(
                                        path,
                                        format!("a finite {name} of {what}"),
                                        format!("{v}"),
                                    ));
                                }
                                p[axis] = v;
                            }
                        }
                    }
                    Property::List(c, item) => {
                        let n =
                            body.value(path, *c, &format!("the length of `{name}` of {what}"))?;
                        if n < 0.0 {
                            return Err(body.error(
                                path,
                                format!("a non-negative length of `{name}` of {what}"),
                                format!("`{n}`"),
                            ));
                        }
                        let n = n as usize;
                        let indices = is_face && k == list;
                        if indices && n < 3 {
                            return Err(body.error(
                                path,
                                format!("a polygon of at least 3 vertices for {what}"),
                                format!("`{n}`"),
                            ));
                        }
                        let mut corners = Vec::with_capacity(if indices { n.min(64) } else { 0 });
                        for j in 0..n {
                            let v = body.value(
                                path,
                                *item,
                                &format!("item {j} of `{name}` of {what}"),
                            )?;
                            if indices {
                                if v < 0.0 || v >= vertex_count as f64 {
                                    return Err(body.error(
                                        path,
                                        format!(
                                            "a vertex index below {vertex_count} (the vertex count) for {what}"
                                        ),
                                        format!("`{v}`"),
                                    ));
                                }
                                corners.push(v as u32);
                            }
                        }
                        for k in 1..corners.len().saturating_sub(1) {
                            triangles.push([corners[0], corners[k], corners[k + 1]]);
                        }
                    }
                }
            }
            body.finish(path, &what)?;
            if is_vertex {
                vertices.push(p);
            }
        }
    }
    match &mut body {
        Body::Ascii { lines, .. } => {
            if let Some(extra) = lines.next() {
                return Err(text::parse_error(
                    path,
                    extra.no,
                    "the end of the file (all declared elements are read)",
                    text::quote(extra.text),
                ));
            }
        }
        Body::Binary { bytes, pos, .. } => {
            if *pos != bytes.len() {
                return Err(binary_error(
                    path,
                    *pos,
                    "the end of the file (all declared elements are read)",
                    format!("{} more bytes", bytes.len() - *pos),
                ));
            }
        }
    }
    Ok(SurfaceMesh {
        vertices,
        triangles,
    })
}
