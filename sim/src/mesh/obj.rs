//! Wavefront OBJ surfaces for [`super::read_surface`]: `v` and `f` statements, polygons fanned
//! into triangles; everything else skipped.

use std::path::Path;

use super::text::{self, DataLines, Line};
use super::{MeshReadError, SurfaceMesh};

pub(super) fn obj(path: &Path, bytes: Vec<u8>) -> Result<SurfaceMesh, MeshReadError> {
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
