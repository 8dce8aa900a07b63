//! Stage one of loading: TOML text → raw structs, with errors that carry file, line, column and
//! key path; plus the key paths and the position lookup that stage two (validation) uses.

use std::fmt;
use std::path::Path;

use serde::de::DeserializeOwned;
use toml_edit::{ImDocument, Item};

use crate::error::{ConfigError, Location};

/// One step of a key path.
#[derive(Debug, Clone, PartialEq, Eq)]
enum Seg {
    Key(String),
    Index(usize),
}

/// A key path such as `body[2].fem.young`, as printed in error messages.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub(crate) struct KeyPath(Vec<Seg>);

impl KeyPath {
    /// The path of a top-level key.
    pub(crate) fn top(key: &str) -> Self {
        KeyPath(vec![Seg::Key(key.to_owned())])
    }

    /// `self.key`.
    pub(crate) fn key(&self, key: &str) -> Self {
        let mut segs = self.0.clone();
        segs.push(Seg::Key(key.to_owned()));
        KeyPath(segs)
    }

    /// `self[index]`.
    pub(crate) fn index(&self, index: usize) -> Self {
        let mut segs = self.0.clone();
        segs.push(Seg::Index(index));
        KeyPath(segs)
    }
}

impl fmt::Display for KeyPath {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.0.is_empty() {
            return f.write_str("(top level)");
        }
        for (i, seg) in self.0.iter().enumerate() {
            match seg {
                Seg::Key(k) if i == 0 => write!(f, "{k}")?,
                Seg::Key(k) => write!(f, ".{k}")?,
                Seg::Index(n) => write!(f, "[{n}]")?,
            }
        }
        Ok(())
    }
}

/// Reads `file` as UTF-8 text. Text that is not UTF-8 is a [`ConfigError::Syntax`] at the line
/// and column of the first bad byte, naming its offset and value (not an I/O error that says
/// neither).
pub(crate) fn read_text(file: &Path) -> Result<String, ConfigError> {
    let bytes = std::fs::read(file).map_err(|source| ConfigError::Read {
        file: file.to_path_buf(),
        source,
    })?;
    String::from_utf8(bytes).map_err(|e| {
        let valid = e.utf8_error().valid_up_to();
        let bytes = e.as_bytes();
        // The valid prefix is text: count lines and columns in it.
        let prefix = std::str::from_utf8(&bytes[..valid]).unwrap_or_default();
        let bad = bytes.get(valid).copied().unwrap_or(0);
        let at = Location::at_offset(file, prefix, valid);
        let (line, column) = (at.line.unwrap_or(1), at.column.unwrap_or(1));
        ConfigError::Syntax {
            at: Box::new(at),
            detail: format!(
                "line {line}, column {column}: not UTF-8 text: byte {valid} is 0x{bad:02x}"
            ),
        }
    })
}

/// A parsed TOML file: its name, its text and a span-keeping document of it.
pub(crate) struct Source<'a> {
    pub(crate) file: &'a Path,
    text: &'a str,
    doc: ImDocument<&'a str>,
}

impl<'a> Source<'a> {
    /// Parses `text` (read from `file`); a syntax error keeps toml's line, column and snippet.
    pub(crate) fn parse(file: &'a Path, text: &'a str) -> Result<Self, ConfigError> {
        match ImDocument::parse(text) {
            Ok(doc) => Ok(Source { file, text, doc }),
            Err(e) => {
                let at = match e.span() {
                    Some(span) => Location::at_offset(file, text, span.start),
                    None => Location::file(file),
                };
                Err(ConfigError::Syntax {
                    at: Box::new(at),
                    detail: e.to_string().trim_end().to_owned(),
                })
            }
        }
    }

    /// Deserializes the raw structs. Unknown keys, missing keys, wrong types and unknown enum
    /// strings become [`ConfigError::Schema`] naming the key path and the position.
    pub(crate) fn deserialize<T: DeserializeOwned>(&self) -> Result<T, ConfigError> {
        let de = toml::Deserializer::new(self.text);
        serde_path_to_error::deserialize(de).map_err(|e| {
            let key = e.path().to_string();
            let inner = e.into_inner();
            let at = match inner.span() {
                Some(span) => Location::at_offset(self.file, self.text, span.start),
                None => Location::file(self.file),
            };
            ConfigError::Schema {
                at: Box::new(at),
                key: if key == "." {
                    "(top level)".to_owned()
                } else {
                    key
                },
                message: inner.message().trim_end().to_owned(),
            }
        })
    }

    /// The top-level keys the file gives, in file order.
    pub(crate) fn top_keys(&self) -> Vec<String> {
        self.doc
            .as_table()
            .iter()
            .map(|(k, _)| k.to_owned())
            .collect()
    }

    /// Where `key` is in the file: the position of its value if it is present, else of the
    /// deepest enclosing table that is, else just the file.
    pub(crate) fn locate(&self, key: &KeyPath) -> Location {
        let mut item: &Item = self.doc.as_item();
        let mut best = None;
        for seg in &key.0 {
            let next = match seg {
                Seg::Key(k) => item.get(k.as_str()),
                Seg::Index(i) => item.get(*i),
            };
            match next {
                Some(next) => {
                    item = next;
                    if let Some(span) = item.span() {
                        best = Some(span.start);
                    }
                }
                None => break,
            }
        }
        match best {
            Some(offset) => Location::at_offset(self.file, self.text, offset),
            None => Location::file(self.file),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn key_paths_print_like_toml_accessors() {
        let k = KeyPath::top("body").index(2).key("fem").key("young");
        assert_eq!(k.to_string(), "body[2].fem.young");
        assert_eq!(KeyPath::default().to_string(), "(top level)");
    }

    #[test]
    fn locate_finds_values_in_arrays_of_tables() {
        let text = "[[body]]\nname = \"a\"\n\n[[body]]\nname = \"b\"\n[body.fem]\nyoung = 5\n";
        let file = Path::new("t.toml");
        let src = Source::parse(file, text).unwrap();
        let young = KeyPath::top("body").index(1).key("fem").key("young");
        assert_eq!(src.locate(&young).line, Some(7));
        // Missing key: falls back to the enclosing table's header.
        let poisson = KeyPath::top("body").index(1).key("fem").key("poisson");
        assert_eq!(src.locate(&poisson).line, Some(6));
        assert_eq!(src.locate(&KeyPath::top("nothing")).line, None);
    }
}
