//! The touched body's step on several threads gives the same numbers as on one, bit for bit:
//! the element loops on the worker pool (rotations and forces, the matrix-free products, the
//! per-node rotations) write disjoint outputs and sum each node's contributions in element
//! order, as the single-threaded scatter does (`lop_sim::parallel`). Checked on a corotational
//! bar swinging under gravity (large rotations: every kernel and several CG iterations per
//! step) and on a block pressed by the god-object's patch through the world's step.

use std::sync::Arc;

use lop_sim::contact::{ForceLaw, ToolSphere};
use lop_sim::fem::{box_mesh, Fem, FemMode, FemParameters};
use lop_sim::haptic::WorldProbe;
use lop_sim::model::Model;
use lop_sim::parallel::WorkerPool;
use lop_sim::world::World;

fn params(dt: f64) -> FemParameters {
    FemParameters {
        young: 3000.0,
        poisson: 0.45,
        density: 1000.0,
        damping: 1.0,
        dt,
        mode: FemMode::Corotational,
    }
}

fn bits(x: &[[f64; 3]]) -> Vec<[u64; 3]> {
    x.iter().map(|p| p.map(f64::to_bits)).collect()
}

#[test]
fn swinging_bar_is_bitwise_the_same_on_one_and_two_threads() {
    let mesh = box_mesh([0.2, 0.05, 0.05], [16, 4, 4], |p| p[0] < 1e-9);
    let mut runs = Vec::new();
    for threads in [1, 2] {
        let mut f = Fem::new(&mesh, params(0.01)).unwrap();
        f.set_worker_pool(Some(Arc::new(WorkerPool::new(threads))));
        assert_eq!(f.threads(), threads);
        let mut trace = Vec::new();
        for _ in 0..60 {
            f.step([0.0, 0.0, -9.81], &[], None).unwrap();
            trace.push((bits(f.positions()), bits(f.velocities())));
        }
        runs.push((trace, f.solver_counters()));
    }
    let (one, two) = (&runs[0], &runs[1]);
    assert!(one.1.cg_iterations > 60, "the swing needs CG: {:?}", one.1);
    assert_eq!(one.1, two.1, "same solver work");
    for (k, (a, b)) in one.0.iter().zip(&two.0).enumerate() {
        assert!(a == b, "step {k}: the two runs differ");
    }
}

#[test]
fn pressed_block_is_bitwise_the_same_on_one_and_two_threads() {
    let mesh = box_mesh([0.01, 0.01, 0.005], [10, 10, 5], |p| p[2] < 1e-9);
    let r = 0.003;
    let top = [0.005 + 1e-5, 0.005 + 2e-5, 0.005];
    let mut runs = Vec::new();
    for threads in [1, 2] {
        let mut f = Fem::new(
            &mesh,
            FemParameters {
                young: 4.1e3,
                poisson: 0.3,
                density: 1050.0,
                damping: 20.0,
                dt: 1e-3,
                mode: FemMode::Corotational,
            },
        )
        .unwrap();
        f.set_worker_pool(Some(Arc::new(WorkerPool::new(threads))));
        let mut world = World::new([0.0; 3]);
        world.add_model("block", mesh.clone(), Model::Fem(f));
        let mut probe = WorldProbe::new(&world, r);
        let mut trace = Vec::new();
        for step in 0..250 {
            // 10 mm/s down from 0.2 mm above the surface, held after 1.5 mm of travel.
            let s = (1e-5 * step as f64).min(1.7e-3);
            let device = [top[0], top[1], top[2] + r + 2e-4 - s];
            probe.tick(&world, device, false);
            let tool = ToolSphere {
                center: device,
                radius: r,
                stiffness: 300.0,
                law: ForceLaw::Linear,
            };
            world
                .step_body_coupled(0, Some(&tool), probe.coupling())
                .unwrap();
            let b = &world.bodies[0];
            trace.push((
                bits(b.model.positions()),
                b.contacts[0].force_on_tissue.map(f64::to_bits),
            ));
        }
        assert!(
            world.bodies[0].contacts[0].force_on_tissue[2] < -1e-3,
            "pressed: {:?}",
            world.bodies[0].contacts[0]
        );
        runs.push(trace);
    }
    for (k, (a, b)) in runs[0].iter().zip(&runs[1]).enumerate() {
        assert!(a == b, "step {k}: the two runs differ");
    }
}
