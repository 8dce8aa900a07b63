//! PLY surfaces (ASCII, binary little- and big-endian) for [`super::read_surface`]: the
//! header, then the `vertex` element's `x y z` and the `face` element's index lists, fanned
//! into triangles; other elements and properties skipped.

use std::path::Path;

use super::surface_io::binary_error;
use super::text::{self, DataLines};
use super::vtk_cells::Scalar;
use super::{MeshReadError, SurfaceMesh};

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

pub(super) fn ply(path: &Path, bytes: &[u8]) -> Result<SurfaceMesh, MeshReadError> {
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
