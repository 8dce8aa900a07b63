//! Cutting a running body (`lop_sim::cut`): the cut body carries its state over, settles where
//! a body meshed without the cut tissue rests, keeps its heat, and stale or impossible cuts
//! change nothing.

use lop_sim::contact::{ForceLaw, ToolSphere};
use lop_sim::cut::{vaporised, CutError, CutEvent, CutParams};
use lop_sim::fem::{box_mesh, Fem, FemMode, FemParameters};
use lop_sim::haptic::WorldProbe;
use lop_sim::heat::{HeatBody, HeatParameters, HeatWorld};
use lop_sim::mesh::{CutRefused, TetMesh};
use lop_sim::model::Model;
use lop_sim::msd::{Integrator, MsdParameters, NodeMass};
use lop_sim::world::{Round, RoundTool, World};

const G: [f64; 3] = [0.0, 0.0, -9.81];

/// A 10 × 2 × 2 cm bar of 10 × 2 × 2 cells (240 tetrahedra), clamped at x = 0.
fn bar() -> TetMesh {
    box_mesh([0.1, 0.02, 0.02], [10, 2, 2], |p| p[0] < 1e-9)
}

/// Soft tissue, heavily damped so that it settles within a simulated second.
fn fem_params() -> FemParameters {
    FemParameters {
        young: 2.0e4,
        poisson: 0.3,
        density: 1000.0,
        damping: 60.0,
        dt: 0.005,
        mode: FemMode::Corotational,
    }
}

/// The tetrahedra of `mesh` whose centroid at positions `x` passes `keep`.
fn tets_where(mesh: &TetMesh, x: &[[f64; 3]], keep: impl Fn([f64; 3]) -> bool) -> Vec<bool> {
    mesh.tets
        .iter()
        .map(|t| {
            let c = t.iter().fold([0.0; 3], |a, &k| {
                let p = x[k as usize];
                [a[0] + p[0] / 4.0, a[1] + p[1] / 4.0, a[2] + p[2] / 4.0]
            });
            keep(c)
        })
        .collect()
}

/// The tetrahedra of `mesh` whose rest centroid lies between `x0` and `x1`.
fn slab(mesh: &TetMesh, x0: f64, x1: f64) -> Vec<bool> {
    tets_where(mesh, &mesh.nodes, |c| c[0] > x0 && c[0] < x1)
}

fn fem_world(mesh: &TetMesh) -> (World, usize) {
    let mut world = World::new(G);
    let fem = Fem::new(mesh, fem_params()).expect("the bar's FEM");
    let b = world.add_model("bar", mesh.clone(), Model::Fem(fem));
    (world, b)
}

#[test]
fn a_cut_bar_settles_where_a_bar_meshed_short_rests() {
    let mesh = bar();
    let (mut world, b) = fem_world(&mesh);
    // Halfway to its sag, still swinging.
    for _ in 0..30 {
        world.step_body(b, None).unwrap();
    }
    let before = world.bodies[b].model.positions().to_vec();
    let remove = slab(&mesh, 0.06, 0.07);
    let report = world.cut_body(b, &remove).expect("the cut lands");
    // One slab of 4 cells asked for; the 3 slabs beyond it are cut loose and go with it.
    assert_eq!(report.removed_tets, 96);
    assert_eq!(report.piece_tets, 72);
    assert_eq!((report.pieces_kept, report.pieces_removed), (1, 1));
    assert_eq!(report.tets_left, 144);
    assert_eq!(report.epoch, 1);
    assert!((report.volume_removed - 0.04 * 0.02 * 0.02).abs() < 1e-15);
    let body = &world.bodies[b];
    assert_eq!(body.epoch, 1);
    assert_eq!(body.mesh.tets.len(), 144);
    // The state carries over node for node: nothing moves at the cut.
    assert_eq!(body.model.positions(), &before[..]);
    // The surface is closed: every edge of it is shared by exactly two triangles.
    let mut edges: Vec<[u32; 2]> = body
        .mesh
        .surface
        .iter()
        .flat_map(|t| [[t[0], t[1]], [t[1], t[2]], [t[2], t[0]]])
        .map(|[a, b]| [a.min(b), a.max(b)])
        .collect();
    edges.sort_unstable();
    assert!(
        edges.chunks(2).all(|p| p.len() == 2 && p[0] == p[1])
            && edges.windows(3).all(|w| w[0] != w[2])
    );

    for _ in 0..400 {
        world.step_body(b, None).unwrap();
    }
    // The reference: the bar meshed without the cut tissue, solved for its rest under
    // gravity (an independent static solve, not a step).
    let short = mesh.without_tets(&remove).unwrap().mesh;
    let mut reference = Fem::new(&short, fem_params()).unwrap();
    reference.solve_static(G, &[]).unwrap();
    let (x, r) = (world.bodies[b].model.positions(), reference.positions());
    let used: Vec<usize> = {
        let mut u: Vec<usize> = short.tets.iter().flatten().map(|&k| k as usize).collect();
        u.sort_unstable();
        u.dedup();
        u
    };
    let sag = used
        .iter()
        .map(|&k| short.nodes[k][2] - r[k][2])
        .fold(0.0, f64::max);
    let off = used
        .iter()
        .map(|&k| {
            (0..3)
                .map(|c| (x[k][c] - r[k][c]).abs())
                .fold(0.0, f64::max)
        })
        .fold(0.0, f64::max);
    // The uncut bar would sag (10/6)^4 ≈ 7.7 times as much: a cut that did not take would be
    // off by several sags.
    assert!(sag > 1e-4, "the short bar sags {sag} m");
    assert!(
        off < 1e-6 * sag,
        "{off} m off the short bar's rest (sag {sag} m)"
    );
    // Nodes the cut freed stay where the cut left them.
    let freed = (0..mesh.nodes.len()).filter(|k| used.binary_search(k).is_err());
    for k in freed {
        assert_eq!(x[k], before[k], "freed node {k}");
    }
}

#[test]
fn a_pressed_body_cut_under_the_tool_goes_on() {
    let mesh = box_mesh([0.04, 0.04, 0.02], [8, 8, 4], |p| p[2] < 1e-9);
    let (mut world, b) = fem_world(&mesh);
    let tool = ToolSphere {
        center: [0.02, 0.02, 0.02 + 0.003 - 0.002],
        radius: 0.003,
        stiffness: 300.0,
        law: ForceLaw::Linear,
    };
    for _ in 0..100 {
        world.step_body(b, Some(&tool)).unwrap();
    }
    let pressed = world.bodies[b].force_on_tissue()[2];
    assert!(pressed < -0.05, "pressed {pressed} N");
    // A crater under the tool: the top layer's four cells around it (1 × 1 cm, 5 mm deep),
    // wider than the 6 mm tool, which stays where it is.
    let remove = tets_where(&mesh, &mesh.nodes, |c| {
        c[2] > 0.015 && (c[0] - 0.02).abs() < 0.005 && (c[1] - 0.02).abs() < 0.005
    });
    let report = world.cut_body(b, &remove).expect("the cut lands");
    assert_eq!((report.removed_tets, report.pieces_removed), (24, 0));
    assert!(world.bodies[b].contacts.iter().all(|c| c.depth == 0.0));
    let mut deepest: f64 = 0.0;
    for _ in 0..300 {
        world.step_body(b, Some(&tool)).unwrap();
        let f = world.bodies[b].force_on_tissue();
        assert!(f.iter().all(|v| v.is_finite()));
        deepest = deepest.max(f.iter().map(|v| v.abs()).fold(0.0, f64::max));
        assert!(world.bodies[b]
            .model
            .positions()
            .iter()
            .flatten()
            .all(|v| v.is_finite()));
    }
    // The tissue under the tool is gone: it gives way and the body springs back, never
    // pressing the tool harder than before.
    let after = world.bodies[b].force_on_tissue();
    assert_eq!(after, [0.0; 3], "after the cut {after:?} N");
    assert!(world.bodies[b].model.max_speed() < 1e-4);
    assert!(
        deepest <= -pressed,
        "largest force after the cut {deepest} N"
    );
}

#[test]
fn vaporised_tissue_is_cut_and_the_heat_carries_over() {
    let mesh = box_mesh([0.02, 0.02, 0.01], [4, 4, 2], |p| p[2] < 1e-9);
    let (mut world, b) = fem_world(&mesh);
    let params = HeatParameters {
        dt: 0.01,
        ..HeatParameters::default()
    };
    let mut heat = HeatBody::new(&mesh, params).unwrap();
    // A hot spot at the top corner (x, y, z) = (0.02, 0.02, 0.01), boiling near it.
    let field: Vec<f64> = mesh
        .nodes
        .iter()
        .map(|p| {
            let d = ((p[0] - 0.02).powi(2) + (p[1] - 0.02).powi(2) + (p[2] - 0.01).powi(2)).sqrt();
            37.0 + 100.0 * (-d / 0.003).exp()
        })
        .collect();
    heat.set_temperatures(&field).unwrap();
    world.set_heat(HeatWorld::new(vec![heat]).unwrap());
    let before = world.heat().unwrap().bodies()[b].clone();
    let remove = vaporised(&mesh, &field, 100.0, |_| true).expect("a node boils");
    // Under a tip that reaches none of it, nothing goes.
    assert_eq!(vaporised(&mesh, &field, 100.0, |_| false), None);
    // Only the corner node boils (137 °C; its neighbours 5 mm away are at 56 °C): the six
    // tetrahedra of its cell go.
    let asked = remove.iter().filter(|&&r| r).count();
    assert_eq!(asked, 6, "{asked} tetrahedra with a node at 100 °C");
    let report = world.cut_body(b, &remove).expect("the cut lands");
    assert_eq!(report.removed_tets - report.piece_tets, asked);
    let after = &world.heat().unwrap().bodies()[b];
    assert_eq!(after.temperatures(), before.temperatures());
    assert_eq!(after.burned(), before.burned());
    // The nodes the cut freed hold no heat capacity any more; the others do.
    let used: std::collections::HashSet<u32> = world.bodies[b]
        .mesh
        .tets
        .iter()
        .flatten()
        .copied()
        .collect();
    for (k, &c) in after.capacities().iter().enumerate() {
        assert_eq!(
            c > 0.0,
            used.contains(&(k as u32)),
            "node {k}: capacity {c}"
        );
    }
    assert!(after.heat_content() < before.heat_content());
}

#[test]
fn stale_and_impossible_cuts_change_nothing() {
    let mesh = bar();
    let mut world = World::new(G);
    let msd = MsdParameters {
        stiffness: 50.0,
        mass: NodeMass::Density(1000.0),
        damping: 0.01,
        dt: 0.005,
        integrator: Integrator::ImplicitEuler,
    };
    let b = world.add_body("bar", mesh.clone(), msd);
    for _ in 0..10 {
        world.step_body(b, None).unwrap();
    }
    let first = world
        .cut_source(b)
        .unwrap()
        .prepare(&slab(&mesh, 0.08, 0.09));
    let second = world
        .cut_source(b)
        .unwrap()
        .prepare(&slab(&mesh, 0.05, 0.06));
    let report = world
        .apply_cut(first.unwrap())
        .expect("the first cut lands");
    assert_eq!(report.tets_left, 192);
    // The second was made on the topology the first replaced.
    let positions = world.bodies[b].model.positions().to_vec();
    assert_eq!(
        world.apply_cut(second.unwrap()).unwrap_err(),
        CutError::Stale {
            body: "bar".into(),
            prepared: 0,
            current: 1
        }
    );
    // Cutting through the clamp would leave nothing held.
    let clamp = slab(&world.bodies[b].mesh, 0.0, 0.01);
    assert!(matches!(
        world.cut_body(b, &clamp),
        Err(CutError::Refused {
            why: CutRefused::WholeBody { .. },
            ..
        })
    ));
    assert!(matches!(
        world.cut_body(7, &clamp),
        Err(CutError::NoBody { body: 7, bodies: 1 })
    ));
    assert_eq!(world.bodies[b].epoch, 1);
    assert_eq!(world.bodies[b].model.positions(), &positions[..]);
    for _ in 0..10 {
        world.step_body(b, None).unwrap();
    }
    assert!(world.bodies[b]
        .model
        .positions()
        .iter()
        .flatten()
        .all(|v| v.is_finite()));
}

/// One run of the electrosurgical cut: a block pressed 0.3 mm by a 3 mm cautery holding the
/// cut button at `power` W for `steps` 1 ms rounds, pushed 4 mm deeper meanwhile. Returns the world and every cut event with
/// the round it came in.
fn electrosurgery(power: f64, steps: usize) -> (World, Vec<(usize, CutEvent)>) {
    const R: f64 = 0.003;
    let mesh = box_mesh([0.02, 0.02, 0.01], [8, 8, 4], |p| p[2] < 1e-9);
    let mut world = World::new([0.0; 3]);
    let fem = Fem::new(
        &mesh,
        FemParameters {
            dt: 0.001,
            ..fem_params()
        },
    )
    .unwrap();
    world.add_model("block", mesh.clone(), Model::Fem(fem));
    let heat = HeatBody::new(&mesh, HeatParameters::default()).unwrap();
    world.set_heat(HeatWorld::new(vec![heat]).unwrap());
    world.set_cutting(Some(CutParams {
        bodies: vec![true],
        delay_steps: 10,
        ..CutParams::default()
    }));
    let mut probe = WorldProbe::new(&world, R);
    let laws = [ToolSphere {
        center: [0.0; 3],
        radius: R,
        stiffness: 300.0,
        law: ForceLaw::Linear,
    }];
    let mut events = Vec::new();
    for step in 0..steps {
        // 0.3 mm into the top, following the wound down 4 mm over the run.
        let device = [
            0.01,
            0.01,
            0.01 + R - 0.3e-3 - 4e-3 * step as f64 / steps as f64,
        ];
        probe.tick(&world, device, false);
        let tool = RoundTool {
            center: device,
            laws: &laws,
            coupling: probe.coupling(),
            heat_power: power,
            cut: true,
        };
        let round = Round {
            drop_lag: false,
            ..Round::to((step + 1) as f64 * 1e-3, 4).with_tools(std::slice::from_ref(&tool))
        };
        let report = world.round(&round, || 0);
        for e in &report.cuts {
            events.push((step, e.clone()));
        }
        if report
            .cuts
            .iter()
            .any(|e| matches!(e, CutEvent::Landed { .. }))
        {
            // The god-object's surface is the new one from the next tick.
            probe = probe.rebuilt(&world);
        }
    }
    (world, events)
}

#[test]
fn a_cautery_holding_the_cut_button_vaporises_its_way_in() {
    let (world, events) = electrosurgery(40.0, 1500);
    let landed: Vec<_> = events
        .iter()
        .filter_map(|(step, e)| match e {
            CutEvent::Landed { report, .. } => Some((*step, *report)),
            _ => None,
        })
        .collect();
    let asked: Vec<_> = events
        .iter()
        .filter_map(|(step, e)| match e {
            CutEvent::Asked { due, tets, .. } => Some((*step, *due, *tets)),
            _ => None,
        })
        .collect();
    assert!(
        !events
            .iter()
            .any(|(_, e)| matches!(e, CutEvent::Refused(_))),
        "{events:?}"
    );
    assert!(landed.len() >= 2, "cuts landed: {landed:?}");
    // A cut is asked for after its round's step; the delay's 10 steps (one a round) pass on
    // the old mesh and it lands before the next: in order, each a new topology.
    for (k, ((asked_at, due, tets), (landed_at, report))) in asked.iter().zip(&landed).enumerate() {
        assert_eq!(
            landed_at - asked_at,
            11,
            "cut {k}: asked {asked_at} (due {due}), landed {landed_at}"
        );
        assert_eq!(report.epoch, k as u64 + 1);
        assert_eq!(report.removed_tets - report.piece_tets, *tets);
    }
    let body = &world.bodies[0];
    assert_eq!(body.epoch, landed.len() as u64);
    let removed: usize = landed.iter().map(|(_, r)| r.removed_tets).sum();
    assert_eq!(body.mesh.tets.len(), 8 * 8 * 4 * 6 - removed);
    // The crater is under the tip: every tetrahedron removed was within two tool radii of it.
    assert!(body
        .model
        .positions()
        .iter()
        .flatten()
        .all(|v| v.is_finite()));
    let t = world.heat().unwrap().bodies()[0].temperatures();
    assert!(t.iter().all(|&v| v.is_finite() && v < 1000.0));
}

#[test]
fn an_electrosurgical_cut_is_deterministic() {
    let (a, ea) = electrosurgery(40.0, 700);
    let (b, eb) = electrosurgery(40.0, 700);
    // The same cuts at the same steps; whether a step waited for a preparation is the
    // machine's, not the run's.
    let timeless = |e: &[(usize, CutEvent)]| -> Vec<(usize, CutEvent)> {
        e.iter()
            .map(|(s, e)| match e {
                CutEvent::Landed { report, .. } => (
                    *s,
                    CutEvent::Landed {
                        report: *report,
                        waited: false,
                    },
                ),
                e => (*s, e.clone()),
            })
            .collect()
    };
    assert_eq!(timeless(&ea), timeless(&eb));
    assert!(ea.iter().any(|(_, e)| matches!(e, CutEvent::Landed { .. })));
    assert_eq!(a.bodies[0].model.positions(), b.bodies[0].model.positions());
    assert_eq!(a.bodies[0].mesh.tets, b.bodies[0].mesh.tets);
}

/// Seeded random cuts (balls of tissue anywhere, through the clamp too, some the whole block)
/// on a pressed block: every cut lands or is refused by its rule, the pieces left always hold a
/// fixed node, and nothing goes non-finite.
#[test]
fn seeded_cuts_land_or_are_refused_and_nothing_goes_non_finite() {
    let mesh = box_mesh([0.04, 0.02, 0.02], [8, 4, 4], |p| p[0] < 1e-9);
    let (mut world, b) = fem_world(&mesh);
    let tool = ToolSphere {
        center: [0.03, 0.01, 0.02 + 0.003 - 0.001],
        radius: 0.003,
        stiffness: 300.0,
        law: ForceLaw::Linear,
    };
    let mut rng = lop_test_support::rng::Rng::new(31);
    let (mut landed, mut refused) = (0, 0);
    for k in 0..60 {
        let body = &world.bodies[b];
        let centre = [
            rng.range(0.0, 0.04),
            rng.range(0.0, 0.02),
            rng.range(0.0, 0.02),
        ];
        // Mostly bites of up to 7 mm; every tenth the whole block.
        let radius = if k % 10 == 9 {
            0.05
        } else {
            rng.range(0.001, 0.007)
        };
        let remove = tets_where(&body.mesh, body.model.positions(), |c| {
            (0..3).map(|j| (c[j] - centre[j]).powi(2)).sum::<f64>() < radius * radius
        });
        match world.cut_body(b, &remove) {
            Ok(r) => {
                landed += 1;
                // Several pieces may stay, each held by the clamp.
                assert!(r.tets_left > 0 && r.pieces_kept >= 1, "{r:?}");
            }
            Err(CutError::Refused { why, .. }) => {
                refused += 1;
                assert!(
                    matches!(why, CutRefused::Nothing | CutRefused::WholeBody { .. }),
                    "{why:?}"
                );
            }
            Err(e) => panic!("{e}"),
        }
        let body = &world.bodies[b];
        assert!(body
            .mesh
            .tets
            .iter()
            .flatten()
            .any(|k| mesh.fixed.contains(k)));
        for _ in 0..5 {
            world.step_body(b, Some(&tool)).unwrap();
        }
        let body = &world.bodies[b];
        assert!(body
            .model
            .positions()
            .iter()
            .flatten()
            .all(|v| v.is_finite()));
        assert!(body.force_on_tissue().iter().all(|v| v.is_finite()));
    }
    assert!(
        landed > 5 && refused > 5,
        "{landed} landed, {refused} refused"
    );
}
