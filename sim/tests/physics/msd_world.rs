//! Mass-spring statics and safety on a shipped mesh (the §6.1 cylinder, base fixed).
//!
//! Invariants guarded:
//! - at rest under gravity the supports carry exactly the weight of the free nodes (springs are
//!   internal forces, so the fixed nodes' spring forces must balance every external load);
//! - the tool's penalty load is carried the same way: the support reaction equals the force the
//!   tissue receives from the tool (action and reaction, to the solver's settling tolerance);
//! - fixed nodes never move; stepping is deterministic bit for bit;
//! - a blow-up is detected, the body reset, and nothing non-finite remains.

use crate::common;

use common::{cylinder, support_reaction};
use lop_sim::contact::{closest_on_surface, ForceLaw, ToolSphere};
use lop_sim::msd::{Integrator, MsdParameters, NodeMass};
use lop_sim::world::World;

/// Table 6.1's MSD column.
fn params() -> MsdParameters {
    MsdParameters {
        stiffness: 700.0,
        mass: NodeMass::Density(120.0),
        damping: 0.4,
        dt: 0.02,
        integrator: Integrator::SymplecticEuler,
    }
}

#[test]
fn supports_carry_the_weight_at_rest() {
    let mesh = cylinder();
    let g = [0.0, -9.81, 0.0];
    let mut world = World::new(g);
    let b = world.add_body("cylinder", mesh.clone(), params());
    for _ in 0..400 {
        world.step_body(b, None).unwrap();
    }
    let model = &world.bodies[b].model;
    assert!(
        model.max_speed() < 1e-4,
        "not settled: {}",
        model.max_speed()
    );
    let fixed: std::collections::HashSet<u32> = mesh.fixed.iter().copied().collect();
    let free_weight: f64 = model
        .masses()
        .iter()
        .enumerate()
        .filter(|(i, _)| !fixed.contains(&(*i as u32)))
        .map(|(_, m)| m * 9.81)
        .sum();
    let r = support_reaction(&mesh, model.positions(), 700.0);
    // Springs pull the supports down by the weight they hold: r_y = −W.
    assert!(
        ((r[1] + free_weight) / free_weight).abs() < 1e-3,
        "support {r:?} vs weight {free_weight}"
    );
    assert!(r[0].abs() < 1e-3 * free_weight && r[2].abs() < 1e-3 * free_weight);
    // The top sagged, the base did not move.
    let top = (0..mesh.nodes.len())
        .max_by(|&i, &j| mesh.nodes[i][1].total_cmp(&mesh.nodes[j][1]))
        .unwrap();
    assert!(model.positions()[top][1] < mesh.nodes[top][1]);
    for &f in &mesh.fixed {
        assert_eq!(model.positions()[f as usize], mesh.nodes[f as usize]);
    }
}

#[test]
fn tool_load_is_carried_by_the_supports() {
    let mesh = cylinder();
    let mut world = World::new([0.0; 3]);
    let b = world.add_body("cylinder", mesh.clone(), params());
    // Press the 3 mm tool 2 mm into the top face (y = 0.12), off-centre.
    let tool = ToolSphere {
        center: [0.01, 0.12 + 0.003 - 0.002, 0.005],
        radius: 0.003,
        stiffness: 300.0,
        law: ForceLaw::Linear,
    };
    for _ in 0..600 {
        world.step_body(b, Some(&tool)).unwrap();
    }
    let body = &world.bodies[b];
    let on_tissue = body.contacts[0].force_on_tissue;
    assert!(body.model.max_speed() < 1e-5);
    assert!(on_tissue[1] < -0.05, "tool load {on_tissue:?}");
    let r = support_reaction(&mesh, body.model.positions(), 700.0);
    for k in 0..3 {
        assert!(
            (r[k] - on_tissue[k]).abs() < 2e-3 * on_tissue[1].abs(),
            "support {r:?} vs tool load {on_tissue:?}"
        );
    }
    // The haptic loop's view of the same surface gives the opposite force to the hand.
    let hit = closest_on_surface(body.model.positions(), &mesh.surface, tool.center).unwrap();
    let on_hand = tool.force_on_tool(&hit);
    for k in 0..3 {
        assert!((on_hand[k] + on_tissue[k]).abs() < 1e-3 * on_tissue[1].abs());
    }
}

#[test]
fn stepping_is_deterministic() {
    let run = || {
        let mut w = World::new([0.0, -9.81, 0.0]);
        let b = w.add_body("c", cylinder(), params());
        let tool = ToolSphere {
            center: [0.0, 0.121, 0.0],
            radius: 0.003,
            stiffness: 300.0,
            law: ForceLaw::Quadratic,
        };
        for _ in 0..50 {
            w.step_body(b, Some(&tool)).unwrap();
        }
        w.bodies[b].model.positions().to_vec()
    };
    let (a, b) = (run(), run());
    assert!(a
        .iter()
        .zip(&b)
        .all(|(p, q)| p.iter().zip(q).all(|(x, y)| x.to_bits() == y.to_bits())));
}

#[test]
fn blow_up_is_detected_and_reset() {
    let mesh = cylinder();
    let mut world = World::new([0.0; 3]);
    let b = world.add_body("c", mesh.clone(), params());
    // An absurd load on one surface triangle drives nodes past the runaway speed.
    world.add_surface_load(b, 0, [1.0 / 3.0; 3], [1e9, 0.0, 0.0]);
    let r = world.step_body(b, None);
    assert!(r.is_err());
    assert_eq!(world.bodies[b].resets, 1);
    assert_eq!(world.bodies[b].model.positions(), mesh.nodes.as_slice());
    assert!(world.bodies[b]
        .model
        .velocities()
        .iter()
        .flatten()
        .all(|v| *v == 0.0));
    // Non-finite loads are refused outright.
    world.clear_loads();
    world.add_surface_load(b, 0, [1.0 / 3.0; 3], [f64::NAN, 0.0, 0.0]);
    assert!(world.bodies[b]
        .loads
        .iter()
        .flatten()
        .all(|v| v.is_finite()));
}
