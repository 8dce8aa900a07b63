//! A cage step allocates nothing after warm-up: gravity, nodal loads and the tool (a body
//! pinned to its cage), with either cage dynamics; nor does a controller that does not switch.

use crate::common;

use common::{cylinder, cylinder_fem_params};
use lop_sim::contact::{ForceLaw, ToolSphere};
use lop_sim::fem::Fem;
use lop_sim::lop::{
    CageDynamics, CageModel, CageShape, CageSprings, GcParameters, LopPolicy, PrecisionController,
};
use lop_sim::model::{ContactSpring, Model, ModelKind, ToolContact};
use lop_sim::patch::{PatchPoint, PatchTool, ToolPatch};
use lop_sim::world::World;
use lop_test_support::alloc;

// The counting allocator (`Counting::armed_threads`) is installed once for this
// test binary, in `main.rs`.

fn precise(mesh: &lop_sim::mesh::TetMesh) -> Model {
    Model::Fem(Fem::new(mesh, cylinder_fem_params()).unwrap())
}

#[test]
fn cage_steps_are_allocation_free() {
    let mesh = cylinder();
    let dynamics = [
        CageDynamics::Projected,
        CageDynamics::MassSpring(CageSprings::THESIS),
    ];
    for dynamics in dynamics {
        let params = GcParameters {
            shape: CageShape::Fitted,
            padding: 0.003,
            dynamics,
            dt: 0.02,
        };
        let gc = CageModel::from_precise(&mesh, params, &precise(&mesh)).unwrap();
        let mut world = World::new([0.0, -9.81, 0.0]);
        let i = world.add_model("cyl", mesh.clone(), Model::Gc(Box::new(gc)));
        // The tool 2 mm into the side, a load on the top.
        let tool = ToolSphere {
            center: [0.031, 0.08, 0.0],
            radius: 0.003,
            stiffness: 300.0,
            law: ForceLaw::Linear,
        };
        let top = (0..mesh.nodes.len())
            .max_by(|&a, &b| mesh.nodes[a][1].total_cmp(&mesh.nodes[b][1]))
            .unwrap();
        world.bodies[i].loads[top] = [0.001, 0.0, 0.0];
        for _ in 0..5 {
            world.step_body(i, Some(&tool)).unwrap();
        }
        let mut touched = 0;
        let n = alloc::this_thread(|| {
            for _ in 0..500 {
                world.step_body(i, Some(&tool)).unwrap();
                touched += (world.bodies[i].contacts[0].depth > 0.0) as usize;
            }
        })
        .allocations;
        assert!(
            touched >= 10,
            "{dynamics:?}: in contact in only {touched} steps"
        );
        assert_eq!(n, 0, "{dynamics:?}: {n} allocations in 500 steps");
    }
}

#[test]
fn an_untouched_controlled_body_is_allocation_free() {
    let mesh = cylinder();
    let p = precise(&mesh);
    let params = GcParameters {
        shape: CageShape::Fitted,
        padding: 0.003,
        dynamics: CageDynamics::Projected,
        dt: 0.02,
    };
    let gc = CageModel::from_precise(&mesh, params, &p).unwrap();
    let (active, lop) = PrecisionController::new(p, gc, LopPolicy::default());
    let mut world = World::new([0.0, -9.81, 0.0]);
    let i = world.add_lop_body("cyl", mesh, active, lop);
    let far = ToolSphere {
        center: [0.2, 0.2, 0.2],
        radius: 0.003,
        stiffness: 300.0,
        law: ForceLaw::Linear,
    };
    for _ in 0..5 {
        world.step_body(i, Some(&far)).unwrap();
    }
    let n = alloc::this_thread(|| {
        for _ in 0..500 {
            world.step_body(i, Some(&far)).unwrap();
        }
    })
    .allocations;
    assert_eq!(world.bodies[i].model.kind(), ModelKind::Gc);
    assert_eq!(n, 0, "{n} allocations in 500 steps");
}

/// A projected cage resolving the god-object's press as a contact patch allocates nothing
/// once its columns have grown to the patch.
#[test]
fn a_cage_with_a_patch_is_allocation_free() {
    let mesh = cylinder();
    let params = GcParameters {
        shape: CageShape::Fitted,
        padding: 0.003,
        dynamics: CageDynamics::Projected,
        dt: 0.02,
    };
    let mut gc = CageModel::from_precise(&mesh, params, &precise(&mesh)).unwrap();
    // The sphere 0.5 mm into the side at the node farthest along x, every surface node in reach
    // a point.
    let side = *mesh
        .nodes
        .iter()
        .max_by(|a, b| a[0].total_cmp(&b[0]))
        .unwrap();
    let r = 0.003;
    let proxy = [side[0] + r - 5e-4, side[1], side[2]];
    let points: Vec<PatchPoint> = mesh
        .surface_nodes()
        .into_iter()
        .filter_map(|k| {
            let p = mesh.nodes[k as usize];
            let d = [p[0] - proxy[0], p[1] - proxy[1], p[2] - proxy[2]];
            let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            (l < 1.05 * r).then(|| PatchPoint {
                nodes: [k; 3],
                weights: [1.0, 0.0, 0.0],
                normal: [d[0] / l, d[1] / l, d[2] / l],
                reach: r,
                tool: 0,
            })
        })
        .collect();
    assert!(!points.is_empty());
    let tool = ToolSphere {
        center: [proxy[0] - 1e-3, proxy[1], proxy[2]],
        radius: r,
        stiffness: 300.0,
        law: ForceLaw::Linear,
    };
    let contact = ToolContact {
        tool,
        surface: &mesh.surface,
        candidates: &[],
        anchor: None,
        patch: Some(ToolPatch {
            tools: &[PatchTool {
                device: tool.center,
                stiffness: tool.stiffness,
            }],
            points: &points,
            holds: &[],
        }),
    };
    let gravity = [0.0, -9.81, 0.0];
    gc.step(gravity, &[], Some(&contact)).unwrap();
    let mut touched = 0;
    let n = alloc::this_thread(|| {
        for _ in 0..100 {
            let r = gc.step(gravity, &[], Some(&contact)).unwrap();
            assert!(r.proxy.is_some(), "{r:?}");
            touched += (r.depth > 0.0) as usize;
        }
    })
    .allocations;
    // The soft cylinder swings away from the fixed sphere and back.
    assert!(touched >= 10, "in contact in only {touched} steps");
    assert_eq!(n, 0, "{n} allocations in 100 steps");
    // With an organ contact spring pushing the other side too, the patch is solved with the
    // springs' factor.
    let far = (0..mesh.nodes.len())
        .min_by(|&a, &b| mesh.nodes[a][0].total_cmp(&mesh.nodes[b][0]))
        .unwrap();
    let spring = ContactSpring {
        nodes: [far as u32; 3],
        weights: [1.0, 0.0, 0.0],
        normal: [1.0, 0.0, 0.0],
        target: mesh.nodes[far][0] + 1e-3,
        stiffness: 300.0,
    };
    let springs = [spring];
    gc.step_colliding(gravity, &[], Some(&contact), &springs)
        .unwrap();
    let mut touched = 0;
    let n = alloc::this_thread(|| {
        for _ in 0..100 {
            let r = gc
                .step_colliding(gravity, &[], Some(&contact), &springs)
                .unwrap();
            assert!(r.proxy.is_some(), "{r:?}");
            touched += (r.depth > 0.0) as usize;
        }
    })
    .allocations;
    assert!(
        touched >= 10,
        "with a spring: in contact in only {touched} steps"
    );
    assert_eq!(n, 0, "with a spring: {n} allocations in 100 steps");
}
