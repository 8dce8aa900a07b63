//! `lopd mesh tetrahedralize` makes the mesh asked for, from clean and from defective
//! surfaces (issue 28):
//! - `--tets N` gives N ± 20 % tetrahedra whose smallest dihedral angle is at least 10°, with
//!   gmsh (the default) and with fTetWild;
//! - a surface with crossing triangles, and one with holes, is refused naming the defects and
//!   pointing at `--repair`; with `--repair` it is meshed to the same targets, what was
//!   repaired is reported, and the boundary stays within the stated distance of the input;
//! - a surface that cannot be repaired (an open sheet) is refused saying what is wrong; a
//!   missing mesher is named with how to install it.
//!
//! The surfaces are small (320 triangles, 600–900 tetrahedra) to keep CI short. The tests
//! need gmsh and pytetwild and fail, not skip, without them: run `scripts/setup.sh`.

use crate::lopd_cli;

use std::path::{Path, PathBuf};

use lopd_cli::{lopd, run};

/// This test's scratch folder `name`.
fn temp_dir(name: &str) -> PathBuf {
    lopd_cli::temp_dir("tetra", name)
}

/// A 15 × 10 × 8 cm ellipsoid (icosphere level 2: 162 vertices, 320 triangles), in cm.
fn ellipsoid() -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let (v, f) = lop_test_support::fixtures::icosphere(2);
    let v = v
        .iter()
        .map(|p| [p[0] * 7.5, p[1] * 5.0, p[2] * 4.0])
        .collect();
    (v, f)
}

fn write_obj(path: &Path, v: &[[f64; 3]], f: &[[u32; 3]]) {
    let mut obj = String::new();
    for p in v {
        obj += &format!("v {} {} {}\n", p[0], p[1], p[2]);
    }
    for [a, b, c] in f {
        obj += &format!("f {} {} {}\n", a + 1, b + 1, c + 1);
    }
    std::fs::write(path, obj).unwrap();
}

/// The ellipsoid and a smaller lobe overlapping it, in one file: two closed sheets whose
/// triangles cross along a loop (lobes segmented apart and saved together).
fn crossing() -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let (mut v, mut f) = ellipsoid();
    let (lobe, lf) = lop_test_support::fixtures::icosphere(2);
    let base = v.len() as u32;
    v.extend(
        lobe.iter()
            .map(|p| [6.5 + p[0] * 3.5, 1.0 + p[1] * 3.0, 1.5 + p[2] * 3.0]),
    );
    f.extend(lf.iter().map(|t| t.map(|i| i + base)));
    (v, f)
}

/// The ellipsoid with the triangles around two vertices removed: two holes of 5-6 edges.
fn holes() -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let (v, f) = ellipsoid();
    let f = f
        .into_iter()
        .filter(|t| !t.contains(&20) && !t.contains(&100))
        .collect();
    (v, f)
}

/// The numbers after `key` on the output's line that starts with it.
fn numbers(out: &str, key: &str) -> Vec<f64> {
    let line = out
        .lines()
        .find(|l| l.trim_start().starts_with(key))
        .unwrap_or_else(|| panic!("no {key:?} in:\n{out}"));
    line[line.find(key).unwrap() + key.len()..]
        .split(|c: char| !(c.is_ascii_digit() || c == '.' || c == '-' || c == 'e'))
        .filter_map(|w| w.parse().ok())
        .collect()
}

/// Runs the command to `--tets n` and checks the targets on what it printed and wrote.
fn meshed_to(surface: &Path, n: usize, extra: &[&str]) -> String {
    let prefix = surface.with_extension("");
    let (code, out, err) = run(lopd()
        .args(["mesh", "tetrahedralize"])
        .arg(surface)
        .arg("--out")
        .arg(&prefix)
        .args(["--units", "cm", "--tets", &n.to_string()])
        .args(extra));
    assert_eq!(code, 0, "{out}\n{err}");
    println!("{out}");
    // The mesh as written reads with lop's own reader (no inverted or degenerate tetrahedra).
    let mesh = lop_sim::mesh::read_tetgen(&prefix).unwrap();
    let made = mesh.tets.len() as f64;
    assert!(
        (made - n as f64).abs() <= 0.2 * n as f64,
        "asked {n}, made {made}:\n{out}"
    );
    let dihedral = numbers(&out, "dihedral angles:");
    assert!(
        dihedral[0] >= 10.0,
        "smallest dihedral {}:\n{out}",
        dihedral[0]
    );
    // The boundary is where the surface is: the printed distance within the allowed one.
    let fit = numbers(&out, "fit:");
    assert!(fit[1] <= fit[3], "{out}");
    out
}

#[test]
fn a_clean_surface_gets_the_size_asked_for_without_slivers() {
    let dir = temp_dir("clean");
    let (v, f) = ellipsoid();
    let obj = dir.join("ellipsoid.obj");
    write_obj(&obj, &v, &f);
    let out = meshed_to(&obj, 900, &[]);
    assert!(out.contains("mesher: gmsh"), "{out}");
    // gmsh's boundary vertices lie on the input triangles (well within 1e-4 of the diagonal).
    assert!(numbers(&out, "fit:")[1] < 0.01, "{out}");
    // fTetWild at 2,000: near 900 this small surface sits at its count's floor (its own
    // surface envelope), and its count varies from run to run (1,104-1,162 for edges of
    // 20.7-23.8 mm in one CI run, 959 at 21.7 mm in another); at 2,000 it follows the edge.
    let out = meshed_to(&obj, 2000, &["--mesher", "ftetwild"]);
    assert!(out.contains("mesher: fTetWild"), "{out}");
    // --edge keeps working: one meshing at that size.
    let (code, out, err) = run(lopd()
        .args(["mesh", "tetrahedralize"])
        .arg(&obj)
        .args(["--units", "cm", "--edge", "3cm", "--out"])
        .arg(dir.join("edge")));
    assert_eq!(code, 0, "{out}\n{err}");
    assert!(out.contains("meshing 1: edge 30.00 mm"), "{out}");
    assert!(!out.contains("meshing 2"), "{out}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn defective_surfaces_are_refused_then_repaired_on_request() {
    let dir = temp_dir("repair");
    for (name, (v, f), defect) in [
        ("crossing", crossing(), "self-intersect"),
        ("holes", holes(), "open edges"),
    ] {
        let obj = dir.join(format!("{name}.obj"));
        write_obj(&obj, &v, &f);
        let (code, _, err) = run(lopd()
            .args(["mesh", "tetrahedralize"])
            .arg(&obj)
            .args(["--units", "cm", "--out"])
            .arg(dir.join("refused")));
        assert_eq!(code, 2, "{name}: {err}");
        assert!(
            err.contains(defect) && err.contains("--repair") && err.contains("triangle"),
            "{name}: {err}"
        );
        let out = meshed_to(&obj, 700, &["--repair"]);
        assert!(out.contains("repaired by fTetWild"), "{name}: {out}");
        let repaired = numbers(&out, "repaired by fTetWild in");
        // [seconds, crossing pairs, open edges, other, vertices, triangles, before, after, %]
        if name == "crossing" {
            assert!(repaired[1] > 0.0, "{out}");
        } else {
            assert!(repaired[2] > 0.0, "{out}");
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn missing_meshers_are_named() {
    let dir = temp_dir("sheet");
    // Half the ellipsoid: a bowl, which encloses nothing. `--repair` refuses it before any
    // mesher runs (fTetWild would now and then wrap a thin shell around the sheet), with
    // both meshers that repair.
    let (v, f) = ellipsoid();
    let bowl: Vec<[u32; 3]> = f
        .into_iter()
        .filter(|t| t.iter().all(|&i| v[i as usize][2] <= 0.0))
        .collect();
    let obj = dir.join("bowl.obj");
    write_obj(&obj, &v, &bowl);
    for mesher in ["gmsh", "ftetwild"] {
        let (code, _, err) = run(lopd()
            .args(["mesh", "tetrahedralize"])
            .arg(&obj)
            .args(["--units", "cm", "--repair", "--mesher", mesher, "--out"])
            .arg(dir.join("bowl")));
        assert_eq!(code, 2, "{err}");
        assert!(
            err.contains("bowl.obj")
                && err.contains("cannot be repaired")
                && err.contains("open edges")
                && err.contains("% of the surface they would close"),
            "{err}"
        );
    }

    let (v, f) = ellipsoid();
    let good = dir.join("good.obj");
    write_obj(&good, &v, &f);
    for (env, value, mesher, says) in [
        ("LOP_GMSH", "no-gmsh", "gmsh", "gmsh not found"),
        ("LOP_TETGEN", "no-tetgen", "tetgen", "tetgen not found"),
        ("LOP_PYTHON", "no-python", "ftetwild", "pytetwild"),
    ] {
        let (code, _, err) = run(lopd()
            .env(env, dir.join(value))
            .args(["mesh", "tetrahedralize"])
            .arg(&good)
            .args(["--mesher", mesher, "--out"])
            .arg(dir.join("x")));
        assert_eq!(code, 1, "{err}");
        assert!(
            err.contains(says) && err.contains("scripts/setup.sh"),
            "{err}"
        );
    }
    // A TetGen switch with another mesher is bad input naming both.
    let (code, _, err) = run(lopd()
        .args(["mesh", "tetrahedralize"])
        .arg(&good)
        .args(["--mesher", "gmsh", "--quality", "1.2", "--out"])
        .arg(dir.join("x")));
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("--quality") && err.contains("gmsh"), "{err}");
    std::fs::remove_dir_all(&dir).unwrap();
}
