//! STL surfaces, binary and ASCII, for [`super::read_surface`]: STL repeats a vertex in every
//! triangle that uses it, so vertices with equal coordinates are welded into one.

use std::collections::hash_map::{Entry, HashMap};
use std::path::Path;

use super::surface_io::binary_error;
use super::text::{self, DataLines, Line};
use super::{MeshReadError, SurfaceMesh};

/// The triangle count of a binary STL (bytes 80..84, little endian), if the header is there.
pub(super) fn stl_count(bytes: &[u8]) -> Option<u32> {
    let count: [u8; 4] = bytes.get(80..84)?.try_into().ok()?;
    Some(u32::from_le_bytes(count))
}

/// The size of a binary STL with `n` triangles.
pub(super) fn stl_size(n: u32) -> u64 {
    84 + 50 * u64::from(n)
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

pub(super) fn stl_binary(path: &Path, bytes: &[u8]) -> Result<SurfaceMesh, MeshReadError> {
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

pub(super) fn stl_ascii(path: &Path, bytes: Vec<u8>) -> Result<SurfaceMesh, MeshReadError> {
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
