//! Legacy VTK binary files (`BINARY` on line 3): the section lines are text, the arrays after
//! them raw big-endian values, as the legacy format specifies.
//!
//! Read: `POINTS <n> <type>` (any numeric type; `float` and `double` in practice), the cell
//! lists `CELLS` / `POLYGONS` / `VERTICES` / `LINES` / `TRIANGLE_STRIPS` either in the classic
//! layout (`<n> <size>` then `size` `int`s: a count and the point ids for each cell) or in the
//! VTK 5.1 layout (`<#offsets> <#connectivity>`, then `OFFSETS <type>` and `CONNECTIVITY
//! <type>` arrays), `CELL_TYPES <n>` (`int`s). `FIELD` arrays and `METADATA` blocks are skipped;
//! reading stops at `POINT_DATA` / `CELL_DATA`. Every count is checked against the bytes left
//! in the file before anything is allocated for it.

use std::path::Path;

use super::vtk::{self, Dataset, Legacy};
use super::vtk_cells::{error_at, Cells, Loc, Scalar};
use super::MeshReadError;

/// Reads the body of a binary legacy file whose header (3 lines) says `BINARY`.
pub(super) fn read(path: &Path, bytes: &[u8]) -> Result<Legacy, MeshReadError> {
    let mut r = Cursor {
        path,
        bytes,
        pos: 0,
    };
    for _ in 0..3 {
        r.raw_line();
    }
    let Some((at, words)) = r.line()? else {
        return Err(r.error(bytes.len(), "`DATASET UNSTRUCTURED_GRID`", "end of file"));
    };
    let dataset = match words.as_slice() {
        [d, kind] if d.eq_ignore_ascii_case("DATASET") => vtk::dataset(path, kind)?,
        _ => {
            return Err(r.error(
                at,
                "`DATASET UNSTRUCTURED_GRID` or `DATASET POLYDATA`",
                quote_words(&words),
            ))
        }
    };
    let mut legacy = Legacy {
        dataset,
        points: Vec::new(),
        cells: Cells::default(),
        polys: Cells::default(),
    };
    let mut cells_at: Option<usize> = None;
    let mut types_at: Option<usize> = None;
    while let Some((at, words)) = r.line()? {
        let keyword = words[0].to_ascii_uppercase();
        match keyword.as_str() {
            "POINTS" => {
                let [_, n, kind] = words[..] else {
                    return Err(r.error(at, "`POINTS <n> <type>`", quote_words(&words)));
                };
                let n = r.count(at, n, "the number of points")?;
                let scalar = r.scalar(at, kind)?;
                legacy.points = r.points(n, scalar)?;
            }
            "CELLS" | "POLYGONS" | "VERTICES" | "LINES" | "TRIANGLE_STRIPS" => {
                let [_, n, size] = words[..] else {
                    return Err(r.error(
                        at,
                        format!("`{keyword} <n> <size>`"),
                        quote_words(&words),
                    ));
                };
                let n = r.count(at, n, "the number of cells")?;
                let size = r.count(at, size, "the size of the cell list")?;
                let list = r.cell_list(n, size)?;
                match keyword.as_str() {
                    "CELLS" => {
                        cells_at = Some(at);
                        legacy.cells = list;
                    }
                    "POLYGONS" => legacy.polys = list,
                    "TRIANGLE_STRIPS" if list.len() > 0 && dataset == Dataset::PolyData => {
                        return Err(r.error(
                            at,
                            "POLYGONS (triangle strips are not read; save the surface as \
                             triangles)",
                            format!("{} triangle strips", list.len()),
                        ))
                    }
                    _ => {} // points and lines are no part of a surface
                }
            }
            "CELL_TYPES" => {
                let [_, n] = words[..] else {
                    return Err(r.error(at, "`CELL_TYPES <n>`", quote_words(&words)));
                };
                let n = r.count(at, n, "the number of cell types")?;
                let cells = legacy.cells.len();
                if n != cells {
                    return Err(r.error(
                        at,
                        format!("as many cell types as CELLS declares ({cells})"),
                        format!("`{n}`"),
                    ));
                }
                let (start, raw) = r.array(n, Scalar::I32, "cell types")?;
                legacy.cells.types = ints(path, start, raw, Scalar::I32, "the type of cell")?;
                types_at = Some(at);
            }
            "METADATA" => r.skip_metadata(),
            "FIELD" => r.skip_field(at, &words)?,
            "POINT_DATA" | "CELL_DATA" => break,
            _ => {
                return Err(r.error(
                    at,
                    "a section keyword (POINTS, CELLS, CELL_TYPES, POLYGONS, POINT_DATA, \
                     CELL_DATA, FIELD)",
                    quote_words(&words),
                ))
            }
        }
    }
    if let (Some(at), None) = (cells_at, types_at) {
        return Err(r.error(
            at,
            "a `CELL_TYPES` section after `CELLS`",
            "end of file (or POINT_DATA / CELL_DATA) first",
        ));
    }
    Ok(legacy)
}

fn quote_words(words: &[&str]) -> String {
    super::text::quote(&words.join(" "))
}

/// `raw` as integers of type `scalar` (big-endian); `start` is its offset in the file.
fn ints(
    path: &Path,
    start: usize,
    raw: &[u8],
    scalar: Scalar,
    what: &str,
) -> Result<Vec<i64>, MeshReadError> {
    let size = scalar.size();
    raw.chunks_exact(size)
        .enumerate()
        .map(|(i, v)| {
            scalar.int(v, true).ok_or_else(|| {
                error_at(
                    path,
                    Loc::byte(start + i * size),
                    format!("an integer below 2^63 for {what} {i}"),
                    "a larger one",
                )
            })
        })
        .collect()
}

/// A byte cursor over a binary legacy file.
struct Cursor<'a> {
    path: &'a Path,
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Cursor<'a> {
    fn error(
        &self,
        at: usize,
        expected: impl Into<String>,
        found: impl Into<String>,
    ) -> MeshReadError {
        error_at(self.path, Loc::byte(at), expected, found)
    }

    /// The rest of the current line, up to and including its `\n`.
    fn raw_line(&mut self) -> &'a [u8] {
        let rest = self.bytes.get(self.pos..).unwrap_or(&[]);
        let len = rest
            .iter()
            .position(|&b| b == b'\n')
            .map_or(rest.len(), |i| i + 1);
        self.pos += len;
        &rest[..len]
    }

    /// The next non-blank text line: its offset and its words (`None` at the end of the
    /// file). After it, the cursor is at the first byte of the next line, where an array's
    /// data starts.
    fn line(&mut self) -> Result<Option<(usize, Vec<&'a str>)>, MeshReadError> {
        while self
            .bytes
            .get(self.pos)
            .is_some_and(|b| b.is_ascii_whitespace())
        {
            self.pos += 1;
        }
        if self.pos >= self.bytes.len() {
            return Ok(None);
        }
        let at = self.pos;
        let line = self.raw_line();
        match std::str::from_utf8(line) {
            Ok(text) if text.is_ascii() => Ok(Some((at, text.split_whitespace().collect()))),
            _ => Err(self.error(
                at,
                "a section line (`POINTS ...`, `CELLS ...`, ...) in text",
                format!(
                    "binary bytes {}",
                    super::text::quote(&String::from_utf8_lossy(&line[..line.len().min(16)]))
                ),
            )),
        }
    }

    fn count(&self, at: usize, token: &str, what: &str) -> Result<usize, MeshReadError> {
        token.parse::<usize>().map_err(|_| {
            self.error(
                at,
                format!("a non-negative integer for {what}"),
                super::text::quote(token),
            )
        })
    }

    fn scalar(&self, at: usize, token: &str) -> Result<Scalar, MeshReadError> {
        Scalar::from_legacy(token).ok_or_else(|| {
            self.error(
                at,
                "a numeric data type (float, double, int, vtktypeint64, ...)",
                super::text::quote(token),
            )
        })
    }

    /// The next `n` values of type `scalar`: the offset they start at and their bytes,
    /// refused before anything is read when the file does not hold them.
    fn array(
        &mut self,
        n: usize,
        scalar: Scalar,
        what: &str,
    ) -> Result<(usize, &'a [u8]), MeshReadError> {
        let left = self.bytes.len().saturating_sub(self.pos);
        let need = n.checked_mul(scalar.size()).filter(|&need| need <= left);
        let Some(need) = need else {
            return Err(self.error(
                self.pos,
                format!(
                    "{n} {what} of {} bytes each ({} bytes)",
                    scalar.size(),
                    (n as u128) * scalar.size() as u128
                ),
                format!("{left} bytes left in the file"),
            ));
        };
        let start = self.pos;
        self.pos += need;
        Ok((start, &self.bytes[start..start + need]))
    }

    fn points(&mut self, n: usize, scalar: Scalar) -> Result<Vec<[f64; 3]>, MeshReadError> {
        let values = n.saturating_mul(3);
        let (start, raw) = self.array(values, scalar, "point coordinates")?;
        let size = scalar.size();
        let mut points = Vec::with_capacity(n);
        for (i, point) in raw.chunks_exact(3 * size).enumerate() {
            let mut p = [0.0; 3];
            for (k, c) in p.iter_mut().enumerate() {
                let at = 3 * size * i + size * k;
                let v = scalar.real(&point[size * k..size * (k + 1)], true);
                if !v.is_finite() {
                    return Err(self.error(
                        start + at,
                        format!("a finite {} coordinate of point {i}", ["x", "y", "z"][k]),
                        format!("{v}"),
                    ));
                }
                *c = v;
            }
            points.push(p);
        }
        Ok(points)
    }

    /// A cell list with `n` cells and `size` numbers (classic) or `n` offsets and `size`
    /// connectivity entries (VTK 5.1, recognised by the `OFFSETS` line that follows).
    ///
    /// The classic list starts with binary data right after the section line, so the peek
    /// compares bytes and never reads them as a text line (which refuses binary bytes: issue
    /// 28). Binary data that spells `OFFSETS ` would be a first cell of 1,330,005,587 points
    /// (`0x4F464653`), which no file holds.
    fn cell_list(&mut self, n: usize, size: usize) -> Result<Cells, MeshReadError> {
        if self.at_keyword(b"OFFSETS") {
            let Some((at, words)) = self.line()? else {
                return Err(self.error(self.pos, "`OFFSETS <type>`", "end of file"));
            };
            self.cells_v51(at, &words, n, size)
        } else {
            self.cells_classic(n, size)
        }
    }

    /// Whether the next line is `keyword` followed by a space or tab, after blank lines and
    /// indentation; the cursor does not move.
    fn at_keyword(&self, keyword: &[u8]) -> bool {
        let rest = self.bytes.get(self.pos..).unwrap_or(&[]);
        let start = rest
            .iter()
            .position(|b| !b.is_ascii_whitespace())
            .unwrap_or(rest.len());
        let rest = &rest[start..];
        rest.len() > keyword.len()
            && rest[..keyword.len()].eq_ignore_ascii_case(keyword)
            && matches!(rest[keyword.len()], b' ' | b'\t')
    }

    /// `size` `int`s: for each of the `n` cells its point count, then its point ids.
    fn cells_classic(&mut self, n: usize, size: usize) -> Result<Cells, MeshReadError> {
        let (start, raw) = self.array(size, Scalar::I32, "numbers in the cell list")?;
        let numbers = ints(self.path, start, raw, Scalar::I32, "number")?;
        let mut cells = Cells {
            offsets: Vec::with_capacity(n.min(size) + 1),
            conn: Vec::with_capacity(size),
            types: Vec::new(),
            locs: Vec::with_capacity(n.min(size)),
        };
        cells.offsets.push(0);
        let mut i = 0usize;
        for c in 0..n {
            let at = start + 4 * i;
            let Some(&k) = numbers.get(i) else {
                return Err(self.error(
                    at,
                    format!("the point count of cell {c} (the list declares {n} cells)"),
                    format!("the end of the {size} numbers of the list"),
                ));
            };
            let ids = usize::try_from(k)
                .ok()
                .and_then(|k| numbers.get(i + 1..i + 1 + k));
            let Some(ids) = ids else {
                return Err(self.error(
                    at,
                    format!(
                        "a point count for cell {c} that fits the list's {} numbers left",
                        size - i - 1
                    ),
                    format!("`{k}`"),
                ));
            };
            cells.conn.extend_from_slice(ids);
            cells.offsets.push(cells.conn.len());
            cells.locs.push(Loc::byte(at));
            i += 1 + ids.len();
        }
        if i != size {
            return Err(self.error(
                start + 4 * i,
                format!("the end of the cell list after {n} cells"),
                format!("{} more numbers", size - i),
            ));
        }
        Ok(cells)
    }

    /// `OFFSETS <type>` with `n` offsets, then `CONNECTIVITY <type>` with `size` point ids.
    fn cells_v51(
        &mut self,
        at: usize,
        words: &[&str],
        n: usize,
        size: usize,
    ) -> Result<Cells, MeshReadError> {
        let [_, kind] = words[..] else {
            return Err(self.error(at, "`OFFSETS <type>`", quote_words(words)));
        };
        let scalar = self.int_type(at, kind)?;
        let (start, raw) = self.array(n, scalar, "offsets")?;
        let offsets = ints(self.path, start, raw, scalar, "offset")?;
        let mut checked = Vec::with_capacity(n);
        for (i, &o) in offsets.iter().enumerate() {
            let prev = checked.last().copied().unwrap_or(0);
            let ok = usize::try_from(o)
                .ok()
                .filter(|&o| o >= prev && (i > 0 || o == 0) && o <= size);
            let Some(o) = ok else {
                return Err(self.error(
                    start + i * scalar.size(),
                    format!(
                        "offset {i} to be 0 for the first cell, non-decreasing and at most {size}"
                    ),
                    format!("`{o}`"),
                ));
            };
            checked.push(o);
        }
        if let Some(&last) = checked.last() {
            if last != size {
                return Err(self.error(
                    start + (n - 1) * scalar.size(),
                    format!("the last offset to equal the connectivity size {size}"),
                    format!("`{last}`"),
                ));
            }
        }
        let Some((at, words)) = self.line()? else {
            return Err(self.error(self.pos, "`CONNECTIVITY <type>`", "end of file"));
        };
        let [c, kind] = words[..] else {
            return Err(self.error(at, "`CONNECTIVITY <type>`", quote_words(&words)));
        };
        if !c.eq_ignore_ascii_case("CONNECTIVITY") {
            return Err(self.error(at, "`CONNECTIVITY <type>`", quote_words(&words)));
        }
        let scalar = self.int_type(at, kind)?;
        let (conn_start, raw) = self.array(size, scalar, "connectivity entries")?;
        let conn = ints(self.path, conn_start, raw, scalar, "connectivity entry")?;
        if checked.is_empty() {
            checked.push(0);
        }
        let locs = checked
            .iter()
            .take(checked.len() - 1)
            .map(|&o| Loc::byte(conn_start + o * scalar.size()))
            .collect();
        Ok(Cells {
            offsets: checked,
            conn,
            types: Vec::new(),
            locs,
        })
    }

    fn int_type(&self, at: usize, token: &str) -> Result<Scalar, MeshReadError> {
        match Scalar::from_legacy(token) {
            Some(s) if s.is_integer() => Ok(s),
            _ => Err(self.error(
                at,
                "an integer data type (vtktypeint64, vtktypeint32, int, ...)",
                super::text::quote(token),
            )),
        }
    }

    /// Skips a `METADATA` block: text lines up to the next blank line.
    fn skip_metadata(&mut self) {
        while self.pos < self.bytes.len() {
            if self.raw_line().iter().all(u8::is_ascii_whitespace) {
                break;
            }
        }
    }

    /// `FIELD <name> <#arrays>`, each array `<name> <#components> <#tuples> <type>` and its
    /// values (and possibly a METADATA block): skipped.
    fn skip_field(&mut self, at: usize, words: &[&str]) -> Result<(), MeshReadError> {
        let [_, _, arrays] = words[..] else {
            return Err(self.error(at, "`FIELD <name> <#arrays>`", quote_words(words)));
        };
        let arrays = self.count(at, arrays, "the number of field arrays")?;
        let mut a = 0;
        while a < arrays {
            let Some((at, words)) = self.line()? else {
                return Err(self.error(self.pos, "a field array", "end of file"));
            };
            if words[0].eq_ignore_ascii_case("METADATA") {
                self.skip_metadata();
                continue;
            }
            let [_, comps, tuples, kind] = words[..] else {
                return Err(self.error(
                    at,
                    "`<name> <#components> <#tuples> <type>`",
                    quote_words(&words),
                ));
            };
            let comps = self.count(at, comps, "the number of components")?;
            let tuples = self.count(at, tuples, "the number of tuples")?;
            let scalar = self.scalar(at, kind)?;
            self.array(comps.saturating_mul(tuples), scalar, "field array values")?;
            a += 1;
        }
        Ok(())
    }
}
