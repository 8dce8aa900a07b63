//! Part 4 of `lop-bench models` (`--only threads`): the touched step at 1 and 2 threads, from
//! ~2k to ~20k tetrahedra — what a lab needs to size its machine.
//!
//! Each size is a soft box of the scaling series (part 2's `scaling_box`, fixed at `x = 0`,
//! `E` = 3 kPa) stepped at the haptic rate (1 ms) and pressed by the god-object's patch as the
//! deformation process does it ([`World::step_body_coupled`] with an offline [`WorldProbe`]): a
//! 5 mm sphere on a 300 N/m tool spring driven 3 mm into the top face at 10 mm/s, then held.
//! The touched step is timed from the first step of the press on (the warm-up steps before
//! contact are not), so the figures hold the press's motion and the hold. Per size, per thread
//! count and per refactor policy — `realtime` (what scenes at the haptic rate use today: the
//! lagged factor refreshed within a step when CG stalls) and `background` (refreshed on the
//! factor thread, `D` = 16 steps) — the step's p50, p99 and max, CG iterations per step, the
//! factorisations within steps and on the factor thread, the steps that waited for one, and
//! whether the run's final positions are bit for bit those of the one-thread run (they must
//! be).

use std::sync::Arc;
use std::time::Instant;

use anyhow::Result;
use lop_sim::contact::{ForceLaw, ToolSphere};
use lop_sim::fem::{Fem, FemMode, FemParameters, RefactorPolicy};
use lop_sim::haptic::WorldProbe;
use lop_sim::model::Model;
use lop_sim::parallel::WorkerPool;
use lop_sim::world::World;
use serde::Serialize;

use super::common::summarize;
use super::scaling::scaling_box;
use crate::table::{table, Align};

/// Default sizes, tetrahedra.
const TARGETS: [usize; 4] = [2_000, 5_000, 10_000, 20_000];
/// Steps before the press (at rest, untimed), of the press, and held.
const WARMUP: usize = 20;
const PRESS_STEPS: usize = 300;
const HOLD_STEPS: usize = 300;
const HOLD_STEPS_QUICK: usize = 30;
/// The background policy's `D`.
const BACKGROUND_DELAY: u32 = 16;

/// One size, thread count and policy.
#[derive(Debug, Clone, Serialize)]
pub struct ThreadRow {
    pub tets: usize,
    pub dofs: usize,
    pub threads: usize,
    pub policy: String,
    pub steps: usize,
    pub p50_us: f64,
    pub p99_us: f64,
    pub max_us: f64,
    pub cg_per_step: f64,
    /// Numeric factorisations within timed steps.
    pub in_step_factorizations: u64,
    /// Factorisations on the factor thread swapped in, and steps that waited for one.
    pub background_factorizations: u64,
    pub factor_waits: u64,
    /// Held force on the tissue at the end, N.
    pub force_n: f64,
    /// Final positions bit for bit those of the one-thread run of the same size and policy.
    pub same_as_one_thread: bool,
}

/// Runs part 4 on `targets` (default: 2k, 5k, 10k, 20k).
pub(super) fn threads(quick: bool, targets: &[usize]) -> Result<Vec<ThreadRow>> {
    let targets = if targets.is_empty() {
        if quick {
            &TARGETS[..2]
        } else {
            &TARGETS[..]
        }
    } else {
        targets
    };
    let hold = if quick { HOLD_STEPS_QUICK } else { HOLD_STEPS };
    let max_threads = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .min(2);
    let mut rows = Vec::new();
    for &target in targets {
        let (_, size, mesh) = scaling_box(target);
        for (policy, name) in [
            (RefactorPolicy::RealTime, "realtime"),
            (
                RefactorPolicy::Background {
                    delay_steps: BACKGROUND_DELAY,
                },
                "background",
            ),
        ] {
            let mut reference: Option<Vec<[f64; 3]>> = None;
            for threads in 1..=max_threads {
                eprintln!(
                    "models: threads / {} tets, {threads} thread(s), {name}",
                    mesh.tets.len()
                );
                let mut fem = Fem::new(
                    &mesh,
                    FemParameters {
                        young: 3000.0,
                        poisson: 0.45,
                        density: 1000.0,
                        damping: 1.0,
                        dt: 1e-3,
                        mode: FemMode::Corotational,
                    },
                )?;
                fem.set_refactor_policy(policy);
                fem.set_worker_pool(Some(Arc::new(WorkerPool::new(threads))));
                let dofs = fem.dofs();
                let mut world = World::new([0.0; 3]);
                world.add_model("box", mesh.clone(), Model::Fem(fem));
                let r = 0.005;
                let mut probe = WorldProbe::new(&world, r);
                let top = [size[0] * 0.5 + 1e-4, size[1] * 0.5 + 2e-4, size[2]];
                let mut ns = Vec::with_capacity(PRESS_STEPS + hold);
                let before = counters(&world);
                for step in 0..WARMUP + PRESS_STEPS + hold {
                    let travel = (1e-5 * step.saturating_sub(WARMUP) as f64).min(3e-3);
                    let device = [top[0], top[1], top[2] + r + 2e-4 - travel];
                    probe.tick(&world, device, false);
                    let tool = ToolSphere {
                        center: device,
                        radius: r,
                        stiffness: 300.0,
                        law: ForceLaw::Linear,
                    };
                    let t0 = Instant::now();
                    world
                        .step_body_coupled(0, Some(&tool), probe.coupling())
                        .map_err(|e| anyhow::anyhow!("blow-up: {e:?}"))?;
                    if step >= WARMUP {
                        ns.push(t0.elapsed().as_nanos() as u64);
                    }
                }
                let after = counters(&world);
                let steps = ns.len();
                let (p50, p99, _, max) = summarize(&mut ns);
                let positions = world.bodies[0].model.positions().to_vec();
                let same = match &reference {
                    None => {
                        reference = Some(positions);
                        true
                    }
                    Some(x) => x
                        .iter()
                        .zip(&positions)
                        .all(|(a, b)| a.map(f64::to_bits) == b.map(f64::to_bits)),
                };
                rows.push(ThreadRow {
                    tets: mesh.tets.len(),
                    dofs,
                    threads,
                    policy: name.into(),
                    steps,
                    p50_us: p50,
                    p99_us: p99,
                    max_us: max,
                    cg_per_step: (after.cg_iterations - before.cg_iterations) as f64
                        / (after.steps - before.steps).max(1) as f64,
                    in_step_factorizations: after.factorizations - before.factorizations,
                    background_factorizations: after.background_factorizations,
                    factor_waits: after.factor_waits,
                    force_n: -world.bodies[0].contacts[0].force_on_tissue[2],
                    same_as_one_thread: same,
                });
            }
        }
    }
    Ok(rows)
}

fn counters(world: &World) -> lop_sim::fem::SolverCounters {
    match &world.bodies[0].model {
        Model::Fem(f) => f.solver_counters(),
        _ => unreachable!("an FEM body"),
    }
}

/// The table of part 4.
pub(super) fn render(rows: &[ThreadRow]) -> String {
    let mut s = String::from(
        "Part 4: the touched step (1 ms, god-object patch pressing 3 mm, then held) at 1 and 2 \
         threads\n",
    );
    let body: Vec<Vec<String>> = rows
        .iter()
        .map(|r| {
            vec![
                r.tets.to_string(),
                r.threads.to_string(),
                r.policy.clone(),
                format!("{:.0}", r.p50_us),
                format!("{:.0}", r.p99_us),
                format!("{:.0}", r.max_us),
                format!("{:.2}", r.cg_per_step),
                r.in_step_factorizations.to_string(),
                r.background_factorizations.to_string(),
                r.factor_waits.to_string(),
                format!("{:.4}", r.force_n),
                if r.same_as_one_thread { "yes" } else { "NO" }.into(),
            ]
        })
        .collect();
    s.push_str(&table(
        &[
            ("tets", Align::Right),
            ("threads", Align::Right),
            ("policy", Align::Left),
            ("p50 µs", Align::Right),
            ("p99 µs", Align::Right),
            ("max µs", Align::Right),
            ("CG/step", Align::Right),
            ("in-step fact.", Align::Right),
            ("bg fact.", Align::Right),
            ("waits", Align::Right),
            ("force N", Align::Right),
            ("bitwise = 1 thread", Align::Left),
        ],
        &body,
    ));
    s
}
