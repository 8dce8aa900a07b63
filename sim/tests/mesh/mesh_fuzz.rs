//! Mesh readers: mutated files of every format (TetGen, Gmsh 1, 2.2 and 4.1, legacy VTK ASCII
//! and binary, VTK XML in each encoding; STL, OBJ, PLY and VTK surfaces) never panic a reader.

use crate::mesh_text;
use crate::vtk_build;

use std::fs;

use lop_sim::mesh::{read_mesh, read_surface, MeshReadError, SurfaceMesh, TetMesh};
use lop_test_support::rng::Rng;
use mesh_text::*;

// ---------------------------------------------------------------------------------------------
// fuzz-ish: mutated inputs never panic

const TOKENS: [&str; 16] = [
    "",
    "0",
    "-1",
    "1",
    "8",
    "9",
    "4",
    "10",
    "nan",
    "-inf",
    "1e999",
    "x",
    "$EndNodes",
    "99999999999999999999",
    "1.5",
    "\u{feff}",
];

fn mutate(rng: &mut Rng, text: &[u8]) -> Vec<u8> {
    let mut out = text.to_vec();
    for _ in 0..1 + rng.below(2) * rng.below(3) {
        match rng.below(6) {
            0 => {
                let at = rng.below(out.len() + 1);
                out.truncate(at);
            }
            1 => {
                // Replace a whitespace-separated token.
                let s = String::from_utf8_lossy(&out).into_owned();
                let tokens: Vec<&str> = s.split_inclusive(char::is_whitespace).collect();
                if tokens.is_empty() {
                    continue;
                }
                let k = rng.below(tokens.len());
                let with = TOKENS[rng.below(TOKENS.len())];
                let mut joined = String::new();
                for (i, t) in tokens.iter().enumerate() {
                    if i == k {
                        joined.push_str(with);
                        joined.push_str(&t[t.trim_end().len()..]);
                    } else {
                        joined.push_str(t);
                    }
                }
                out = joined.into_bytes();
            }
            2 => {
                // Delete or duplicate a line.
                let s = String::from_utf8_lossy(&out).into_owned();
                let mut lines: Vec<&str> = s.lines().collect();
                if lines.is_empty() {
                    continue;
                }
                let k = rng.below(lines.len());
                if rng.below(2) == 0 {
                    lines.remove(k);
                } else {
                    lines.insert(k, lines[k]);
                }
                out = (lines.join("\n") + "\n").into_bytes();
            }
            3 => {
                if !out.is_empty() {
                    let k = rng.below(out.len());
                    out[k] = b" 0123456789.-e\n#$x"[rng.below(18)];
                }
            }
            4 => {
                let k = rng.below(out.len() + 1);
                out.insert(k, (rng.next_u64() & 0xff) as u8);
            }
            _ => {
                // Swap two digits somewhere: changes indices and counts plausibly.
                let digits: Vec<usize> = (0..out.len())
                    .filter(|&i| out[i].is_ascii_digit())
                    .collect();
                if digits.len() >= 2 {
                    let a = digits[rng.below(digits.len())];
                    let b = digits[rng.below(digits.len())];
                    out.swap(a, b);
                }
            }
        }
    }
    out
}

/// Checks what a successful read promises.
fn check_ok(mesh: &TetMesh) {
    let n = mesh.nodes.len() as u32;
    assert!(!mesh.tets.is_empty());
    for (i, t) in mesh.tets.iter().enumerate() {
        assert!(t.iter().all(|&v| v < n));
        assert!(mesh.tet_volume(i) > 0.0);
    }
    assert!(mesh.surface.iter().flatten().all(|&v| v < n));
    assert!(mesh.fixed.windows(2).all(|w| w[0] < w[1]));
    assert!(mesh.fixed.iter().all(|&v| v < n));
    assert!(mesh.nodes.iter().flatten().all(|v| v.is_finite()));
    let info = mesh.info();
    assert!(info.volume > 0.0 && info.quality_min > 0.0 && info.quality_mean <= 1.0 + 1e-12);
}

#[test]
fn mutated_files_never_panic() {
    let dir = scratch("fuzz");
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    let mut outcomes = [0usize; 2];
    for round in 0..720 {
        let which = round % 6;
        let result = match which {
            0 | 1 => {
                let (node, ele) = if which == 0 {
                    (mutate(&mut rng, NODE1.as_bytes()), ELE1.as_bytes().to_vec())
                } else {
                    (NODE1.as_bytes().to_vec(), mutate(&mut rng, ELE1.as_bytes()))
                };
                fs::write(dir.join("f.node"), node).unwrap();
                fs::write(dir.join("f.ele"), ele).unwrap();
                let bnd = mutate(&mut rng, b"2\n1\n8\n");
                fs::write(dir.join("f.bnd"), bnd).unwrap();
                read_mesh(&dir.join("f"))
            }
            2 => {
                let path = write(&dir, "f.msh", mutate(&mut rng, MSH22.as_bytes()));
                read_mesh(&path)
            }
            3 => {
                let path = write(&dir, "g.msh", mutate(&mut rng, MSH41.as_bytes()));
                read_mesh(&path)
            }
            4 => {
                // Format 1, under a name that does not say Gmsh.
                let path = write(&dir, "h.dat", mutate(&mut rng, MSH1.as_bytes()));
                read_mesh(&path)
            }
            _ => {
                let path = write(&dir, "f.vtk", mutate(&mut rng, VTK.as_bytes()));
                read_mesh(&path)
            }
        };
        match result {
            Ok(mesh) => {
                check_ok(&mesh);
                outcomes[0] += 1;
            }
            Err(err) => {
                let msg = err.to_string();
                if std::env::var_os("LOP_MESH_FUZZ_LOG").is_some() {
                    eprintln!("{msg}");
                }
                assert!(
                    msg.contains(dir.to_str().unwrap()),
                    "message does not name the file: {msg}"
                );
                outcomes[1] += 1;
            }
        }
    }
    // The mutations must exercise both paths.
    println!("ok: {}, errors: {}", outcomes[0], outcomes[1]);
    assert!(outcomes[0] >= 20 && outcomes[1] >= 300, "{outcomes:?}");
}

// ---------------------------------------------------------------------------------------------
// surfaces

/// A tetrahedron's surface in each surface format: (file name, contents).
fn surface_fixtures() -> Vec<(&'static str, Vec<u8>)> {
    let p: [[f32; 3]; 4] = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
    ];
    let tris = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
    let mut ascii = String::from("solid t\n");
    let mut binary = vec![b' '; 80];
    binary.extend_from_slice(&4u32.to_le_bytes());
    for t in tris {
        ascii.push_str("facet normal 0 0 0\nouter loop\n");
        binary.extend_from_slice(&[0; 12]);
        for i in t {
            let [x, y, z] = p[i];
            ascii.push_str(&format!("vertex {x} {y} {z}\n"));
            for c in [x, y, z] {
                binary.extend_from_slice(&c.to_le_bytes());
            }
        }
        ascii.push_str("endloop\nendfacet\n");
        binary.extend_from_slice(&[0; 2]);
    }
    ascii.push_str("endsolid t\n");
    let mut obj = String::from("# t\n");
    let mut ply = String::from(
        "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n\
         property float z\nelement face 4\nproperty list uchar int vertex_indices\nend_header\n",
    );
    let mut ply_bin = ply.replace("ascii", "binary_big_endian").into_bytes();
    for [x, y, z] in p {
        obj.push_str(&format!("v {x} {y} {z}\n"));
        ply.push_str(&format!("{x} {y} {z}\n"));
        for c in [x, y, z] {
            ply_bin.extend_from_slice(&c.to_be_bytes());
        }
    }
    for [a, b, c] in tris {
        obj.push_str(&format!("f {}/1 -{} {}//2\n", a + 1, 4 - b, c + 1));
        ply.push_str(&format!("3 {a} {b} {c}\n"));
        ply_bin.push(3);
        for i in [a, b, c] {
            ply_bin.extend_from_slice(&(i as i32).to_be_bytes());
        }
    }
    vec![
        ("a.stl", ascii.into_bytes()),
        ("b.stl", binary),
        ("c.obj", obj.into_bytes()),
        ("d.ply", ply.into_bytes()),
        ("e.ply", ply_bin),
    ]
}

fn check_surface(s: &SurfaceMesh) {
    let n = s.vertices.len() as u32;
    assert!(s.triangles.iter().flatten().all(|&v| v < n));
    assert!(s.vertices.iter().flatten().all(|v| v.is_finite()));
}

#[test]
fn mutated_surfaces_never_panic() {
    let dir = scratch("fuzz-surface");
    let fixtures = surface_fixtures();
    for (name, bytes) in &fixtures {
        let s = read_surface(&write(&dir, name, bytes)).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!((s.vertices.len(), s.triangles.len()), (4, 4), "{name}");
    }
    let mut rng = Rng(0x2545_f491_4f6c_dd1d);
    let mut outcomes = [0usize; 2];
    for round in 0..1000 {
        let (name, bytes) = &fixtures[round % fixtures.len()];
        // Half of the rounds under a name that says nothing about the format.
        let name = if round % 2 == 0 { name } else { "x.dat" };
        let path = write(&dir, name, mutate(&mut rng, bytes));
        match read_surface(&path) {
            Ok(s) => {
                check_surface(&s);
                outcomes[0] += 1;
            }
            Err(err) => {
                let msg = err.to_string();
                if std::env::var_os("LOP_MESH_FUZZ_LOG").is_some() {
                    eprintln!("{msg}");
                }
                assert!(msg.contains(name), "message does not name the file: {msg}");
                let located = err.line().is_some()
                    || err.offset().is_some()
                    || matches!(err, MeshReadError::UnsupportedFormat { .. });
                assert!(located, "no line or offset: {msg}");
                outcomes[1] += 1;
            }
        }
    }
    println!("ok: {}, errors: {}", outcomes[0], outcomes[1]);
    assert!(outcomes[0] >= 50 && outcomes[1] >= 300, "{outcomes:?}");
}

// ---------------------------------------------------------------------------------------------
// VTK: binary legacy, XML in each encoding, POLYDATA

/// The cube of `mesh_text::VTK` as a binary legacy file, in the 5.1 layout or the classic one.
fn vtk_binary(v51: bool) -> Vec<u8> {
    let mut b =
        b"# vtk DataFile Version 5.1\ncube\nBINARY\nDATASET UNSTRUCTURED_GRID\nPOINTS 8 float\n"
            .to_vec();
    for p in cube_nodes() {
        for c in p {
            b.extend((c as f32).to_be_bytes());
        }
    }
    let tets = cube_tets();
    if v51 {
        b.extend(b"\nCELLS 6 20\nOFFSETS vtktypeint64\n");
        for o in 0..6i64 {
            b.extend((4 * o).to_be_bytes());
        }
        b.extend(b"\nCONNECTIVITY vtktypeint64\n");
        for i in tets.iter().flatten() {
            b.extend(i64::from(*i).to_be_bytes());
        }
    } else {
        b.extend(b"\nCELLS 5 25\n");
        for t in &tets {
            b.extend(4i32.to_be_bytes());
            for i in t {
                b.extend((*i as i32).to_be_bytes());
            }
        }
    }
    b.extend(b"\nCELL_TYPES 5\n");
    for _ in &tets {
        b.extend(10i32.to_be_bytes());
    }
    b.extend(b"\n");
    b
}

/// A tetrahedron's surface as a legacy POLYDATA (ASCII or binary) and a `.vtp`.
fn polydata_fixtures() -> Vec<(&'static str, Vec<u8>)> {
    let p = [
        [0.0f32, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
    ];
    let tris = [[0i32, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
    let mut ascii =
        String::from("# vtk DataFile Version 3.0\nt\nASCII\nDATASET POLYDATA\nPOINTS 4 float\n");
    let mut bin =
        b"# vtk DataFile Version 3.0\nt\nBINARY\nDATASET POLYDATA\nPOINTS 4 float\n".to_vec();
    for q in p {
        ascii += &format!("{} {} {}\n", q[0], q[1], q[2]);
        for c in q {
            bin.extend(c.to_be_bytes());
        }
    }
    ascii += "POLYGONS 4 16\n";
    bin.extend(b"\nPOLYGONS 4 16\n");
    for t in tris {
        ascii += &format!("3 {} {} {}\n", t[0], t[1], t[2]);
        bin.extend(3i32.to_be_bytes());
        for i in t {
            bin.extend(i.to_be_bytes());
        }
    }
    let e = vtk_build::Encoding {
        place: vtk_build::Place::Raw,
        big: true,
        u64_header: false,
        zlib: Some(16),
        separate: true,
    };
    let points = p.iter().flatten().map(|&c| f64::from(c)).collect();
    let conn = tris.iter().flatten().map(|&i| f64::from(i)).collect();
    let vtp = vtk_build::vtk_xml(
        &e,
        "PolyData",
        "NumberOfPoints=\"4\" NumberOfPolys=\"4\"",
        &[
            (
                "Points",
                vec![vtk_build::Array::new("Float32", "Points", 3, points)],
            ),
            (
                "Polys",
                vec![
                    vtk_build::Array::new("Int64", "connectivity", 1, conn),
                    vtk_build::Array::new("Int64", "offsets", 1, vec![3., 6., 9., 12.]),
                ],
            ),
        ],
    );
    vec![
        ("s.vtk", ascii.into_bytes()),
        ("t.vtk", bin),
        ("u.vtp", vtp),
    ]
}

#[test]
fn mutated_vtk_files_never_panic() {
    use vtk_build::{cube_vtu, Encoding, Place};
    let dir = scratch("fuzz-vtk");
    let enc = |place, big, u64_header, zlib, separate| Encoding {
        place,
        big,
        u64_header,
        zlib,
        separate,
    };
    let volumes: Vec<(&str, Vec<u8>)> = vec![
        ("a.vtk", vtk_binary(true)),
        ("b.vtk", vtk_binary(false)),
        (
            "c.vtu",
            cube_vtu(&enc(Place::Ascii, false, false, None, true)),
        ),
        (
            "d.vtu",
            cube_vtu(&enc(Place::Inline, false, false, None, false)),
        ),
        (
            "e.vtu",
            cube_vtu(&enc(Place::Inline, true, true, Some(32), true)),
        ),
        (
            "f.vtu",
            cube_vtu(&enc(Place::Raw, false, false, None, true)),
        ),
        (
            "g.vtu",
            cube_vtu(&enc(Place::Raw, true, true, Some(32), true)),
        ),
        (
            "h.vtu",
            cube_vtu(&enc(Place::Base64, false, false, Some(32), true)),
        ),
    ];
    for (name, bytes) in &volumes {
        let mesh = read_mesh(&write(&dir, name, bytes)).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(mesh.tets, cube_tets(), "{name}");
    }
    let surfaces = polydata_fixtures();
    for (name, bytes) in &surfaces {
        let s = read_surface(&write(&dir, name, bytes)).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!((s.vertices.len(), s.triangles.len()), (4, 4), "{name}");
    }
    let mut rng = Rng(0x1234_5678_9abc_def1);
    let mut outcomes = [0usize; 2];
    let n = volumes.len() + surfaces.len();
    for round in 0..2200 {
        let k = round % n;
        let surface = k >= volumes.len();
        let (name, bytes) = if surface {
            &surfaces[k - volumes.len()]
        } else {
            &volumes[k]
        };
        let path = write(&dir, name, mutate(&mut rng, bytes));
        let result = if surface {
            read_surface(&path).map(|s| check_surface(&s))
        } else {
            read_mesh(&path).map(|m| check_ok(&m))
        };
        match result {
            Ok(()) => outcomes[0] += 1,
            Err(err) => {
                let msg = err.to_string();
                if std::env::var_os("LOP_MESH_FUZZ_LOG").is_some() {
                    eprintln!("{msg}");
                }
                assert!(msg.contains(name), "message does not name the file: {msg}");
                outcomes[1] += 1;
            }
        }
    }
    println!("ok: {}, errors: {}", outcomes[0], outcomes[1]);
    assert!(outcomes[0] >= 100 && outcomes[1] >= 1000, "{outcomes:?}");
}
