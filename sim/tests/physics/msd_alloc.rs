//! `MassSpring::step` allocates nothing after the first step, for every integrator, with the
//! tool in contact (the sparse refactorisation and solve of implicit Euler included).
//!
//! A counting global allocator (this test binary only) counts the allocations made by the
//! current thread while tracking is on, so other tests' threads cannot disturb the count.

use lop_sim::contact::{ForceLaw, ToolSphere};
use lop_sim::mesh::read_mesh;
use lop_sim::model::ToolContact;
use lop_sim::msd::{Integrator, MassSpring, MsdParameters, NodeMass};
use lop_sim::patch::{PatchPoint, PatchTool, ToolPatch};

use lop_test_support::alloc;
use lop_test_support::fixtures::mesh_path;
use lop_test_support::vec3::{norm, scale, sub};

// The counting allocator (`Counting::armed_threads`) is installed once for this
// test binary, in `main.rs`.

#[test]
fn step_is_allocation_free_after_the_first_step() {
    // The counter counts.
    assert!(alloc::this_thread(|| drop(std::hint::black_box(vec![0u8; 16]))).allocations >= 1);
    let mesh = read_mesh(&mesh_path("cylinder")).expect("shipped cylinder mesh");
    // Press on the top face: every triangle touching the node closest to the tool.
    let tool = ToolSphere {
        center: [0.0, 0.121, 0.0],
        radius: 0.003,
        stiffness: 300.0,
        law: ForceLaw::Linear,
    };
    let candidates: Vec<u32> = (0..mesh.surface.len() as u32).collect();
    let contact = ToolContact {
        tool,
        surface: &mesh.surface,
        candidates: &candidates,
        anchor: None,
        patch: None,
    };
    let loads = vec![[0.0, 0.0, 1e-4]; mesh.nodes.len()];
    for integrator in Integrator::ALL {
        let params = MsdParameters {
            stiffness: 700.0,
            mass: NodeMass::Density(120.0),
            damping: 0.4,
            dt: 0.02,
            integrator,
        };
        let mut ms = MassSpring::new(&mesh, params);
        ms.step([0.0, -9.81, 0.0], &loads, Some(&contact)).unwrap();
        let n = alloc::this_thread(|| {
            for _ in 0..3 {
                let r = ms.step([0.0, -9.81, 0.0], &loads, Some(&contact)).unwrap();
                assert!(r.depth > 0.0);
            }
        })
        .allocations;
        assert_eq!(n, 0, "{integrator:?} allocated {n} times in 3 steps");
    }
}

/// The same with the tool as a contact patch (the god-object's press): the sphere 0.5 mm into
/// the top, every top node in reach a point.
#[test]
fn step_with_a_patch_is_allocation_free_after_the_first_step() {
    let mesh = read_mesh(&mesh_path("cylinder")).expect("shipped cylinder mesh");
    let top = mesh.nodes.iter().map(|p| p[1]).fold(f64::MIN, f64::max);
    let centre = *mesh
        .nodes
        .iter()
        .filter(|p| p[1] > top - 1e-9)
        .min_by(|a, b| (a[0].hypot(a[2])).total_cmp(&b[0].hypot(b[2])))
        .unwrap();
    let r = 0.003;
    let proxy = [centre[0], top + r - 5e-4, centre[2]];
    let points: Vec<PatchPoint> = mesh
        .surface_nodes()
        .into_iter()
        .filter_map(|k| {
            let d = sub(mesh.nodes[k as usize], proxy);
            let l = norm(d);
            (l < 1.05 * r).then(|| PatchPoint {
                nodes: [k; 3],
                weights: [1.0, 0.0, 0.0],
                normal: scale(d, 1.0 / l),
                reach: r,
                tool: 0,
            })
        })
        .collect();
    assert!(!points.is_empty());
    let tool = ToolSphere {
        center: sub(proxy, [0.0, 5e-4, 0.0]),
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
    for integrator in Integrator::ALL {
        let params = MsdParameters {
            stiffness: 700.0,
            mass: NodeMass::Density(120.0),
            damping: 0.4,
            dt: 0.02,
            integrator,
        };
        let mut ms = MassSpring::new(&mesh, params);
        ms.step([0.0, -9.81, 0.0], &[], Some(&contact)).unwrap();
        let n = alloc::this_thread(|| {
            for _ in 0..3 {
                let r = ms.step([0.0, -9.81, 0.0], &[], Some(&contact)).unwrap();
                assert!(r.proxy.is_some() && r.depth > 0.0, "{integrator:?}: {r:?}");
            }
        })
        .allocations;
        assert_eq!(n, 0, "{integrator:?} allocated {n} times in 3 steps");
    }
}
