//! VTK files in the encodings meshio cannot write, built byte by byte (`vtk_build`): VTK XML
//! with appended raw and base64 data, big-endian, UInt64 headers, multi-block zlib, base64
//! headers encoded apart from or with the data; legacy and XML POLYDATA surfaces. Each reads
//! to the mesh it encodes; broken ones are refused with the file and the line or byte offset.

use crate::mesh_text;
use crate::vtk_build;

use lop_sim::mesh::{read_mesh, read_surface, read_vtk_xml, MeshReadError};
use mesh_text::*;
use vtk_build::*;

#[test]
fn every_hand_built_encoding_reads_to_the_cube() {
    let dir = scratch("vtk-enc");
    let encodings = all_encodings();
    assert!(encodings.len() >= 30, "{}", encodings.len());
    for e in &encodings {
        let name = name(e);
        let path = write(&dir, &name, cube_vtu(e));
        let mesh = read_mesh(&path).unwrap_or_else(|err| panic!("{name}: {err}"));
        assert_eq!(mesh.nodes, cube_nodes(), "{name}");
        assert_eq!(mesh.tets, cube_tets(), "{name}");
        let again = read_vtk_xml(&path).unwrap();
        assert_eq!(again.tets, mesh.tets);
    }
}

/// Reads a broken file (as a mesh, or as a surface for names starting with `s`) and checks
/// that the error names the file and a line or offset, and says each needle.
fn refused(dir: &std::path::Path, name: &str, bytes: &[u8], needles: &[&str]) -> MeshReadError {
    let path = write(dir, name, bytes);
    let err = if name.starts_with('s') {
        read_surface(&path).unwrap_err()
    } else {
        read_mesh(&path).unwrap_err()
    };
    assert!(
        err.line().is_some() || err.offset().is_some(),
        "{name}: no line or offset: {err}"
    );
    let mut all = vec![name];
    all.extend_from_slice(needles);
    says(&err, &all);
    err
}

fn enc(place: Place, zlib: Option<usize>) -> Encoding {
    Encoding {
        place,
        big: false,
        u64_header: false,
        zlib,
        separate: true,
    }
}

fn find(hay: &[u8], needle: &[u8]) -> usize {
    hay.windows(needle.len())
        .position(|w| w == needle)
        .unwrap_or_else(|| panic!("{:?} not found", String::from_utf8_lossy(needle)))
}

#[test]
fn broken_appended_and_compressed_data_is_refused_with_its_place() {
    let dir = scratch("vtk-enc-bad");

    // Raw appended data cut short: the error gives the byte offset of the array.
    let raw = cube_vtu(&enc(Place::Raw, None));
    let mut cut = raw[..raw.len() - 60].to_vec();
    cut.extend_from_slice(b"\n</AppendedData></VTKFile>\n");
    let err = refused(&dir, "cut.vtu", &cut, &["bytes of appended data left"]);
    assert!(err.offset().is_some(), "{err}");

    // No `_` marker.
    let t = String::from_utf8(cube_vtu(&enc(Place::Base64, None))).unwrap();
    refused(
        &dir,
        "marker.vtu",
        t.replacen("   _", "    ", 1).as_bytes(),
        &["`_`"],
    );

    // An offset past the appended data.
    let t = t.replacen("offset=\"0\"", "offset=\"99999\"", 1);
    refused(&dir, "offset.vtu", t.as_bytes(), &["`offset`", "99999"]);

    // A zlib header that claims a huge block count, and one whose block expands more than
    // deflate can.
    let z = cube_vtu(&enc(Place::Raw, Some(48)));
    let start = find(&z, b"   _") + 4;
    let mut b = z.clone();
    b[start..start + 4].copy_from_slice(&0x7fff_ffffu32.to_le_bytes());
    let err = refused(&dir, "blocks.vtu", &b, &["2147483647 blocks"]);
    assert_eq!(err.offset(), Some(start as u64));
    let mut b = z.clone();
    b[start + 4..start + 8].copy_from_slice(&0x7fff_0000u32.to_le_bytes());
    refused(&dir, "ratio.vtu", &b, &["declaring"]);

    // Corrupt zlib data in a raw appended array.
    let mut b = z.clone();
    let data = start + 4 * 7; // 2 blocks of Points (192 bytes in blocks of 48: 4 blocks) ...
    for x in &mut b[data + 2..data + 6] {
        *x ^= 0xff;
    }
    refused(&dir, "zlib.vtu", &b, &["zlib"]);

    // An inline base64 array with trailing characters.
    let t = String::from_utf8(cube_vtu(&enc(Place::Inline, None))).unwrap();
    let t = t.replacen("\n        </DataArray>", "AAAA\n        </DataArray>", 1);
    refused(&dir, "trail.vtu", t.as_bytes(), &["more characters"]);

    // Unsupported compressor, dataset and attributes.
    let t = String::from_utf8(cube_vtu(&enc(Place::Inline, Some(48)))).unwrap();
    let err = read_mesh(&write(&dir, "lz4.vtu", t.replace("vtkZLib", "vtkLZ4"))).unwrap_err();
    assert!(matches!(err, MeshReadError::UnsupportedFormat { .. }));
    says(&err, &["lz4.vtu", "vtkLZ4DataCompressor"]);
    refused(
        &dir,
        "order.vtu",
        t.replace("LittleEndian", "Middle").as_bytes(),
        &[":2:", "`Middle`"],
    );
    refused(
        &dir,
        "type.vtu",
        t.replace("Float64", "Float16").as_bytes(),
        &["`Float16`"],
    );
    let err = read_mesh(&write(
        &dir,
        "poly.vtu",
        t.replace("UnstructuredGrid", "PolyData"),
    ))
    .unwrap_err();
    says(&err, &["poly.vtu", "read_surface"]);
    refused(
        &dir,
        "xml.vtu",
        t.replace("</Piece>", "</Peace>").as_bytes(),
        &["XML"],
    );
}

// ---------------------------------------------------------------------------------------------
// POLYDATA

/// A unit square's corners and its apex: the surface is a triangle and a quadrilateral.
const SURF_POINTS: [[f32; 3]; 5] = [
    [0.0, 0.0, 0.0],
    [1.0, 0.0, 0.0],
    [1.0, 1.0, 0.0],
    [0.0, 1.0, 0.0],
    [0.5, 0.5, 1.0],
];

/// Polygons: triangle 0 1 4 and quadrilateral 0 3 2 1 (split into 0 3 2 and 0 2 1).
const SURF_TRIS: [[u32; 3]; 3] = [[0, 1, 4], [0, 3, 2], [0, 2, 1]];

fn legacy_polydata_ascii(v51: bool) -> String {
    let mut t = String::from("# vtk DataFile Version 5.1\nsurface\nASCII\nDATASET POLYDATA\n");
    t += "POINTS 5 float\n";
    for [x, y, z] in SURF_POINTS {
        t += &format!("{x} {y} {z}\n");
    }
    t += "VERTICES 1 2\n1 4\n"; // skipped
    if v51 {
        t += "POLYGONS 3 7\nOFFSETS vtktypeint64\n0 3 7\nCONNECTIVITY vtktypeint64\n0 1 4\n0 3 2 1\n";
    } else {
        t += "POLYGONS 2 9\n3 0 1 4\n4 0 3 2 1\n";
    }
    t += "POINT_DATA 5\nSCALARS s float\nLOOKUP_TABLE default\n0 0 0 0 0\n";
    t
}

fn legacy_polydata_binary(v51: bool) -> Vec<u8> {
    let mut b =
        b"# vtk DataFile Version 5.1\nsurface\nBINARY\nDATASET POLYDATA\nPOINTS 5 float\n".to_vec();
    for p in SURF_POINTS {
        for c in p {
            b.extend(c.to_be_bytes());
        }
    }
    if v51 {
        b.extend(b"\nPOLYGONS 3 7\nOFFSETS vtktypeint64\n");
        for o in [0i64, 3, 7] {
            b.extend(o.to_be_bytes());
        }
        b.extend(b"\nCONNECTIVITY vtktypeint64\n");
        for i in [0i64, 1, 4, 0, 3, 2, 1] {
            b.extend(i.to_be_bytes());
        }
    } else {
        b.extend(b"\nPOLYGONS 2 9\n");
        for i in [3i32, 0, 1, 4, 4, 0, 3, 2, 1] {
            b.extend(i.to_be_bytes());
        }
    }
    b.extend(b"\nCELL_DATA 2\n");
    b
}

fn vtp(e: &Encoding) -> Vec<u8> {
    let points = SURF_POINTS
        .iter()
        .flatten()
        .map(|&c| f64::from(c))
        .collect();
    vtk_xml(
        e,
        "PolyData",
        "NumberOfPoints=\"5\" NumberOfVerts=\"0\" NumberOfLines=\"0\" NumberOfStrips=\"0\" \
         NumberOfPolys=\"2\"",
        &[
            ("Points", vec![Array::new("Float32", "Points", 3, points)]),
            (
                "Polys",
                vec![
                    Array::new("Int32", "connectivity", 1, vec![0., 1., 4., 0., 3., 2., 1.]),
                    Array::new("Int32", "offsets", 1, vec![3., 7.]),
                ],
            ),
        ],
    )
}

#[test]
fn polydata_surfaces_read_in_every_form() {
    let dir = scratch("vtk-poly");
    let mut files: Vec<(String, Vec<u8>)> = vec![
        ("a.vtk".into(), legacy_polydata_ascii(false).into_bytes()),
        ("b.vtk".into(), legacy_polydata_ascii(true).into_bytes()),
        ("c.vtk".into(), legacy_polydata_binary(false)),
        ("d.vtk".into(), legacy_polydata_binary(true)),
        // Recognised by content, whatever the name.
        ("e.dat".into(), legacy_polydata_binary(true)),
    ];
    for (i, e) in all_encodings().iter().enumerate() {
        files.push((format!("f{i}.vtp"), vtp(e)));
    }
    for (name, bytes) in &files {
        let s = read_surface(&write(&dir, name, bytes)).unwrap_or_else(|e| panic!("{name}: {e}"));
        let expected: Vec<[f64; 3]> = SURF_POINTS.iter().map(|p| p.map(f64::from)).collect();
        assert_eq!(s.vertices, expected, "{name}");
        assert_eq!(s.triangles, SURF_TRIS, "{name}");
    }
    // A surface is not a volume mesh.
    let err = read_mesh(&write(&dir, "p.vtk", legacy_polydata_ascii(false))).unwrap_err();
    assert!(matches!(err, MeshReadError::UnsupportedFormat { .. }));
    says(&err, &["p.vtk", "POLYDATA", "read_surface"]);
}

#[test]
fn polydata_polygons_other_than_triangles_and_quads_are_refused() {
    let dir = scratch("vtk-poly-bad");
    let t = legacy_polydata_ascii(false).replace(
        "POLYGONS 2 9\n3 0 1 4\n4 0 3 2 1\n",
        "POLYGONS 2 10\n3 0 1 4\n5 0 3 2 1 4\n",
    );
    let err = refused(
        &dir,
        "s5.vtk",
        t.as_bytes(),
        &[":15:", "polygon 1", "5 points"],
    );
    assert!(matches!(err, MeshReadError::Parse { line: 15, .. }));
    let t = legacy_polydata_ascii(false).replace("POLYGONS 2 9", "TRIANGLE_STRIPS 2 9");
    refused(
        &dir,
        "strips.vtk",
        t.as_bytes(),
        &[":13:", "triangle strips"],
    );
    let t = legacy_polydata_ascii(false).replace("4 0 3 2 1", "4 0 3 2 9");
    refused(
        &dir,
        "sid.vtk",
        t.as_bytes(),
        &[":15:", "node index 9", "5 nodes"],
    );
    // Binary: the byte offset of the bad point id.
    let mut b = legacy_polydata_binary(true);
    let at = find(&b, b"CONNECTIVITY vtktypeint64\n") + 26 + 8 * 5;
    b[at..at + 8].copy_from_slice(&7i64.to_be_bytes());
    let err = refused(
        &dir,
        "sbin.vtk",
        &b,
        &["point id below 5", "polygon 1", "`7`"],
    );
    assert_eq!(err.offset(), Some(at as u64 - 16));
    let t = String::from_utf8(vtp(&enc(Place::Ascii, None))).unwrap();
    let t = t.replace("NumberOfStrips=\"0\"", "NumberOfStrips=\"1\"");
    refused(&dir, "sstrip.vtp", t.as_bytes(), &["NumberOfStrips=\"1\""]);
}
