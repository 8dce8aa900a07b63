//! Small helpers shared by the text readers: reading a file, walking data lines with their
//! numbers, parsing tokens into numbers with precise errors.

use std::fmt::Display;
use std::path::{Path, PathBuf};

use super::MeshReadError;

/// Reads a whole file as UTF-8 text (a leading byte-order mark is dropped).
pub(crate) fn read_text(path: &Path) -> Result<String, MeshReadError> {
    let bytes = std::fs::read(path).map_err(|source| MeshReadError::Io {
        path: path.to_owned(),
        source,
    })?;
    bytes_to_text(path, bytes)
}

/// Like [`read_text`], but a missing file is `Ok(None)`.
pub(crate) fn read_optional_text(path: &Path) -> Result<Option<String>, MeshReadError> {
    match std::fs::read(path) {
        Ok(bytes) => bytes_to_text(path, bytes).map(Some),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(source) => Err(MeshReadError::Io {
            path: path.to_owned(),
            source,
        }),
    }
}

pub(crate) fn bytes_to_text(path: &Path, bytes: Vec<u8>) -> Result<String, MeshReadError> {
    match String::from_utf8(bytes) {
        Ok(mut text) => {
            if text.starts_with('\u{feff}') {
                text.drain(..'\u{feff}'.len_utf8());
            }
            Ok(text)
        }
        Err(e) => {
            let valid = e.utf8_error().valid_up_to();
            let bytes = e.as_bytes();
            let line = 1 + bytes.iter().take(valid).filter(|&&b| b == b'\n').count();
            let bad = bytes.get(valid).copied().unwrap_or(0);
            Err(MeshReadError::Parse {
                path: path.to_owned(),
                line,
                expected: "UTF-8 text".to_owned(),
                found: format!("the byte 0x{bad:02x} (is this a binary file?)"),
            })
        }
    }
}

/// The first non-blank line of a file, trimmed (a byte-order mark dropped, invalid UTF-8
/// replaced), looked at in the first 4 KiB only: enough to recognise a format without reading a
/// large file twice. Empty if the file is blank there.
pub(crate) fn first_line(path: &Path) -> Result<String, MeshReadError> {
    use std::io::Read as _;
    let io = |source| MeshReadError::Io {
        path: path.to_owned(),
        source,
    };
    let mut head = Vec::with_capacity(4096);
    std::fs::File::open(path)
        .map_err(io)?
        .take(4096)
        .read_to_end(&mut head)
        .map_err(io)?;
    let head = String::from_utf8_lossy(&head);
    let head = head.strip_prefix('\u{feff}').unwrap_or(&head);
    Ok(head
        .lines()
        .map(str::trim)
        .find(|l| !l.is_empty())
        .unwrap_or("")
        .to_owned())
}

/// `base` with `.ext` appended (not replacing an existing extension: `liver.v2` -> `liver.v2.node`).
pub(crate) fn with_suffix(base: &Path, ext: &str) -> PathBuf {
    let mut s = base.as_os_str().to_owned();
    s.push(".");
    s.push(ext);
    PathBuf::from(s)
}

/// The lower-cased extension of a path, if any.
pub(crate) fn extension(path: &Path) -> Option<String> {
    path.extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
}

/// One non-blank data line: its 1-based number and its text with any comment removed.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Line<'a> {
    pub no: usize,
    pub text: &'a str,
}

impl<'a> Line<'a> {
    /// Fields separated by whitespace (and, for TetGen, commas).
    pub fn fields(&self, commas: bool) -> Vec<&'a str> {
        if commas {
            self.text
                .split(|c: char| c.is_whitespace() || c == ',')
                .filter(|t| !t.is_empty())
                .collect()
        } else {
            self.text.split_whitespace().collect()
        }
    }
}

/// Iterates over the data lines of a text: blank lines (and, if enabled, `#` comments) are
/// skipped.
#[derive(Clone)]
pub(crate) struct DataLines<'a> {
    lines: std::iter::Enumerate<std::str::Lines<'a>>,
    hash_comments: bool,
    /// Number of the last line handed out or skipped (for end-of-file messages).
    last: usize,
}

impl<'a> DataLines<'a> {
    pub fn new(text: &'a str, hash_comments: bool) -> Self {
        Self {
            lines: text.lines().enumerate(),
            hash_comments,
            last: 0,
        }
    }

    /// The line number to blame for an unexpected end of file (at least 1).
    pub fn eof_line(&self) -> usize {
        self.last.max(1)
    }

    /// Counts the data lines that are left.
    pub fn count_rest(&mut self) -> usize {
        let mut n = 0;
        while self.next().is_some() {
            n += 1;
        }
        n
    }
}

impl<'a> Iterator for DataLines<'a> {
    type Item = Line<'a>;

    fn next(&mut self) -> Option<Line<'a>> {
        for (i, raw) in self.lines.by_ref() {
            self.last = i + 1;
            let text = if self.hash_comments {
                raw.split('#').next().unwrap_or("")
            } else {
                raw
            };
            let text = text.trim();
            if !text.is_empty() {
                return Some(Line { no: i + 1, text });
            }
        }
        None
    }
}

/// A token quoted for a message; invisible characters are shown escaped.
pub(crate) fn quote(token: &str) -> String {
    const MAX: usize = 80;
    let mut out = String::from("`");
    for (i, c) in token.chars().enumerate() {
        if i == MAX {
            out.push_str("...");
            break;
        }
        if c.is_control() || c == '\u{feff}' || (c.is_whitespace() && c != ' ') {
            out.extend(c.escape_unicode());
        } else {
            out.push(c);
        }
    }
    out.push('`');
    out
}

pub(crate) fn parse_error(
    path: &Path,
    line: usize,
    expected: impl Into<String>,
    found: impl Into<String>,
) -> MeshReadError {
    MeshReadError::Parse {
        path: path.to_owned(),
        line,
        expected: expected.into(),
        found: found.into(),
    }
}

pub(crate) fn eof_error(path: &Path, line: usize, expected: impl Into<String>) -> MeshReadError {
    parse_error(path, line, expected, "end of file")
}

/// Parses a real number (`nan` and `inf` parse, the caller checks finiteness).
pub(crate) fn parse_f64(
    path: &Path,
    line: usize,
    token: &str,
    what: impl Display,
) -> Result<f64, MeshReadError> {
    token
        .parse::<f64>()
        .map_err(|_| parse_error(path, line, format!("a number for {what}"), quote(token)))
}

/// Parses an integer (a node number, a tag, a type code).
pub(crate) fn parse_i64(
    path: &Path,
    line: usize,
    token: &str,
    what: impl Display,
) -> Result<i64, MeshReadError> {
    token
        .parse::<i64>()
        .map_err(|_| parse_error(path, line, format!("an integer for {what}"), quote(token)))
}

/// Parses a count (a non-negative integer).
pub(crate) fn parse_count(
    path: &Path,
    line: usize,
    token: &str,
    what: impl Display,
) -> Result<usize, MeshReadError> {
    token.parse::<usize>().map_err(|_| {
        parse_error(
            path,
            line,
            format!("a non-negative integer for {what}"),
            quote(token),
        )
    })
}

/// Checks that a line has exactly `n` fields.
pub(crate) fn expect_fields(
    path: &Path,
    line: &Line<'_>,
    fields: &[&str],
    n: usize,
    what: impl Display,
) -> Result<(), MeshReadError> {
    if fields.len() == n {
        Ok(())
    } else {
        Err(parse_error(
            path,
            line.no,
            format!("{} ({what})", plural(n, "field")),
            format!("{}: {}", plural(fields.len(), "field"), quote(line.text)),
        ))
    }
}

/// `1 field`, `2 fields`.
pub(crate) fn plural(n: usize, noun: &str) -> String {
    if n == 1 {
        format!("1 {noun}")
    } else {
        format!("{n} {noun}s")
    }
}

/// A capacity hint that cannot be abused by a bogus header.
pub(crate) fn capacity(declared: usize) -> usize {
    declared.min(1 << 16)
}

/// Like [`capacity`], and no more records than a file of `file_bytes` bytes can hold if each
/// takes at least `min_record_bytes`: a header claiming 10^12 records in a small file reserves
/// what the file could hold, not 65,536 records.
pub(crate) fn capacity_within(
    declared: usize,
    file_bytes: usize,
    min_record_bytes: usize,
) -> usize {
    capacity(declared).min(file_bytes / min_record_bytes.max(1) + 1)
}

/// Reads exactly `declared` records with `record`, then checks that no data lines are left.
/// `header_line` is the line with the declaration (for [`MeshReadError::CountMismatch`]).
pub(crate) fn read_records<'a>(
    path: &Path,
    lines: &mut DataLines<'a>,
    header_line: usize,
    declared: usize,
    what: &'static str,
    mut record: impl FnMut(usize, Line<'a>) -> Result<(), MeshReadError>,
) -> Result<(), MeshReadError> {
    for i in 0..declared {
        let Some(line) = lines.next() else {
            return Err(MeshReadError::CountMismatch {
                path: path.to_owned(),
                line: header_line,
                what,
                declared,
                found: i,
            });
        };
        record(i, line)?;
    }
    let extra = lines.count_rest();
    if extra > 0 {
        return Err(MeshReadError::CountMismatch {
            path: path.to_owned(),
            line: header_line,
            what,
            declared,
            found: declared.saturating_add(extra),
        });
    }
    Ok(())
}
