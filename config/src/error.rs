//! The one error type of this crate.

use std::fmt;
use std::path::{Path, PathBuf};

/// Where in a file an error was found: `file:line:column`, or just `file` when the position is
/// unknown (a key that has a default and is absent from the file, say).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Location {
    /// The file the text came from.
    pub file: PathBuf,
    /// 1-based line, when known.
    pub line: Option<usize>,
    /// 1-based column (in characters), when known.
    pub column: Option<usize>,
}

impl Location {
    /// A location that names only the file.
    pub fn file(file: &Path) -> Self {
        Location {
            file: file.to_path_buf(),
            line: None,
            column: None,
        }
    }

    /// The location of byte `offset` of `text`, which was read from `file`.
    pub(crate) fn at_offset(file: &Path, text: &str, offset: usize) -> Self {
        let (line, column) = line_column(text, offset);
        Location {
            file: file.to_path_buf(),
            line: Some(line),
            column: Some(column),
        }
    }
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file.display())?;
        if let Some(line) = self.line {
            write!(f, ":{line}")?;
            if let Some(column) = self.column {
                write!(f, ":{column}")?;
            }
        }
        Ok(())
    }
}

/// 1-based line and column (in characters) of byte `offset` in `text`. Never panics: an offset
/// past the end or inside a character is clamped.
pub(crate) fn line_column(text: &str, offset: usize) -> (usize, usize) {
    let mut offset = offset.min(text.len());
    while !text.is_char_boundary(offset) {
        offset -= 1;
    }
    let before = &text[..offset];
    let line = before.matches('\n').count() + 1;
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    let column = before[line_start..].chars().count() + 1;
    (line, column)
}

/// Everything that can go wrong while finding, reading or validating a scene, a daemon config or
/// a mock script path.
///
/// Positions are boxed to keep `Result<_, ConfigError>` small.
///
/// Each variant's message names the file, the key path (`body[2].fem.young`) and the offending
/// value where there is one, so a user can fix the file from the message alone.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ConfigError {
    /// The file could not be read (missing, unreadable). Text that is not UTF-8 is a
    /// [`ConfigError::Syntax`] at the first bad byte.
    #[error("{}: cannot read file: {source}", file.display())]
    Read {
        /// The file.
        file: PathBuf,
        /// The underlying I/O error.
        #[source]
        source: std::io::Error,
    },

    /// The text is not valid TOML (or not UTF-8). `detail` is toml's own report (line, column, a
    /// snippet of the offending line and what was expected), or the offset and value of the first
    /// byte that is not UTF-8.
    #[error("{}: invalid TOML: {detail}", at.file.display())]
    Syntax {
        /// File, line and column of the error.
        at: Box<Location>,
        /// toml's report, starting with `TOML parse error at line L, column C`.
        detail: String,
    },

    /// Valid TOML whose shape does not match the schema: an unknown key, a missing key, a value of
    /// the wrong type or an unknown enum string.
    #[error("{at}: {key}: {message}")]
    Schema {
        /// File, line and column of the error.
        at: Box<Location>,
        /// Key path, e.g. `body[0].fem.young`; `(top level)` for the document itself.
        key: String,
        /// What is wrong, including the offending key or value.
        message: String,
    },

    /// A value of the right type that is out of range or inconsistent with the rest of the file.
    #[error("{at}: {key} = {value}{}: {reason}", body_suffix(body))]
    Invalid {
        /// File, line and column of the offending value (or of the table that lacks a key).
        at: Box<Location>,
        /// Key path, e.g. `body[2].fem.young`.
        key: String,
        /// Name of the body the key belongs to, when it belongs to one.
        body: Option<String>,
        /// The offending value as written in TOML (`-5`, `NaN`, `"liver"`, `(missing)`).
        value: String,
        /// What the value must be.
        reason: String,
    },

    /// A body's mesh file does not exist.
    #[error(
        "{at}: {key} = {given:?}{}: mesh not found: tried {}",
        body_suffix(body),
        list_paths(tried)
    )]
    MeshNotFound {
        /// Location of the `mesh` key.
        at: Box<Location>,
        /// Key path, e.g. `body[1].mesh`.
        key: String,
        /// Name of the body.
        body: Option<String>,
        /// The path as written in the scene file.
        given: String,
        /// The resolved paths that were tried.
        tried: Vec<PathBuf>,
    },

    /// A scene or mock script given as a path does not exist.
    #[error("{what} {} not found", path.display())]
    NoSuchFile {
        /// `"scene file"` or `"mock script"`.
        what: &'static str,
        /// The path that was given.
        path: PathBuf,
    },

    /// A scene or mock script given by name is in none of the search directories.
    #[error(
        "{what} {name:?} not found; searched {}; available: {}",
        list_paths(searched),
        list_names(available)
    )]
    UnknownName {
        /// `"scene"` or `"mock script"`.
        what: &'static str,
        /// The name that was given.
        name: String,
        /// The directories searched, in order.
        searched: Vec<PathBuf>,
        /// Names that would have been found.
        available: Vec<String>,
    },
}

impl ConfigError {
    /// The file the error is about, if it is about one file.
    pub fn file(&self) -> Option<&Path> {
        match self {
            ConfigError::Read { file, .. } => Some(file),
            ConfigError::Syntax { at, .. }
            | ConfigError::Schema { at, .. }
            | ConfigError::Invalid { at, .. }
            | ConfigError::MeshNotFound { at, .. } => Some(&at.file),
            ConfigError::NoSuchFile { path, .. } => Some(path),
            ConfigError::UnknownName { .. } => None,
        }
    }

    /// The key path the error is about (`body[2].fem.young`), if any.
    pub fn key(&self) -> Option<&str> {
        match self {
            ConfigError::Schema { key, .. }
            | ConfigError::Invalid { key, .. }
            | ConfigError::MeshNotFound { key, .. } => Some(key),
            _ => None,
        }
    }

    /// The line the error is on (1-based), if known.
    pub fn line(&self) -> Option<usize> {
        match self {
            ConfigError::Syntax { at, .. }
            | ConfigError::Schema { at, .. }
            | ConfigError::Invalid { at, .. }
            | ConfigError::MeshNotFound { at, .. } => at.line,
            _ => None,
        }
    }
}

fn body_suffix(body: &Option<String>) -> String {
    match body {
        Some(name) => format!(" (body {name:?})"),
        None => String::new(),
    }
}

fn list_paths(paths: &[PathBuf]) -> String {
    if paths.is_empty() {
        return "nothing".to_owned();
    }
    paths
        .iter()
        .map(|p| p.display().to_string())
        .collect::<Vec<_>>()
        .join(", ")
}

fn list_names(names: &[String]) -> String {
    if names.is_empty() {
        "none".to_owned()
    } else {
        names.join(", ")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn line_column_is_one_based_and_clamped() {
        let text = "a = 1\nbé = 2\n";
        assert_eq!(line_column(text, 0), (1, 1));
        assert_eq!(line_column(text, 6), (2, 1));
        // 'é' is two bytes: the '=' after "bé " is the 4th character of line 2.
        assert_eq!(line_column(text, 10), (2, 4));
        // Inside a multi-byte character, and past the end: no panic.
        assert_eq!(line_column(text, 8), (2, 2));
        assert_eq!(line_column(text, 1000), (3, 1));
    }
}
