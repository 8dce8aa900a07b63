//! `lopd simulate`: run a scene offline — no device, no shared memory, no wall clock — and write
//! what happened: per-step timings (`steps.csv`), final node positions (`final_<body>.vtk` and
//! `final_positions.csv`), a summary (`summary.json`) and, where a cautery cut (`[cut]`),
//! every cut asked for, landed or refused (`cuts.csv`).
//!
//! Every body takes steps of its own `dt`; `--steps N` means N steps of every body. The world
//! advances by the rounds `lopd deform` runs (`World::round`: organ collision, the bodies due,
//! heat), each round to the earliest next step time of the bodies still running, so every
//! body due then takes one step. Mock scripts (`--script` or `--device mock[:SCRIPT]`, one per
//! tool of the scene in order; or a recording with `--device replay:PATH` for the first tool)
//! move the devices on simulated time and each tool's god-object decides its contact, as the
//! haptic loop does live (`lop_scene::OfflineSession`), with the tool's law as its device
//! would render it (`lop_scene::ToolLaws`, clamped to the mock's or the recording's stiffness
//! limit) and its kind deciding what its buttons do; so a run is deterministic and can be
//! compared bit for bit. `--static` solves the static equilibrium of the
//! FEM bodies (K u = f) instead, for validation and calibration.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use lop_config::Scene;
use lop_drivers::{BUTTON_CUT, BUTTON_GRAB, BUTTON_HEAT};
use lop_scene::session::RoundInput;
use lop_scene::{DeviceClamp, OfflineSession, ToolLaws, ToolSource};
use lop_sim::lop::SwitchReason;
use lop_sim::mesh::{write_vtk, TetMesh};
use lop_sim::model::Model;
use serde::Serialize;

/// Options of `lopd simulate`.
pub struct SimulateOptions {
    /// The scene.
    pub scene: Scene,
    /// Steps per body (a cap with `until_converged`).
    pub steps: u64,
    /// Stop once every body has settled.
    pub until_converged: bool,
    /// Solve the static equilibrium of FEM bodies instead of stepping.
    pub static_solve: bool,
    /// Mock scripts, one per tool in the scene's order from the first (tools past the last
    /// have no device); at most as many as the scene has tools.
    pub scripts: Vec<PathBuf>,
    /// The first tool's trajectory from a session recording (`--device replay:PATH`), by tick
    /// index, instead of its script.
    pub replay: Option<PathBuf>,
    /// Output directory.
    pub out: PathBuf,
}

/// A body counts as settled below this largest nodal speed, m/s …
pub const SETTLED_SPEED: f64 = 1e-4;
/// … for this many consecutive steps.
pub const SETTLED_STEPS: u32 = 20;

#[derive(Serialize)]
struct BodySummary {
    name: String,
    model: String,
    nodes: usize,
    steps: u64,
    simulated_s: f64,
    step_us_median: f64,
    step_us_p99: f64,
    step_us_max: f64,
    kinetic_energy_j: f64,
    max_speed_m_s: f64,
    max_displacement_m: f64,
    settled: bool,
    resets: u32,
    /// Levels-of-precision transitions (0 for a pinned body).
    switches: u32,
    /// A FEM body's system: stored entries of the matrix (one triangle) and of its Cholesky
    /// factor, what a step's solves stream (null for other models).
    matrix_entries: Option<usize>,
    factor_entries: Option<usize>,
    static_solve: Option<String>,
}

#[derive(Serialize)]
struct Summary {
    scene: String,
    scene_path: String,
    steps_per_body: u64,
    until_converged: bool,
    static_solve: bool,
    /// The trajectory of each tool with one (scripts, or the recording), in tool order.
    scripts: Vec<String>,
    wall_s: f64,
    bodies: Vec<BodySummary>,
}

fn percentile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return 0.0;
    }
    let i = ((sorted.len() - 1) as f64 * q).round() as usize;
    sorted[i.min(sorted.len() - 1)]
}

/// What a run leaves: the summary's path and the world as it ended.
pub struct Outcome {
    /// `summary.json` in the output directory.
    pub summary: PathBuf,
    /// The world after the last round.
    pub world: lop_sim::world::World,
}

/// Runs the simulation and writes the outputs.
pub fn run(opts: SimulateOptions) -> Result<Outcome> {
    std::fs::create_dir_all(&opts.out)
        .with_context(|| format!("creating {}", opts.out.display()))?;
    if opts.scripts.len() > opts.scene.tools.len() {
        bail!(
            "{} scripts for the {} tool(s) of scene {:?}: give at most one per tool",
            opts.scripts.len(),
            opts.scene.tools.len(),
            opts.scene.name
        );
    }
    // Each tool's trajectory: the recording drives the first tool, else the scripts in order.
    let sources: Vec<ToolSource> = match &opts.replay {
        Some(r) => ToolSource::load(None, Some(r))?.into_iter().collect(),
        None => (opts.scripts.iter())
            .map(|p| Ok(ToolSource::load(Some(p), None)?.expect("a script was given")))
            .collect::<Result<_>>()?,
    };
    // Per tool: where its device maps, what its buttons do (its kind) and its laws on the
    // device its trajectory stands for; a session has at least the first tool.
    let tools: Vec<_> = (0..sources.len().max(1))
        .map(|k| {
            let spec = &opts.scene.tools[k];
            let clamp = DeviceClamp {
                max_stiffness_n_per_mm: sources
                    .get(k)
                    .map_or(f64::INFINITY, |s| s.limits().max_stiffness_n_per_mm),
            };
            let laws = ToolLaws::of_tool(&opts.scene, k, clamp);
            (spec.workspace.transform(), spec.kind, laws)
        })
        .collect();
    let loaded = lop_scene::load(opts.scene)?;
    let scene_name = loaded.scene.name.clone();
    let scene_path = loaded.scene.path.display().to_string();
    let mut world = loaded.world;
    let n_bodies = world.bodies.len();
    let wall = Instant::now();

    let mut static_results: Vec<Option<String>> = vec![None; n_bodies];
    let mut times: Vec<Vec<f64>> = vec![Vec::new(); n_bodies];
    let mut steps_done = vec![0u64; n_bodies];
    let mut settled_for = vec![0u32; n_bodies];
    let mut cuts_csv = std::io::BufWriter::new(std::fs::File::create(opts.out.join("cuts.csv"))?);
    writeln!(
        cuts_csv,
        "sim_time_s,body,event,tets,epoch,removed_tets,piece_tets,pieces_removed,tets_left,\
         volume_removed_m3,waited"
    )?;
    let steps_csv = opts.out.join("steps.csv");
    let mut csv = std::io::BufWriter::new(std::fs::File::create(&steps_csv)?);
    writeln!(
        csv,
        "body,step,sim_time_s,model,step_us,kinetic_energy_j,max_speed_m_s,contact_force_n,\
         cg_iterations,factorizations,preconditioner_solves,node_rotation_updates"
    )?;

    if opts.static_solve {
        let gravity = world.gravity;
        for (i, b) in world.bodies.iter_mut().enumerate() {
            // A body under the controller solves with its precise model.
            if let Some(lop) = &mut b.lop {
                lop.to_precise(&mut b.model, b.time, SwitchReason::Requested);
            }
            let t0 = Instant::now();
            static_results[i] = Some(match &mut b.model {
                Model::Fem(fem) => {
                    let zero = vec![[0.0; 3]; b.mesh.nodes.len()];
                    match fem.solve_static(gravity, &zero) {
                        Ok(r) => format!("{r:?}"),
                        Err(e) => bail!("body {:?}: static solve failed: {e}", b.name),
                    }
                }
                _ => "skipped: not an FEM body".to_string(),
            });
            times[i].push(t0.elapsed().as_secs_f64() * 1e6);
        }
    } else {
        // Round by round, as the deformation process runs them: each round advances every body
        // due at the earliest next step time, after the god-object has moved (with a script).
        let laws = tools.iter().map(|(_, _, l)| l.clone()).collect();
        let mut session = OfflineSession::with_tools(world, laws);
        let mut inputs: Vec<Option<RoundInput>> = vec![None; tools.len()];
        let mut active: Vec<bool> = vec![opts.steps > 0; n_bodies];
        let mut skip: Vec<bool> = vec![false; n_bodies];
        loop {
            let bodies = &session.world().bodies;
            let next = (0..n_bodies)
                .filter(|&i| active[i])
                .map(|i| bodies[i].time + bodies[i].model.dt())
                .min_by(f64::total_cmp);
            let Some(next) = next else {
                break;
            };
            let now = (0..n_bodies)
                .filter(|&i| active[i])
                .map(|i| bodies[i].time)
                .fold(f64::INFINITY, f64::min);
            for (k, (source, (workspace, kind, _))) in sources.iter().zip(&tools).enumerate() {
                let sample = source.sample(now);
                let at = workspace.device_to_scene(sample.position_mm);
                session.probe_tool(k, at, kind.holds() && sample.pressed(BUTTON_GRAB));
                inputs[k] = Some(RoundInput {
                    center: at,
                    heat: kind.cauterizes() && sample.pressed(BUTTON_HEAT),
                    cut: kind.cauterizes() && sample.pressed(BUTTON_CUT),
                    stiffness: None,
                });
            }
            for (s, a) in skip.iter_mut().zip(&active) {
                *s = !a;
            }
            session.advance_tools(next, &inputs, &skip, || wall.elapsed().as_nanos() as u64);
            let world = session.world();
            let report = world.last_round();
            for e in &report.cuts {
                write_cut(&mut cuts_csv, world, next, e)?;
            }
            for (i, r) in report.bodies.iter().enumerate() {
                if r.steps == 0 {
                    continue;
                }
                let b = &world.bodies[i];
                if let Some(cause) = r.blow_up {
                    tracing::warn!(
                        "body {:?} blew up at step {} ({cause:?}); reset",
                        b.name,
                        steps_done[i]
                    );
                }
                let us = r.last_step_ns as f64 * 1e-3;
                times[i].push(us);
                steps_done[i] += 1;
                let f = b.force_on_tissue();
                // An FEM step's CG iterations, and the factorisations, preconditioner solves and
                // per-node rotation updates its body has made so far (factorisations on the
                // stepping thread or its factor thread): what makes a slow step slow.
                let (iterations, factors, solves, turns) = match &b.model {
                    Model::Fem(fem) => {
                        let c = fem.solver_counters();
                        (
                            fem.last_iterations() as u64,
                            c.factorizations + c.background_factorizations,
                            c.preconditioner_solves,
                            c.node_rotation_updates,
                        )
                    }
                    _ => (0, 0, 0, 0),
                };
                writeln!(
                    csv,
                    "{},{},{:.6},{:?},{:.3},{:.6e},{:.6e},{:.6e},{},{},{},{}",
                    b.name,
                    steps_done[i],
                    b.time,
                    b.model.kind(),
                    us,
                    b.model.kinetic_energy(),
                    b.model.max_speed(),
                    (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt(),
                    iterations,
                    factors,
                    solves,
                    turns
                )?;
                if steps_done[i] >= opts.steps {
                    active[i] = false;
                }
                if opts.until_converged {
                    if b.model.max_speed() < SETTLED_SPEED {
                        settled_for[i] += 1;
                    } else {
                        settled_for[i] = 0;
                    }
                    if settled_for[i] >= SETTLED_STEPS {
                        active[i] = false;
                    }
                }
            }
        }
        world = session.into_world();
    }
    csv.flush()?;
    cuts_csv.flush()?;

    // Final positions: VTK per body, one CSV for all.
    let mut pos_csv =
        std::io::BufWriter::new(std::fs::File::create(opts.out.join("final_positions.csv"))?);
    writeln!(pos_csv, "body,node,x,y,z")?;
    let mut bodies = Vec::new();
    for (i, b) in world.bodies.iter().enumerate() {
        let x = b.model.positions();
        for (k, p) in x.iter().enumerate() {
            writeln!(
                pos_csv,
                "{},{k},{:.9e},{:.9e},{:.9e}",
                b.name, p[0], p[1], p[2]
            )?;
        }
        let deformed = TetMesh {
            nodes: x.to_vec(),
            ..b.mesh.clone()
        };
        write_vtk(&deformed, &opts.out.join(format!("final_{}.vtk", b.name)))?;
        let max_disp = x
            .iter()
            .zip(&b.mesh.nodes)
            .map(|(p, q)| {
                ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
            })
            .fold(0.0, f64::max);
        let mut sorted = times[i].clone();
        sorted.sort_by(f64::total_cmp);
        let fem = [Some(&b.model), b.lop.as_ref().map(|l| l.parked())]
            .into_iter()
            .flatten()
            .find_map(|m| match m {
                Model::Fem(f) => Some(f.solver_info()),
                _ => None,
            });
        bodies.push(BodySummary {
            name: b.name.clone(),
            model: format!("{:?}", b.model.kind()),
            nodes: x.len(),
            steps: steps_done[i],
            simulated_s: b.time,
            step_us_median: percentile(&sorted, 0.5),
            step_us_p99: percentile(&sorted, 0.99),
            step_us_max: sorted.last().copied().unwrap_or(0.0),
            kinetic_energy_j: b.model.kinetic_energy(),
            max_speed_m_s: b.model.max_speed(),
            max_displacement_m: max_disp,
            settled: b.model.max_speed() < SETTLED_SPEED,
            resets: b.resets,
            switches: b.lop.as_ref().map_or(0, |l| l.switches()),
            matrix_entries: fem.map(|f| f.0),
            factor_entries: fem.map(|f| f.1),
            static_solve: static_results[i].clone(),
        });
    }
    pos_csv.flush()?;
    let summary = Summary {
        scene: scene_name,
        scene_path,
        steps_per_body: opts.steps,
        until_converged: opts.until_converged,
        static_solve: opts.static_solve,
        scripts: (opts.replay.iter())
            .chain(&opts.scripts)
            .map(|p| p.display().to_string())
            .collect(),
        wall_s: wall.elapsed().as_secs_f64(),
        bodies,
    };
    let path = opts.out.join("summary.json");
    std::fs::write(&path, serde_json::to_string_pretty(&summary)? + "\n")?;
    print_summary(&summary, &opts.out);
    Ok(Outcome {
        summary: path,
        world,
    })
}

fn print_summary(s: &Summary, out: &Path) {
    println!(
        "{:<12} {:>5} {:>7} {:>11} {:>11} {:>12} {:>10} {:>8}",
        "body", "model", "steps", "median µs", "p99 µs", "max disp m", "KE J", "settled"
    );
    for b in &s.bodies {
        println!(
            "{:<12} {:>5} {:>7} {:>11.1} {:>11.1} {:>12.4e} {:>10.2e} {:>8}",
            b.name,
            match b.model.as_str() {
                "Fem" => "FEM",
                "Gc" => "GC",
                _ => "MSD",
            },
            b.steps,
            b.step_us_median,
            b.step_us_p99,
            b.max_displacement_m,
            b.kinetic_energy_j,
            b.settled
        );
    }
    println!("wrote {}", out.display());
}

/// One line of `cuts.csv` for cut event `e` at simulated time `t`, and its log line.
fn write_cut(
    out: &mut impl Write,
    world: &lop_sim::world::World,
    t: f64,
    e: &lop_sim::cut::CutEvent,
) -> Result<()> {
    use lop_sim::cut::CutEvent;
    let name = |b: usize| world.bodies.get(b).map_or("?", |b| b.name.as_str());
    match e {
        CutEvent::Asked { body, tets, .. } => {
            writeln!(out, "{t:.6},{},asked,{tets},,,,,,,", name(*body))?;
        }
        CutEvent::Landed { report: r, waited } => {
            tracing::info!("{}: cut at {t:.3} s: {r}", name(r.body));
            writeln!(
                out,
                "{t:.6},{},landed,,{},{},{},{},{},{:.6e},{waited}",
                name(r.body),
                r.epoch,
                r.removed_tets,
                r.piece_tets,
                r.pieces_removed,
                r.tets_left,
                r.volume_removed
            )?;
        }
        CutEvent::Refused(why) => {
            tracing::warn!("cut refused at {t:.3} s: {why}");
            writeln!(out, "{t:.6},,refused,,,,,,,,")?;
        }
    }
    Ok(())
}
