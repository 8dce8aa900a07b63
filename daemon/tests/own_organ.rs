//! "Bring your own organ": a closed surface in centimetres (an OBJ ellipsoid, liver-sized,
//! 15 × 10 × 8 cm) becomes a running scene with two commands, `lopd mesh tetrahedralize` and
//! `lopd scene new`, and the mock device's poke touches it.
//!
//! Invariants guarded:
//! - the surface is checked and filled; the mesh is in metres and `lopd mesh info` reads it;
//!   the input surface is kept beside it and the scene draws the body by it;
//! - the generated scene validates and loads, its fixed patch is on the back (−z) and the
//!   front is free; the poke script presses into the body: offline (`lopd simulate`) and live
//!   (`lopd run` with the mock device) the tool force is clearly nonzero;
//! - a defective surface is refused with exit code 2 naming the triangles, a missing tetgen is
//!   a message that says how to install it, and `--select` shows what a selector picks.

mod lopd_cli;

use std::path::{Path, PathBuf};

use lopd_cli::{lopd, run};

/// This test's scratch folder `name`.
fn temp_dir(name: &str) -> PathBuf {
    lopd_cli::temp_dir("own-organ", name)
}

/// An icosphere subdivided `levels` times, scaled to semi-axes `axes` (file units), as OBJ.
fn ellipsoid_obj(axes: [f64; 3], levels: u32) -> String {
    let (v, f) = lop_test_support::fixtures::icosphere(levels as usize);
    let mut obj = String::from("# liver-sized ellipsoid, centimetres\n");
    for p in &v {
        obj += &format!(
            "v {} {} {}\n",
            p[0] * axes[0],
            p[1] * axes[1],
            p[2] * axes[2]
        );
    }
    for [a, b, c] in &f {
        obj += &format!("f {} {} {}\n", a + 1, b + 1, c + 1);
    }
    obj
}

/// Largest `column` of `steps.csv` rows (any body).
fn max_column(csv: &str, column: &str) -> f64 {
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let k = header
        .iter()
        .position(|h| *h == column)
        .unwrap_or_else(|| panic!("no {column} in {header:?}"));
    lines
        .map(|l| l.split(',').nth(k).unwrap().parse::<f64>().unwrap())
        .fold(0.0, f64::max)
}

#[test]
fn an_obj_surface_in_centimetres_becomes_a_running_scene() {
    let dir = temp_dir("e2e");
    let obj = dir.join("liver.obj");
    std::fs::write(&obj, ellipsoid_obj([7.5, 5.0, 4.0], 2)).unwrap();

    // 1. Tetrahedralise.
    let prefix = dir.join("mesh/liver");
    let (code, out, err) = run(lopd()
        .args(["mesh", "tetrahedralize"])
        .arg(&obj)
        .arg("--out")
        .arg(&prefix)
        .args(["--units", "cm", "--edge", "2.5cm", "--quality", "2"]));
    assert_eq!(code, 0, "{out}\n{err}");
    assert!(
        out.contains("closed, manifold, consistently wound"),
        "{out}"
    );
    for ext in ["node", "ele", "face"] {
        assert!(prefix.with_extension(ext).is_file(), "{ext}");
    }
    // The input surface, kept beside the mesh to draw the organ by.
    let render = dir.join("mesh/liver.render.obj");
    assert!(out.contains(&render.display().to_string()), "{out}");
    let kept = lop_sim::mesh::read_surface(&render).unwrap();
    assert_eq!((kept.vertices.len(), kept.triangles.len()), (162, 320));
    let (code, info, err) = run(lopd().args(["mesh", "info"]).arg(&prefix));
    assert_eq!(code, 0, "{err}");
    // In metres: 0.15 x 0.10 x 0.08 m.
    assert!(info.contains("0.150000 x 0.100000 x 0.080000 m"), "{info}");

    // 2. The scene.
    let scene = dir.join("scenes/myliver.toml");
    let (code, out, err) = run(lopd()
        .args(["scene", "new", "myliver", "--mesh"])
        .arg(&prefix)
        .args(["--tissue", "liver", "--out"])
        .arg(&scene));
    assert_eq!(code, 0, "{out}\n{err}");
    let script = dir.join("scenes/myliver-poke.toml");
    assert!(script.is_file());
    let text = std::fs::read_to_string(&scene).unwrap();
    assert!(
        text.contains("render_surface = \"../mesh/liver.render.obj\""),
        "{text}"
    );
    let loaded = lop_scene::load(lop_config::load_scene(&scene).unwrap()).unwrap();
    // Drawn by the surface as it came: every vertex embedded, none far outside the mesh.
    let drawn = &loaded.topology.bodies[0];
    assert_eq!(
        (drawn.render_vertex_count, drawn.render_triangle_count),
        (162, 320)
    );
    let body = &loaded.world.bodies[0];
    assert_eq!(loaded.scene.bodies[0].fem.as_ref().unwrap().young, 4100.0);
    // Fixed on the back only: every fixed node in the back 15 % of the depth (z <= -0.028).
    assert!(body.mesh.fixed.len() >= 3, "{:?}", body.mesh.fixed);
    for &n in &body.mesh.fixed {
        assert!(body.mesh.nodes[n as usize][2] <= -0.04 + 0.15 * 0.08 + 1e-9);
    }
    // Running it again refuses to overwrite.
    let (code, _, err) = run(lopd()
        .args(["scene", "new", "myliver", "--mesh"])
        .arg(&prefix)
        .arg("--out")
        .arg(&scene));
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("exists") && err.contains("--force"), "{err}");

    // 3a. Offline: the poke presses the body.
    let sim = dir.join("sim");
    let (code, out, err) = run(lopd()
        .args(["simulate", "--scene"])
        .arg(&scene)
        .arg("--script")
        .arg(&script)
        // The cage steps at 20 ms until the tool is near, then the precise model at 1 ms:
        // 1500 steps take the poke past its full depth (2 s into the script).
        .args(["--steps", "1500", "--out"])
        .arg(&sim));
    assert_eq!(code, 0, "{out}\n{err}");
    let steps = std::fs::read_to_string(sim.join("steps.csv")).unwrap();
    let force = max_column(&steps, "contact_force_n");
    assert!(
        force > 0.05 && force < 3.0,
        "offline contact force {force} N"
    );

    // 3b. Live, with the mock device playing the scene's poke: the hand feels the body.
    let forces = dir.join("forces.csv");
    let (code, _, err) = run(lopd()
        .env("LOP_LOG", "info")
        .args([
            "run",
            "--device",
            "mock",
            "--duration",
            "3",
            "--quiet",
            "--scene",
        ])
        .arg(&scene)
        .args(["--prefix", &format!("own-organ-{}", std::process::id())])
        .arg("--force-log")
        .arg(&forces));
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("myliver-poke.toml"), "{err}");
    let peak = std::fs::read_to_string(&forces)
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| {
            l.split(',')
                .skip(1)
                .map(|v| v.parse::<f64>().unwrap().powi(2))
                .sum::<f64>()
                .sqrt()
        })
        .fold(0.0, f64::max);
    assert!(peak > 0.05 && peak <= 3.0, "live peak force {peak} N");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn defective_surfaces_are_refused_naming_the_triangles() {
    let dir = temp_dir("defects");
    let obj = ellipsoid_obj([7.5, 5.0, 4.0], 1);
    // Drop the last face: a hole of three edges.
    let open: String = {
        let mut lines: Vec<&str> = obj.lines().collect();
        lines.pop();
        lines.join("\n") + "\n"
    };
    let path = dir.join("open.obj");
    std::fs::write(&path, &open).unwrap();
    let tetra = |extra: &[&str]| {
        run(lopd()
            .args(["mesh", "tetrahedralize"])
            .arg(&path)
            .arg("--out")
            .arg(dir.join("out/open"))
            .args(["--units", "cm"])
            .args(extra))
    };
    let (code, _, err) = tetra(&[]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("3 open edges") && err.contains("open.obj") && err.contains("triangle"),
        "{err}"
    );
    assert!(err.contains("--close-holes"), "{err}");
    // Closing it makes it fine.
    let (code, out, err) = tetra(&["--close-holes", "3", "--quality", "2"]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("holes closed: 1"), "{out}");

    // A missing tetgen says how to get it (runtime failure, exit 1).
    let (code, _, err) = run(lopd()
        .env("LOP_TETGEN", dir.join("no-tetgen"))
        .args(["mesh", "tetrahedralize"])
        .arg(&path)
        .args(["--mesher", "tetgen", "--out", "x"]));
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("tetgen not found") && err.contains("scripts/setup.sh"),
        "{err}"
    );

    // Bad sizes are bad input.
    let (code, _, err) = tetra(&["--edge=-3mm"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("-3mm"), "{err}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn mesh_info_shows_what_a_selector_picks() {
    let cylinder = Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/meshes/cylinder");
    // The base of the cylinder (y = 0): its 22 .bnd nodes.
    let (code, out, err) = run(lopd().args(["mesh", "info"]).arg(&cylinder).args([
        "--select",
        "kind = \"slab\", point = [0, 0.0001, 0], normal = [0, 1, 0]",
    ]));
    assert_eq!(code, 0, "{err}");
    assert!(
        out.contains("selected:          22 nodes (22 on the surface)"),
        "{out}"
    );
    assert!(out.contains("selected nodes:    0 1 2"), "{out}");
    // A bad selector names the key.
    let (code, _, err) = run(lopd().args(["mesh", "info"]).arg(&cylinder).args([
        "--select",
        "kind = \"sphere\", center = [0, 0, 0], radius = -1",
    ]));
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("select.radius") && err.contains("-1"), "{err}");
}
