//! Part 2 of `lop-bench models`: scaling with the mesh size on box meshes, the log–log fit,
//! its table, and the rows of part 2b (orderings) over the same sizes.

use std::fmt::Write as _;
use std::time::Instant;

use anyhow::{Context, Result};
use lop_sim::fem::{FemMode, FemParameters};
use lop_sim::mesh::TetMesh;
use lop_sim::model::Model;
use lop_sim::msd::{Integrator, MsdParameters, NodeMass};
use serde::Serialize;

use super::common::{build, time_model, Bench, Budget, Timing};
use super::orderings;
use super::step_times::{scene_body, shipped_mesh, MESH_CASES};
use crate::table::{table, Align};

// ---------------------------------------------------------------------------------------------
// Part 2.

/// Target sizes of the scaling series, tetrahedra.
const SCALING_TARGETS: [usize; 6] = [1_000, 3_000, 10_000, 30_000, 50_000, 100_000];
const SCALING_TARGETS_QUICK: usize = 3;

/// Timed steps of every corotational FEM row of the scaling series (after the warm-up): 0.4 s
/// of simulated time, the same window of the motion at every size.
const COROTATIONAL_SCALING_STEPS: usize = 40;

/// Soft-tissue material of the scaling series.
const SOFT_YOUNG: f64 = 3000.0;
const SOFT_POISSON: f64 = 0.45;
const SOFT_DENSITY: f64 = 1000.0;
const SOFT_ALPHA: f64 = 1.0;
const SOFT_DT: f64 = 0.01;
/// The FEM parameters of that material.
const SOFT_FEM: FemParameters = FemParameters {
    young: SOFT_YOUNG,
    poisson: SOFT_POISSON,
    density: SOFT_DENSITY,
    damping: SOFT_ALPHA,
    dt: SOFT_DT,
    mode: FemMode::Corotational,
};
/// Cross-section of the scaling boxes, m.
const BOX_WIDTH: f64 = 0.1;

/// The models of the scaling series.
const SCALING_MODELS: [Bench; 3] = [
    Bench::Fem(FemMode::Corotational),
    Bench::Fem(FemMode::Linear),
    Bench::Msd(Integrator::ImplicitEuler),
];

/// One model on one box.
#[derive(Debug, Clone, Serialize)]
pub struct ScaleRow {
    pub model: String,
    pub label: String,
    pub cells: [usize; 3],
    pub tets: usize,
    pub nodes: usize,
    /// Free degrees of freedom (3 per free node).
    pub dofs: usize,
    /// FEM: stored non-zeros of the Cholesky factor.
    pub factor_nnz: Option<usize>,
    pub setup_ms: f64,
    #[serde(flatten)]
    pub timing: Timing,
}

/// Least-squares fit `median ∝ tets^exponent` of one model.
#[derive(Debug, Clone, Serialize)]
pub struct ScaleFit {
    pub model: String,
    pub label: String,
    pub exponent: f64,
    /// Coefficient of determination of the log–log fit.
    pub r2: f64,
    /// The fit's prediction at 50k tetrahedra, µs.
    pub predicted_50k_us: f64,
}

/// Cells `[nx, n, n]` of a box with about `target` tetrahedra, about twice as long as wide.
fn box_cells(target: usize) -> [usize; 3] {
    let n = ((target as f64 / 12.0).cbrt().round() as usize).max(1);
    let nx = ((target as f64 / (6 * n * n) as f64).round() as usize).max(1);
    [nx, n, n]
}

/// The scaling box of about `target` tetrahedra: its cells, size (m) and mesh, fixed at `x = 0`.
pub(super) fn scaling_box(target: usize) -> ([usize; 3], [f64; 3], TetMesh) {
    let cells = box_cells(target);
    let a = BOX_WIDTH / cells[1] as f64;
    let size = [a * cells[0] as f64, BOX_WIDTH, BOX_WIDTH];
    let mesh = lop_sim::fem::box_mesh(size, cells, |p| p[0] <= 1e-9 * size[0]);
    (cells, size, mesh)
}

/// The scaling series' sizes: `--tets` if given, else the default series (`--quick`: its
/// smallest sizes).
fn scaling_targets(quick: bool, targets: &[usize]) -> &[usize] {
    match (targets.is_empty(), quick) {
        (false, _) => targets,
        (true, true) => &SCALING_TARGETS[..SCALING_TARGETS_QUICK],
        (true, false) => &SCALING_TARGETS[..],
    }
}

/// Part 2b: both orderings on the shipped meshes and the scaling boxes.
pub(super) fn ordering_rows(quick: bool, targets: &[usize]) -> Result<Vec<orderings::OrderingRow>> {
    let mut rows = Vec::new();
    for case in &MESH_CASES {
        let (_, body) = scene_body(case.scene, case.mesh)?;
        let mesh = shipped_mesh(case.mesh, Some(&body))?;
        let fem = body.fem.with_context(|| {
            format!("scene {}: body {} has no [body.fem]", case.scene, body.name)
        })?;
        eprintln!("models: orderings / {}", case.mesh);
        rows.push(orderings::compare(case.mesh, &mesh, fem, quick)?);
    }
    for &target in scaling_targets(quick, targets) {
        let (cells, _, mesh) = scaling_box(target);
        let name = format!("box {}x{}x{}", cells[0], cells[1], cells[2]);
        eprintln!("models: orderings / {name}");
        rows.push(orderings::compare(&name, &mesh, SOFT_FEM, quick)?);
    }
    Ok(rows)
}

/// Slope and R² of `ln y` on `ln x`.
pub fn loglog_fit(points: &[(f64, f64)]) -> Option<(f64, f64, f64)> {
    let pts: Vec<(f64, f64)> = points
        .iter()
        .filter(|p| p.0 > 0.0 && p.1 > 0.0)
        .map(|p| (p.0.ln(), p.1.ln()))
        .collect();
    if pts.len() < 2 {
        return None;
    }
    let n = pts.len() as f64;
    let mx = pts.iter().map(|p| p.0).sum::<f64>() / n;
    let my = pts.iter().map(|p| p.1).sum::<f64>() / n;
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let syy: f64 = pts.iter().map(|p| (p.1 - my).powi(2)).sum();
    // All sizes equal (or NaN): no slope.
    if sxx.is_nan() || sxx <= 0.0 {
        return None;
    }
    let slope = sxy / sxx;
    let intercept = my - slope * mx;
    let r2 = if syy > 0.0 {
        (sxy * sxy) / (sxx * syy)
    } else {
        1.0
    };
    Some((slope, r2, intercept))
}

pub(super) fn scaling(
    quick: bool,
    targets: &[usize],
    models: &[Bench],
) -> Result<(Vec<ScaleRow>, Vec<ScaleFit>)> {
    let budget = if quick {
        Budget {
            warmup: 1,
            min_steps: 3,
            max_steps: 20,
            seconds: 0.2,
        }
    } else {
        Budget {
            warmup: 2,
            min_steps: 8,
            max_steps: 500,
            seconds: 3.0,
        }
    };
    let targets = scaling_targets(quick, targets);
    let corotational_steps = if quick {
        budget.max_steps
    } else {
        COROTATIONAL_SCALING_STEPS
    };
    let models = if models.is_empty() {
        &SCALING_MODELS[..]
    } else {
        models
    };
    let gravity = [0.0, -9.81, 0.0];
    let mut rows = Vec::new();
    for &target in targets {
        let (cells, size, mesh) = scaling_box(target);
        let edges = mesh.edges();
        let mean_edge = edges
            .iter()
            .map(|&[i, j]| {
                let (p, q) = (mesh.nodes[i as usize], mesh.nodes[j as usize]);
                ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
            })
            .sum::<f64>()
            / edges.len() as f64;
        let volume = size[0] * size[1] * size[2];
        let mean_node_mass = SOFT_DENSITY * volume / mesh.nodes.len() as f64;
        let msd = MsdParameters {
            stiffness: SOFT_YOUNG * mean_edge,
            mass: NodeMass::Density(SOFT_DENSITY),
            damping: SOFT_ALPHA * mean_node_mass,
            dt: SOFT_DT,
            integrator: Integrator::ImplicitEuler,
        };
        let fem = SOFT_FEM;
        let free_nodes = mesh.nodes.len() - mesh.fixed.len();
        for &bench in models {
            eprintln!(
                "models: box {}x{}x{} ({} tets) / {}",
                cells[0],
                cells[1],
                cells[2],
                mesh.tets.len(),
                bench.label()
            );
            let t0 = Instant::now();
            let (mut model, _, _) = build(bench, &mesh, msd, fem)?;
            let setup_ms = t0.elapsed().as_secs_f64() * 1e3;
            let factor_nnz = match &model {
                Model::Fem(f) => Some(f.solver_info().1),
                _ => None,
            };
            // Corotational FEM: the same simulated window at every size (see the module docs).
            let budget = match bench {
                Bench::Fem(FemMode::Corotational) => Budget {
                    min_steps: corotational_steps,
                    max_steps: corotational_steps,
                    ..budget
                },
                _ => budget,
            };
            let (timing, _) = time_model(&mut model, gravity, None, budget)?;
            rows.push(ScaleRow {
                model: bench.key(),
                label: bench.label(),
                cells,
                tets: mesh.tets.len(),
                nodes: mesh.nodes.len(),
                dofs: 3 * free_nodes,
                factor_nnz,
                setup_ms,
                timing,
            });
        }
    }
    let mut fits = Vec::new();
    for &bench in models {
        let pts: Vec<(f64, f64)> = rows
            .iter()
            .filter(|r| r.model == bench.key())
            .map(|r| (r.tets as f64, r.timing.median_us))
            .collect();
        if let Some((e, r2, c)) = loglog_fit(&pts) {
            fits.push(ScaleFit {
                model: bench.key(),
                label: bench.label(),
                exponent: e,
                r2,
                predicted_50k_us: (c + e * 50_000f64.ln()).exp(),
            });
        }
    }
    Ok((rows, fits))
}

pub(super) fn render_scaling(rows: &[ScaleRow], fits: &[ScaleFit], quick: bool) -> String {
    let mut s = format!(
        "Part 2: scaling on box meshes (0.1 x 0.1 m bars about twice as long, cubes of 6 tets, \
         fixed at x = 0, sagging under gravity from rest; E {SOFT_YOUNG} Pa, nu {SOFT_POISSON}, \
         rho {SOFT_DENSITY}, alpha {SOFT_ALPHA}, dt {SOFT_DT}){}\n",
        if quick { " [--quick]" } else { "" }
    );
    let cells: Vec<Vec<String>> = rows
        .iter()
        .map(|r| {
            vec![
                r.label.clone(),
                format!("{}x{}x{}", r.cells[0], r.cells[1], r.cells[2]),
                r.tets.to_string(),
                r.nodes.to_string(),
                r.dofs.to_string(),
                r.timing.steps.to_string(),
                format!("{:.3}", r.timing.median_us / 1e3),
                format!("{:.3}", r.timing.p99_us / 1e3),
                format!("{:.3}", r.timing.mean_us / 1e3),
                format!("{:.0}", r.setup_ms),
                r.factor_nnz
                    .map_or("-".into(), |n| format!("{:.2}", n as f64 / 1e6)),
                match r.timing.cg_per_step {
                    Some(cg) if r.model == "fem-corotational" => format!("{cg:.1}"),
                    _ => "-".into(),
                },
                match r.timing.factorizations {
                    Some(f) if r.model == "fem-corotational" => f.to_string(),
                    _ => "-".into(),
                },
            ]
        })
        .collect();
    s += &table(
        &[
            ("model", Align::Left),
            ("cells", Align::Right),
            ("tets", Align::Right),
            ("nodes", Align::Right),
            ("dofs", Align::Right),
            ("steps", Align::Right),
            ("median ms", Align::Right),
            ("p99 ms", Align::Right),
            ("mean ms", Align::Right),
            ("setup ms", Align::Right),
            ("nnz(L) M", Align::Right),
            ("CG/step", Align::Right),
            ("refactors", Align::Right),
        ],
        &cells,
    );
    for f in fits {
        let _ = writeln!(
            s,
            "fit {}: step time ∝ tets^{:.2} (R² {:.3}); at 50k tets {:.1} ms",
            f.label,
            f.exponent,
            f.r2,
            f.predicted_50k_us / 1e3
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fit_recovers_a_power_law() {
        let pts: Vec<(f64, f64)> = [1e3, 3e3, 1e4, 3e4]
            .iter()
            .map(|&x: &f64| (x, 2.0 * x.powf(1.3)))
            .collect();
        let (e, r2, c) = loglog_fit(&pts).unwrap();
        assert!((e - 1.3).abs() < 1e-12 && (r2 - 1.0).abs() < 1e-12);
        assert!((c.exp() - 2.0).abs() < 1e-9);
    }

    #[test]
    fn box_cells_hit_the_targets() {
        for t in SCALING_TARGETS {
            let c = box_cells(t);
            let tets = 6 * c[0] * c[1] * c[2];
            assert!(
                (tets as f64 / t as f64 - 1.0).abs() < 0.1,
                "{t}: {c:?} -> {tets}"
            );
        }
    }
}
