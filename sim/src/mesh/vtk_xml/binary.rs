//! Binary and appended `DataArray`s of a VTK XML file: where the bytes are (base64 in the
//! text, raw or base64 appended data), their header words and their zlib blocks, every size
//! checked against the bytes in the file before anything is allocated (see the
//! [module docs](super)).

use std::borrow::Cow;
use std::io::Read as _;
use std::path::Path;

use base64::engine::{DecodePaddingMode, GeneralPurpose, GeneralPurposeConfig};
use base64::Engine as _;
use roxmltree::Node;

use super::super::text;
use super::super::vtk_cells::{error_at, Loc, Scalar};
use super::super::MeshReadError;
use super::{Binary, File, Layout};

/// Standard base64; padding optional, as some writers drop it.
const BASE64: GeneralPurpose = GeneralPurpose::new(
    &base64::alphabet::STANDARD,
    GeneralPurposeConfig::new()
        .with_decode_padding_mode(DecodePaddingMode::Indifferent)
        .with_decode_allow_trailing_bits(true),
);

/// Deflate expands at most 1032:1; the slack covers tiny blocks.
const MAX_ZLIB_RATIO: usize = 1032;
const ZLIB_SLACK: usize = 64;

impl<'a> File<'a, '_> {
    /// The decoded bytes of a `binary` or `appended` `DataArray` that must hold `count`
    /// values of `scalar`.
    pub(super) fn binary(
        &self,
        da: Node<'_, '_>,
        scalar: Scalar,
        count: usize,
        what: &str,
    ) -> Result<Binary<'a>, MeshReadError> {
        let Some(need) = count.checked_mul(scalar.size()) else {
            return Err(text::parse_error(
                self.path,
                self.line(da),
                format!("a count that fits in memory for {} ({what})", self.name(da)),
                format!("{count} values"),
            ));
        };
        let framing = Framing {
            path: self.path,
            layout: self.layout,
            need,
            what: format!("{count} values of {} ({what}, {need} bytes)", self.name(da)),
        };
        if self.format(da)? == "binary" {
            let loc = self.at(da);
            let clean: Vec<u8> = da
                .text()
                .unwrap_or("")
                .bytes()
                .filter(|b| !b.is_ascii_whitespace())
                .collect();
            let data = framing.base64(&clean, loc, true)?;
            return Ok(Binary {
                data: Cow::Owned(data),
                loc,
            });
        }
        let Some(app) = self.appended else {
            return Err(text::parse_error(
                self.path,
                self.line(da),
                "an <AppendedData> element for a DataArray with format=\"appended\"",
                "none",
            ));
        };
        let offset = self.count(da, "offset")?;
        let region = &self.bytes[app.start..app.end];
        let at = app.start.saturating_add(offset);
        let Some(rest) = region.get(offset..) else {
            return Err(text::parse_error(
                self.path,
                self.line(da),
                format!(
                    "an `offset` within the {} bytes of appended data",
                    region.len()
                ),
                format!("`{offset}`"),
            ));
        };
        let loc = Loc::byte(at);
        if self.appended_base64 {
            let clean: Vec<u8> = rest
                .iter()
                .copied()
                .filter(|b| !b.is_ascii_whitespace())
                .collect();
            let data = framing.base64(&clean, loc, false)?;
            Ok(Binary {
                data: Cow::Owned(data),
                loc,
            })
        } else {
            let data = framing.raw(rest, at)?;
            Ok(Binary { data, loc })
        }
    }
}

/// Reading one binary array: its header, then its data (decompressed if need be).
struct Framing<'p> {
    path: &'p Path,
    layout: Layout,
    /// The byte count the array must have.
    need: usize,
    /// The array, for messages.
    what: String,
}

impl Framing<'_> {
    fn error(
        &self,
        loc: Loc,
        expected: impl Into<String>,
        found: impl Into<String>,
    ) -> MeshReadError {
        error_at(self.path, loc, expected, found)
    }

    fn word(&self, raw: &[u8]) -> usize {
        let v = self
            .layout
            .header
            .int(raw, self.layout.big)
            .unwrap_or(i64::MAX);
        usize::try_from(v).unwrap_or(usize::MAX)
    }

    fn words(&self, raw: &[u8]) -> Vec<usize> {
        raw.chunks_exact(self.layout.header.size())
            .map(|w| self.word(w))
            .collect()
    }

    /// Checks the uncompressed size a header declares against the size the array must have.
    fn check_size(&self, loc: Loc, declared: usize) -> Result<(), MeshReadError> {
        if declared != self.need {
            return Err(self.error(
                loc,
                format!("a binary header declaring {}", self.what),
                format!("{declared} bytes declared"),
            ));
        }
        Ok(())
    }

    /// Raw appended data at file offset `at`: `rest` runs from there to `</AppendedData>`.
    fn raw<'b>(&self, rest: &'b [u8], at: usize) -> Result<Cow<'b, [u8]>, MeshReadError> {
        let h = self.layout.header.size();
        let short = |what: &str, need: usize| {
            self.error(
                Loc::byte(at),
                format!("{what} ({need} bytes) for {}", self.what),
                format!("{} bytes of appended data left", rest.len()),
            )
        };
        if !self.layout.zlib {
            let Some(head) = rest.get(..h) else {
                return Err(short("a header", h));
            };
            let size = self.word(head);
            self.check_size(Loc::byte(at), size)?;
            return match rest.get(h..h + size) {
                Some(data) => Ok(Cow::Borrowed(data)),
                None => Err(short("the data", size)),
            };
        }
        let Some(first) = rest.get(..3 * h) else {
            return Err(short("a compression header", 3 * h));
        };
        let nblocks = self.word(first);
        let hb = nblocks
            .checked_add(3)
            .and_then(|n| n.checked_mul(h))
            .filter(|&hb| hb <= rest.len());
        let Some(hb) = hb else {
            return Err(short(
                &format!("a compression header of {nblocks} blocks"),
                nblocks.saturating_add(3).saturating_mul(h),
            ));
        };
        let header = self.words(&rest[..hb]);
        let compressed: usize = header[3..].iter().fold(0usize, |a, &c| a.saturating_add(c));
        let Some(data) = rest.get(hb..hb.saturating_add(compressed)) else {
            return Err(short("compressed blocks", compressed));
        };
        let data = self.inflate(&header, data, Loc::byte(at))?;
        Ok(Cow::Owned(data))
    }

    /// Base64 text (whitespace removed) starting with this array. `whole`: the text is the
    /// array's alone (inline data), so nothing may follow it.
    fn base64(&self, text: &[u8], loc: Loc, whole: bool) -> Result<Vec<u8>, MeshReadError> {
        let h = self.layout.header.size();
        let chars = |bytes: usize| bytes.div_ceil(3).saturating_mul(4);
        let short = |what: &str, need: usize| {
            self.error(
                loc,
                format!("{what} ({need} base64 characters) for {}", self.what),
                format!("{} characters", text.len()),
            )
        };
        // A header encoded apart from the data ends in padding (`=`) unless its size is a
        // multiple of 3; one encoded with the data does not.
        let apart = |header_bytes: usize| {
            header_bytes.is_multiple_of(3) || text.get(chars(header_bytes) - 1) == Some(&b'=')
        };
        let (header, data_text): (Vec<usize>, &[u8]) = if !self.layout.zlib {
            let Some(head_text) = text.get(..chars(h)) else {
                return Err(short("a header", chars(h)));
            };
            let head = self.decode(head_text, loc, "the header")?;
            let size = self.word(head.get(..h).unwrap_or(&[]));
            self.check_size(loc, size)?;
            if apart(h) {
                (vec![size], &text[chars(h)..])
            } else {
                let Some(all) = text.get(..chars(h + size)) else {
                    return Err(short("the header and data", chars(h.saturating_add(size))));
                };
                let mut all = self.decode(all, loc, "the data")?;
                all.drain(..h);
                return self.finish(all, text.len() - chars(h + size), loc, whole);
            }
        } else {
            let Some(first) = text.get(..4 * h) else {
                return Err(short("a compression header", 4 * h));
            };
            let first = self.decode(first, loc, "the compression header")?;
            let nblocks = self.word(first.get(..h).unwrap_or(&[]));
            let hb = nblocks.saturating_add(3).saturating_mul(h);
            let Some(head_text) = text.get(..chars(hb)) else {
                return Err(short(
                    &format!("a compression header of {nblocks} blocks"),
                    chars(hb),
                ));
            };
            let head = self.decode(head_text, loc, "the compression header")?;
            let header = self.words(head.get(..hb).unwrap_or(&[]));
            if header.len() != nblocks.saturating_add(3) {
                return Err(short(
                    &format!("a compression header of {nblocks} blocks"),
                    chars(hb),
                ));
            }
            if apart(hb) {
                (header, &text[chars(hb)..])
            } else {
                let compressed: usize =
                    header[3..].iter().fold(0usize, |a, &c| a.saturating_add(c));
                let total = hb.saturating_add(compressed);
                let Some(all) = text.get(..chars(total)) else {
                    return Err(short("the header and compressed blocks", chars(total)));
                };
                let all = self.decode(all, loc, "the compressed blocks")?;
                let data = self.inflate(&header, &all[hb..total], loc)?;
                return self.finish(data, text.len() - chars(total), loc, whole);
            }
        };
        let size = if self.layout.zlib {
            header[3..].iter().fold(0usize, |a, &c| a.saturating_add(c))
        } else {
            header[0]
        };
        let Some(body) = data_text.get(..chars(size)) else {
            return Err(short("the data", chars(size)));
        };
        let left = data_text.len() - body.len();
        let mut data = self.decode(body, loc, "the data")?;
        data.truncate(size);
        if self.layout.zlib {
            data = self.inflate(&header, &data, loc)?;
        }
        self.finish(data, left, loc, whole)
    }

    /// Checks that nothing is left over in an inline array.
    fn finish(
        &self,
        data: Vec<u8>,
        left: usize,
        loc: Loc,
        whole: bool,
    ) -> Result<Vec<u8>, MeshReadError> {
        if whole && left > 0 {
            return Err(self.error(
                loc,
                format!("the end of the base64 text after {}", self.what),
                format!("{left} more characters"),
            ));
        }
        Ok(data)
    }

    fn decode(&self, b64: &[u8], loc: Loc, part: &str) -> Result<Vec<u8>, MeshReadError> {
        BASE64.decode(b64).map_err(|e| {
            let (loc, found) = match e {
                base64::DecodeError::InvalidByte(i, b)
                | base64::DecodeError::InvalidLastSymbol(i, b) => (
                    match loc {
                        Loc::Byte(at) => Loc::Byte(at + i as u64),
                        line => line,
                    },
                    format!("the byte 0x{b:02x} at character {i}"),
                ),
                other => (loc, other.to_string()),
            };
            self.error(loc, format!("base64 for {part} of {}", self.what), found)
        })
    }

    /// Decompresses the zlib blocks `data` described by `header` (`nblocks`, block size, last
    /// block size, compressed sizes).
    fn inflate(&self, header: &[usize], data: &[u8], loc: Loc) -> Result<Vec<u8>, MeshReadError> {
        let (nblocks, block, last) = (header[0], header[1], header[2]);
        let sizes = &header[3..];
        let last_size = if last == 0 { block } else { last };
        let total = match nblocks {
            0 => Some(0),
            n => (n - 1)
                .checked_mul(block)
                .and_then(|t| t.checked_add(last_size)),
        };
        self.check_size(loc, total.unwrap_or(usize::MAX))?;
        let mut pos = 0usize;
        for (k, &c) in sizes.iter().enumerate() {
            let expect = if k + 1 == nblocks { last_size } else { block };
            if expect > c.saturating_mul(MAX_ZLIB_RATIO).saturating_add(ZLIB_SLACK) {
                return Err(self.error(
                    loc,
                    format!(
                        "a block that zlib can expand to its declared size, for {}",
                        self.what
                    ),
                    format!("block {k}: {c} compressed bytes declared to expand to {expect}"),
                ));
            }
            pos = pos.saturating_add(c);
        }
        if pos > data.len() {
            return Err(self.error(
                loc,
                format!("{pos} bytes of compressed blocks for {}", self.what),
                format!("{} bytes", data.len()),
            ));
        }
        let mut out = Vec::with_capacity(self.need);
        let mut pos = 0usize;
        for (k, &c) in sizes.iter().enumerate() {
            let expect = if k + 1 == nblocks { last_size } else { block };
            let before = out.len();
            let stream = &data[pos..pos + c];
            let result = flate2::read::ZlibDecoder::new(stream)
                .take(expect as u64 + 1)
                .read_to_end(&mut out);
            let got = out.len() - before;
            match result {
                Ok(_) if got == expect => {}
                Ok(_) => {
                    return Err(self.error(
                        loc,
                        format!("block {k} of {} to expand to {expect} bytes", self.what),
                        format!(
                            "{}{got} bytes",
                            if got > expect { "more than " } else { "" }
                        ),
                    ))
                }
                Err(e) => {
                    return Err(self.error(
                        loc,
                        format!("a zlib stream for block {k} of {}", self.what),
                        e.to_string(),
                    ))
                }
            }
            pos += c;
        }
        Ok(out)
    }
}
