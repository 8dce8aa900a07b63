//! Surface readers (`read_surface`): STL written by gmsh (ASCII and binary), OBJ and PLY
//! written here in every variant, format recognition by content, and malformed files whose
//! errors name the file, the line or byte offset, and the value.

use crate::mesh_text;

use std::collections::HashMap;

use lop_sim::mesh::{read_surface, MeshReadError, SurfaceMesh};
use mesh_text::*;

/// Unit cube corners, corner i = (i & 1, (i >> 1) & 1, (i >> 2) & 1).
fn corners() -> Vec<[f64; 3]> {
    cube_nodes()
}

/// The cube's six faces as quads, 0-based, counter-clockwise seen from outside.
const QUADS: [[u32; 4]; 6] = [
    [0, 2, 3, 1],
    [4, 5, 7, 6],
    [0, 1, 5, 4],
    [2, 6, 7, 3],
    [0, 4, 6, 2],
    [1, 3, 7, 5],
];

/// The quads fanned into triangles from their first corner.
fn cube_triangles() -> Vec<[u32; 3]> {
    QUADS
        .iter()
        .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
        .collect()
}

/// Every directed edge appears once and its reverse once: closed, consistently wound.
fn assert_closed(s: &SurfaceMesh) {
    let mut edges: HashMap<(u32, u32), usize> = HashMap::new();
    for t in &s.triangles {
        for k in 0..3 {
            *edges.entry((t[k], t[(k + 1) % 3])).or_default() += 1;
        }
    }
    for (&(a, b), &n) in &edges {
        assert_eq!(n, 1, "edge {a}-{b} used {n} times");
        assert_eq!(edges.get(&(b, a)), Some(&1), "edge {a}-{b} has no twin");
    }
}

fn area(s: &SurfaceMesh) -> f64 {
    s.triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| s.vertices[i as usize]);
            let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
            let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
            let n = [
                u[1] * v[2] - u[2] * v[1],
                u[2] * v[0] - u[0] * v[2],
                u[0] * v[1] - u[1] * v[0],
            ];
            0.5 * (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt()
        })
        .sum()
}

fn read_err(dir: &std::path::Path, name: &str, bytes: impl AsRef<[u8]>) -> MeshReadError {
    let path = write(dir, name, bytes);
    let err = read_surface(&path).expect_err("the surface should be rejected");
    let msg = err.to_string();
    assert!(msg.contains(name), "message does not name the file: {msg}");
    err
}

// ---------------------------------------------------------------------------------------------
// STL

const GEO: &str = "SetFactory(\"OpenCASCADE\");
Box(1) = {0, 0, 0, 0.04, 0.03, 0.02};
Mesh.CharacteristicLengthMax = 0.01;
";

#[test]
fn stl_ascii_and_binary_written_by_gmsh() {
    let dir = scratch("stl-gmsh");
    let geo = write(&dir, "box.geo", GEO);
    let ascii = dir.join("ascii.stl");
    let binary = dir.join("binary.stl");
    gmsh("-2", &geo, "stl", &[], &ascii);
    gmsh("-2", &geo, "stl", &["-bin"], &binary);
    let head = std::fs::read(&binary).unwrap();
    assert!(!head.starts_with(b"solid"), "gmsh -bin wrote ASCII");
    assert!(std::fs::read_to_string(&ascii)
        .unwrap()
        .starts_with("solid"));

    let a = read_surface(&ascii).unwrap();
    let b = read_surface(&binary).unwrap();
    assert!(a.triangles.len() > 50, "{}", a.triangles.len());
    for s in [&a, &b] {
        assert_eq!(s.triangles.len(), a.triangles.len());
        // Welded: a closed box, V - E + F = 2 with E = 3F/2.
        assert_closed(s);
        assert_eq!(
            s.vertices.len() + s.triangles.len() - 3 * s.triangles.len() / 2,
            2
        );
        let total = 2.0 * (0.04 * 0.03 + 0.04 * 0.02 + 0.03 * 0.02);
        assert!((area(s) - total).abs() < 1e-6 * total, "{}", area(s));
    }
    assert_eq!(a.vertices.len(), b.vertices.len());
    // The binary file holds f32: the same triangles within single precision.
    for (ta, tb) in a.triangles.iter().zip(&b.triangles) {
        for (&i, &j) in ta.iter().zip(tb) {
            let (p, q) = (a.vertices[i as usize], b.vertices[j as usize]);
            assert!((0..3).all(|k| (p[k] - q[k]).abs() < 1e-7), "{p:?} vs {q:?}");
        }
    }
    // Recognised by content under other names.
    let renamed_a = write(&dir, "surface.txt", std::fs::read(&ascii).unwrap());
    let renamed_b = write(&dir, "surface.dat", std::fs::read(&binary).unwrap());
    assert_eq!(read_surface(&renamed_a).unwrap(), a);
    assert_eq!(read_surface(&renamed_b).unwrap(), b);
}

/// A binary STL of `tris` (three corners each), with `header` as its first 80 bytes.
fn stl_binary(header: &[u8], tris: &[[[f32; 3]; 3]]) -> Vec<u8> {
    let mut out = header.to_vec();
    out.resize(80, b' ');
    out.extend_from_slice(&(tris.len() as u32).to_le_bytes());
    for t in tris {
        out.extend_from_slice(&[0u8; 12]);
        for p in t {
            for c in p {
                out.extend_from_slice(&c.to_le_bytes());
            }
        }
        out.extend_from_slice(&[0u8; 2]);
    }
    out
}

fn cube_stl_tris() -> Vec<[[f32; 3]; 3]> {
    let c = corners();
    cube_triangles()
        .iter()
        .map(|t| t.map(|i| c[i as usize].map(|x| x as f32)))
        .collect()
}

fn cube_stl_ascii() -> String {
    let mut s = String::from("solid cube\n");
    for t in cube_stl_tris() {
        s.push_str("  facet normal 0 0 0\n    outer loop\n");
        for p in t {
            s.push_str(&format!("      vertex {} {} {}\n", p[0], p[1], p[2]));
        }
        s.push_str("    endloop\n  endfacet\n");
    }
    s.push_str("endsolid cube\n");
    s
}

#[test]
fn stl_welds_equal_vertices_and_trusts_size_over_solid() {
    let dir = scratch("stl-weld");
    // A binary file whose header starts with "solid" is still binary.
    let bin = read_surface(&write(
        &dir,
        "a.stl",
        stl_binary(b"solid cube", &cube_stl_tris()),
    ))
    .unwrap();
    let ascii = read_surface(&write(&dir, "b.stl", cube_stl_ascii())).unwrap();
    assert_eq!(bin, ascii);
    assert_eq!(bin.vertices.len(), 8);
    assert_eq!(bin.triangles.len(), 12);
    assert_closed(&bin);
    // -0 and 0 weld; 1e-9 apart do not.
    let mut tris = cube_stl_tris();
    tris[0][0][0] = -0.0;
    assert_eq!(
        read_surface(&write(&dir, "c.stl", stl_binary(b"", &tris)))
            .unwrap()
            .vertices
            .len(),
        8
    );
    tris[0][0][0] = 1e-9;
    assert_eq!(
        read_surface(&write(&dir, "d.stl", stl_binary(b"", &tris)))
            .unwrap()
            .vertices
            .len(),
        9
    );
}

#[test]
fn stl_huge_triangle_count_is_refused_before_allocating() {
    let dir = scratch("stl-huge");
    // u32::MAX triangles (about 4.3e9, 215 GB) claimed by a 134-byte file.
    let mut bytes = stl_binary(b"binary", &cube_stl_tris()[..1]);
    bytes[80..84].copy_from_slice(&u32::MAX.to_le_bytes());
    let err = read_err(&dir, "huge.stl", &bytes);
    assert!(
        matches!(err, MeshReadError::BinaryParse { offset: 80, .. }),
        "{err}"
    );
    assert_eq!(err.offset(), Some(80));
    says(
        &err,
        &[
            "huge.stl: byte 80:",
            "134 bytes",
            "1 triangles",
            "4294967295, which needs 214748364834 bytes",
        ],
    );
    // One triangle too few for the size.
    let mut bytes = stl_binary(b"binary", &cube_stl_tris()[..2]);
    bytes[80] = 1;
    let err = read_err(&dir, "short.stl", &bytes);
    says(
        &err,
        &[
            "short.stl: byte 80:",
            "184 bytes",
            "2 triangles)",
            "1, which needs 134 bytes",
        ],
    );
    bytes.push(0);
    let err = read_err(&dir, "odd.stl", &bytes);
    says(
        &err,
        &["odd.stl: byte 80:", "2 triangles and some bytes left over"],
    );
    // Shorter than the header.
    let err = read_err(&dir, "tiny.stl", b"abc");
    says(
        &err,
        &["tiny.stl: byte 3:", "header", "end of file after 3 bytes"],
    );
}

#[test]
fn stl_malformed() {
    let dir = scratch("stl-bad");
    let mut tris = cube_stl_tris();
    tris[2][1][2] = f32::NAN;
    let err = read_err(&dir, "nan.stl", stl_binary(b"", &tris));
    // Triangle 3 starts at 84 + 100; its 2nd vertex's z at +12 +12 +8.
    says(
        &err,
        &[
            "nan.stl: byte 216:",
            "z coordinate of vertex 2 of triangle 3",
            "NaN",
        ],
    );

    let text = cube_stl_ascii();
    let err = read_err(
        &dir,
        "a.stl",
        replace_line(&text, 5, "      vertex 1 zwei 0"),
    );
    says(
        &err,
        &["a.stl:5:", "y coordinate of vertex 2 of facet 1", "`zwei`"],
    );
    let err = read_err(&dir, "b.stl", replace_line(&text, 7, "      vertex 1 1 1"));
    says(&err, &["b.stl:7:", "`endloop`", "`vertex 1 1 1`"]);
    let err = read_err(&dir, "c.stl", replace_line(&text, 6, "    endloop"));
    says(
        &err,
        &[
            "c.stl:6:",
            "a facet has 3 vertices, this one 2",
            "`endloop`",
        ],
    );
    let err = read_err(&dir, "d.stl", text.replace("endsolid cube\n", ""));
    says(&err, &["d.stl:", "`endsolid`", "end of file"]);
    let err = read_err(&dir, "e.stl", replace_line(&text, 2, "  facet normal 0 0"));
    says(
        &err,
        &[
            "e.stl:2:",
            "`facet normal <x> <y> <z>`",
            "`facet normal 0 0`",
        ],
    );
    let err = read_err(&dir, "f.stl", replace_line(&text, 3, "    outer"));
    says(&err, &["f.stl:3:", "`outer loop`", "`outer`"]);
    let err = read_err(
        &dir,
        "g.stl",
        replace_line(&text, 4, "      vertex 1 inf 0"),
    );
    says(
        &err,
        &[
            "g.stl:4:",
            "a finite y coordinate of vertex 1 of facet 1",
            "`inf`",
        ],
    );
    // A stray byte in a text file is reported on its line, not taken for binary STL.
    let mut bytes = text.clone().into_bytes();
    bytes.insert(text.find("vertex 0 1").unwrap(), 0xff);
    let err = read_err(&dir, "i.stl", bytes);
    says(&err, &["i.stl:5:", "UTF-8", "0xff"]);
    // A truncated binary STL whose header says "solid" is still binary.
    let bin = stl_binary(b"solid cube", &cube_stl_tris());
    let err = read_err(&dir, "j.stl", &bin[..bin.len() - 10]);
    says(&err, &["j.stl: byte 80:", "12, which needs 684 bytes"]);
    let err = read_err(&dir, "h.stl", format!("{text}junk\n"));
    says(&err, &["h.stl:87:", "`solid`", "`junk`"]);
    // Cut in the middle: an error with a line, never a panic.
    // (Up to `endsolid`: cut after it, the name is merely shorter.)
    for cut in (10..text.len() - 6).step_by(37) {
        let err = read_err(&dir, "cut.stl", &text[..cut]);
        assert!(err.line().is_some() || err.offset().is_some(), "{err}");
    }
}

// ---------------------------------------------------------------------------------------------
// OBJ

/// The cube in OBJ, corners written with `corner(vertex_number_1_based, position_in_quad)`.
fn cube_obj(corner: impl Fn(usize, usize) -> String) -> String {
    let mut s = String::from("# cube\nmtllib cube.mtl\no cube\n");
    for p in corners() {
        s.push_str(&format!("v {} {} {}\n", p[0], p[1], p[2]));
    }
    s.push_str("vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\ng side\nusemtl red\ns off\n");
    for q in QUADS {
        s.push('f');
        for (k, &v) in q.iter().enumerate() {
            s.push(' ');
            s.push_str(&corner(v as usize + 1, k));
        }
        s.push('\n');
    }
    s
}

/// Writes one face corner from the 1-based vertex number and the corner's place in the quad.
type Corner = dyn Fn(usize, usize) -> String;

#[test]
fn obj_all_corner_forms_and_negative_indices() {
    let dir = scratch("obj");
    let expect = SurfaceMesh {
        vertices: corners(),
        triangles: cube_triangles(),
    };
    let forms: [(&str, Box<Corner>); 5] = [
        ("plain", Box::new(|v, _| format!("{v}"))),
        ("vt", Box::new(|v, k| format!("{v}/{}", k + 1))),
        ("vn", Box::new(|v, _| format!("{v}//1"))),
        ("vtvn", Box::new(|v, k| format!("{v}/{}/1", k + 1))),
        // All 8 vertices come before the faces: vertex v is -(9 - v).
        (
            "negative",
            Box::new(|v, _| format!("{}/-1/-1", v as i64 - 9)),
        ),
    ];
    for (name, form) in forms {
        let path = write(&dir, &format!("{name}.obj"), cube_obj(form));
        assert_eq!(read_surface(&path).unwrap(), expect, "{name}");
    }
    // Recognised by content without the extension; comments at the end of lines.
    let text = cube_obj(|v, _| format!("{v}")).replace("v 1 1 1", "v 1 1 1 # last corner");
    assert_eq!(
        read_surface(&write(&dir, "cube.model", text)).unwrap(),
        expect
    );
    // v with a weight or a colour.
    let text = cube_obj(|v, _| format!("{v}")).replace("v 1 1 1", "v 1 1 1 0.5 0.5 0.5");
    assert_eq!(read_surface(&write(&dir, "rgb.obj", text)).unwrap(), expect);
    // A pentagon becomes three triangles.
    let pent = "v 0 0 0\nv 1 0 0\nv 2 1 0\nv 1 2 0\nv 0 1 0\nf 1 2 3 4 5\n";
    let s = read_surface(&write(&dir, "pent.obj", pent)).unwrap();
    assert_eq!(s.triangles, vec![[0, 1, 2], [0, 2, 3], [0, 3, 4]]);
}

#[test]
fn obj_malformed() {
    let dir = scratch("obj-bad");
    let base = cube_obj(|v, _| format!("{v}"));
    // Line 4 is the first vertex, line 20 the first face.
    let err = read_err(&dir, "a.obj", replace_line(&base, 5, "v 1 O 0"));
    says(&err, &["a.obj:5:", "y coordinate of vertex 2", "`O`"]);
    let err = read_err(&dir, "b.obj", replace_line(&base, 20, "f 1 3 4 9"));
    says(
        &err,
        &["b.obj:20:", "1..=8", "8 vertices are defined so far", "`9`"],
    );
    let err = read_err(&dir, "c.obj", replace_line(&base, 20, "f 1 3 4 0"));
    says(&err, &["c.obj:20:", "`0`"]);
    let err = read_err(&dir, "d.obj", replace_line(&base, 20, "f 1 3 4 -9"));
    says(&err, &["d.obj:20:", "-8..=-1", "`-9`"]);
    let err = read_err(&dir, "e.obj", replace_line(&base, 20, "f 1 3"));
    says(&err, &["e.obj:20:", "at least 3 corners", "`f 1 3`"]);
    let err = read_err(&dir, "f.obj", replace_line(&base, 20, "f 1 3/x 4"));
    says(&err, &["f.obj:20:", "face corner", "`3/x`"]);
    let err = read_err(&dir, "g.obj", replace_line(&base, 20, "curv 0 1 1 2"));
    says(&err, &["g.obj:20:", "an OBJ statement", "`curv`"]);
    let err = read_err(&dir, "h.obj", replace_line(&base, 4, "v 0 0"));
    says(&err, &["h.obj:4:", "`v 0 0`"]);
    let err = read_err(&dir, "i.obj", replace_line(&base, 4, "v 0 nan 0"));
    says(
        &err,
        &["i.obj:4:", "finite y coordinate of vertex 1", "`nan`"],
    );
    let err = read_err(&dir, "j.obj", "f 1 2 3\nv 0 0 0\n");
    says(&err, &["j.obj:1:", "0 vertices are defined so far", "`1`"]);
}

// ---------------------------------------------------------------------------------------------
// PLY

#[derive(Clone, Copy, Debug)]
enum Enc {
    Ascii,
    Little,
    Big,
}

/// The cube in PLY, with an extra vertex property, an extra face property and an extra
/// element, so that the reader has to skip them.
fn cube_ply(enc: Enc, coord: &str, count: &str, index: &str) -> Vec<u8> {
    let format = match enc {
        Enc::Ascii => "ascii",
        Enc::Little => "binary_little_endian",
        Enc::Big => "binary_big_endian",
    };
    let mut out = format!(
        "ply\nformat {format} 1.0\ncomment made by lop's tests\nelement vertex 8\n\
         property {coord} x\nproperty {coord} y\nproperty {coord} z\nproperty uchar red\n\
         element face 6\nproperty list {count} {index} vertex_indices\nproperty short tag\n\
         element edge 1\nproperty int vertex1\nproperty int vertex2\nend_header\n"
    )
    .into_bytes();
    let put = |out: &mut Vec<u8>, ty: &str, v: f64| {
        let bytes: Vec<u8> = match ty {
            "float" => (v as f32).to_be_bytes().to_vec(),
            "double" => v.to_be_bytes().to_vec(),
            "uchar" => vec![v as u8],
            "short" => (v as i16).to_be_bytes().to_vec(),
            "int" => (v as i32).to_be_bytes().to_vec(),
            "uint" => (v as u32).to_be_bytes().to_vec(),
            _ => unreachable!(),
        };
        match enc {
            Enc::Ascii => out.extend_from_slice(format!("{v} ").as_bytes()),
            Enc::Big => out.extend_from_slice(&bytes),
            Enc::Little => out.extend(bytes.iter().rev()),
        }
    };
    let end = |out: &mut Vec<u8>| {
        if let Enc::Ascii = enc {
            out.pop();
            out.push(b'\n');
        }
    };
    for (i, p) in corners().iter().enumerate() {
        for &c in p {
            put(&mut out, coord, c);
        }
        put(&mut out, "uchar", i as f64);
        end(&mut out);
    }
    for q in QUADS {
        put(&mut out, count, 4.0);
        for v in q {
            put(&mut out, index, f64::from(v));
        }
        put(&mut out, "short", -7.0);
        end(&mut out);
    }
    put(&mut out, "int", 0.0);
    put(&mut out, "int", 1.0);
    end(&mut out);
    out
}

#[test]
fn ply_ascii_and_binary_both_byte_orders() {
    let dir = scratch("ply");
    let expect = SurfaceMesh {
        vertices: corners(),
        triangles: cube_triangles(),
    };
    for enc in [Enc::Ascii, Enc::Little, Enc::Big] {
        for coord in ["float", "double"] {
            for (count, index) in [("uchar", "int"), ("int", "uint"), ("uchar", "uint")] {
                let name = format!("{enc:?}-{coord}-{count}-{index}.ply");
                let path = write(&dir, &name, cube_ply(enc, coord, count, index));
                assert_eq!(read_surface(&path).unwrap(), expect, "{name}");
            }
        }
    }
    // Recognised by content.
    let path = write(
        &dir,
        "cube.bin",
        cube_ply(Enc::Little, "float", "uchar", "int"),
    );
    assert_eq!(read_surface(&path).unwrap(), expect);
}

#[test]
fn ply_malformed() {
    let dir = scratch("ply-bad");
    let ascii = String::from_utf8(cube_ply(Enc::Ascii, "float", "uchar", "int")).unwrap();
    // Header: 15 lines; vertex i on line 16 + i, face j on line 24 + j.
    let err = read_err(&dir, "a.ply", replace_line(&ascii, 2, "format ascii 2.0"));
    says(
        &err,
        &["a.ply:2:", "`format ascii 1.0`", "`format ascii 2.0`"],
    );
    let err = read_err(&dir, "b.ply", ascii.replace("end_header\n", ""));
    says(&err, &["b.ply:15:", "a PLY header line", "`0 0 0 0`"]);
    let err = read_err(&dir, "b2.ply", "ply\nformat ascii 1.0\nelement vertex 3\n");
    says(&err, &["b2.ply:3:", "`end_header`", "end of file"]);
    let err = read_err(&dir, "c.ply", replace_line(&ascii, 5, "property quad x"));
    says(&err, &["c.ply:5:", "`property quad x`"]);
    let err = read_err(&dir, "d.ply", replace_line(&ascii, 17, "1 0 zero 1"));
    says(
        &err,
        &["d.ply:17:", "a float for `z` of vertex 1", "`zero`"],
    );
    let err = read_err(&dir, "e.ply", replace_line(&ascii, 25, "4 4 5 7 8 -7"));
    says(
        &err,
        &["e.ply:25:", "vertex index below 8", "face 1", "`8`"],
    );
    let err = read_err(&dir, "f.ply", replace_line(&ascii, 25, "4 4 5 7 6 -7 9"));
    says(&err, &["f.ply:25:", "the end of face 1", "`9`"]);
    let err = read_err(&dir, "g.ply", replace_line(&ascii, 25, "2 4 5 -7"));
    says(&err, &["g.ply:25:", "at least 3 vertices", "`2`"]);
    let err = read_err(&dir, "h.ply", replace_line(&ascii, 4, "element vertex 9"));
    says(&err, &["h.ply:24:", "the end of vertex 8", "`1 -7`"]);
    let err = read_err(&dir, "i.ply", replace_line(&ascii, 16, "0 0 0 300"));
    says(
        &err,
        &["i.ply:16:", "a uchar for `red` of vertex 0", "`300`"],
    );
    let err = read_err(&dir, "j.ply", format!("{ascii}1 2\n"));
    says(&err, &["j.ply:31:", "end of the file", "`1 2`"]);
    let err = read_err(&dir, "k.ply", ascii.replace("vertex_indices", "corners"));
    says(&err, &["k.ply:9:", "vertex_indices", "none"]);

    // Binary: a face index out of range, at its byte offset.
    let mut bin = cube_ply(Enc::Little, "float", "uchar", "int");
    let body = bin.len() - (8 * 13 + 6 * 19 + 8);
    // Face 2's third index: 8 vertices of 13 bytes, two faces of 19 bytes, then count + 2 ints.
    let at = body + 8 * 13 + 2 * 19 + 1 + 2 * 4;
    bin[at..at + 4].copy_from_slice(&1000i32.to_le_bytes());
    let err = read_err(&dir, "l.ply", &bin);
    assert!(matches!(err, MeshReadError::BinaryParse { .. }), "{err}");
    assert_eq!(err.offset(), Some(at as u64), "{err}");
    says(&err, &["vertex index below 8", "face 2", "`1000`"]);
    // Truncated binary body.
    let bin = cube_ply(Enc::Big, "double", "int", "uint");
    let err = read_err(&dir, "m.ply", &bin[..bin.len() - 30]);
    says(&err, &["m.ply: byte", "end of file"]);
    let err = read_err(&dir, "n.ply", &bin[..bin.len() - 3]);
    says(
        &err,
        &[
            "n.ply: byte",
            "1 `edge` elements",
            "5 bytes left in the file",
        ],
    );
    // A count the file cannot hold is refused before reading.
    let mut big = bin.clone();
    let pos = big
        .windows(14)
        .position(|w| w == b"element face 6")
        .unwrap();
    big.splice(pos..pos + 14, b"element face 4000000000".iter().copied());
    let err = read_err(&dir, "o.ply", &big);
    says(
        &err,
        &[
            "o.ply: byte",
            "4000000000 `face` elements",
            "bytes left in the file",
        ],
    );
    let err = read_err(
        &dir,
        "p.ply",
        "ply\nformat ascii 1.0\nelement vertex 0\nend_header\n",
    );
    says(
        &err,
        &[
            "p.ply:3:",
            "`property <type> x` of the vertex element",
            "none",
        ],
    );
    let xyz = "property float x\nproperty float y\nproperty float z\n";
    let err = read_err(
        &dir,
        "q.ply",
        format!("ply\nformat ascii 1.0\nelement vertex 0\n{xyz}end_header\n"),
    );
    says(
        &err,
        &["q.ply:7:", "`element face <count>`", "`end_header`"],
    );
}

#[test]
fn unknown_surface_names_file_and_first_line() {
    let dir = scratch("surface-unknown");
    let err = read_err(&dir, "x.srf", "hello world\n");
    assert!(matches!(err, MeshReadError::UnsupportedFormat { .. }));
    says(&err, &["x.srf", "STL", "OBJ", "PLY", "`hello world`"]);
    // A VTK volume mesh is recognised, and refused as a surface at its first tetrahedron.
    let err = read_err(&dir, "y.vtk", VTK);
    says(&err, &["y.vtk:15:", "cell 0", "type `10`", "read_mesh"]);
    let err = read_surface(&dir.join("missing.stl")).unwrap_err();
    assert!(matches!(err, MeshReadError::Io { .. }));
}
