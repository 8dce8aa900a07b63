//! Organ-to-organ collision response (`World::enable_collisions`): two bodies pressed together
//! do not interpenetrate, whatever models they run, and the pushed body is pushed along.
//!
//! Two shipped cylinders (60 mm across, 120 mm tall, base fixed) stand 2 mm apart along x. A
//! sideways load on the top of the first bends it into the second. Without collision its top
//! would go 10 mm into the second (measured, and asserted below, so the test can fail); with
//! collision both bend and the surfaces stay within a fraction of a millimetre, and the second
//! cylinder's top moves away by millimetres.

use crate::common;

use common::{cylinder, cylinder_fem_params};
use lop_sim::collide::{CollisionParams, Collisions};
use lop_sim::fem::Fem;
use lop_sim::lop::{CageDynamics, CageModel, CageShape, GcParameters};
use lop_sim::mesh::TetMesh;
use lop_sim::model::{Model, ModelKind};
use lop_sim::msd::{Integrator, MassSpring, MsdParameters, NodeMass};
use lop_sim::world::World;
use lop_test_support::alloc;

// The counting allocator (`Counting::armed_threads`) is installed once for this
// test binary, in `main.rs`.

/// Centre distance of the two cylinders, m: a 2 mm gap.
const SPACING: f64 = 0.062;
/// Total sideways load on the first cylinder's top ring, N: what bends it about 10 mm (FEM,
/// Table 6.1's soft material) or 7 mm (the stiffer mass-spring) when free.
fn load(kind: ModelKind) -> f64 {
    match kind {
        ModelKind::MassSpring => 0.06,
        _ => 0.01,
    }
}
/// Contact stiffness per spring, N/m.
const STIFFNESS: f64 = 50.0;
/// Contact skin, m.
const SKIN: f64 = 0.0005;

fn msd_params() -> MsdParameters {
    MsdParameters {
        stiffness: 30.0,
        mass: NodeMass::Density(30.0),
        damping: 0.05,
        dt: 0.02,
        integrator: Integrator::ImplicitEuler,
    }
}

fn model(kind: ModelKind, mesh: &TetMesh) -> Model {
    let fem = || Model::Fem(Fem::new(mesh, cylinder_fem_params()).unwrap());
    match kind {
        ModelKind::Fem => fem(),
        ModelKind::MassSpring => Model::MassSpring(MassSpring::new(mesh, msd_params())),
        ModelKind::Gc => {
            let params = GcParameters {
                shape: CageShape::Fitted,
                padding: 0.003,
                dynamics: CageDynamics::Projected,
                dt: 0.02,
            };
            Model::Gc(Box::new(
                CageModel::from_precise(mesh, params, &fem()).unwrap(),
            ))
        }
    }
}

fn world(a: ModelKind, b: ModelKind, collide: bool) -> World {
    let mesh_a = cylinder();
    let mut mesh_b = cylinder();
    for p in &mut mesh_b.nodes {
        p[0] += SPACING;
    }
    let mut w = World::new([0.0; 3]);
    let ma = model(a, &mesh_a);
    let mb = model(b, &mesh_b);
    w.add_model("a", mesh_a, ma);
    w.add_model("b", mesh_b, mb);
    if collide {
        w.enable_collisions(
            CollisionParams {
                stiffness: STIFFNESS,
            },
            SKIN,
            0.02,
        );
    }
    w
}

/// Loads the top ring of body 0 along +x for `steps` steps (both bodies step in lockstep).
fn press(w: &mut World, steps: usize) {
    let load = load(w.bodies[0].model.kind());
    let top: Vec<usize> = (0..w.bodies[0].mesh.nodes.len())
        .filter(|&i| w.bodies[0].mesh.nodes[i][1] > 0.115)
        .collect();
    for _ in 0..steps {
        w.clear_loads();
        for &i in &top {
            w.bodies[0].loads[i] = [load / top.len() as f64, 0.0, 0.0];
        }
        w.detect_collisions();
        for i in 0..w.bodies.len() {
            w.step_body(i, None).unwrap();
        }
    }
}

/// The deepest surface vertex of either body inside the other, m (no skin).
fn interpenetration(w: &World) -> f64 {
    let surfaces: Vec<&[[u32; 3]]> = w.bodies.iter().map(|b| &b.mesh.surface[..]).collect();
    let mut c = Collisions::new(&surfaces);
    c.detect(&w.collision_bodies());
    c.stats().max_depth
}

/// Total force of a body's contact springs at its current positions, N, and their count.
fn spring_force(w: &World, body: usize) -> ([f64; 3], usize) {
    let x = w.bodies[body].model.positions();
    let mut total = [0.0; 3];
    let mut active = 0;
    for s in w.contact_springs(body) {
        let mut p = [0.0; 3];
        for k in 0..3 {
            for c in 0..3 {
                p[c] += s.weights[k] * x[s.nodes[k] as usize][c];
            }
        }
        let gap = s.target - (0..3).map(|c| s.normal[c] * p[c]).sum::<f64>();
        if gap > 0.0 {
            active += 1;
            for (t, n) in total.iter_mut().zip(s.normal) {
                *t += s.stiffness * gap * n;
            }
        }
    }
    (total, active)
}

/// Largest x displacement of a body's top ring, m.
fn top_shift(w: &World, body: usize) -> f64 {
    let b = &w.bodies[body];
    (0..b.mesh.nodes.len())
        .filter(|&i| b.mesh.nodes[i][1] > 0.115)
        .map(|i| b.model.positions()[i][0] - b.mesh.nodes[i][0])
        .fold(f64::NEG_INFINITY, f64::max)
}

#[test]
fn without_collision_the_bodies_pass_through_each_other() {
    for kind in [ModelKind::Fem, ModelKind::MassSpring] {
        let mut w = world(kind, kind, false);
        press(&mut w, 300);
        let depth = interpenetration(&w);
        println!("{kind:?}: free bending goes {:.2} mm deep", depth * 1e3);
        assert!(depth > 0.003, "{kind:?}: free bending goes {depth} m deep");
    }
}

#[test]
fn two_bodies_pressed_together_do_not_interpenetrate() {
    use ModelKind::{Fem, Gc, MassSpring};
    for (a, b) in [
        (Fem, Fem),
        (MassSpring, MassSpring),
        (Fem, MassSpring),
        (MassSpring, Fem),
        (Fem, Gc),
        (MassSpring, Gc),
    ] {
        let mut w = world(a, b, true);
        press(&mut w, 600);
        let depth = interpenetration(&w);
        let pushed = top_shift(&w, 1);
        let pusher = top_shift(&w, 0);
        println!(
            "{a:?} → {b:?}: interpenetration {:.3} mm, pusher top {:.2} mm, pushed top {:.2} mm",
            depth * 1e3,
            pusher * 1e3,
            pushed * 1e3
        );
        assert!(depth < 5e-4, "{a:?} → {b:?}: {depth} m deep");
        // In contact, and action = reaction: the springs push the two bodies apart equally,
        // along x, with part of the load (the rest holds the pusher's own bending).
        let (on_a, na) = spring_force(&w, 0);
        let (on_b, nb) = spring_force(&w, 1);
        println!("  contact force on a {on_a:?} ({na} springs), on b {on_b:?} ({nb})");
        assert!(na > 0 && nb > 0, "{a:?} → {b:?}: not in contact");
        let load = load(a);
        assert!(
            on_b[0] > 0.02 * load && on_b[0] < load,
            "{a:?} → {b:?}: b receives {} N of a {load} N load",
            on_b[0]
        );
        let imbalance = (0..3)
            .map(|c| (on_a[c] + on_b[c]).powi(2))
            .sum::<f64>()
            .sqrt();
        assert!(
            imbalance < 0.05 * on_b[0],
            "{a:?} → {b:?}: contact forces {on_a:?} and {on_b:?} do not balance"
        );
        assert!(pushed > 5e-4, "{a:?} → {b:?}: pushed body moved {pushed} m");
    }
}

#[test]
fn colliding_steps_allocate_nothing() {
    use ModelKind::{Fem, Gc, MassSpring};
    for (a, b) in [(Fem, MassSpring), (MassSpring, Gc)] {
        let mut w = world(a, b, true);
        // Into contact (the first colliding steps size the factor buffers).
        press(&mut w, 200);
        let top: Vec<usize> = (0..w.bodies[0].mesh.nodes.len())
            .filter(|&i| w.bodies[0].mesh.nodes[i][1] > 0.115)
            .collect();
        let load = load(a) / top.len() as f64;
        let n = alloc::this_thread(|| {
            for _ in 0..20 {
                w.clear_loads();
                for &i in &top {
                    w.bodies[0].loads[i] = [load, 0.0, 0.0];
                }
                let stats = w.detect_collisions().unwrap();
                assert!(stats.penetrations > 0);
                for i in 0..2 {
                    w.step_body(i, None).unwrap();
                }
            }
        })
        .allocations;
        assert_eq!(n, 0, "{a:?} → {b:?}: {n} allocations in 20 colliding steps");
    }
}

/// `World::set_collision_interval`: rounds every 20 ms (the bodies' step) with an interval of
/// 50 ms detect in every third round (at 20, 80, 140 … ms); with no interval every round
/// detects.
#[test]
fn collision_interval_spaces_the_detections() {
    use lop_sim::world::Round;
    for (interval, every) in [(0.0, 1usize), (0.05, 3)] {
        let mut w = world(ModelKind::MassSpring, ModelKind::MassSpring, true);
        w.set_collision_interval(interval);
        let mut detected = Vec::new();
        for k in 1..=12 {
            let until = 0.02 * k as f64;
            w.round(&Round::to(until, 4), || 0);
            detected.push(w.last_round().detected);
        }
        for (k, d) in detected.iter().enumerate() {
            assert_eq!(
                *d,
                k % every == 0,
                "interval {interval}: round {k}: {detected:?}"
            );
        }
    }
}
