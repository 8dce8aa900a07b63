//! `Fem::step` allocates nothing once warmed up: in linear and corotational mode, with and
//! without the tool, including the corotational solver's refactorisations and the contact's
//! extra solves, and on a worker pool with the factors made on the factor thread (issue 27).
//! Counted by a global allocator (this test binary only).

use lop_sim::contact::{ForceLaw, ToolSphere};
use std::sync::Arc;

use lop_sim::fem::{CorotationalSolver, Fem, FemMode, FemParameters, RefactorPolicy};
use lop_sim::mesh::read_mesh;
use lop_sim::model::ToolContact;
use lop_sim::parallel::WorkerPool;
use lop_test_support::alloc::{self, Counting};
use lop_test_support::fixtures::mesh_path;

// Every thread's allocations count: the test binary holds this one test only.
#[global_allocator]
static A: Counting = Counting::every_thread();

#[test]
fn step_is_allocation_free() {
    let mesh = read_mesh(&mesh_path("liver")).unwrap();
    let top = mesh
        .surface_nodes()
        .into_iter()
        .max_by(|&a, &b| mesh.nodes[a as usize][2].total_cmp(&mesh.nodes[b as usize][2]))
        .unwrap();
    let p = mesh.nodes[top as usize];
    let candidates: Vec<u32> = (0..mesh.surface.len() as u32).collect();
    let loads = vec![[0.0, 0.0, 1e-6]; mesh.nodes.len()];
    for (mode, solver, pooled) in [
        (FemMode::Linear, CorotationalSolver::LaggedFactorPcg, false),
        (
            FemMode::Corotational,
            CorotationalSolver::LaggedFactorPcg,
            false,
        ),
        (FemMode::Corotational, CorotationalSolver::Refactor, false),
        // Issue 27: on a 2-thread pool, with the factors made on the factor thread.
        (
            FemMode::Corotational,
            CorotationalSolver::LaggedFactorPcg,
            true,
        ),
    ] {
        let params = FemParameters {
            young: 140.0,
            poisson: 0.023,
            density: 10.0,
            damping: 10.0,
            dt: 0.01,
            mode,
        };
        let mut fem = Fem::new(&mesh, params).unwrap();
        fem.set_corotational_solver(solver);
        if pooled {
            fem.set_worker_pool(Some(Arc::new(WorkerPool::new(2))));
            fem.set_refactor_policy(RefactorPolicy::Background { delay_steps: 2 });
        }
        let g = [0.0, -9.81, 0.0];
        fem.step(g, &loads, None).unwrap();
        let landed = fem.solver_counters().background_factorizations;
        let factored = fem.solver_counters().factorizations;
        let before = alloc::allocations();
        let mut touched = 0;
        for s in 0..120 {
            // The tool presses, slides, and leaves, repeatedly.
            let tool = ToolSphere {
                center: [p[0] + 0.01 * (s as f64 * 0.1).sin(), p[1], p[2] - 0.002],
                radius: 0.003,
                stiffness: 300.0,
                law: ForceLaw::Linear,
            };
            let contact = ToolContact {
                tool,
                surface: &mesh.surface,
                candidates: &candidates,
                anchor: None,
                patch: None,
            };
            let c = (s % 40 < 30).then_some(&contact);
            let report = fem.step(g, &loads, c).unwrap();
            touched += (report.depth > 0.0) as usize;
        }
        let after = alloc::allocations();
        let refactors = fem.solver_counters().factorizations - factored;
        assert!(
            touched > 10,
            "{mode:?}: the tool touched in {touched} steps"
        );
        if pooled {
            let c = fem.solver_counters();
            assert!(
                c.background_factorizations > landed,
                "a factor landed: {c:?}"
            );
        } else if mode == FemMode::Corotational && solver == CorotationalSolver::LaggedFactorPcg {
            // Counted by the body (a CG run's iteration count no longer tells: with the
            // lagged factor refreshed within the step it converges in a few).
            assert!(refactors > 0, "a refactorisation happened in the window");
        }
        assert_eq!(
            after - before,
            0,
            "{mode:?}/{solver:?} (pool and background: {pooled}): allocations in step"
        );
    }
}
