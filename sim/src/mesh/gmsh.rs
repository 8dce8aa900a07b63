//! Gmsh `.msh` files, ASCII: the legacy format 1 (`$NOD` / `$ELM`), format 2.x and 4.1.

use std::collections::hash_map::{Entry, HashMap};
use std::path::Path;

use super::text::{self, DataLines, Line};
use super::validate::{self, NodeLabels, Origin};
use super::{bnd, MeshReadError, TetMesh};

/// Gmsh element type of the 4-node tetrahedron.
const TETRAHEDRON: i64 = 4;

const REEXPORT: &str =
    "re-export it as ASCII 4.1 or 2.2 (e.g. `gmsh -save -format msh22 file.msh`)";

#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Version {
    /// The legacy format: no `$MeshFormat`, nodes in `$NOD`, elements in `$ELM`.
    V1,
    V2,
    V41,
}

/// Reads a Gmsh ASCII mesh (legacy format 1, format 2.x or 4.1) and the fixed nodes from a sibling
/// `<stem>.bnd` (Gmsh node tags) if there is one. See the [module docs](super).
///
/// # Errors
/// Any [`MeshReadError`] naming the `.msh` or `.bnd` file at fault; binary files and format
/// 4.0 are [`MeshReadError::UnsupportedFormat`].
pub fn read_gmsh(path: &Path) -> Result<TetMesh, MeshReadError> {
    let bytes = std::fs::read(path).map_err(|source| MeshReadError::Io {
        path: path.to_owned(),
        source,
    })?;
    if declares_binary(&bytes) {
        return Err(MeshReadError::UnsupportedFormat {
            path: path.to_owned(),
            reason: format!("binary Gmsh files are not supported; {REEXPORT}"),
        });
    }
    let text = text::bytes_to_text(path, bytes)?;
    let mut reader = Reader {
        path,
        lines: DataLines::new(&text, false),
        text_bytes: text.len(),
        nodes: Vec::new(),
        tags: Vec::new(),
        index_of: HashMap::new(),
        node_lines: Vec::new(),
        tets: Vec::new(),
        tet_lines: Vec::new(),
        tet_labels: Vec::new(),
        skipped: 0,
    };
    let version = reader.mesh_format()?;
    // Format 1 names its sections differently and closes them with `$END<NAME>`.
    let (nodes, elements) = match version {
        Version::V1 => ("$NOD", "$ELM"),
        Version::V2 | Version::V41 => ("$Nodes", "$Elements"),
    };
    let mut have_nodes = false;
    let mut have_elements = false;
    while let Some(line) = reader.lines.next() {
        match line.text {
            t if t == nodes && have_nodes => {
                return Err(text::parse_error(
                    path,
                    line.no,
                    format!("a single `{nodes}` section"),
                    "a second one",
                ))
            }
            t if t == nodes => {
                match version {
                    Version::V1 => reader.nodes_v2("$ENDNOD")?,
                    Version::V2 => reader.nodes_v2("$EndNodes")?,
                    Version::V41 => reader.nodes_v41()?,
                }
                have_nodes = true;
            }
            t if t == elements && !have_nodes => {
                return Err(text::parse_error(
                    path,
                    line.no,
                    format!("the `{nodes}` section before `{elements}`"),
                    text::quote(t),
                ))
            }
            t if t == elements && have_elements => {
                return Err(text::parse_error(
                    path,
                    line.no,
                    format!("a single `{elements}` section"),
                    "a second one",
                ))
            }
            t if t == elements => {
                match version {
                    Version::V1 => reader.elements_v1()?,
                    Version::V2 => reader.elements_v2()?,
                    Version::V41 => reader.elements_v41()?,
                }
                have_elements = true;
            }
            other => match other.strip_prefix('$') {
                Some(name)
                    if !name.is_empty() && !name.starts_with("End") && !name.starts_with("END") =>
                {
                    reader.skip_section(name, version)?
                }
                _ => {
                    return Err(text::parse_error(
                        path,
                        line.no,
                        format!("a section such as `{nodes}` or `{elements}`"),
                        text::quote(other),
                    ))
                }
            },
        }
    }
    if reader.tets.is_empty() {
        return Err(MeshReadError::NoTets {
            path: path.to_owned(),
            skipped: reader.skipped,
        });
    }

    let bnd_path = path.with_extension("bnd");
    let index_of = &reader.index_of;
    let fixed = bnd::read_optional(&bnd_path, |line, tag| {
        index_of
            .get(&tag)
            .copied()
            .ok_or_else(|| MeshReadError::UnknownNodeTag {
                path: bnd_path.clone(),
                line,
                tag,
                mesh_file: path.to_owned(),
            })
    })?
    .unwrap_or_default();

    let origin = Origin {
        tet_file: path.to_owned(),
        tet_lines: reader.tet_lines,
        tet_labels: reader.tet_labels,
        node_labels: NodeLabels::Tags(reader.tags),
    };
    validate::build(reader.nodes, reader.tets, fixed, path.to_owned(), &origin)
}

/// Whether the `$MeshFormat` header says "binary" (checked on the raw bytes, before the binary
/// payload can trip the UTF-8 check).
fn declares_binary(bytes: &[u8]) -> bool {
    let mut lines = bytes
        .split(|&b| b == b'\n')
        .map(|l| String::from_utf8_lossy(l).trim().to_owned())
        .filter(|l| !l.is_empty());
    if lines.next().as_deref() != Some("$MeshFormat") {
        return false;
    }
    lines
        .next()
        .is_some_and(|l| l.split_whitespace().nth(1) == Some("1"))
}

struct Reader<'a> {
    path: &'a Path,
    lines: DataLines<'a>,
    /// Length of the file's text: no count may reserve more records than it can hold.
    text_bytes: usize,
    nodes: Vec<[f64; 3]>,
    /// Tag of each node, in file order.
    tags: Vec<i64>,
    index_of: HashMap<i64, u32>,
    node_lines: Vec<usize>,
    tets: Vec<[u32; 4]>,
    tet_lines: Vec<usize>,
    tet_labels: Vec<i64>,
    skipped: usize,
}

impl<'a> Reader<'a> {
    fn parse_error(
        &self,
        line: usize,
        expected: impl Into<String>,
        found: impl Into<String>,
    ) -> MeshReadError {
        text::parse_error(self.path, line, expected, found)
    }

    /// The next line of a section that must not end yet.
    fn data_line(&mut self, end: &str, expected: &str) -> Result<Line<'a>, MeshReadError> {
        match self.lines.next() {
            Some(line) if line.text == end => {
                Err(self.parse_error(line.no, expected, text::quote(end)))
            }
            Some(line) => Ok(line),
            None => Err(text::eof_error(self.path, self.lines.eof_line(), expected)),
        }
    }

    /// Expects the end marker of a section; anything else before it is an error.
    fn expect_end(
        &mut self,
        end: &str,
        header_line: usize,
        declared: usize,
        what: &'static str,
    ) -> Result<(), MeshReadError> {
        let mut extra = 0usize;
        loop {
            match self.lines.next() {
                Some(line) if line.text == end => break,
                Some(line) if line.text.starts_with('$') => {
                    return Err(self.parse_error(
                        line.no,
                        format!("`{end}`"),
                        text::quote(line.text),
                    ))
                }
                Some(_) => extra += 1,
                None => {
                    return Err(text::eof_error(
                        self.path,
                        self.lines.eof_line(),
                        format!("`{end}`"),
                    ))
                }
            }
        }
        if extra > 0 {
            return Err(MeshReadError::CountMismatch {
                path: self.path.to_owned(),
                line: header_line,
                what,
                declared,
                found: declared.saturating_add(extra),
            });
        }
        Ok(())
    }

    /// `$MeshFormat` / `<version> <file-type> <data-size>` / `$EndMeshFormat`.
    fn mesh_format(&mut self) -> Result<Version, MeshReadError> {
        let path = self.path;
        let before = self.lines.clone();
        let Some(first) = self.lines.next() else {
            return Err(text::eof_error(
                path,
                self.lines.eof_line(),
                "`$MeshFormat` (or `$NOD` for the legacy format 1)",
            ));
        };
        if first.text == "$NOD" {
            // Format 1 has no header: its first section is the nodes, read by the caller.
            self.lines = before;
            return Ok(Version::V1);
        }
        if first.text != "$MeshFormat" {
            return Err(MeshReadError::UnsupportedFormat {
                path: path.to_owned(),
                reason: format!(
                    "not a Gmsh file: the first line is {} instead of `$MeshFormat` (formats 2.2 \
                     and 4.1) or `$NOD` (format 1)",
                    text::quote(first.text)
                ),
            });
        }
        let line = self.data_line("$EndMeshFormat", "`<version> <file-type> <data-size>`")?;
        let fields = line.fields(false);
        text::expect_fields(
            path,
            &line,
            &fields,
            3,
            "`<version> <file-type> <data-size>`",
        )?;
        let version = match fields[0] {
            "2" | "2.0" | "2.1" | "2.2" => Version::V2,
            "4.1" => Version::V41,
            v => {
                text::parse_f64(path, line.no, v, "the Gmsh format version")?;
                return Err(MeshReadError::UnsupportedFormat {
                    path: path.to_owned(),
                    reason: format!("Gmsh format {v} is not supported; {REEXPORT}"),
                });
            }
        };
        match fields[1] {
            "0" => {}
            "1" => {
                return Err(MeshReadError::UnsupportedFormat {
                    path: path.to_owned(),
                    reason: format!("binary Gmsh files are not supported; {REEXPORT}"),
                })
            }
            other => {
                return Err(self.parse_error(line.no, "file type 0 (ASCII)", text::quote(other)))
            }
        }
        text::parse_count(path, line.no, fields[2], "the data size")?;
        match self.lines.next() {
            Some(line) if line.text == "$EndMeshFormat" => Ok(version),
            Some(line) => {
                Err(self.parse_error(line.no, "`$EndMeshFormat`", text::quote(line.text)))
            }
            None => Err(text::eof_error(
                path,
                self.lines.eof_line(),
                "`$EndMeshFormat`",
            )),
        }
    }

    /// Skips an unknown section `$name` ... `$Endname` (format 1: `$ENDNAME`).
    fn skip_section(&mut self, name: &str, version: Version) -> Result<(), MeshReadError> {
        let end = match version {
            Version::V1 => format!("$END{}", name.to_ascii_uppercase()),
            Version::V2 | Version::V41 => format!("$End{name}"),
        };
        for line in self.lines.by_ref() {
            if line.text == end {
                return Ok(());
            }
        }
        Err(text::eof_error(
            self.path,
            self.lines.eof_line(),
            format!("`{end}`"),
        ))
    }

    /// Records node `tag` at `p`.
    fn add_node(&mut self, line: usize, tag: i64, p: [f64; 3]) -> Result<(), MeshReadError> {
        let index = u32::try_from(self.nodes.len()).map_err(|_| MeshReadError::TooManyNodes {
            path: self.path.to_owned(),
            count: self.nodes.len(),
        })?;
        match self.index_of.entry(tag) {
            Entry::Occupied(e) => {
                let first_line = self.node_lines.get(*e.get() as usize).copied().unwrap_or(0);
                return Err(self.parse_error(
                    line,
                    "a node tag that is not used yet",
                    format!("tag {tag} again (first on line {first_line})"),
                ));
            }
            Entry::Vacant(e) => {
                e.insert(index);
            }
        }
        self.nodes.push(p);
        self.tags.push(tag);
        self.node_lines.push(line);
        Ok(())
    }

    fn coordinates(
        &self,
        line: &Line<'_>,
        tokens: &[&str],
        tag: i64,
    ) -> Result<[f64; 3], MeshReadError> {
        let mut p = [0.0; 3];
        for (k, (axis, token)) in ["x", "y", "z"].iter().zip(tokens).enumerate() {
            let what = format_args!("the {axis} coordinate of node {tag}");
            let value = text::parse_f64(self.path, line.no, token, what)?;
            if !value.is_finite() {
                return Err(MeshReadError::NonFiniteCoordinate {
                    path: self.path.to_owned(),
                    line: Some(line.no),
                    node: tag,
                    value,
                });
            }
            p[k] = value;
        }
        Ok(p)
    }

    fn header(
        &mut self,
        end: &str,
        n: usize,
        expected: &str,
    ) -> Result<(Line<'a>, Vec<usize>), MeshReadError> {
        let line = self.data_line(end, expected)?;
        let fields = line.fields(false);
        text::expect_fields(self.path, &line, &fields, n, expected)?;
        let numbers = fields
            .iter()
            .map(|t| text::parse_count(self.path, line.no, t, expected))
            .collect::<Result<Vec<_>, _>>()?;
        Ok((line, numbers))
    }

    fn node_tag(
        &self,
        line: usize,
        token: &str,
        what: std::fmt::Arguments<'_>,
    ) -> Result<u32, MeshReadError> {
        let tag = text::parse_i64(self.path, line, token, what)?;
        self.index_of
            .get(&tag)
            .copied()
            .ok_or_else(|| MeshReadError::UnknownNodeTag {
                path: self.path.to_owned(),
                line,
                tag,
                mesh_file: self.path.to_owned(),
            })
    }

    fn tet(
        &mut self,
        line: &Line<'_>,
        tag_token: &str,
        node_tokens: &[&str],
    ) -> Result<(), MeshReadError> {
        let tag = text::parse_i64(self.path, line.no, tag_token, "the element tag")?;
        let mut tet = [0u32; 4];
        for (k, (slot, token)) in tet.iter_mut().zip(node_tokens).enumerate() {
            *slot = self.node_tag(
                line.no,
                token,
                format_args!("node {} of element {tag}", k + 1),
            )?;
        }
        self.tets.push(tet);
        self.tet_lines.push(line.no);
        self.tet_labels.push(tag);
        Ok(())
    }

    /// Formats 1 and 2: `<count>` then `<tag> <x> <y> <z>` lines, up to `end` (`$ENDNOD` in
    /// format 1, `$EndNodes` in format 2).
    fn nodes_v2(&mut self, end: &str) -> Result<(), MeshReadError> {
        let (header, h) = self.header(end, 1, "the number of nodes")?;
        let declared = h[0];
        for i in 0..declared {
            let line = self.section_line(end, header.no, declared, i, "nodes")?;
            let fields = line.fields(false);
            text::expect_fields(self.path, &line, &fields, 4, "`<node tag> <x> <y> <z>`")?;
            let tag = text::parse_i64(self.path, line.no, fields[0], "the node tag")?;
            let p = self.coordinates(&line, &fields[1..], tag)?;
            self.add_node(line.no, tag, p)?;
        }
        self.expect_end(end, header.no, declared, "nodes")
    }

    /// Format 4.1: `<#blocks> <#nodes> <min tag> <max tag>`, then per block
    /// `<entity dim> <entity tag> <parametric> <#nodes in block>`, the block's tags one per line,
    /// then its coordinates one node per line.
    fn nodes_v41(&mut self) -> Result<(), MeshReadError> {
        const HEADER: &str = "`<#entity blocks> <#nodes> <min node tag> <max node tag>`";
        const BLOCK: &str = "`<entity dim> <entity tag> <parametric> <#nodes in block>`";
        let (header, h) = self.header("$EndNodes", 4, HEADER)?;
        let (blocks, declared) = (h[0], h[1]);
        let mut total = 0usize;
        for k in 0..blocks {
            self.no_early_end("$EndNodes", header.no, blocks, k)?;
            let (block, b) = self.header("$EndNodes", 4, BLOCK)?;
            let (dim, parametric, n) = (b[0], b[2], b[3]);
            if parametric > 1 || dim > 3 {
                return Err(self.parse_error(block.no, BLOCK, text::quote(block.text)));
            }
            let per_line = 3 + if parametric == 1 { dim } else { 0 };
            // The shortest tag line, a digit and its newline, takes 2 bytes.
            let mut tags = Vec::with_capacity(text::capacity_within(n, self.text_bytes, 2));
            for i in 0..n {
                let line = self.section_line("$EndNodes", block.no, n, i, "nodes in the block")?;
                let fields = line.fields(false);
                text::expect_fields(
                    self.path,
                    &line,
                    &fields,
                    1,
                    format_args!(
                        "one node tag: tag {} of the {n} the block on line {} declares",
                        i + 1,
                        block.no
                    ),
                )?;
                tags.push((
                    line.no,
                    text::parse_i64(self.path, line.no, fields[0], "the node tag")?,
                ));
            }
            for (i, &(_, tag)) in tags.iter().enumerate() {
                let line = self.section_line("$EndNodes", block.no, n, i, "nodes in the block")?;
                let fields = line.fields(false);
                text::expect_fields(self.path, &line, &fields, per_line, "`<x> <y> <z>`")?;
                let p = self.coordinates(&line, &fields, tag)?;
                self.add_node(line.no, tag, p)?;
            }
            total = total.saturating_add(n);
        }
        if total != declared {
            return Err(MeshReadError::CountMismatch {
                path: self.path.to_owned(),
                line: header.no,
                what: "nodes",
                declared,
                found: total,
            });
        }
        self.expect_end("$EndNodes", header.no, blocks, "entity blocks")
    }

    /// Format 1: `<count>` then
    /// `<element number> <type> <physical region> <elementary region> <#nodes> <nodes...>` lines,
    /// up to `$ENDELM`. The node count is part of the line, so every element is checked to have
    /// as many node numbers as it says; a tetrahedron must say 4.
    fn elements_v1(&mut self) -> Result<(), MeshReadError> {
        const END: &str = "$ENDELM";
        const LAYOUT: &str =
            "`<element number> <type> <physical> <elementary> <#nodes> <node numbers...>`";
        let (header, h) = self.header(END, 1, "the number of elements")?;
        let declared = h[0];
        for i in 0..declared {
            let line = self.section_line(END, header.no, declared, i, "elements")?;
            let fields = line.fields(false);
            if fields.len() < 5 {
                return Err(self.parse_error(line.no, LAYOUT, text::quote(line.text)));
            }
            let tag = text::parse_i64(self.path, line.no, fields[0], "the element number")?;
            let kind = text::parse_i64(self.path, line.no, fields[1], "the element type")?;
            text::parse_i64(self.path, line.no, fields[2], "the physical region")?;
            text::parse_i64(self.path, line.no, fields[3], "the elementary region")?;
            let n = text::parse_count(self.path, line.no, fields[4], "the number of nodes")?;
            text::expect_fields(
                self.path,
                &line,
                &fields,
                n.saturating_add(5),
                format_args!("element {tag} says it has {n} nodes"),
            )?;
            if kind != TETRAHEDRON {
                self.skipped += 1;
                continue;
            }
            if n != 4 {
                return Err(self.parse_error(
                    line.no,
                    format!("4 nodes for element {tag} of type 4 (tetrahedron)"),
                    text::quote(fields[4]),
                ));
            }
            self.tet(&line, fields[0], &fields[5..])?;
        }
        self.expect_end(END, header.no, declared, "elements")
    }

    /// Format 2: `<count>` then `<tag> <type> <#tags> <tags...> <nodes...>` lines.
    fn elements_v2(&mut self) -> Result<(), MeshReadError> {
        const LAYOUT: &str = "`<element tag> <type> <#tags> <tags...> <node tags...>`";
        let (header, h) = self.header("$EndElements", 1, "the number of elements")?;
        let declared = h[0];
        for i in 0..declared {
            let line = self.section_line("$EndElements", header.no, declared, i, "elements")?;
            let fields = line.fields(false);
            if fields.len() < 3 {
                return Err(self.parse_error(line.no, LAYOUT, text::quote(line.text)));
            }
            let kind = text::parse_i64(self.path, line.no, fields[1], "the element type")?;
            if kind != TETRAHEDRON {
                text::parse_i64(self.path, line.no, fields[0], "the element tag")?;
                self.skipped += 1;
                continue;
            }
            let ntags = text::parse_count(self.path, line.no, fields[2], "the number of tags")?;
            let n = ntags.saturating_add(7);
            text::expect_fields(
                self.path,
                &line,
                &fields,
                n,
                "a tetrahedron: tag, type 4, #tags, tags, 4 nodes",
            )?;
            self.tet(&line, fields[0], &fields[3 + ntags..])?;
        }
        self.expect_end("$EndElements", header.no, declared, "elements")
    }

    /// Format 4.1: `<#blocks> <#elements> <min tag> <max tag>`, then per block
    /// `<entity dim> <entity tag> <element type> <#elements in block>` and one
    /// `<tag> <node tags...>` line per element.
    fn elements_v41(&mut self) -> Result<(), MeshReadError> {
        const HEADER: &str = "`<#entity blocks> <#elements> <min element tag> <max element tag>`";
        const BLOCK: &str = "`<entity dim> <entity tag> <element type> <#elements in block>`";
        let (header, h) = self.header("$EndElements", 4, HEADER)?;
        let (blocks, declared) = (h[0], h[1]);
        let mut total = 0usize;
        for k in 0..blocks {
            self.no_early_end("$EndElements", header.no, blocks, k)?;
            let line = self.data_line("$EndElements", BLOCK)?;
            let fields = line.fields(false);
            text::expect_fields(self.path, &line, &fields, 4, BLOCK)?;
            let kind = text::parse_i64(self.path, line.no, fields[2], "the element type")?;
            let n = text::parse_count(
                self.path,
                line.no,
                fields[3],
                "the number of elements in the block",
            )?;
            for i in 0..n {
                let el =
                    self.section_line("$EndElements", line.no, n, i, "elements in the block")?;
                let f = el.fields(false);
                if kind == TETRAHEDRON {
                    text::expect_fields(
                        self.path,
                        &el,
                        &f,
                        5,
                        "`<element tag> <n1> <n2> <n3> <n4>`",
                    )?;
                    self.tet(&el, f[0], &f[1..])?;
                } else {
                    self.skipped += 1;
                }
            }
            total = total.saturating_add(n);
        }
        if total != declared {
            return Err(MeshReadError::CountMismatch {
                path: self.path.to_owned(),
                line: header.no,
                what: "elements",
                declared,
                found: total,
            });
        }
        self.expect_end("$EndElements", header.no, blocks, "entity blocks")
    }

    /// Before entity block `k` of the `blocks` declared on `header_line`: the section's end (or
    /// the file's) there is a count mismatch that quotes the declaration.
    fn no_early_end(
        &self,
        end: &str,
        header_line: usize,
        blocks: usize,
        k: usize,
    ) -> Result<(), MeshReadError> {
        match self.lines.clone().next() {
            Some(line) if line.text != end => Ok(()),
            _ => Err(MeshReadError::CountMismatch {
                path: self.path.to_owned(),
                line: header_line,
                what: "entity blocks",
                declared: blocks,
                found: k,
            }),
        }
    }

    /// Record `i` of `declared` in a section: running into the end marker (or any other
    /// section marker, or the end of the file) early is a count mismatch.
    fn section_line(
        &mut self,
        end: &str,
        header_line: usize,
        declared: usize,
        i: usize,
        what: &'static str,
    ) -> Result<Line<'a>, MeshReadError> {
        match self.lines.next() {
            Some(line) if !line.text.starts_with('$') => Ok(line),
            Some(line) if line.text != end => {
                Err(self.parse_error(line.no, format!("`{end}`"), text::quote(line.text)))
            }
            _ => Err(MeshReadError::CountMismatch {
                path: self.path.to_owned(),
                line: header_line,
                what,
                declared,
                found: i,
            }),
        }
    }
}
