//! Surfaces written by VTK's own writers read to the surface VTK has: Python's `vtk` package
//! (`sim/tests/data/vtk_write.py`) writes one 10,000-triangle surface with
//! `vtkPolyDataWriter` in both legacy layouts — classic (file version 4.2: `POLYGONS n size`
//! and one big-endian `int` list of counts and ids) and 5.1 (`OFFSETS` / `CONNECTIVITY`) —
//! ASCII and binary, and with `vtkXMLPolyDataWriter` as `.vtp` (ASCII, base64, appended raw,
//! with and without zlib), in single and double precision. lop must read every file to the
//! point and triangle counts and the area that VTK computes (`vtkMassProperties`), and the
//! double-precision binary files to the same surface bit for bit. Triangle strips and an LZ4
//! `.vtp` are refused with a message naming the file and what to do.
//!
//! Issue 28 found the classic binary layout refused ("expected a section line … found binary
//! bytes"): the reader peeked for an `OFFSETS` line with its text-line reader.
//!
//! The tests fail (they do not skip) when the `vtk` package is missing: run
//! `scripts/setup.sh` (it installs PyPI `vtk`).

use crate::mesh_text;

use std::path::Path;

use lop_sim::mesh::{read_surface, MeshReadError};
use mesh_text::*;

/// What the script wrote and computed.
struct Reference {
    points: usize,
    triangles: usize,
    area: f64,
    /// (file name, kind)
    files: Vec<(String, String)>,
}

fn vtk_files(dir: &Path) -> Reference {
    let stdout = run_writer("vtk_write.py", "vtk", "PyPI package vtk", dir);
    let mut r = Reference {
        points: 0,
        triangles: 0,
        area: 0.0,
        files: Vec::new(),
    };
    for line in stdout.lines() {
        let f: Vec<&str> = line.split_whitespace().collect();
        match f[..] {
            ["points", n] => r.points = n.parse().unwrap(),
            ["triangles", n] => r.triangles = n.parse().unwrap(),
            ["area", v] => r.area = v.parse().unwrap(),
            ["file", name, kind] => r.files.push((name.to_owned(), kind.to_owned())),
            ["vtk", version] => println!("vtk {version}"),
            _ => panic!("unexpected line from vtk_write.py: {line}"),
        }
    }
    assert_eq!((r.points, r.triangles), (5002, 10_000), "{stdout}");
    assert!(r.files.len() >= 20, "{stdout}");
    r
}

#[test]
fn every_layout_vtk_writes_reads_to_its_surface() {
    let dir = scratch("vtk-writers");
    let r = vtk_files(&dir);
    let mut classic_binary = 0;
    for (name, kind) in &r.files {
        let path = dir.join(name);
        match kind.as_str() {
            "surface" | "surface32" => {
                let s = read_surface(&path).unwrap_or_else(|e| panic!("{name}: {e}"));
                assert_eq!(s.vertices.len(), r.points, "{name}");
                assert_eq!(s.triangles.len(), r.triangles, "{name}");
                // VTK's area is computed from the doubles; single precision rounds each
                // coordinate by 6e-8 relative, ASCII files by VTK's printed digits.
                let rel = if kind == "surface" { 1e-9 } else { 1e-6 };
                let a = s.area();
                assert!(
                    (a - r.area).abs() <= rel * r.area,
                    "{name}: area {a} vs {}",
                    r.area
                );
                classic_binary += usize::from(name.starts_with("classic_binary"));
            }
            "quads" => {
                // A cube of 6 quadrilaterals, each split into 2 triangles.
                let s = read_surface(&path).unwrap_or_else(|e| panic!("{name}: {e}"));
                assert_eq!((s.vertices.len(), s.triangles.len()), (24, 12), "{name}");
                let a = s.area();
                let want = 2.0 * (0.03 * 0.02 + 0.03 * 0.01 + 0.02 * 0.01);
                assert!((a - want).abs() < 1e-9, "{name}: area {a}");
            }
            "refused_strips" => {
                let err = read_surface(&path).unwrap_err();
                says(&err, &[name, "triangle strips"]);
            }
            "refused_lz4" => {
                let err = read_surface(&path).unwrap_err();
                assert!(
                    matches!(err, MeshReadError::UnsupportedFormat { .. }),
                    "{name}: {err}"
                );
                says(&err, &[name, "vtkLZ4DataCompressor"]);
            }
            other => panic!("unknown kind {other}"),
        }
    }
    assert_eq!(
        classic_binary, 2,
        "the classic binary layout was written and read"
    );

    // The binary double-precision files hold the same surface bit for bit.
    let a = read_surface(&dir.join("classic_binary_64.vtk")).unwrap();
    for name in [
        "v51_binary_64.vtk",
        "base64_64.vtp",
        "base64_zlib_64.vtp",
        "appended_64.vtp",
        "appended_zlib_64.vtp",
    ] {
        let b = read_surface(&dir.join(name)).unwrap();
        assert_eq!(a, b, "{name}");
    }
}

#[test]
fn truncated_classic_binary_polydata_is_refused_at_its_byte() {
    let dir = scratch("vtk-writers-bad");
    vtk_files(&dir);
    let bytes = std::fs::read(dir.join("classic_binary_64.vtk")).unwrap();
    let at = bytes
        .windows(9)
        .position(|w| w == b"POLYGONS ")
        .expect("POLYGONS line");
    // Cut in the middle of the polygon list.
    let path = dir.join("cut.vtk");
    std::fs::write(&path, &bytes[..at + 40 + 4 * 5000]).unwrap();
    let err = read_surface(&path).unwrap_err();
    assert!(err.offset().is_some(), "{err}");
    says(&err, &["cut.vtk", "byte", "bytes left"]);
}
