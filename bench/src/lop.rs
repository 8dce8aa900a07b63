//! `lop-bench lop`: the thesis' evaluation of levels of precision (§6.3 efficiency, §6.4
//! effectiveness) re-run on the shipped scenes, plus the speed-up of the Green-coordinates (GC)
//! cage over the FEM step it stands in for. Everything runs in this process on `lop-sim`
//! directly (no daemon, no IPC); scenes come from `config/scenes/*.toml` and are modified in
//! memory per configuration (`model` pin, `importance`, `[lop] start`) before
//! `lop_scene::load`, so every run sees the bodies exactly as `lopd` would (the heat model is
//! detached: the thesis times the deformation alone).
//!
//! # Part 1 — efficiency (thesis Figs. 6.4–6.9): time per iteration per body
//! The world is stepped as the daemon steps it, by its one round (`World::round`): simulated
//! time advances in ticks of the smallest `dt` of any model in the scene, and each tick is a
//! round in which every body takes the steps that are due, the tool (when a mock script drives
//! it) placed from the script at the round's start through the scene's workspace map, with each
//! body's tool law (`lop_scene::ToolLaws`, clamped to the mock's Omni). Each body step is timed
//! by the round's report with `std::time::Instant` (no warm-up: the thesis' plots start at
//! iteration 1), so a step includes the tool's proximity test and, on a switch, the hand-over.
//! The tool acts on the bodies as `Coupling::Nearest` (the sphere pushes the surface nearest to
//! it), in every trial.
//!
//! Organ-to-organ collision (the scenes' `[collision]`, on by default) is switched off
//! (`World::disable_collisions`) in every trial but the third: the thesis runs those without it
//! (§6.3.2: the times are "not including the collision detection between objects").
//!
//! - `cylinders`, trial **gravity** (Figs. 6.4/6.5): no tool, from rest, 4 s simulated. Each
//!   pair (A, B) ∈ {FEM, MSD}² runs *without GC* (both bodies pinned) and *with GC* (both
//!   `model = "auto"`, `importance` important for FEM, normal for MSD). With GC the bodies start
//!   on their precise model (`[lop] start = "precise"`), as in Fig. 6.5, and hand over to the
//!   cage once settled: from the cage there is nothing to do under gravity alone.
//! - `cylinders`, trial **interaction** (Fig. 6.6): the same eight configurations, from rest,
//!   `config/scripts/cylinders-poke.toml` driving the tool for 6 s: the script's 4.3 s played
//!   once (not looped), then the tool lifted out of the scene (§6.3.2: "removing the scalpel
//!   from the model"), so a poked body can settle and hand back to its cage. With GC the bodies
//!   start as cages (the scene's `start = "gc"`).
//! - `cylinders`, trial **interaction-collision** (§6.3.3, Fig. 6.7: "an interaction with the
//!   Model A in a way that it collides with Model B"): the same eight configurations, from rest,
//!   collision on with the scene's `[collision]` (`cylinders.toml`: springs of 200 N/m, 0.5 mm skin,
//!   10 mm depth limit), `config/scripts/cylinders-push.toml` played the same way for 6 s: the
//!   tip approaches cylinder A from −x at 3/4 of its height, pushes 12 mm in along +x (1.5 →
//!   2.5 s), holds 1 s, withdraws by 4.6 s, so A bends into B across the 2 mm gap. As
//!   `lopd deform` does, the round detects organ contacts once per tick in which a body is due,
//!   before the due bodies step. **Attribution:** the detection is timed on its own and
//!   reported per round (median over all rounds, over the rounds in contact and apart, mean,
//!   p99, max, and its share of the run's computing time), *not* added into the bodies' step
//!   times: those keep the thesis' meaning (Fig. 6.7 counts "the time for detecting the
//!   collision of the scalpel, and the time for computing the deformation"; the object-to-object
//!   detection comes separately, as in Fig. 6.10). A body's step does include resolving its
//!   contact springs (its model's solve); the table adds the steps taken with springs and their
//!   median. **The push must reach B:** each configuration is run a second time as a control,
//!   the same push with collision off (untimed), and the bench reports B's largest node
//!   displacement along +x with and without collision, the largest x force of B's contact
//!   springs, and how deep A goes into B in the control; B counts as moved when it goes at
//!   least 0.1 mm farther along +x than in the control (a warning names the configurations
//!   where it does not).
//! - `organs`, trial **interaction** (Figs. 6.8/6.9): all four organs FEM (important), with GC
//!   vs without, `organs-poke.toml` for 6 s, played the same way, collision off: unlike the
//!   thesis' (§6.3.4: the interaction "propagated to other organs"), the liver does not push
//!   the others here.
//!
//! With GC a body runs the scene's `[body.gc]` cage (the shipped scenes: fitted cage,
//! projected dynamics). Per run: a CSV of every step (`iteration,body,time_s,model,step_us`;
//! `model` is the model that took the step), with collision a CSV of every detection
//! (`part1-<key>-collision.csv`: `round,time_s,detect_us,penetrations,max_depth_mm,tree_builds`),
//! one SVG per scene × trial (a panel per configuration, x = iteration, y = ms per step, one
//! line per body, plus the detection per round), and a table per body: steps, median µs while
//! GC, median µs while precise, mean µs, share of steps on the cage, switches; the JSON also has
//! each body's largest displacement from rest (and along +x) and contact force.
//!
//! # Part 2 — GC speed-up over FEM
//! For every body of `organs` and `cylinders`: the corotational FEM step (the body's
//! `[body.fem]`, its default solver) and the GC step with projected dynamics for each cage
//! shape (box, fitted, subdivided box n = 2), all under the scene's gravity and the same small
//! sinusoidal nodal load (1 mN in total along +x, 1 Hz, on the four free surface nodes farthest
//! from the fixed ones) so the body keeps moving; the GC step without the nodal load for
//! reference (the cylinders still sag under gravity there), and the implicit-Euler MSD step
//! (`[body.msd]`) for context. Each model is stepped on its own, outside `World` (no tool
//! proximity test). 2000 timed steps after 20 warm-up steps (`--quick`: 30 after 3); median,
//! p99, and the ratio FEM median / median.
//!
//! # Part 3 — effectiveness (thesis Fig. 6.13): the cage's approximation error
//! The cylinder (`cylinder_a` of `cylinders.toml` alone, gravity on) and the liver
//! (`organs.toml`, gravity off), from rest: a lateral load along +x on the free surface nodes
//! of the body's −x side and upper half (below/above the bounding box's centre), ramped
//! linearly over 0.5 s, held 1 s, released, run to 5 s (`--quick`: 0.5 s). The loads are sized
//! for a few millimetres of each reference's motion: against the FEM 2 mN (cylinder) / 10 mN
//! (liver) — the Table 6.1 cylinder (E = 600 Pa) bends by about 0.1 m, more than its diameter,
//! under 50 mN — and against the MSD 1 N (its Table 6.1 cylinder is ~80× stiffer) / 10 mN.
//! References: corotational FEM and implicit-Euler MSD (pinned, the scene's parameters).
//! Approximations: a GC model for each cage shape × dynamics {projected from the reference it
//! approximates (built as `lopd` builds it, under the scene's gravity), plain Galerkin,
//! mass-spring with the scene's `[body.gc]` stiffness/density/damping (the thesis' table
//! values)}, the thesis' box mass-spring cage with its parameters searched for on another load
//! (the thesis tuned them by hand; see `effectiveness::Tuned`), the cage fitted to the reference's shape every iteration ("best fit", the
//! bound for any dynamics on that cage), and the rest shape ("no deformation"). All
//! step in lockstep with identical loads at the reference's `dt` (the cage too, whatever its
//! scene `dt`). Per iteration, over all nodes: mean and max of `|x_gc − x_ref|` divided by the
//! body's smallest rest extent, in %.
//!
//! `--json PATH` writes every number printed and the list of files.

mod effectiveness;
mod efficiency;
mod speedup;

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use clap::Args;
use lop_config::{BodySpec, ModelPin, Scene};
use lop_sim::lop::{CageDynamics, CageShape, CageSprings, GcParameters};
use lop_sim::mesh::TetMesh;
use lop_sim::model::ModelKind;
use serde::Serialize;

use crate::models::workspace_root;
// The parts below use the bench's one quantile definition (`crate::stats`).
use crate::stats::{median, quantile_sorted};

/// Options of `lop-bench lop`.
#[derive(Args, Debug, Clone)]
pub struct LopArgs {
    /// Small and fast (for the smoke test): 0.5 s of simulated time per efficiency and
    /// effectiveness run (the poke scripts started 1 s in, the cylinders' 1.2 s in, so the
    /// tool reaches the body; the push 1.9 s in, so the pushed cylinder reaches the other), 30
    /// timed steps per speed-up row.
    #[arg(long)]
    quick: bool,
    /// Where the CSV and SVG files go (created if missing).
    #[arg(long, default_value = "target/lop-bench/lop")]
    out: PathBuf,
    /// Also write every number as JSON to this file.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Run only these parts (1 efficiency, 2 speed-up, 3 effectiveness), e.g. `--part 2,3`;
    /// all three by default.
    #[arg(long, value_delimiter = ',', value_parser = clap::value_parser!(u8).range(1..=3))]
    part: Vec<u8>,
}

// ---------------------------------------------------------------------------------------------
// Shared helpers.

/// A shipped scene by name (`config/scenes/NAME.toml`).
pub(crate) fn shipped_scene(name: &str) -> Result<Scene> {
    let path = workspace_root()
        .join("config/scenes")
        .join(format!("{name}.toml"));
    lop_config::load_scene(&path).with_context(|| format!("loading scene {}", path.display()))
}

/// Every body of `scene` with its mesh as the daemon places it (transformed, with the scene's
/// extra fixed nodes). Loads the scene with every body pinned to mass-spring: the cheapest
/// models to build; only the meshes are kept.
fn placed_bodies(scene: &Scene) -> Result<Vec<(BodySpec, TetMesh)>> {
    let mut pinned = scene.clone();
    for b in &mut pinned.bodies {
        b.model = ModelPin::Msd;
    }
    let loaded = lop_scene::load(pinned)?;
    Ok(scene
        .bodies
        .iter()
        .cloned()
        .zip(loaded.world.bodies.into_iter().map(|b| b.mesh))
        .collect())
}

/// Short name of a model kind, as the thesis' figures label them.
fn kind_label(k: ModelKind) -> &'static str {
    match k {
        ModelKind::Gc => "GC",
        ModelKind::MassSpring => "MSD",
        ModelKind::Fem => "FEM",
    }
}

/// The cage shapes compared, in the order they are reported.
const SHAPES: [CageShape; 3] = [
    CageShape::Box,
    CageShape::Fitted,
    CageShape::SubdividedBox(2),
];

/// Stable machine name of a cage shape.
fn shape_key(s: CageShape) -> String {
    match s {
        CageShape::Box => "box".into(),
        CageShape::Fitted => "fitted".into(),
        CageShape::SubdividedBox(n) => format!("subdivided-box-{n}"),
    }
}

/// Human name of a cage shape.
fn shape_label(s: CageShape) -> String {
    match s {
        CageShape::Box => "box".into(),
        CageShape::Fitted => "fitted".into(),
        CageShape::SubdividedBox(n) => format!("subdivided box {n}"),
    }
}

/// Cage dynamics compared in Part 3.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum DynKind {
    /// Projected, stiffness matched to the precise model's compliance (the default).
    Projected,
    /// Plain Galerkin projection (`GᵀKG`).
    Galerkin,
    /// The thesis' hand-tuned mass-spring cage.
    MassSpring,
}

impl DynKind {
    /// Stable machine name.
    pub(crate) fn key(self) -> &'static str {
        match self {
            DynKind::Projected => "projected",
            DynKind::Galerkin => "galerkin",
            DynKind::MassSpring => "mass-spring",
        }
    }
    /// Human name.
    pub(crate) fn label(self) -> &'static str {
        match self {
            DynKind::Projected => "projected",
            DynKind::Galerkin => "Galerkin",
            DynKind::MassSpring => "mass-spring (thesis)",
        }
    }
}

/// The body's GC parameters (`[body.gc]`: padding, the mass-spring cage's parameters) with
/// `shape`, `dynamics` and `dt` replaced.
fn gc_variant(
    spec: &BodySpec,
    mesh: &TetMesh,
    shape: CageShape,
    dynamics: DynKind,
    dt: f64,
) -> GcParameters {
    let base = lop_scene::gc_parameters(spec, mesh, dt);
    let gc = spec.gc.clone().unwrap_or_default();
    GcParameters {
        shape,
        dynamics: match dynamics {
            DynKind::MassSpring => {
                CageDynamics::MassSpring(gc.springs.unwrap_or(CageSprings::THESIS))
            }
            DynKind::Galerkin => CageDynamics::Galerkin,
            DynKind::Projected => CageDynamics::Projected,
        },
        dt,
        ..base
    }
}

fn norm3(a: [f64; 3]) -> f64 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}

fn dist3(a: [f64; 3], b: [f64; 3]) -> f64 {
    norm3([a[0] - b[0], a[1] - b[1], a[2] - b[2]])
}

/// `out/name` as listed in the report.
fn listed(out: &Path, name: &str) -> String {
    out.join(name).display().to_string()
}

fn write_file(path: &Path, text: &str) -> Result<()> {
    std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))
}

// ---------------------------------------------------------------------------------------------
// Report.

/// One target of the levels-of-precision work, measured.
#[derive(Debug, Clone, Serialize)]
pub struct Target {
    /// What is asked.
    pub target: String,
    /// The figure compared with it.
    pub measured: String,
    /// The number itself (a ratio or a percentage).
    pub value: f64,
    /// The bound.
    pub limit: f64,
    /// Whether `value` is on the right side of `limit`.
    pub met: bool,
}

/// Everything `lop-bench lop` reports (the JSON file).
#[derive(Debug, Clone, Serialize)]
pub struct LopReport {
    pub quick: bool,
    /// Logical CPUs of the machine.
    pub cpus: usize,
    /// CPU model name (from /proc/cpuinfo, if readable).
    pub cpu_model: Option<String>,
    /// Whether this binary was built with optimisations (`--release`).
    pub optimized_build: bool,
    /// Part 1.
    pub efficiency: Vec<efficiency::RunRow>,
    /// Part 2.
    pub speedup: Vec<speedup::SpeedRow>,
    /// Part 3.
    pub effectiveness: Vec<effectiveness::CaseReport>,
    /// Parts 2 and 3 against their targets.
    pub targets: Vec<Target>,
    /// Every file written into `--out`.
    pub files: Vec<String>,
}

/// Runs the subcommand.
pub fn run(a: LopArgs) -> Result<()> {
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("creating output directory {}", a.out.display()))?;
    if cfg!(debug_assertions) {
        eprintln!("lop: note: debug build; run `cargo build --release -p lop-bench` for figures");
    }
    let mut files = Vec::new();

    let wanted = |p: u8| a.part.is_empty() || a.part.contains(&p);
    let mut efficiency = Vec::new();
    if wanted(1) {
        efficiency = efficiency::run(a.quick, &a.out, &mut files)?;
        print!("{}", efficiency::render(&efficiency));
        println!();
    }

    let mut speed = Vec::new();
    if wanted(2) {
        speed = speedup::run(a.quick)?;
        print!("{}", speedup::render(&speed));
        println!();
    }

    let mut effectiveness = Vec::new();
    if wanted(3) {
        effectiveness = effectiveness::run(a.quick, &a.out, &mut files)?;
        print!("{}", effectiveness::render(&effectiveness));
        println!();
    }

    let mut targets = speedup::targets(&speed);
    targets.extend(effectiveness::targets(&effectiveness));
    print!("{}", render_targets(&targets, a.quick));
    println!();

    println!("files written to {}:", a.out.display());
    for f in &files {
        println!("  {f}");
    }
    let report = LopReport {
        quick: a.quick,
        cpus: std::thread::available_parallelism().map_or(0, |n| n.get()),
        cpu_model: crate::models::cpu_model(),
        optimized_build: !cfg!(debug_assertions),
        efficiency,
        speedup: speed,
        effectiveness,
        targets,
        files,
    };
    if let Some(path) = &a.json {
        let text = serde_json::to_string_pretty(&report)?;
        write_file(path, &text)?;
        println!("JSON written to {}", path.display());
    }
    Ok(())
}

fn render_targets(targets: &[Target], quick: bool) -> String {
    use crate::table::{table, Align};
    let mut s = format!(
        "Against the targets{}\n",
        if quick {
            " [--quick: short runs, not the figures]"
        } else {
            ""
        }
    );
    let cells: Vec<Vec<String>> = targets
        .iter()
        .map(|t| {
            vec![
                t.target.clone(),
                t.measured.clone(),
                if t.met { "yes" } else { "NO" }.into(),
            ]
        })
        .collect();
    s += &table(
        &[
            ("target", Align::Left),
            ("measured", Align::Left),
            ("met", Align::Left),
        ],
        &cells,
    );
    s
}
