//! `lop-bench models`: what the deformation models cost per step, how that scales with the
//! mesh, and the thesis' chapter-3 integrator study (§3.2, Figs. 3.7–3.11) re-run on our
//! mass-spring model. Everything runs in this process on `lop-sim` directly (no daemon, no
//! IPC); every figure is wall-clock time of one `step` call, timed with `std::time::Instant`,
//! after a few warm-up steps that are not counted. Figures: `docs/benchmarks.md`, "Deformation
//! models — `lop-bench models`".
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
//! a step.
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
//! # Part 4 — the touched step on 1 and 2 threads (`--only threads`)
//!
//! The scaling boxes of ~2k, 5k, 10k and 20k tetrahedra at the haptic rate (1 ms), pressed 3 mm
//! by the god-object's patch and held; the step's p50/p99/max at each thread count (1 up to
//! the machine's cores, at most 2) under the `realtime` and `background` refactor policies,
//! and whether every thread count ends bit for bit where one thread does
//! (`models/threads.rs`). Not part of the default run.
//!
//! `--only scaling,orderings` runs only the named parts (`step-times`, `scaling`, `orderings`,
//! `study`); `--tets 50000` replaces the scaling series' sizes (also for part 2b) and
//! `--scaling-models corotational` limits its models.

mod common;
mod orderings;
mod scaling;
mod step_times;
mod study;
mod threads;

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use lop_sim::fem::FemMode;
use lop_sim::msd::Integrator;
use serde::Serialize;

pub use common::{integrator_key, integrator_label, summarize, us, workspace_root, Bench};
use scaling::{ordering_rows, render_scaling, scaling};
pub use scaling::{ScaleFit, ScaleRow};
use step_times::{render_step_times, shipped_mesh, step_times};
pub use step_times::{MeshRow, StepRow};

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
    /// Part 4: the touched step at 1 and 2 threads, ~2k to ~20k tetrahedra (`--tets` replaces
    /// the sizes). Runs only when named.
    Threads,
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
    /// Part 4 (`--only threads`).
    pub threads: Vec<threads::ThreadRow>,
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

    let runs = |p: Part| (a.only.is_empty() && p != Part::Threads) || a.only.contains(&p);

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

    let thread_rows = if runs(Part::Threads) {
        let rows = threads::threads(a.quick, &a.tets)?;
        print!("{}", threads::render(&rows));
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
        threads: thread_rows,
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
