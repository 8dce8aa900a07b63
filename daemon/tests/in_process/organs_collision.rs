//! On the shipped `organs` scene, as loaded by the daemon (levels of precision on, every organ
//! starting as its cage): an organ pushed towards its neighbour pushes it along, and the two
//! do not pass through each other. The organs are about 1 mm apart at rest.

use std::path::PathBuf;

use lop_sim::collide::Collisions;
use lop_sim::world::World;

fn organs() -> World {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../config/scenes/organs.toml");
    let scene = lop_config::load_scene(&path).unwrap();
    assert!(scene.collision.enabled, "collision is on by default");
    lop_scene::load(scene).unwrap().world
}

/// Deepest vertex inside another body, m (no skin), and the penetrations within `skin`.
fn contacts(w: &World, skin: f64) -> (f64, Vec<lop_sim::collide::Penetration>) {
    let surfaces: Vec<&[[u32; 3]]> = w.bodies.iter().map(|b| &b.mesh.surface[..]).collect();
    let mut c = Collisions::new(&surfaces);
    let bodies = w.collision_bodies();
    c.detect(&bodies);
    let deepest = c.stats().max_depth;
    c.set_skin(skin);
    (deepest, c.detect(&bodies).to_vec())
}

fn max_displacement(w: &World, i: usize) -> f64 {
    let b = &w.bodies[i];
    b.model
        .positions()
        .iter()
        .zip(&b.mesh.nodes)
        .map(|(p, q)| {
            ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
        })
        .fold(0.0, f64::max)
}

/// Pushes the organ closest to a neighbour towards it; returns (names, moved a, moved b,
/// deepest vertex, neighbour's model), lengths in m.
fn push(collide: bool) -> ((String, String), f64, f64, f64, lop_sim::model::ModelKind) {
    let mut w = organs();
    if !collide {
        w.disable_collisions();
    }
    let (deepest, near) = contacts(&w, 0.003);
    assert_eq!(deepest, 0.0, "the organs do not overlap at rest");
    // The closest pair: push the first body of the closest vertex towards the other, with a
    // load on its surface vertices within 3 mm of it.
    let closest = near
        .iter()
        .max_by(|a, b| a.depth.total_cmp(&b.depth))
        .expect("some organs are within 3 mm of each other");
    let (a, b) = (closest.body, closest.other);
    let dir = closest.normal.map(|c| -c);
    let pushed: Vec<u32> = near
        .iter()
        .filter(|p| p.body == a && p.other == b)
        .map(|p| p.node)
        .collect();
    let names = (w.bodies[a].name.clone(), w.bodies[b].name.clone());
    let total = 0.002;
    let steps = 300;
    let mut t = 0.0;
    let dt = w
        .bodies
        .iter()
        .map(|b| b.model.dt())
        .fold(f64::INFINITY, f64::min);
    for _ in 0..steps {
        t += dt;
        w.clear_loads();
        for &n in &pushed {
            w.bodies[a].loads[n as usize] = dir.map(|c| c * total / pushed.len() as f64);
        }
        w.detect_collisions();
        for i in 0..w.bodies.len() {
            while w.body_due(i, t) {
                w.step_body(i, None).unwrap();
            }
        }
    }
    let (deepest, _) = contacts(&w, 0.0);
    let (moved_a, moved_b) = (max_displacement(&w, a), max_displacement(&w, b));
    let kind = w.bodies[b].model.kind();
    (names, moved_a, moved_b, deepest, kind)
}

#[test]
fn a_pushed_organ_pushes_its_neighbour() {
    let (names, free_a, free_b, free_deepest, _) = push(false);
    println!(
        "without collision: {} moves {:.2} mm, {:.2} mm into {} ({} moves {:.2} mm)",
        names.0,
        free_a * 1e3,
        free_deepest * 1e3,
        names.1,
        names.1,
        free_b * 1e3
    );
    assert!(
        free_deepest > 0.002,
        "the push must be strong enough to matter"
    );
    assert_eq!(free_b, 0.0);
    let (names, moved_a, moved_b, deepest, kind) = push(true);
    println!(
        "with collision: {} moves {:.2} mm, {} ({kind:?}) is pushed {:.2} mm, deepest vertex \
         {:.3} mm",
        names.0,
        moved_a * 1e3,
        names.1,
        moved_b * 1e3,
        deepest * 1e3
    );
    assert!(moved_a > 0.003, "{} moved only {moved_a} m", names.0);
    assert!(moved_b > 0.0005, "{} was not pushed: {moved_b} m", names.1);
    assert!(
        deepest < 0.0005,
        "{} and {} overlap by {deepest} m",
        names.0,
        names.1
    );
}
