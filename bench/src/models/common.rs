//! Helpers shared by the parts of `lop-bench models`: the benchmarked models and their
//! parameters, building one, timing its steps, and the plain-text tables.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{anyhow, bail, Result};
use lop_sim::fem::{Fem, FemMode, FemParameters};
use lop_sim::mesh::TetMesh;
use lop_sim::model::{ContactReport, Model, ToolContact};
use lop_sim::msd::{Integrator, MassSpring, MsdParameters, SubstepPolicy};
use serde::Serialize;

use crate::pipeline;

/// The workspace root (meshes and scenes are found relative to it).
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

// ---------------------------------------------------------------------------------------------
// Models and parameters.

/// One of the seven benchmarked models.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Bench {
    Msd(Integrator),
    Fem(FemMode),
}

impl Bench {
    /// Every model, MSD integrators in the thesis' order, then FEM.
    pub const ALL: [Bench; 7] = [
        Bench::Msd(Integrator::ExplicitEuler),
        Bench::Msd(Integrator::SymplecticEuler),
        Bench::Msd(Integrator::Verlet),
        Bench::Msd(Integrator::Rk4),
        Bench::Msd(Integrator::ImplicitEuler),
        Bench::Fem(FemMode::Linear),
        Bench::Fem(FemMode::Corotational),
    ];

    /// Stable machine name.
    pub fn key(self) -> String {
        match self {
            Bench::Msd(i) => format!("msd-{}", integrator_key(i)),
            Bench::Fem(FemMode::Linear) => "fem-linear".into(),
            Bench::Fem(FemMode::Corotational) => "fem-corotational".into(),
        }
    }

    /// Table label.
    pub fn label(self) -> String {
        match self {
            Bench::Msd(i) => format!("MSD {}", integrator_label(i)),
            Bench::Fem(FemMode::Linear) => "FEM linear".into(),
            Bench::Fem(FemMode::Corotational) => "FEM corotational".into(),
        }
    }
}

/// Stable machine name of an integrator (the scene files' spelling).
pub fn integrator_key(i: Integrator) -> &'static str {
    match i {
        Integrator::ExplicitEuler => "explicit-euler",
        Integrator::SymplecticEuler => "symplectic-euler",
        Integrator::Verlet => "verlet",
        Integrator::Rk4 => "rk4",
        Integrator::ImplicitEuler => "implicit-euler",
    }
}

/// Human name of an integrator.
pub fn integrator_label(i: Integrator) -> &'static str {
    match i {
        Integrator::ExplicitEuler => "explicit Euler",
        Integrator::SymplecticEuler => "symplectic Euler",
        Integrator::Verlet => "Verlet",
        Integrator::Rk4 => "RK4",
        Integrator::ImplicitEuler => "implicit Euler",
    }
}

/// An MSD body taking exactly one integrator step per `step`: implicit Euler at `p.dt`, an
/// explicit integrator at `p.dt / (its automatic sub-step count)`. Returns the body and that
/// sub-step count (1 for implicit Euler).
fn msd_one_step(mesh: &TetMesh, mut p: MsdParameters) -> (MassSpring, usize) {
    let substeps = if p.integrator.is_explicit() {
        MassSpring::new(mesh, p).substeps()
    } else {
        1
    };
    p.dt /= substeps as f64;
    let body = MassSpring::new(mesh, p).with_substep_policy(SubstepPolicy::Fixed(1));
    (body, substeps)
}

/// Builds the model for one row; returns it, the `dt` of one step and the automatic sub-step
/// count the scene's `dt` would need (1 unless explicit MSD).
pub(super) fn build(
    bench: Bench,
    mesh: &TetMesh,
    msd: MsdParameters,
    fem: FemParameters,
) -> Result<(Model, f64, usize)> {
    Ok(match bench {
        Bench::Msd(i) => {
            let (body, substeps) = msd_one_step(
                mesh,
                MsdParameters {
                    integrator: i,
                    ..msd
                },
            );
            let dt = body.dt();
            (Model::MassSpring(body), dt, substeps)
        }
        Bench::Fem(mode) => {
            let body = Fem::new(mesh, FemParameters { mode, ..fem })
                .map_err(|e| anyhow!("FEM on {}: {e}", mesh.source.display()))?;
            let dt = body.dt();
            (Model::Fem(body), dt, 1)
        }
    })
}

// ---------------------------------------------------------------------------------------------
// Timing.

/// How long to time one row.
#[derive(Debug, Clone, Copy)]
pub(super) struct Budget {
    /// Untimed steps first.
    pub(super) warmup: usize,
    /// At least this many timed steps...
    pub(super) min_steps: usize,
    /// ...and at most this many...
    pub(super) max_steps: usize,
    /// ...stopping once this much wall time has passed (after `min_steps`).
    pub(super) seconds: f64,
}

/// Per-step times of one row.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct Timing {
    /// Timed steps.
    pub steps: usize,
    /// Median, µs.
    pub median_us: f64,
    /// 99th percentile (nearest rank), µs.
    pub p99_us: f64,
    /// Mean, µs.
    pub mean_us: f64,
    /// Largest, µs.
    pub max_us: f64,
    /// Steps (warm-up included) that blew up and reset the body.
    pub blow_ups: usize,
    /// FEM: conjugate-gradient iterations per timed step (0 in linear mode).
    pub cg_per_step: Option<f64>,
    /// FEM: numeric factorisations during the timed steps.
    pub factorizations: Option<u64>,
}

/// Median, p99 (nearest rank, `crate::stats`), mean and max of `ns`, in µs.
pub fn summarize(ns: &mut [u64]) -> (f64, f64, f64, f64) {
    crate::stats::summarize_ns(ns)
}

/// Steps `model` per `budget`, timing each `step` call; returns the timing and the last
/// successful step's contact report.
pub(super) fn time_model(
    model: &mut Model,
    gravity: [f64; 3],
    contact: Option<&ToolContact<'_>>,
    budget: Budget,
) -> Result<(Timing, ContactReport)> {
    let external = vec![[0.0; 3]; model.positions().len()];
    let mut blow_ups = 0;
    let mut last = ContactReport::default();
    for _ in 0..budget.warmup {
        match model.step(gravity, &external, contact) {
            Ok(r) => last = r,
            Err(_) => blow_ups += 1,
        }
    }
    let counters = |m: &Model| match m {
        Model::Fem(f) => Some(f.solver_counters()),
        _ => None,
    };
    let before = counters(model);
    let mut ns: Vec<u64> = Vec::with_capacity(budget.max_steps);
    let start = Instant::now();
    while ns.len() < budget.max_steps
        && (ns.len() < budget.min_steps || start.elapsed().as_secs_f64() < budget.seconds)
    {
        let t = Instant::now();
        let r = model.step(gravity, &external, contact);
        ns.push(t.elapsed().as_nanos() as u64);
        match r {
            Ok(r) => last = r,
            Err(_) => blow_ups += 1,
        }
        if pipeline::interrupted() {
            bail!("interrupted");
        }
    }
    let delta = before.zip(counters(model)).map(|(b, a)| {
        (
            (a.cg_iterations - b.cg_iterations) as f64 / ns.len() as f64,
            a.factorizations - b.factorizations,
        )
    });
    let (median_us, p99_us, mean_us, max_us) = summarize(&mut ns);
    Ok((
        Timing {
            steps: ns.len(),
            median_us,
            p99_us,
            mean_us,
            max_us,
            blow_ups,
            cg_per_step: delta.map(|d| d.0),
            factorizations: delta.map(|d| d.1),
        },
        last,
    ))
}

// ---------------------------------------------------------------------------------------------
// Tables (printed by `crate::table`).

/// A time in µs with 3 significant digits or so.
pub fn us(v: f64) -> String {
    if v >= 1000.0 {
        format!("{v:.0}")
    } else if v >= 100.0 {
        format!("{v:.1}")
    } else {
        format!("{v:.2}")
    }
}

/// A time step, s.
pub(super) fn dt_text(dt: f64) -> String {
    if dt >= 1e-3 {
        format!("{dt:.4}")
    } else {
        format!("{dt:.2e}")
    }
}
