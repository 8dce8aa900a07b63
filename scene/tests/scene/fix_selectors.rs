//! `[[body.fix]]` selectors are evaluated in scene coordinates, after the body's transform: a
//! slab through the base of a raised cylinder picks exactly the base nodes its `.bnd` file
//! lists; a selector that picks nothing fails the load naming `body[i].fix[j]`. And the tissue
//! library's mass-spring calibration reproduces the `abdomen` scene's spring constants from the
//! organs' own meshes.

use std::path::PathBuf;

use lop_config::{load_scene, parse_scene, resolve_scene, tissue};
use lop_scene::{place_bodies, place_body};
use lop_sim::mesh::read_mesh;

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// A scene of one cylinder (assets/meshes/cylinder, base at y = 0, radius 0.03, height 0.12)
/// raised by 0.5 m, with `fix` appended to its body; it "lives" in config/scenes.
fn cylinder_scene(fix: &str) -> lop_config::Scene {
    let text = format!(
        r#"[[body]]
name = "c"
mesh = "../../assets/meshes/cylinder"
translate = [0.0, 0.5, 0.0]

[body.msd]
stiffness = 100.0
density = 1000.0
damping = 0.1
dt = 0.01

{fix}
"#
    );
    parse_scene(&text, &repo().join("config/scenes/test-fix.toml"))
        .unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn selectors_work_in_scene_coordinates() {
    let bnd = read_mesh(&repo().join("assets/meshes/cylinder"))
        .unwrap()
        .fixed;
    assert_eq!(bnd.len(), 22);
    // Without a selector: the .bnd nodes only.
    assert_eq!(place_body(&cylinder_scene(""), 0).unwrap().fixed, bnd);
    // The base is at y = 0.5 in the scene: a slab just above it picks the same nodes.
    let slab =
        "[[body.fix]]\nkind = \"slab\"\npoint = [0.0, 0.5001, 0.0]\nnormal = [0.0, 1.0, 0.0]";
    assert_eq!(place_body(&cylinder_scene(slab), 0).unwrap().fixed, bnd);
    // The top cap, facing up: surface nodes at y = 0.62, none of the base.
    let top = "[[body.fix]]\nkind = \"facing\"\ndirection = [0.0, 1.0, 0.0]\nangle_deg = 30.0";
    let mesh = place_body(&cylinder_scene(top), 0).unwrap();
    let extra: Vec<u32> = mesh
        .fixed
        .iter()
        .copied()
        .filter(|n| !bnd.contains(n))
        .collect();
    assert!(extra.len() >= 8, "{extra:?}");
    for n in extra {
        assert!((mesh.nodes[n as usize][1] - 0.62).abs() < 1e-9, "node {n}");
    }
}

#[test]
fn a_selector_that_picks_nothing_fails_naming_it() {
    // In the mesh's own coordinates this sphere holds the base centre; in the scene it is
    // 0.5 m below the body.
    let sphere =
        "[[body.fix]]\nkind = \"slab\"\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 1.0, 0.0]\n\n\
                  [[body.fix]]\nkind = \"sphere\"\ncenter = [0.0, 0.0, 0.0]\nradius = 0.01";
    let err = place_bodies(&cylinder_scene(sphere)).unwrap_err();
    let msg = format!("{err:#}");
    assert!(
        msg.contains("body[0].fix[0]") && msg.contains("picks no node") && msg.contains("slab"),
        "{msg}"
    );
    assert!(
        msg.contains("test-fix.toml") && msg.contains("\"c\""),
        "{msg}"
    );
    // The whole load fails the same way.
    assert!(lop_scene::load(cylinder_scene(sphere)).is_err());
}

#[test]
fn tissue_calibration_reproduces_the_abdomen_springs() {
    let scene = load_scene(&resolve_scene("abdomen").unwrap()).unwrap();
    for (body, mesh) in scene.bodies.iter().zip(place_bodies(&scene).unwrap()) {
        let edges = mesh.edges();
        let mean: f64 = edges
            .iter()
            .map(|&[a, b]| {
                let (p, q) = (mesh.nodes[a as usize], mesh.nodes[b as usize]);
                (0..3).map(|k| (p[k] - q[k]).powi(2)).sum::<f64>().sqrt()
            })
            .sum::<f64>()
            / edges.len() as f64;
        let k = tissue(&body.name).unwrap().msd_stiffness(mean);
        let given = body.msd.as_ref().unwrap().stiffness;
        // The scene's comment rounds the edge lengths to 0.1 mm (pancreas: 10.9 mm, 1.3 % off).
        assert!(
            (k - given).abs() <= 0.02 * given,
            "{}: {k} vs {given}",
            body.name
        );
    }
}
