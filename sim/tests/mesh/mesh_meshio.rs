//! Files written by an independent library read to the mesh it wrote: Python's meshio
//! (`sim/tests/data/meshio_write.py`) writes one tetrahedral mesh as VTK XML (ASCII, base64,
//! zlib; UInt32 and UInt64 headers; Float64/Int64 and Float32/Int32 arrays) and legacy VTK
//! (5.1 and 4.2 layouts, ASCII and binary), and its boundary surface as STL (ASCII, binary),
//! OBJ, PLY (ASCII, binary) and VTK. lop must read every file to the counts, volume and area
//! that the script computes with numpy. Then malformed copies of those files (truncated,
//! counts corrupted, bad base64, bad zlib, wrong cell ids) are refused with an error that
//! names the file and the line or byte offset, never a panic.
//!
//! meshio cannot write appended data, big-endian files, base64 with the header encoded apart
//! from the data (as VTK does) or POLYDATA: `mesh_vtk.rs` covers those with files built byte
//! by byte.
//!
//! The tests fail (they do not skip) when meshio is missing: run `scripts/setup.sh`.

use crate::mesh_text;

use std::path::Path;

use base64::Engine as _;
use lop_sim::mesh::{read_mesh, read_surface, MeshReadError};
use mesh_text::*;

/// What the script wrote and computed.
struct Reference {
    points: usize,
    tets: usize,
    volume: f64,
    surface_points: usize,
    triangles: usize,
    area: f64,
    /// (file name, kind)
    files: Vec<(String, String)>,
}

fn meshio_files(dir: &Path) -> Reference {
    let stdout = run_writer(
        "meshio_write.py",
        "meshio",
        "Debian package python3-meshio",
        dir,
    );
    let mut r = Reference {
        points: 0,
        tets: 0,
        volume: 0.0,
        surface_points: 0,
        triangles: 0,
        area: 0.0,
        files: Vec::new(),
    };
    for line in stdout.lines() {
        let f: Vec<&str> = line.split_whitespace().collect();
        match f[..] {
            ["points", n] => r.points = n.parse().unwrap(),
            ["tets", n] => r.tets = n.parse().unwrap(),
            ["volume", v] => r.volume = v.parse().unwrap(),
            ["surface_points", n] => r.surface_points = n.parse().unwrap(),
            ["triangles", n] => r.triangles = n.parse().unwrap(),
            ["area", v] => r.area = v.parse().unwrap(),
            ["file", name, kind] => r.files.push((name.to_owned(), kind.to_owned())),
            ["meshio", version] => println!("meshio {version}"),
            _ => panic!("unexpected line from meshio_write.py: {line}"),
        }
    }
    assert!(r.files.len() >= 20, "{stdout}");
    r
}

fn close(a: f64, b: f64, rel: f64) -> bool {
    (a - b).abs() <= rel * b.abs()
}

#[test]
fn every_file_meshio_writes_reads_to_its_mesh() {
    let dir = scratch("meshio");
    let r = meshio_files(&dir);
    for (name, kind) in &r.files {
        let path = dir.join(name);
        match kind.as_str() {
            "volume" | "volume32" => {
                let mesh = read_mesh(&path).unwrap_or_else(|e| panic!("{name}: {e}"));
                let info = mesh.info();
                assert_eq!((info.nodes, info.tets), (r.points, r.tets), "{name}");
                let rel = if kind == "volume" { 1e-12 } else { 1e-6 };
                assert!(close(info.volume, r.volume, rel), "{name}: {}", info.volume);
                assert_eq!(info.surface_triangles, r.triangles, "{name}");
                assert!(info.quality_min > 0.3, "{name}: {info}");
            }
            "surface" | "surface32" => {
                let s = read_surface(&path).unwrap_or_else(|e| panic!("{name}: {e}"));
                assert_eq!(s.triangles.len(), r.triangles, "{name}");
                assert_eq!(s.vertices.len(), r.surface_points, "{name}");
                let rel = if kind == "surface" { 1e-9 } else { 1e-6 };
                assert!(close(s.area(), r.area, rel), "{name}: {}", s.area());
            }
            "refused" => {
                let err = read_mesh(&path).unwrap_err();
                assert!(
                    matches!(err, MeshReadError::UnsupportedFormat { .. }),
                    "{name}: {err}"
                );
                says(&err, &[name, "vtkLZMADataCompressor", "zlib"]);
            }
            other => panic!("unknown kind {other}"),
        }
    }
    // Recognised by content: a .vtu under another name, and XML inside a .vtk.
    for (from, to) in [
        ("vol-zlib.vtu", "renamed.dat"),
        ("vol-base64.vtu", "xml.vtk"),
    ] {
        let path = write(&dir, to, std::fs::read(dir.join(from)).unwrap());
        let mesh = read_mesh(&path).unwrap_or_else(|e| panic!("{to}: {e}"));
        assert_eq!(mesh.tets.len(), r.tets, "{to}");
    }
    // The binary files with doubles give the same mesh bit for bit (meshio's ASCII files
    // round coordinates to 12 digits).
    let a = read_mesh(&dir.join("vol-base64.vtu")).unwrap();
    for name in [
        "vol-zlib.vtu",
        "vol-base64-u64.vtu",
        "vol-zlib-u64.vtu",
        "vol-binary-51.vtk",
        "vol-binary-42.vtk",
    ] {
        let b = read_mesh(&dir.join(name)).unwrap();
        assert_eq!((&a.nodes, &a.tets), (&b.nodes, &b.tets), "{name}");
    }
}

/// Reads a malformed file and checks the error names the file and a line or byte offset.
fn refused(dir: &Path, name: &str, bytes: &[u8], needles: &[&str]) -> MeshReadError {
    let path = write(dir, name, bytes);
    let err = if name.contains("surf") {
        read_surface(&path).unwrap_err()
    } else {
        read_mesh(&path).expect_err(name)
    };
    let located = err.line().is_some() || err.offset().is_some();
    assert!(located, "{name}: no line or offset: {err}");
    let mut all = vec![name];
    all.extend_from_slice(needles);
    says(&err, &all);
    err
}

fn text(dir: &Path, name: &str) -> String {
    std::fs::read_to_string(dir.join(name)).unwrap()
}

/// The text of the first `<DataArray ...>` element whose start tag contains `attr`, and the
/// byte range of its content.
fn array_content(xml: &str, attr: &str) -> std::ops::Range<usize> {
    let tag = xml.find(attr).unwrap();
    let start = tag + xml[tag..].find('>').unwrap() + 1;
    let end = start + xml[start..].find("</DataArray>").unwrap();
    start..end
}

#[test]
fn malformed_meshio_files_are_refused_with_their_place() {
    let dir = scratch("meshio-bad");
    let r = meshio_files(&dir);
    let bad = scratch("meshio-bad-out");

    // Truncated: in the middle of a base64 array, and of a binary legacy array.
    let b64 = text(&dir, "vol-base64.vtu");
    let cut = array_content(&b64, "Name=\"connectivity\"");
    let err = refused(&bad, "trunc.vtu", &b64.as_bytes()[..cut.start + 40], &[]);
    assert!(matches!(err, MeshReadError::Parse { .. }), "{err}");
    let bin = std::fs::read(dir.join("vol-binary-51.vtk")).unwrap();
    refused(
        &bad,
        "trunc.vtk",
        &bin[..bin.len() / 2],
        &["byte", "bytes left"],
    );
    let bin42 = std::fs::read(dir.join("vol-binary-42.vtk")).unwrap();
    refused(&bad, "trunc42.vtk", &bin42[..bin42.len() - 30], &["byte"]);

    // Corrupted counts.
    let points = format!("NumberOfPoints=\"{}\"", r.points);
    for (name, file) in [
        ("count-b64.vtu", "vol-base64.vtu"),
        ("count-zlib.vtu", "vol-zlib.vtu"),
        ("count-ascii.vtu", "vol-ascii.vtu"),
    ] {
        let t = text(&dir, file).replace(&points, "NumberOfPoints=\"61\"");
        refused(&bad, name, t.as_bytes(), &["Points", "61"]);
    }
    let t = text(&dir, "vol-zlib.vtu").replace(
        &format!("NumberOfCells=\"{}\"", r.tets),
        "NumberOfCells=\"7\"",
    );
    refused(&bad, "cells.vtu", t.as_bytes(), &["offsets"]);
    let mut b = bin42.clone();
    let at = find(&b, b"CELL_TYPES ");
    b.splice(at..at + 14, b"CELL_TYPES 143".iter().copied());
    refused(&bad, "types42.vtk", &b, &["byte", "cell types", "143"]);
    let mut b = bin.clone();
    let at = find(&b, b"POINTS 60");
    b[at + 7] = b'9';
    // 69 points take the bytes of the offsets too: the reader then meets binary data where
    // the next section line should be.
    refused(&bad, "points51.vtk", &b, &["byte", "section line"]);

    // Bad base64: a character outside the alphabet.
    let mut t = b64.clone();
    let c = array_content(&t, "Name=\"offsets\"");
    t.replace_range(c.start + 10..c.start + 11, "*");
    let err = refused(&bad, "b64.vtu", t.as_bytes(), &["base64", "0x2a"]);
    assert_eq!(err.line(), Some(line_of(&t, c.start)), "{err}");

    // Bad zlib: flip bytes in the middle of the compressed connectivity.
    let z = text(&dir, "vol-zlib.vtu");
    let c = array_content(&z, "Name=\"connectivity\"");
    let body = z[c.clone()].trim();
    let header_chars = 32; // 1 block, UInt32: 6 words of 4 bytes, 24 bytes, 32 characters
    let mut data = base64_decode(&body[header_chars..]);
    let mid = data.len() / 2;
    for b in &mut data[mid..mid + 4] {
        *b ^= 0x5a;
    }
    let mut t = z.clone();
    t.replace_range(
        c.clone(),
        &format!("\n{}{}\n", &body[..header_chars], base64_encode(&data)),
    );
    refused(&bad, "zlib.vtu", t.as_bytes(), &["zlib", "connectivity"]);

    // Wrong cell ids: a point id past the end, and a negative one.
    let a = text(&dir, "vol-ascii.vtu");
    let c = array_content(&a, "Name=\"connectivity\"");
    let mut t = a.clone();
    let first = c.start + a[c.clone()].find(|ch: char| ch.is_ascii_digit()).unwrap();
    let end = first + a[first..].find(char::is_whitespace).unwrap();
    t.replace_range(first..end, "60");
    let err = refused(
        &bad,
        "ids.vtu",
        t.as_bytes(),
        &["node index 60", "60 nodes"],
    );
    assert!(
        matches!(err, MeshReadError::IndexOutOfRange { .. }),
        "{err}"
    );
    let mut b = bin.clone();
    let at = find(&b, b"CONNECTIVITY vtktypeint64\n") + 26;
    b[at..at + 8].copy_from_slice(&(-3i64).to_be_bytes());
    let err = refused(&bad, "ids51.vtk", &b, &["point id below 60", "`-3`"]);
    assert_eq!(err.offset(), Some(at as u64));

    // A surface file with a broken polygon.
    let s = text(&dir, "surf-ascii-42.vtk");
    let t = s.replacen("\n3\n", "\n2\n", 1);
    refused(&bad, "surf-bad.vtk", t.as_bytes(), &[]);
}

fn find(hay: &[u8], needle: &[u8]) -> usize {
    hay.windows(needle.len())
        .position(|w| w == needle)
        .unwrap_or_else(|| panic!("{:?} not found", String::from_utf8_lossy(needle)))
}

fn line_of(text: &str, at: usize) -> usize {
    1 + text[..at].matches('\n').count()
}

fn base64_encode(bytes: &[u8]) -> String {
    base64::engine::general_purpose::STANDARD.encode(bytes)
}

fn base64_decode(text: &str) -> Vec<u8> {
    base64::engine::general_purpose::STANDARD
        .decode(text)
        .unwrap()
}
