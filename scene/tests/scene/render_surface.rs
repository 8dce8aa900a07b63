//! A body's `render_surface`: read, placed by the body's transform and embedded in its placed
//! mesh, so that at rest every render vertex is drawn exactly where the file puts it (moved
//! into the scene), and published in the topology after the triangles and tetrahedra. A
//! surface in other units than its mesh is refused naming the scene, the body, the file and the
//! vertex; a missing file names the key.

use std::path::PathBuf;

use lop_config::{load_scene, parse_scene};
use lop_scene::{load, render_surface, RENDER_VERTEX_WORDS};
use lop_sim::mesh::{read_mesh, read_surface, SurfaceMesh};

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The cylinder mesh (assets/meshes/cylinder) raised by 0.5 m, drawn by `render`.
fn cylinder_scene(render: &std::path::Path) -> Result<lop_config::Scene, String> {
    let text = format!(
        r#"[[body]]
name = "c"
mesh = "../../assets/meshes/cylinder"
render_surface = "{}"
translate = [0.0, 0.5, 0.0]

[body.msd]
stiffness = 100.0
density = 1000.0
damping = 0.1
dt = 0.01
"#,
        render.display()
    );
    parse_scene(&text, &repo().join("config/scenes/test-render.toml")).map_err(|e| e.to_string())
}

fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("lop-render-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

#[test]
fn the_abdomen_liver_is_drawn_by_its_render_surface_at_rest_exactly() {
    let scene = load_scene(&repo().join("config/scenes/abdomen.toml")).unwrap();
    let file = read_surface(scene.bodies[0].render_surface.as_ref().unwrap()).unwrap();
    let loaded = load(scene).unwrap();
    let t = &loaded.topology;
    let liver = &t.bodies[0];
    assert_eq!(liver.name, "liver");
    assert_eq!(
        (liver.render_vertex_count, liver.render_triangle_count),
        (1890, 3776)
    );
    assert!(t.bodies[1..].iter().all(|b| b.render_vertex_count == 0));
    assert_eq!(
        t.indices.len(),
        3 * t.triangle_count + 4 * t.tet_count + 3 * 3776 + RENDER_VERTEX_WORDS * 1890
    );
    // Decode the published words as a renderer does and place the vertices on the rest nodes.
    let nodes: Vec<[f64; 3]> = loaded
        .world
        .bodies
        .iter()
        .flat_map(|b| b.mesh.nodes.iter().copied())
        .collect();
    let start = 3 * t.triangle_count + 4 * t.tet_count + 3 * 3776;
    let mut worst = 0.0f64;
    for (v, w) in t.indices[start..]
        .chunks_exact(RENDER_VERTEX_WORDS)
        .enumerate()
    {
        let mut p = [0.0f64; 3];
        for i in 0..4 {
            let x = nodes[w[i] as usize];
            let weight = f32::from_bits(w[4 + i]) as f64;
            for d in 0..3 {
                p[d] += weight * x[d];
            }
        }
        let q = file.vertices[v];
        worst = worst.max((0..3).map(|d| (p[d] - q[d]).abs()).fold(0.0, f64::max));
    }
    // The weights travel as f32: ~1e-7 relative on coordinates of ~0.1 m.
    assert!(
        worst < 1e-6,
        "a render vertex is {worst} m from where the file puts it"
    );
    let tris = &t.indices[3 * t.triangle_count + 4 * t.tet_count..start];
    assert!(tris.iter().all(|&k| (k as usize) < 1890));

    // The finer surface bulges past the mesh's flat faces by a little, never by much.
    let mesh = lop_scene::place_body(&loaded.scene, 0).unwrap();
    let r = render_surface(&loaded.scene, 0, &mesh).unwrap().unwrap();
    println!(
        "liver render surface: {} of {} vertices outside the mesh, at most {:.2} mm",
        r.embedding.outside,
        r.embedding.len(),
        r.embedding.max_outside * 1e3
    );
    assert!(r.embedding.outside > 0);
    assert!(
        r.embedding.max_outside < 0.003,
        "{}",
        r.embedding.max_outside
    );
}

#[test]
fn a_render_surface_follows_the_body_transform_and_other_units_are_refused() {
    let mesh = read_mesh(&repo().join("assets/meshes/cylinder")).unwrap();
    let surface = SurfaceMesh {
        vertices: mesh.nodes.clone(),
        triangles: mesh.surface.clone(),
    };
    let path = temp("cylinder.obj");
    surface.write_obj(&path).unwrap();
    let scene = cylinder_scene(&path).unwrap();
    let placed = lop_scene::place_body(&scene, 0).unwrap();
    let r = render_surface(&scene, 0, &placed).unwrap().unwrap();
    assert_eq!(r.triangles, mesh.surface);
    assert_eq!(r.embedding.outside, 0);
    let mut at = Vec::new();
    r.embedding.place(&placed.nodes, &mut at);
    for (p, q) in at.iter().zip(&placed.nodes) {
        assert!((0..3).all(|d| (p[d] - q[d]).abs() < 1e-12), "{p:?} {q:?}");
    }

    // The same surface written in centimetres.
    let cm = SurfaceMesh {
        vertices: mesh.nodes.iter().map(|p| p.map(|c| c * 100.0)).collect(),
        triangles: mesh.surface.clone(),
    };
    let path = temp("cylinder-cm.obj");
    cm.write_obj(&path).unwrap();
    let scene = cylinder_scene(&path).unwrap();
    let err = format!("{:#}", render_surface(&scene, 0, &placed).unwrap_err());
    for part in [
        "test-render.toml",
        "body \"c\"",
        "cylinder-cm.obj",
        "render vertex",
        "units",
    ] {
        assert!(err.contains(part), "{part:?} missing from: {err}");
    }

    // A missing file names the key.
    let err = cylinder_scene(&temp("nothing.obj")).unwrap_err();
    assert!(err.contains("body[0].render_surface"), "{err}");
    assert!(err.contains("nothing.obj"), "{err}");
}
