//! Builds VTK XML files byte by byte, in the encodings no independent writer at hand produces
//! (meshio writes neither appended data, nor big-endian, nor VTK's separately encoded base64
//! headers): used by `mesh_vtk.rs` and `mesh_vtk_bounded.rs`.
#![allow(dead_code)] // each test binary uses what it needs

use std::io::Write as _;

use base64::Engine as _;

/// Where the arrays go and how they are encoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Place {
    /// `format="ascii"`.
    Ascii,
    /// `format="binary"`, base64 in the element.
    Inline,
    /// `format="appended"`, `<AppendedData encoding="raw">`.
    Raw,
    /// `format="appended"`, `<AppendedData encoding="base64">`.
    Base64,
}

#[derive(Clone, Copy, Debug)]
pub struct Encoding {
    pub place: Place,
    pub big: bool,
    pub u64_header: bool,
    /// zlib blocks of this many bytes (so that arrays span several blocks).
    pub zlib: Option<usize>,
    /// Base64: the header encoded apart from the data (as VTK does) or with it (as meshio
    /// does for uncompressed data).
    pub separate: bool,
}

/// One array: VTK type name, `Name`, components, values (as f64; integer types cast).
pub struct Array {
    pub kind: &'static str,
    pub name: &'static str,
    pub comps: usize,
    pub values: Vec<f64>,
}

impl Array {
    pub fn new(kind: &'static str, name: &'static str, comps: usize, values: Vec<f64>) -> Self {
        Self {
            kind,
            name,
            comps,
            values,
        }
    }

    fn bytes(&self, big: bool) -> Vec<u8> {
        let mut out = Vec::new();
        for &v in &self.values {
            let mut b: Vec<u8> = match self.kind {
                "Float64" => v.to_le_bytes().to_vec(),
                "Float32" => (v as f32).to_le_bytes().to_vec(),
                "Int64" => (v as i64).to_le_bytes().to_vec(),
                "UInt64" => (v as u64).to_le_bytes().to_vec(),
                "Int32" => (v as i32).to_le_bytes().to_vec(),
                "UInt32" => (v as u32).to_le_bytes().to_vec(),
                "UInt8" => vec![v as u8],
                other => panic!("type {other}"),
            };
            if big {
                b.reverse();
            }
            out.extend_from_slice(&b);
        }
        out
    }
}

fn word(e: &Encoding, v: usize) -> Vec<u8> {
    let mut b = if e.u64_header {
        (v as u64).to_le_bytes().to_vec()
    } else {
        (v as u32).to_le_bytes().to_vec()
    };
    if e.big {
        b.reverse();
    }
    b
}

/// The header and the (compressed) data of one array, as VTK frames them.
pub fn framed(e: &Encoding, data: &[u8]) -> (Vec<u8>, Vec<u8>) {
    match e.zlib {
        None => (word(e, data.len()), data.to_vec()),
        Some(block) => {
            let blocks: Vec<&[u8]> = data.chunks(block).collect();
            let last = if data.len().is_multiple_of(block) {
                0
            } else {
                data.len() % block
            };
            let mut header = word(e, blocks.len());
            header.extend(word(e, block));
            header.extend(word(e, if blocks.is_empty() { 0 } else { last }));
            let mut body = Vec::new();
            for b in &blocks {
                let mut z =
                    flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
                z.write_all(b).unwrap();
                let c = z.finish().unwrap();
                header.extend(word(e, c.len()));
                body.extend(c);
            }
            (header, body)
        }
    }
}

pub fn b64(bytes: &[u8]) -> String {
    base64::engine::general_purpose::STANDARD.encode(bytes)
}

/// The base64 text of one framed array.
fn b64_framed(e: &Encoding, header: &[u8], body: &[u8]) -> String {
    if e.separate {
        b64(header) + &b64(body)
    } else {
        let mut all = header.to_vec();
        all.extend_from_slice(body);
        b64(&all)
    }
}

/// A VTK XML file of `kind` (`UnstructuredGrid` or `PolyData`) with one piece: `piece_attrs`
/// on `<Piece>`, and `sections` (element name, arrays) inside it.
pub fn vtk_xml(
    e: &Encoding,
    kind: &str,
    piece_attrs: &str,
    sections: &[(&str, Vec<Array>)],
) -> Vec<u8> {
    let mut xml = String::from("<?xml version=\"1.0\"?>\n");
    xml += &format!(
        "<VTKFile type=\"{kind}\" version=\"1.0\" byte_order=\"{}\" header_type=\"{}\"{}>\n",
        if e.big { "BigEndian" } else { "LittleEndian" },
        if e.u64_header { "UInt64" } else { "UInt32" },
        if e.zlib.is_some() {
            " compressor=\"vtkZLibDataCompressor\""
        } else {
            ""
        }
    );
    xml += &format!("  <{kind}>\n    <Piece {piece_attrs}>\n");
    let mut appended: Vec<u8> = Vec::new();
    for (section, arrays) in sections {
        xml += &format!("      <{section}>\n");
        for a in arrays {
            let format = match e.place {
                Place::Ascii => "ascii",
                Place::Inline => "binary",
                Place::Raw | Place::Base64 => "appended",
            };
            let comps = if a.comps > 1 {
                format!(" NumberOfComponents=\"{}\"", a.comps)
            } else {
                String::new()
            };
            let offset = match e.place {
                Place::Raw | Place::Base64 => format!(" offset=\"{}\"", appended.len()),
                _ => String::new(),
            };
            xml += &format!(
                "        <DataArray type=\"{}\" Name=\"{}\"{comps} format=\"{format}\"{offset}>",
                a.kind, a.name
            );
            let (header, body) = framed(e, &a.bytes(e.big));
            match e.place {
                Place::Ascii => {
                    xml += "\n";
                    for v in &a.values {
                        if a.kind.starts_with("Float") {
                            xml += &format!("          {v:?}\n");
                        } else {
                            xml += &format!("          {}\n", *v as i64);
                        }
                    }
                    xml += "        ";
                }
                Place::Inline => {
                    xml += &format!("\n          {}\n        ", b64_framed(e, &header, &body))
                }
                Place::Raw => {
                    appended.extend(header);
                    appended.extend(body);
                }
                Place::Base64 => appended.extend(b64_framed(e, &header, &body).into_bytes()),
            }
            xml += "</DataArray>\n";
        }
        xml += &format!("      </{section}>\n");
    }
    xml += &format!("    </Piece>\n  </{kind}>\n");
    let mut out = xml.into_bytes();
    match e.place {
        Place::Raw | Place::Base64 => {
            let encoding = if e.place == Place::Raw {
                "raw"
            } else {
                "base64"
            };
            out.extend(format!("  <AppendedData encoding=\"{encoding}\">\n   _").into_bytes());
            out.extend(appended);
            out.extend(b"\n  </AppendedData>\n");
        }
        _ => {}
    }
    out.extend(b"</VTKFile>\n");
    out
}

/// The unit cube of `mesh_text` (8 points, 5 tetrahedra) as a `.vtu`.
pub fn cube_vtu(e: &Encoding) -> Vec<u8> {
    let points: Vec<f64> = (0..8)
        .flat_map(|i| [(i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64])
        .collect();
    let conn: Vec<f64> = [
        [0, 1, 3, 5],
        [2, 0, 3, 6],
        [0, 4, 5, 6],
        [7, 3, 5, 6],
        [3, 0, 5, 6],
    ]
    .iter()
    .flatten()
    .map(|&i| f64::from(i))
    .collect();
    vtk_xml(
        e,
        "UnstructuredGrid",
        "NumberOfPoints=\"8\" NumberOfCells=\"5\"",
        &[
            ("Points", vec![Array::new("Float64", "Points", 3, points)]),
            (
                "Cells",
                vec![
                    Array::new("Int64", "connectivity", 1, conn),
                    Array::new("Int64", "offsets", 1, vec![4.0, 8.0, 12.0, 16.0, 20.0]),
                    Array::new("UInt8", "types", 1, vec![10.0; 5]),
                ],
            ),
        ],
    )
}

/// Every encoding: each place × byte order × header type × compression × base64 framing.
pub fn all_encodings() -> Vec<Encoding> {
    let mut out = Vec::new();
    for place in [Place::Ascii, Place::Inline, Place::Raw, Place::Base64] {
        for big in [false, true] {
            for u64_header in [false, true] {
                for zlib in [None, Some(48)] {
                    for separate in [true, false] {
                        let b64 = matches!(place, Place::Inline | Place::Base64);
                        if (place == Place::Ascii && (big || u64_header || zlib.is_some()))
                            || (!separate && !b64)
                        {
                            continue;
                        }
                        out.push(Encoding {
                            place,
                            big,
                            u64_header,
                            zlib,
                            separate,
                        });
                    }
                }
            }
        }
    }
    out
}

pub fn name(e: &Encoding) -> String {
    format!(
        "{:?}-{}-{}-{}-{}.vtu",
        e.place,
        if e.big { "be" } else { "le" },
        if e.u64_header { "u64" } else { "u32" },
        if e.zlib.is_some() { "zlib" } else { "plain" },
        if e.separate { "apart" } else { "joint" }
    )
    .to_lowercase()
}
