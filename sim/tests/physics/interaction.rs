//! The tool on simulated tissue through the god-object: the tissue receives the force the hand
//! feels (action and reaction), and picking drags the grabbed tissue and lets it go.

use crate::common;

use common::{cylinder, cylinder_fem_params};
use lop_sim::contact::{ForceLaw, ToolSphere};
use lop_sim::fem::Fem;
use lop_sim::haptic::{hand_force, WorldProbe};
use lop_sim::model::Model;
use lop_sim::msd::{Integrator, MsdParameters, NodeMass};
use lop_sim::world::World;
use lop_test_support::vec3::norm;

const R: f64 = 0.003;
const K: f64 = 300.0;

fn tool(center: [f64; 3]) -> ToolSphere {
    ToolSphere {
        center,
        radius: R,
        stiffness: K,
        law: ForceLaw::Linear,
    }
}

fn fem_world() -> World {
    let mesh = cylinder();
    let mut w = World::new([0.0; 3]);
    let fem = Fem::new(&mesh, cylinder_fem_params()).unwrap();
    w.add_model("cylinder", mesh, Model::Fem(fem));
    w
}

fn msd_world() -> World {
    let mesh = cylinder();
    let mut w = World::new([0.0; 3]);
    w.add_body(
        "cylinder",
        mesh,
        MsdParameters {
            stiffness: 30.0,
            mass: NodeMass::Density(30.0),
            damping: 0.05,
            dt: 0.01,
            integrator: Integrator::ImplicitEuler,
        },
    );
    w
}

/// Presses the top cap (y = 0.12) 4 mm in and holds; returns (hand force, force on tissue).
fn press(world: &mut World) -> ([f64; 3], [f64; 3]) {
    let mut probe = WorldProbe::new(world, R);
    let top = 0.12;
    let mut hand = [0.0; 3];
    for step in 0..400 {
        let y = (top + R + 0.01 - 0.014 * (step as f64 / 100.0).min(1.0)).max(top + R - 0.004);
        let device = [0.004, y, 0.002];
        // The haptic loop ticks many times per deformation step.
        let mut s = probe.tick(world, device, false);
        for _ in 0..9 {
            s = probe.tick(world, device, false);
        }
        hand = hand_force(&s, ForceLaw::Linear, K, 0.0, [0.0; 3]);
        world
            .step_body_coupled(0, Some(&tool(device)), probe.coupling())
            .unwrap();
    }
    (hand, world.bodies[0].contacts[0].force_on_tissue)
}

#[test]
fn the_tissue_receives_the_force_the_hand_feels() {
    for (name, mut world) in [("FEM", fem_world()), ("MSD", msd_world())] {
        let (hand, tissue) = press(&mut world);
        // The hand is pushed up, the tissue down, as hard: equal magnitudes (2 %) and opposite
        // directions (10°). The residual is the multirate delay — the hand's force is from
        // before the last step, the tissue's from after it, and this soft body still creeps.
        eprintln!("{name}: hand {hand:?} tissue {tissue:?}");
        assert!(hand[1] > 0.01, "{name}: hand force {hand:?}");
        let (h, t) = (norm(hand), norm(tissue));
        assert!(
            (h - t).abs() < 0.02 * h,
            "{name}: |hand| {h} vs |tissue| {t}"
        );
        let cos = -(hand[0] * tissue[0] + hand[1] * tissue[1] + hand[2] * tissue[2]) / (h * t);
        assert!(
            cos > 10f64.to_radians().cos(),
            "{name}: hand {hand:?} vs tissue {tissue:?}"
        );
        // The tissue gave way: the pressed top moved down.
        let top = world.bodies[0]
            .model
            .positions()
            .iter()
            .zip(&world.bodies[0].mesh.nodes)
            .filter(|(_, r)| r[1] > 0.1199)
            .map(|(p, r)| r[1] - p[1])
            .fold(0.0, f64::max);
        assert!(top > 0.001, "{name}: top sank {top} m");
    }
}

#[test]
fn picking_drags_the_grabbed_tissue_and_releases_it() {
    let mut world = fem_world();
    let mut probe = WorldProbe::new(&world, R);
    let top = 0.12;
    let rest = world.bodies[0].mesh.nodes.clone();
    let mut grabbed = None;
    let mut max_lift: f64 = 0.0;
    // 0–1 s: touch 1 mm deep; 1–2 s: grab and pull 1 cm up; 2–2.5 s hold; then release, lift
    // away and let it settle for 4 s.
    let steps = 325;
    for step in 0..steps {
        let t = step as f64 * 0.02;
        let (y, grab) = if t < 1.0 {
            (top + R + 0.005 - 0.006 * t, false)
        } else if t < 2.0 {
            (top + R - 0.001 + 0.011 * (t - 1.0), true)
        } else if t < 2.5 {
            (top + R + 0.010, true)
        } else {
            (top + R + 0.03, false)
        };
        let device = [0.004, y, 0.002];
        let s = probe.tick(&world, device, grab);
        if s.grabbing && grabbed.is_none() {
            let a = s.anchor.unwrap();
            grabbed = Some(probe.surfaces().triangles()[a.triangle]);
        }
        if let Some(tri) = grabbed {
            if t > 2.0 && t < 2.5 {
                let x = world.bodies[0].model.positions();
                let lift = tri
                    .iter()
                    .map(|&v| x[v as usize][1] - rest[v as usize][1])
                    .fold(f64::INFINITY, f64::min);
                max_lift = max_lift.max(lift);
                // The hand is pulled back down towards the tissue.
                let f = hand_force(&s, ForceLaw::Linear, K, 0.0, [0.0; 3]);
                assert!(f[1] < 0.0, "grabbing: hand force {f:?}");
            }
        }
        world
            .step_body_coupled(0, Some(&tool(device)), probe.coupling())
            .unwrap();
    }
    assert!(grabbed.is_some(), "never grabbed");
    assert!(max_lift > 0.004, "grabbed nodes lifted only {max_lift} m");
    // Released: back to rest.
    let x = world.bodies[0].model.positions();
    let back = x
        .iter()
        .zip(&rest)
        .map(|(p, r)| norm([p[0] - r[0], p[1] - r[1], p[2] - r[2]]))
        .fold(0.0, f64::max);
    assert!(back < 5e-4, "not recovered: {back} m");
}
