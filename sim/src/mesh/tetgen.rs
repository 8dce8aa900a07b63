//! TetGen `.node` / `.ele` / `.face` files (plus lop's `.bnd`): reading and writing.

use std::io::Write;
use std::path::{Path, PathBuf};

use super::text::{self, DataLines};
use super::validate::{self, NodeLabels, Origin};
use super::{bnd, MeshReadError, TetMesh};

const AXES: [&str; 3] = ["x", "y", "z"];

/// Reads the TetGen mesh `base.node` + `base.ele` (+ `base.face`, `base.bnd` if present).
///
/// `base` may also be given as `X.node`, `X.ele` or `X.face`. See the
/// [module docs](super) for the format and the numbering rules.
///
/// # Errors
/// Any [`MeshReadError`] naming the `.node`, `.ele`, `.face` or `.bnd` file at fault: a missing
/// `.node` / `.ele` is [`MeshReadError::Io`].
pub fn read_tetgen(base: &Path) -> Result<TetMesh, MeshReadError> {
    let base = strip_tetgen_extension(base);
    let node_path = text::with_suffix(&base, "node");
    let ele_path = text::with_suffix(&base, "ele");
    let face_path = text::with_suffix(&base, "face");
    let bnd_path = text::with_suffix(&base, "bnd");

    let node_text = text::read_text(&node_path)?;
    let (nodes, first) = parse_node(&node_path, &node_text)?;
    let count = nodes.len();
    let nodes_ref = NodeRef {
        node_file: &node_path,
        count,
        first,
    };

    let ele_text = text::read_text(&ele_path)?;
    let ele = parse_ele(&ele_path, &ele_text, &nodes_ref)?;

    if let Some(face_text) = text::read_optional_text(&face_path)? {
        check_face(&face_path, &face_text, &nodes_ref)?;
    }

    let fixed = bnd::read_optional(&bnd_path, |line, number| {
        nodes_ref
            .resolve(number)
            .ok_or_else(|| MeshReadError::BadBoundary {
                path: bnd_path.clone(),
                line: Some(line),
                index: number,
                count,
                first_index: first,
                node_file: node_path.clone(),
            })
    })?
    .unwrap_or_default();

    let origin = Origin {
        tet_file: ele_path,
        tet_lines: ele.lines,
        tet_labels: ele.labels,
        node_labels: NodeLabels::Offset(first),
    };
    validate::build(nodes, ele.tets, fixed, node_path, &origin)
}

/// Writes `base.node`, `base.ele`, `base.face` (the surface) and `base.bnd` (the fixed nodes,
/// possibly none), numbered from 1 as TetGen itself writes them.
///
/// # Errors
/// Any I/O error from creating or writing the files.
pub fn write_tetgen(mesh: &TetMesh, base: &Path) -> std::io::Result<()> {
    write_tetgen_numbered(mesh, base, 1)
}

/// Like [`write_tetgen`], numbering nodes, tetrahedra and faces from `first_number` (0 or 1;
/// anything else is an `InvalidInput` error).
///
/// # Errors
/// `InvalidInput` for another `first_number`; any I/O error from writing the files.
pub fn write_tetgen_numbered(
    mesh: &TetMesh,
    base: &Path,
    first_number: u32,
) -> std::io::Result<()> {
    if first_number > 1 {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            format!("TetGen files are numbered from 0 or 1, not {first_number}"),
        ));
    }
    let first = u64::from(first_number);
    let n = |i: u32| u64::from(i) + first;
    let source = mesh.source.display();

    let mut out = create(&text::with_suffix(base, "node"))?;
    writeln!(out, "# lop-sim mesh from {source}")?;
    writeln!(
        out,
        "# <#points> <dimension> <#attributes> <#boundary markers>"
    )?;
    writeln!(out, "{} 3 0 0", mesh.nodes.len())?;
    for (i, [x, y, z]) in (first..).zip(&mesh.nodes) {
        // `{:?}` prints the shortest text that parses back to the same f64.
        writeln!(out, "{i} {x:?} {y:?} {z:?}")?;
    }
    out.flush()?;

    let mut out = create(&text::with_suffix(base, "ele"))?;
    writeln!(out, "# <#tetrahedra> <nodes per tetrahedron> <#attributes>")?;
    writeln!(out, "{} 4 0", mesh.tets.len())?;
    for (i, [a, b, c, d]) in (first..).zip(&mesh.tets) {
        writeln!(out, "{i} {} {} {} {}", n(*a), n(*b), n(*c), n(*d))?;
    }
    out.flush()?;

    let mut out = create(&text::with_suffix(base, "face"))?;
    writeln!(
        out,
        "# boundary surface, wound counter-clockwise seen from outside"
    )?;
    writeln!(out, "# <#faces> <boundary marker>")?;
    writeln!(out, "{} 0", mesh.surface.len())?;
    for (i, [a, b, c]) in (first..).zip(&mesh.surface) {
        writeln!(out, "{i} {} {} {}", n(*a), n(*b), n(*c))?;
    }
    out.flush()?;

    bnd::write_bnd(&mesh.fixed, first_number, &text::with_suffix(base, "bnd"))
}

fn create(path: &Path) -> std::io::Result<std::io::BufWriter<std::fs::File>> {
    Ok(std::io::BufWriter::new(std::fs::File::create(path)?))
}

/// `X.node` / `X.ele` / `X.face` -> `X`; anything else is already a base.
fn strip_tetgen_extension(path: &Path) -> PathBuf {
    match text::extension(path).as_deref() {
        Some("node" | "ele" | "face") => path.with_extension(""),
        _ => path.to_owned(),
    }
}

/// How the `.node` file numbers its points, for checking references to them.
struct NodeRef<'a> {
    node_file: &'a Path,
    count: usize,
    first: i64,
}

impl NodeRef<'_> {
    /// The 0-based index of node `number`, if it exists.
    fn resolve(&self, number: i64) -> Option<u32> {
        let i = number.checked_sub(self.first)?;
        let i = usize::try_from(i).ok()?;
        if i < self.count {
            u32::try_from(i).ok()
        } else {
            None
        }
    }

    fn resolve_or_err(&self, path: &Path, line: usize, number: i64) -> Result<u32, MeshReadError> {
        self.resolve(number)
            .ok_or_else(|| MeshReadError::IndexOutOfRange {
                path: path.to_owned(),
                line: Some(line),
                index: number,
                count: self.count,
                first_index: self.first,
                node_file: self.node_file.to_owned(),
            })
    }
}

/// Reads an optional header field with a default.
fn header_field(
    path: &Path,
    line: usize,
    fields: &[&str],
    i: usize,
    default: usize,
    what: &str,
) -> Result<usize, MeshReadError> {
    match fields.get(i) {
        Some(token) => text::parse_count(path, line, token, what),
        None => Ok(default),
    }
}

/// Parses a `.node` file: the points and the first number.
fn parse_node(path: &Path, text: &str) -> Result<(Vec<[f64; 3]>, i64), MeshReadError> {
    const HEADER: &str =
        "the .node header `<#points> <dimension> <#attributes> <#boundary markers>`";
    let mut lines = DataLines::new(text, true);
    let header = lines
        .next()
        .ok_or_else(|| text::eof_error(path, lines.eof_line(), HEADER))?;
    let fields = header.fields(true);
    if fields.len() > 4 {
        return Err(text::parse_error(
            path,
            header.no,
            HEADER,
            text::quote(header.text),
        ));
    }
    let declared = header_field(path, header.no, &fields, 0, 0, "the number of points")?;
    let dim = header_field(path, header.no, &fields, 1, 3, "the dimension")?;
    if dim != 3 {
        return Err(text::parse_error(
            path,
            header.no,
            "dimension 3 (only 3D meshes are read)",
            text::quote(fields.get(1).copied().unwrap_or_default()),
        ));
    }
    let attributes = header_field(path, header.no, &fields, 2, 0, "the number of attributes")?;
    let markers = header_field(
        path,
        header.no,
        &fields,
        3,
        0,
        "the number of boundary markers",
    )?;
    if markers > 1 {
        return Err(text::parse_error(
            path,
            header.no,
            "0 or 1 boundary markers",
            text::quote(fields.get(3).copied().unwrap_or_default()),
        ));
    }
    let per_line = 4usize.saturating_add(attributes).saturating_add(markers);
    let layout = format!(
        "`<point number> <x> <y> <z>` followed by {attributes} attribute(s) and {markers} marker(s)"
    );

    // The shortest point line, `1 0 0 0` and its newline, takes 8 bytes.
    let mut nodes = Vec::with_capacity(text::capacity_within(declared, text.len(), 8));
    let mut first = 0;
    text::read_records(
        path,
        &mut lines,
        header.no,
        declared,
        "points",
        |i, line| {
            let fields = line.fields(true);
            text::expect_fields(path, &line, &fields, per_line, &layout)?;
            let number = text::parse_i64(path, line.no, fields[0], "the point number")?;
            if i == 0 {
                if number != 0 && number != 1 {
                    return Err(text::parse_error(
                        path,
                        line.no,
                        "the first point to be numbered 0 or 1",
                        text::quote(fields[0]),
                    ));
                }
                first = number;
            } else {
                let expected = first.saturating_add(i64::try_from(i).unwrap_or(i64::MAX));
                if number != expected {
                    return Err(text::parse_error(
                        path,
                        line.no,
                        format!("point number {expected} (points must be numbered consecutively)"),
                        text::quote(fields[0]),
                    ));
                }
            }
            let mut p = [0.0; 3];
            for (k, axis) in AXES.iter().enumerate() {
                let what = format_args!("the {axis} coordinate of point {number}");
                let value = text::parse_f64(path, line.no, fields[1 + k], what)?;
                if !value.is_finite() {
                    return Err(MeshReadError::NonFiniteCoordinate {
                        path: path.to_owned(),
                        line: Some(line.no),
                        node: number,
                        value,
                    });
                }
                p[k] = value;
            }
            for (k, token) in fields[4..4 + attributes].iter().enumerate() {
                text::parse_f64(
                    path,
                    line.no,
                    token,
                    format_args!("attribute {} of point {number}", k + 1),
                )?;
            }
            if markers == 1 {
                text::parse_i64(
                    path,
                    line.no,
                    fields[4 + attributes],
                    format_args!("the boundary marker of point {number}"),
                )?;
            }
            nodes.push(p);
            Ok(())
        },
    )?;
    if u32::try_from(nodes.len()).is_err() {
        return Err(MeshReadError::TooManyNodes {
            path: path.to_owned(),
            count: nodes.len(),
        });
    }
    Ok((nodes, first))
}

struct Ele {
    tets: Vec<[u32; 4]>,
    lines: Vec<usize>,
    labels: Vec<i64>,
}

/// Parses an `.ele` file against the points of the `.node` file.
fn parse_ele(path: &Path, text: &str, nodes: &NodeRef<'_>) -> Result<Ele, MeshReadError> {
    const HEADER: &str = "the .ele header `<#tetrahedra> <nodes per tetrahedron> <#attributes>`";
    let mut lines = DataLines::new(text, true);
    let header = lines
        .next()
        .ok_or_else(|| text::eof_error(path, lines.eof_line(), HEADER))?;
    let fields = header.fields(true);
    if !(2..=3).contains(&fields.len()) {
        return Err(text::parse_error(
            path,
            header.no,
            HEADER,
            text::quote(header.text),
        ));
    }
    let declared = text::parse_count(path, header.no, fields[0], "the number of tetrahedra")?;
    let corners = text::parse_count(
        path,
        header.no,
        fields[1],
        "the number of nodes per tetrahedron",
    )?;
    if corners != 4 && corners != 10 {
        return Err(text::parse_error(
            path,
            header.no,
            "4 or 10 nodes per tetrahedron",
            text::quote(fields[1]),
        ));
    }
    let attributes = header_field(path, header.no, &fields, 2, 0, "the number of attributes")?;
    let per_line = (1 + corners).saturating_add(attributes);
    let layout = format!(
        "`<tetrahedron number>` and {corners} node numbers, followed by {attributes} attribute(s)"
    );

    // The shortest tetrahedron line, `1 1 2 3 4` and its newline, takes 10 bytes.
    let capacity = text::capacity_within(declared, text.len(), 10);
    let mut ele = Ele {
        tets: Vec::with_capacity(capacity),
        lines: Vec::with_capacity(capacity),
        labels: Vec::with_capacity(capacity),
    };
    text::read_records(
        path,
        &mut lines,
        header.no,
        declared,
        "tetrahedra",
        |_, line| {
            let fields = line.fields(true);
            text::expect_fields(path, &line, &fields, per_line, &layout)?;
            let number = text::parse_i64(path, line.no, fields[0], "the tetrahedron number")?;
            let mut tet = [0u32; 4];
            for (k, token) in fields[1..1 + corners].iter().enumerate() {
                let what = format_args!("node {} of tetrahedron {number}", k + 1);
                let node = text::parse_i64(path, line.no, token, what)?;
                let index = nodes.resolve_or_err(path, line.no, node)?;
                if let Some(slot) = tet.get_mut(k) {
                    *slot = index;
                }
            }
            for (k, token) in fields[1 + corners..].iter().enumerate() {
                let what = format_args!("attribute {} of tetrahedron {number}", k + 1);
                text::parse_f64(path, line.no, token, what)?;
            }
            ele.tets.push(tet);
            ele.lines.push(line.no);
            ele.labels.push(number);
            Ok(())
        },
    )?;
    if ele.tets.is_empty() {
        return Err(MeshReadError::NoTets {
            path: path.to_owned(),
            skipped: 0,
        });
    }
    Ok(ele)
}

/// Checks that a `.face` file parses and refers to existing nodes.
fn check_face(path: &Path, text: &str, nodes: &NodeRef<'_>) -> Result<(), MeshReadError> {
    const HEADER: &str = "the .face header `<#faces> <boundary marker 0|1>`";
    let mut lines = DataLines::new(text, true);
    let header = lines
        .next()
        .ok_or_else(|| text::eof_error(path, lines.eof_line(), HEADER))?;
    let fields = header.fields(true);
    if !(1..=2).contains(&fields.len()) {
        return Err(text::parse_error(
            path,
            header.no,
            HEADER,
            text::quote(header.text),
        ));
    }
    let declared = text::parse_count(path, header.no, fields[0], "the number of faces")?;
    let markers = header_field(path, header.no, &fields, 1, 0, "the boundary marker flag")?;
    if markers > 1 {
        return Err(text::parse_error(
            path,
            header.no,
            "a boundary marker flag 0 or 1",
            text::quote(fields[1]),
        ));
    }
    let layout = if markers == 1 {
        "`<face number> <a> <b> <c> <marker>`"
    } else {
        "`<face number> <a> <b> <c>`"
    };
    text::read_records(path, &mut lines, header.no, declared, "faces", |_, line| {
        let fields = line.fields(true);
        text::expect_fields(path, &line, &fields, 4 + markers, layout)?;
        let number = text::parse_i64(path, line.no, fields[0], "the face number")?;
        for (k, token) in fields[1..4].iter().enumerate() {
            let what = format_args!("node {} of face {number}", k + 1);
            let node = text::parse_i64(path, line.no, token, what)?;
            nodes.resolve_or_err(path, line.no, node)?;
        }
        if markers == 1 {
            text::parse_i64(
                path,
                line.no,
                fields[4],
                format_args!("the boundary marker of face {number}"),
            )?;
        }
        Ok(())
    })
}
