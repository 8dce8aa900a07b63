//! `lop-bench models`: what the deformation models cost per step, how that scales with the
//! mesh, and the thesis' chapter-3 integrator study (§3.2, Figs. 3.7–3.11) re-run on our
//! mass-spring model. Everything runs in this process on `lop-sim` directly (no daemon, no
//! IPC); every figure is wall-clock time of one `step` call, timed with `std::time::Instant`,
//! after a few warm-up steps that are not counted.
//!
//! # Part 1 — time per step on the shipped meshes
//! Seven models — the mass-spring model (MSD) with each of its five integrators, linear FEM and
//! corotational FEM — on `assets/meshes/{beam,cylinder,liver}`, with the parameters of the body
//! using that mesh in `config/scenes/{beam,cylinders,organs}.toml` (`[body.msd]`, `[body.fem]`;
//! the integrator and the FEM mode are overridden per row) and the scene's gravity. Every row
//! takes **one integrator step per `step` call** (`SubstepPolicy::Fixed(1)`):
//! - implicit Euler and both FEM modes step at the scene's `dt`;
//! - an explicit integrator (explicit Euler, symplectic Euler, Verlet, RK4) steps at a *stable*
//!   `dt` for that mesh: the scene's `dt` divided by the number of sub-steps its automatic
//!   stability bound asks for (`SubstepPolicy::Auto`). The cost of one step does not depend on
//!   `dt`; what the explicit rows do not show is how many such steps a scene's `dt` needs (that
//!   count is the "sub-steps" column): the real cost of one scene step is that many times the
//!   median.
//!
//! The liver row set has the tool pressing on the body all the time, so the contact path is
//! timed too: the scene's tool (3 mm sphere, linear law 300 N/m) with its centre on the rest
//! surface of a front (+z) triangle, i.e. pressed 3 mm deep at the start; the candidate
//! triangles (every surface triangle sharing a node with it, as `World::step_body` finds them)
//! are found once at rest. `World`'s per-step closest-triangle search is not part of the timed
//! `step`. The beam and the cylinder have no contact; the liver scene has no gravity.
//!
//! # Part 2 — scaling with the mesh size
//! Box meshes (`lop_sim::fem::box_mesh`: cubes split into 6 tetrahedra) with a 0.1 × 0.1 m
//! cross-section and cubic cells, about twice as long as wide, fixed at `x = 0`, sagging under
//! gravity from rest; from ~1k to ~100k tetrahedra (`--quick`: up to ~10k). Soft tissue: `E` =
//! 3 kPa, `ν` = 0.45, `ρ` = 1000 kg/m³, `α` = 1 /s, `dt` = 0.01 s. Corotational FEM, linear FEM
//! and MSD with implicit Euler (springs `k = E · mean edge length`, masses lumped from `ρ`,
//! `γ = α · mean node mass`, the same mapping the organ scenes use). The exponent `e` of
//! `time ∝ tets^e` is a least-squares fit on log–log axes; `e ≈ 1–1.2` is "close to linear".
//! For FEM the table also shows the factor's size (`nnz(L)`), and for corotational FEM the
//! conjugate-gradient iterations per timed step and the factorisations among the timed steps.
//! Each row is timed for up to 3 s (at least 8 steps, at most 500), except corotational FEM,
//! whose cost depends on the motion: it is timed over exactly 40 steps (0.4 s of simulated
//! time after the 2 warm-up steps) at every size, so every size and every version of the
//! solver is measured on the same window: about 30 steps of smooth sagging, then the bar
//! folds at its clamp (inverted elements), where the lagged preconditioner goes stale within
//! a step. (Until 2026-11 the corotational rows had the 3 s budget too, which timed only the
//! smooth first steps of the large boxes: 27 steps at 50k tets, 8 at 100k.)
//!
//! # Part 2b — fill-reducing orderings
//! On the shipped meshes (with their scenes' material) and the scaling boxes: the size of the
//! FEM system's Cholesky factor with AMD and with geometric nested dissection, and the time of
//! its single-precision numeric factorisation (the corotational preconditioner) and of one
//! pair of triangular solves with it (`bench/src/models/orderings.rs`). `Fem::new` keeps the
//! ordering with the smaller factor.
//!
//! # Part 3 — thesis chapter 3 (§3.2)
//! The beam (`assets/meshes/beam`: 0.4 × 0.1 × 0.1 m along +x, the wall nodes at `x = 0`
//! fixed), gravity 9.81 m/s² down, MSD with 0.1 kg per node, exactly **one integrator step per
//! `dt`** (no automatic sub-stepping), from rest for a fixed simulated time (5 s; `--quick`
//! 0.5 s). Recorded at every step: the displacement magnitude `|x − X|` of two nodes,
//! - *first point*: the node nearest the middle of the top edge, `(0.2, 0.05, 0)`;
//! - *second point*: the node nearest the free-end top corner, `(0.4, 0.05, 0.05)`.
//!
//! | figure | what changes | fixed |
//! |---|---|---|
//! | Fig. 3.7 | stiffness 250 vs 300 N/m | damping 0.01, dt 0.0048 |
//! | Fig. 3.8 | dt 0.0050 vs 0.0054 s | stiffness 250, damping 0.01 |
//! | Fig. 3.9 | damping 0.01 vs 0.1 N·s/m (the caption's 0.01; §3.2.4's text says 0.001) | stiffness 250, dt 0.005 |
//! | Fig. 3.10 | dt growing from 0.005 to 0.04 s: RK4, with symplectic Euler, Verlet and implicit Euler for comparison | stiffness 250, damping 0.01 |
//! | Fig. 3.11 | time per step per integrator (from part 1, beam) | — |
//!
//! Figs. 3.7–3.9 run explicit Euler, symplectic Euler, Verlet, RK4 and, beyond the thesis,
//! implicit Euler. Beyond the figures, a bisection finds each integrator's largest stable `dt`
//! on the bar (stiffness 250, damping 0.01; "stable" = runs the whole simulated time without a
//! blow-up), which is where Figs. 3.8 and 3.10 draw their line. A run that blows up (the model resets itself and returns `BlowUp`: a
//! non-finite value or a node faster than 50 m/s) is stopped there and marked. Each parameter
//! set (one row of panels in the thesis' figure) gets a CSV (`time_s`, then one column per
//! integrator × point, in mm; empty after a blow-up) and each figure an SVG laid out like the
//! thesis' (rows: parameter sets; left: first point, right: second point; one line per
//! integrator).
//!
//! `--json PATH` writes every number printed (and the per-run summaries of part 3).
//! `--only scaling,orderings` runs only the named parts (`step-times`, `scaling`, `orderings`,
//! `study`); `--tets 50000` replaces the scaling series' sizes (also for part 2b) and
//! `--scaling-models corotational` limits its models.

mod orderings;
mod study;

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{anyhow, bail, Context, Result};
use clap::Args;
use lop_config::{BodySpec, FemParams, MassSpec, MsdParams, Scene, ToolSpec};
use lop_sim::contact::{triangle_normal, ToolSphere};
use lop_sim::fem::{Fem, FemMode, FemParameters};
use lop_sim::mesh::{read_mesh, TetMesh};
use lop_sim::model::{ContactReport, Model, ToolContact};
use lop_sim::msd::{Integrator, MassSpring, MsdParameters, NodeMass, SubstepPolicy};
use serde::Serialize;

use crate::pipeline;

/// Options of `lop-bench models`.
#[derive(Args, Debug, Clone)]
pub struct ModelsArgs {
    /// Small and fast (for the smoke test): fewer timed steps, scaling up to ~10k tetrahedra,
    /// 0.5 s of simulated time in the chapter-3 study.
    #[arg(long)]
    quick: bool,
    /// Where the chapter-3 CSV and SVG files go (created if missing).
    #[arg(long, default_value = "target/lop-bench/models")]
    out: PathBuf,
    /// Also write every number as JSON to this file.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Run only these parts (comma-separated; default: all three).
    #[arg(long, value_enum, value_delimiter = ',')]
    only: Vec<Part>,
    /// Scaling series: these target sizes in tetrahedra instead of the default series
    /// (comma-separated, e.g. `--tets 50000`).
    #[arg(long, value_delimiter = ',')]
    tets: Vec<usize>,
    /// Scaling series: only these models (comma-separated; default: all three).
    #[arg(long, value_enum, value_delimiter = ',')]
    scaling_models: Vec<ScalingModel>,
}

/// A part of `lop-bench models`, for `--only`.
#[derive(clap::ValueEnum, Debug, Clone, Copy, PartialEq, Eq)]
pub enum Part {
    /// Part 1: time per step on the shipped meshes.
    StepTimes,
    /// Part 2: scaling with the mesh size.
    Scaling,
    /// Part 2b: fill-reducing orderings (AMD vs nested dissection) on the shipped meshes and
    /// the scaling boxes.
    Orderings,
    /// Part 3: the thesis' chapter-3 study (and Fig. 3.11, which needs part 1's beam rows).
    Study,
}

/// A model of the scaling series, for `--scaling-models`.
#[derive(clap::ValueEnum, Debug, Clone, Copy, PartialEq, Eq)]
pub enum ScalingModel {
    Corotational,
    Linear,
    Msd,
}

impl ScalingModel {
    fn bench(self) -> Bench {
        match self {
            ScalingModel::Corotational => Bench::Fem(FemMode::Corotational),
            ScalingModel::Linear => Bench::Fem(FemMode::Linear),
            ScalingModel::Msd => Bench::Msd(Integrator::ImplicitEuler),
        }
    }
}

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

/// Scene `[body.msd]` → model parameters.
pub fn msd_params(p: &MsdParams) -> MsdParameters {
    MsdParameters {
        stiffness: p.stiffness,
        mass: match p.mass {
            MassSpec::Density(d) => NodeMass::Density(d),
            MassSpec::NodeMass(m) => NodeMass::PerNode(m),
        },
        damping: p.damping,
        dt: p.dt,
        integrator: match p.integrator {
            lop_config::Integrator::ExplicitEuler => Integrator::ExplicitEuler,
            lop_config::Integrator::SymplecticEuler => Integrator::SymplecticEuler,
            lop_config::Integrator::Verlet => Integrator::Verlet,
            lop_config::Integrator::Rk4 => Integrator::Rk4,
            lop_config::Integrator::ImplicitEuler => Integrator::ImplicitEuler,
        },
    }
}

/// Scene `[body.fem]` → model parameters.
pub fn fem_params(p: &FemParams) -> FemParameters {
    FemParameters {
        young: p.young,
        poisson: p.poisson,
        density: p.density,
        damping: p.damping,
        dt: p.dt,
        mode: match p.mode {
            lop_config::FemMode::Linear => FemMode::Linear,
            lop_config::FemMode::Corotational => FemMode::Corotational,
        },
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
fn build(
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
struct Budget {
    /// Untimed steps first.
    warmup: usize,
    /// At least this many timed steps...
    min_steps: usize,
    /// ...and at most this many...
    max_steps: usize,
    /// ...stopping once this much wall time has passed (after `min_steps`).
    seconds: f64,
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

/// Median, p99 (nearest rank), mean and max of `ns`, in µs.
pub fn summarize(ns: &mut [u64]) -> (f64, f64, f64, f64) {
    if ns.is_empty() {
        return (0.0, 0.0, 0.0, 0.0);
    }
    ns.sort_unstable();
    let rank = |q: f64| {
        let k = (q * ns.len() as f64).ceil() as usize;
        ns[k.clamp(1, ns.len()) - 1] as f64 / 1000.0
    };
    let mean = ns.iter().map(|&v| v as f64).sum::<f64>() / ns.len() as f64 / 1000.0;
    (
        rank(0.5),
        rank(0.99),
        mean,
        ns[ns.len() - 1] as f64 / 1000.0,
    )
}

/// Steps `model` per `budget`, timing each `step` call; returns the timing and the last
/// successful step's contact report.
fn time_model(
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
// Part 1.

/// A shipped mesh and the scene that gives its parameters.
struct MeshCase {
    mesh: &'static str,
    scene: &'static str,
    /// Press the tool on it during the timing.
    press: bool,
}

const MESH_CASES: [MeshCase; 3] = [
    MeshCase {
        mesh: "beam",
        scene: "beam",
        press: false,
    },
    MeshCase {
        mesh: "cylinder",
        scene: "cylinders",
        press: false,
    },
    MeshCase {
        mesh: "liver",
        scene: "organs",
        press: true,
    },
];

/// Tool penetration at rest in part 1, m.
const PRESS_DEPTH: f64 = 0.003;

/// A shipped mesh as benchmarked.
#[derive(Debug, Clone, Serialize)]
pub struct MeshRow {
    pub mesh: String,
    pub scene: String,
    pub body: String,
    pub nodes: usize,
    pub tets: usize,
    pub surface_triangles: usize,
    pub fixed_nodes: usize,
    pub gravity: [f64; 3],
    /// The steady tool contact, if any.
    pub contact: Option<PressInfo>,
}

/// The tool pressing on a body in part 1.
#[derive(Debug, Clone, Serialize)]
pub struct PressInfo {
    /// Surface triangle pressed (index into the mesh's surface).
    pub triangle: usize,
    /// Candidate triangles tested by the models.
    pub candidates: usize,
    /// Tool centre, m.
    pub center: [f64; 3],
    pub radius_m: f64,
    pub stiffness_n_per_m: f64,
    /// Penetration at rest, m.
    pub depth_at_rest_m: f64,
}

/// One model on one mesh.
#[derive(Debug, Clone, Serialize)]
pub struct StepRow {
    pub mesh: String,
    /// [`Bench::key`].
    pub model: String,
    pub label: String,
    /// Time step of one `step` call, s.
    pub dt: f64,
    /// The scene's `dt`, s.
    pub scene_dt: f64,
    /// Sub-steps the scene's `dt` needs with this integrator (explicit MSD; else 1).
    pub substeps_per_scene_step: usize,
    /// Model construction time (FEM: assembly, symbolic analysis, first factorisation), ms.
    pub setup_ms: f64,
    #[serde(flatten)]
    pub timing: Timing,
    /// Contact force magnitude on the tissue after the last step, N (pressed meshes only).
    pub contact_force_n: Option<f64>,
    /// Contact depth after the last step, m (pressed meshes only).
    pub contact_depth_m: Option<f64>,
}

/// The scene and its body that uses `mesh` (by the mesh path's file name).
fn scene_body(scene_name: &str, mesh: &str) -> Result<(Scene, BodySpec)> {
    let path = workspace_root()
        .join("config/scenes")
        .join(format!("{scene_name}.toml"));
    let scene = lop_config::load_scene(&path)
        .with_context(|| format!("loading scene {}", path.display()))?;
    let body = scene
        .bodies
        .iter()
        .find(|b| b.mesh.file_name().and_then(|f| f.to_str()) == Some(mesh))
        .cloned()
        .with_context(|| format!("scene {} has no body on mesh {mesh}", path.display()))?;
    Ok((scene, body))
}

/// Reads a shipped mesh (with the body's extra fixed nodes, untransformed: the timings do not
/// depend on placement).
fn shipped_mesh(name: &str, body: Option<&BodySpec>) -> Result<TetMesh> {
    let path = workspace_root().join("assets/meshes").join(name);
    let mut mesh = read_mesh(&path).with_context(|| format!("reading mesh {}", path.display()))?;
    if let Some(b) = body {
        mesh.fixed.extend(b.fixed_nodes.iter().copied());
        mesh.fixed.sort_unstable();
        mesh.fixed.dedup();
    }
    Ok(mesh)
}

/// The tool of `spec` pressed `PRESS_DEPTH` into the front (+z) surface of `mesh`, near the
/// middle of its x/y extent; the candidate triangles as `World::step_body` collects them.
fn press(mesh: &TetMesh, spec: &ToolSpec) -> Result<(ToolSphere, Vec<u32>, PressInfo)> {
    let info = mesh.info();
    let target = [
        0.5 * (info.bbox_min[0] + info.bbox_max[0]),
        0.5 * (info.bbox_min[1] + info.bbox_max[1]),
        info.bbox_max[2],
    ];
    let mut best: Option<(usize, f64, [f64; 3], [f64; 3])> = None;
    for (t, tri) in mesh.surface.iter().enumerate() {
        let p = tri.map(|k| mesh.nodes[k as usize]);
        let n = triangle_normal(p[0], p[1], p[2]);
        if n[2] < 0.5 {
            continue;
        }
        let c: [f64; 3] = std::array::from_fn(|k| (p[0][k] + p[1][k] + p[2][k]) / 3.0);
        let d2: f64 = (0..3).map(|k| (c[k] - target[k]).powi(2)).sum();
        if best.is_none_or(|b| d2 < b.1) {
            best = Some((t, d2, c, n));
        }
    }
    let (triangle, _, centroid, normal) =
        best.context("the mesh has no surface triangle facing +z")?;
    let offset = spec.radius - PRESS_DEPTH;
    let center: [f64; 3] = std::array::from_fn(|k| centroid[k] + offset * normal[k]);
    let mut candidates: Vec<u32> = Vec::new();
    let nodes = mesh.surface[triangle];
    for (t, tri) in mesh.surface.iter().enumerate() {
        if tri.iter().any(|k| nodes.contains(k)) {
            candidates.push(t as u32);
        }
    }
    let tool = lop_scene::tool_sphere(spec, center);
    let info = PressInfo {
        triangle,
        candidates: candidates.len(),
        center,
        radius_m: spec.radius,
        stiffness_n_per_m: spec.stiffness,
        depth_at_rest_m: PRESS_DEPTH,
    };
    Ok((tool, candidates, info))
}

fn step_times(quick: bool) -> Result<(Vec<MeshRow>, Vec<StepRow>)> {
    let budget = if quick {
        Budget {
            warmup: 3,
            min_steps: 5,
            max_steps: 200,
            seconds: 0.05,
        }
    } else {
        Budget {
            warmup: 20,
            min_steps: 300,
            max_steps: 20_000,
            seconds: 2.0,
        }
    };
    let mut meshes = Vec::new();
    let mut rows = Vec::new();
    for case in &MESH_CASES {
        let (scene, body) = scene_body(case.scene, case.mesh)?;
        let mesh = shipped_mesh(case.mesh, Some(&body))?;
        let msd = msd_params(body.msd.as_ref().with_context(|| {
            format!("scene {}: body {} has no [body.msd]", case.scene, body.name)
        })?);
        let fem = fem_params(body.fem.as_ref().with_context(|| {
            format!("scene {}: body {} has no [body.fem]", case.scene, body.name)
        })?);
        let pressed = if case.press {
            Some(press(&mesh, &scene.tool)?)
        } else {
            None
        };
        let contact = pressed.as_ref().map(|(tool, cand, _)| ToolContact {
            tool: *tool,
            surface: &mesh.surface,
            candidates: cand,
            anchor: None,
        });
        meshes.push(MeshRow {
            mesh: case.mesh.into(),
            scene: case.scene.into(),
            body: body.name.clone(),
            nodes: mesh.nodes.len(),
            tets: mesh.tets.len(),
            surface_triangles: mesh.surface.len(),
            fixed_nodes: mesh.fixed.len(),
            gravity: scene.gravity,
            contact: pressed.as_ref().map(|p| p.2.clone()),
        });
        for bench in Bench::ALL {
            eprintln!("models: {} / {}", case.mesh, bench.label());
            let t0 = Instant::now();
            let (mut model, dt, substeps) = build(bench, &mesh, msd, fem)?;
            let setup_ms = t0.elapsed().as_secs_f64() * 1e3;
            let (timing, last) = time_model(&mut model, scene.gravity, contact.as_ref(), budget)?;
            let force = last.force_on_tissue;
            rows.push(StepRow {
                mesh: case.mesh.into(),
                model: bench.key(),
                label: bench.label(),
                dt,
                scene_dt: match bench {
                    Bench::Msd(_) => msd.dt,
                    Bench::Fem(_) => fem.dt,
                },
                substeps_per_scene_step: substeps,
                setup_ms,
                timing,
                contact_force_n: contact
                    .is_some()
                    .then(|| (force[0].powi(2) + force[1].powi(2) + force[2].powi(2)).sqrt()),
                contact_depth_m: contact.is_some().then_some(last.depth),
            });
        }
    }
    Ok((meshes, rows))
}

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
fn scaling_box(target: usize) -> ([usize; 3], [f64; 3], TetMesh) {
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
fn ordering_rows(quick: bool, targets: &[usize]) -> Result<Vec<orderings::OrderingRow>> {
    let mut rows = Vec::new();
    for case in &MESH_CASES {
        let (_, body) = scene_body(case.scene, case.mesh)?;
        let mesh = shipped_mesh(case.mesh, Some(&body))?;
        let fem = fem_params(body.fem.as_ref().with_context(|| {
            format!("scene {}: body {} has no [body.fem]", case.scene, body.name)
        })?);
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

fn scaling(
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

// ---------------------------------------------------------------------------------------------
// Report.

/// Everything `lop-bench models` reports (the JSON file).
#[derive(Debug, Clone, Serialize)]
pub struct ModelsReport {
    pub quick: bool,
    /// Logical CPUs of the machine.
    pub cpus: usize,
    /// CPU model name (from /proc/cpuinfo, if readable).
    pub cpu_model: Option<String>,
    /// Whether this binary was built with optimisations (`--release`).
    pub optimized_build: bool,
    pub meshes: Vec<MeshRow>,
    /// Part 1.
    pub step_times: Vec<StepRow>,
    /// Part 2.
    pub scaling: Vec<ScaleRow>,
    pub scaling_fits: Vec<ScaleFit>,
    /// Part 2b.
    pub orderings: Vec<orderings::OrderingRow>,
    /// Part 3 (`None` when not run).
    pub study: Option<study::StudyReport>,
    /// Fig. 3.11 analogue (from part 1, beam).
    pub fig3_11: Vec<study::StepCost>,
    /// Every file written into `--out`.
    pub files: Vec<String>,
}

pub fn cpu_model() -> Option<String> {
    let text = std::fs::read_to_string("/proc/cpuinfo").ok()?;
    text.lines()
        .find(|l| l.starts_with("model name"))
        .and_then(|l| l.split(':').nth(1))
        .map(|s| s.trim().to_string())
}

/// Runs the subcommand.
pub fn run(a: ModelsArgs) -> Result<()> {
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("creating output directory {}", a.out.display()))?;
    if cfg!(debug_assertions) {
        eprintln!(
            "models: note: debug build; run `cargo build --release -p lop-bench` for figures"
        );
    }

    let runs = |p: Part| a.only.is_empty() || a.only.contains(&p);

    let (meshes, step_rows) = if runs(Part::StepTimes) {
        let (meshes, rows) = step_times(a.quick)?;
        print!("{}", render_step_times(&meshes, &rows));
        println!();
        (meshes, rows)
    } else {
        (Vec::new(), Vec::new())
    };

    let (scale_rows, fits) = if runs(Part::Scaling) {
        let models: Vec<Bench> = a.scaling_models.iter().map(|m| m.bench()).collect();
        let (rows, fits) = scaling(a.quick, &a.tets, &models)?;
        print!("{}", render_scaling(&rows, &fits, a.quick));
        println!();
        (rows, fits)
    } else {
        (Vec::new(), Vec::new())
    };

    let ordering_rows = if runs(Part::Orderings) {
        let rows = ordering_rows(a.quick, &a.tets)?;
        print!("{}", orderings::render(&rows));
        println!();
        rows
    } else {
        Vec::new()
    };

    let mut files = Vec::new();
    let (study_report, fig3_11) = if runs(Part::Study) {
        let cfg = if a.quick {
            study::StudyConfig::quick()
        } else {
            study::StudyConfig::full()
        };
        let beam = shipped_mesh("beam", None)?;
        let study_report = study::run(&beam, &cfg, &a.out, &mut files)?;
        print!("{}", study::render(&study_report));
        let fig3_11 = if step_rows.is_empty() {
            Vec::new()
        } else {
            let f = study::fig3_11(&step_rows, &a.out, &mut files)?;
            print!("{}", study::render_fig3_11(&f));
            f
        };
        println!();
        (Some(study_report), fig3_11)
    } else {
        (None, Vec::new())
    };
    if !files.is_empty() {
        println!("files written to {}:", a.out.display());
        for f in &files {
            println!("  {f}");
        }
    }

    let report = ModelsReport {
        quick: a.quick,
        cpus: std::thread::available_parallelism().map_or(0, |n| n.get()),
        cpu_model: cpu_model(),
        optimized_build: !cfg!(debug_assertions),
        meshes,
        step_times: step_rows,
        scaling: scale_rows,
        scaling_fits: fits,
        orderings: ordering_rows,
        study: study_report,
        fig3_11,
        files,
    };
    if let Some(path) = &a.json {
        let text = serde_json::to_string_pretty(&report)?;
        std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))?;
        println!("JSON written to {}", path.display());
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// Tables.

/// Column alignment.
#[derive(Clone, Copy)]
pub enum Align {
    Left,
    Right,
}

/// An aligned text table: a header line, then one line per row, columns two spaces apart.
pub fn table(headers: &[(&str, Align)], rows: &[Vec<String>]) -> String {
    let mut w: Vec<usize> = headers.iter().map(|h| h.0.chars().count()).collect();
    for r in rows {
        for (k, c) in r.iter().enumerate() {
            if k < w.len() {
                w[k] = w[k].max(c.chars().count());
            }
        }
    }
    let line = |cells: Vec<&str>| {
        let mut s = String::new();
        for (k, c) in cells.iter().enumerate() {
            let pad = w[k].saturating_sub(c.chars().count());
            if k > 0 {
                s.push_str("  ");
            }
            match headers[k].1 {
                Align::Left => {
                    s.push_str(c);
                    if k + 1 < cells.len() {
                        s.push_str(&" ".repeat(pad));
                    }
                }
                Align::Right => {
                    s.push_str(&" ".repeat(pad));
                    s.push_str(c);
                }
            }
        }
        let mut s = s.trim_end().to_string();
        s.push('\n');
        s
    };
    let mut out = line(headers.iter().map(|h| h.0).collect());
    for r in rows {
        out += &line(r.iter().map(|c| c.as_str()).collect());
    }
    out
}

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
fn dt_text(dt: f64) -> String {
    if dt >= 1e-3 {
        format!("{dt:.4}")
    } else {
        format!("{dt:.2e}")
    }
}

fn render_step_times(meshes: &[MeshRow], rows: &[StepRow]) -> String {
    let mut s = String::from(
        "Part 1: time per step, one integrator step per call (warm-up excluded), µs\n",
    );
    for m in meshes {
        let _ = write!(
            s,
            "\n{}: {} nodes, {} tets, {} fixed; parameters of body \"{}\" in config/scenes/{}.toml; \
             gravity {:?}\n",
            m.mesh, m.nodes, m.tets, m.fixed_nodes, m.body, m.scene, m.gravity
        );
        if let Some(c) = &m.contact {
            let _ = writeln!(
                s,
                "contact: tool r {} mm, {} N/m, pressed {} mm into surface triangle {} at rest \
                 ({} candidate triangles), held there",
                c.radius_m * 1e3,
                c.stiffness_n_per_m,
                c.depth_at_rest_m * 1e3,
                c.triangle,
                c.candidates
            );
        } else {
            s.push_str("contact: none\n");
        }
        let mut cells = Vec::new();
        for r in rows.iter().filter(|r| r.mesh == m.mesh) {
            let mut note = String::new();
            if r.substeps_per_scene_step > 1 {
                note = format!(
                    "stable dt = scene dt {} / {} sub-steps",
                    dt_text(r.scene_dt),
                    r.substeps_per_scene_step
                );
            }
            if let Some(f) = r.contact_force_n {
                if !note.is_empty() {
                    note.push_str("; ");
                }
                let _ = write!(
                    note,
                    "contact {:.3} N at {:.2} mm",
                    f,
                    r.contact_depth_m.unwrap_or(0.0) * 1e3
                );
            }
            cells.push(vec![
                r.label.clone(),
                dt_text(r.dt),
                r.substeps_per_scene_step.to_string(),
                r.timing.steps.to_string(),
                us(r.timing.median_us),
                us(r.timing.p99_us),
                us(r.timing.mean_us),
                format!("{:.1}", r.setup_ms),
                r.timing.blow_ups.to_string(),
                note,
            ]);
        }
        s += &table(
            &[
                ("model", Align::Left),
                ("dt (s)", Align::Right),
                ("sub-steps", Align::Right),
                ("steps", Align::Right),
                ("median", Align::Right),
                ("p99", Align::Right),
                ("mean", Align::Right),
                ("setup ms", Align::Right),
                ("blow-ups", Align::Right),
                ("note", Align::Left),
            ],
            &cells,
        );
    }
    s
}

fn render_scaling(rows: &[ScaleRow], fits: &[ScaleFit], quick: bool) -> String {
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

    #[test]
    fn percentiles_by_nearest_rank() {
        let mut ns: Vec<u64> = (1..=100).map(|v| v * 1000).collect();
        let (med, p99, mean, max) = summarize(&mut ns);
        assert_eq!((med, p99, max), (50.0, 99.0, 100.0));
        assert!((mean - 50.5).abs() < 1e-12);
    }

    #[test]
    fn table_aligns_columns() {
        let t = table(
            &[("a", Align::Left), ("bb", Align::Right)],
            &[vec!["xyz".into(), "1".into()]],
        );
        assert_eq!(t, "a    bb\nxyz   1\n");
    }
}
