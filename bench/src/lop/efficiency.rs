//! Part 1 of `lop-bench lop`: time per iteration per body under gravity, under a scripted
//! poke and under a scripted push of one body into another, with and without the
//! levels-of-precision controller (thesis §6.3, Figs. 6.4–6.9). See the parent module's docs
//! for the set-up; this file runs it, `efficiency/output.rs` writes the CSV and SVG files and
//! the tables.

mod output;

use std::path::Path;
use std::time::Instant;

use anyhow::{bail, Result};
use lop_config::{Importance, ModelPin, Scene, StartLevel};
use lop_drivers::mock::{MockDevice, MockScript};
use lop_scene::{DeviceClamp, Rounds, TickTool, ToolLaws};
use lop_sim::collide::Collisions;
use lop_sim::model::{ContactSpring, ModelKind};
use lop_sim::world::{BodyRound, Coupling};
use serde::Serialize;

use super::{kind_label, listed, shipped_scene};
use crate::models::workspace_root;
use crate::pipeline;
use crate::stats::{median, quantile_sorted};

pub use output::render;
use output::{write_csv, write_detection_csv, write_svg};

/// Simulated time of the gravity trial, s.
const GRAVITY_SECONDS: f64 = 4.0;
/// Simulated time of an interaction trial, s (the poke scripts last 4.3–4.4 s, the push 4.6 s).
const INTERACTION_SECONDS: f64 = 6.0;
/// `--quick`: simulated time of every run, s (where the scripts start is [`Trial::quick_offset`]).
const QUICK_SECONDS: f64 = 0.5;
/// How much farther along +x the pushed body's nodes must go with collision than in the
/// control run without it (same push, same models), m, for the push to count as propagated:
/// ten times what a pinned cylinder moves along x under gravity alone (0.01 mm; the Table 6.1
/// material's Poisson ratio is 0.0023).
const PROPAGATED_M: f64 = 0.1e-3;

/// A body's precise model in a configuration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Precise {
    Fem,
    Msd,
}

impl Precise {
    fn key(self) -> &'static str {
        match self {
            Precise::Fem => "fem",
            Precise::Msd => "msd",
        }
    }
    fn label(self) -> &'static str {
        match self {
            Precise::Fem => "FEM",
            Precise::Msd => "MSD",
        }
    }
    fn pin(self) -> ModelPin {
        match self {
            Precise::Fem => ModelPin::Fem,
            Precise::Msd => ModelPin::Msd,
        }
    }
    /// The importance that makes the controller pick this model on contact.
    fn importance(self) -> Importance {
        match self {
            Precise::Fem => Importance::Important,
            Precise::Msd => Importance::Normal,
        }
    }
}

/// One trial: a scene, with or without a tool script, with or without organ-to-organ
/// collision.
#[derive(Debug, Clone, Copy)]
struct Trial {
    scene: &'static str,
    /// "gravity", "interaction" or "interaction-collision".
    name: &'static str,
    /// Thesis figures it reproduces.
    thesis: &'static str,
    /// The mock script driving the tool (a file in `config/scripts/`), if any.
    script: Option<&'static str>,
    /// `--quick`: where the script starts, s (past its initial rest, so the tool reaches the
    /// body within the short run; the push: into the pushing phase, so it reaches the other
    /// body too).
    quick_offset: f64,
    /// Organ-to-organ collision on (the scene's `[collision]`, detected once per tick as
    /// `lopd` does) or off (`World::disable_collisions`, as in the thesis' trials without it).
    collision: bool,
    /// With `collision`: the body pushed by the other one, whose motion is checked.
    pushed: Option<&'static str>,
}

const TRIALS: [Trial; 4] = [
    Trial {
        scene: "cylinders",
        name: "gravity",
        thesis: "Figs. 6.4 (without GC) and 6.5 (with GC)",
        script: None,
        quick_offset: 0.0,
        collision: false,
        pushed: None,
    },
    Trial {
        scene: "cylinders",
        name: "interaction",
        thesis: "Fig. 6.6",
        script: Some("cylinders-poke.toml"),
        quick_offset: 1.2,
        collision: false,
        pushed: None,
    },
    Trial {
        scene: "cylinders",
        name: "interaction-collision",
        thesis: "Fig. 6.7",
        script: Some("cylinders-push.toml"),
        quick_offset: 1.9,
        collision: true,
        pushed: Some("cylinder_b"),
    },
    Trial {
        scene: "organs",
        name: "interaction",
        thesis: "Figs. 6.8 (with GC) and 6.9 (without GC)",
        script: Some("organs-poke.toml"),
        quick_offset: 1.0,
        collision: false,
        pushed: None,
    },
];

impl Trial {
    fn scripted(&self) -> bool {
        self.script.is_some()
    }
}

/// The configurations of a trial: the precise model of each body, with GC or without.
fn configurations(trial: &Trial, bodies: usize) -> Vec<(Vec<Precise>, bool)> {
    let mut out = Vec::new();
    if trial.scene == "cylinders" {
        for (a, b) in [
            (Precise::Fem, Precise::Fem),
            (Precise::Fem, Precise::Msd),
            (Precise::Msd, Precise::Fem),
            (Precise::Msd, Precise::Msd),
        ] {
            for with_gc in [false, true] {
                out.push((vec![a, b], with_gc));
            }
        }
    } else {
        for with_gc in [false, true] {
            out.push((vec![Precise::Fem; bodies], with_gc));
        }
    }
    out
}

fn config_key(precise: &[Precise], with_gc: bool) -> String {
    let models = if precise.len() > 2 && precise.iter().all(|p| *p == precise[0]) {
        format!("all-{}", precise[0].key())
    } else {
        precise
            .iter()
            .map(|p| p.key())
            .collect::<Vec<_>>()
            .join("-")
    };
    format!("{models}-{}", if with_gc { "gc" } else { "nogc" })
}

fn config_label(precise: &[Precise]) -> String {
    if precise.len() > 2 && precise.iter().all(|p| *p == precise[0]) {
        format!("all {}", precise[0].label())
    } else {
        precise
            .iter()
            .map(|p| p.label())
            .collect::<Vec<_>>()
            .join("+")
    }
}

/// One levels-of-precision transition.
#[derive(Debug, Clone, Serialize)]
pub struct SwitchRow {
    /// Body time, s.
    pub time_s: f64,
    pub from: String,
    pub to: String,
    /// "Contact", "Settled" or "Requested".
    pub reason: String,
    /// Largest displayed vertex jump at the switch, mm.
    pub jump_mm: f64,
    /// Going to the cage: what the cage could not represent (blended out), mm.
    pub residual_mm: f64,
}

/// One body in one run.
#[derive(Debug, Clone, Serialize)]
pub struct BodyRow {
    pub body: String,
    /// The body's precise model ("FEM" or "MSD").
    pub precise: String,
    pub nodes: usize,
    /// Steps taken.
    pub steps: usize,
    /// Steps taken by the cage / by the precise model.
    pub gc_steps: usize,
    pub precise_steps: usize,
    /// Median µs of the steps taken by the cage (`None`: none).
    pub median_gc_us: Option<f64>,
    /// Median µs of the steps taken by the precise model (`None`: none).
    pub median_precise_us: Option<f64>,
    /// Steps taken with contact springs (organ-to-organ collision found the body touching
    /// another), by either model, and their median µs (`None`: none).
    pub colliding_steps: usize,
    pub median_colliding_us: Option<f64>,
    /// Over every step, µs.
    pub mean_us: f64,
    pub p99_us: f64,
    pub max_us: f64,
    /// Share of steps taken by the cage, 0..1.
    pub gc_share: f64,
    /// Transitions (0 for a pinned body).
    pub switches: u32,
    pub switch_log: Vec<SwitchRow>,
    /// The model running at the end.
    pub final_model: String,
    /// Blow-ups (the body reset itself).
    pub resets: u32,
    /// Largest displacement of any node from its rest position over the run, mm (gravity's
    /// sag included).
    pub max_displacement_mm: f64,
    /// Largest displacement of any node along +x (the push's direction) over the run, mm.
    pub max_dx_mm: f64,
    /// Largest total force of the body's contact springs (organ-to-organ collision) at the
    /// end of a step, over the run, mN: its magnitude and its x component's (0: collision off
    /// or no contact).
    pub max_contact_force_mn: f64,
    pub max_contact_force_x_mn: f64,
}

/// Organ-to-organ collision detection in one run: one `World::detect_collisions` per tick
/// with a body due, timed on its own (not in the bodies' step times).
#[derive(Debug, Clone, Serialize)]
pub struct CollisionRow {
    /// The scene's `[collision]`: spring stiffness N/m, skin and depth limit mm.
    pub stiffness_n_per_m: f64,
    pub skin_mm: f64,
    pub depth_limit_mm: f64,
    /// Detections (one per tick).
    pub detections: usize,
    /// Over the detections, µs.
    pub median_us: f64,
    /// Median over the detections that found a penetrating vertex / found none, µs.
    pub median_contact_us: Option<f64>,
    pub median_apart_us: Option<f64>,
    pub mean_us: f64,
    pub p99_us: f64,
    pub max_us: f64,
    /// Detections that found at least one penetrating vertex.
    pub contact_detections: usize,
    /// Most penetrating vertices in one detection (both bodies).
    pub max_penetrations: usize,
    /// Largest penetration depth, mm; it counts the skin (a vertex touching the other surface
    /// has depth = skin).
    pub max_depth_mm: f64,
    /// Detection's share of the run's computing time (detections + every step), %.
    pub share_pct: f64,
    /// The body pushed through the contact.
    pub pushed: Option<String>,
    /// The control run (the same push, collision off): the pushed body's `max_dx_mm`, and the
    /// deepest any surface vertex went into the other body, mm (no skin).
    pub control_pushed_max_dx_mm: Option<f64>,
    pub control_max_interpenetration_mm: Option<f64>,
    /// Whether the pushed body went at least 0.1 mm farther along +x than in the control: the
    /// trial is only meaningful if it did.
    pub propagated: bool,
    /// The per-detection CSV.
    pub csv: String,
}

/// One run (scene × trial × configuration).
#[derive(Debug, Clone, Serialize)]
pub struct RunRow {
    /// Stable machine name, e.g. `cylinders-interaction-fem-msd-gc`.
    pub key: String,
    pub scene: String,
    /// "gravity", "interaction" or "interaction-collision".
    pub trial: String,
    /// The precise model of each body, e.g. "FEM+MSD".
    pub configuration: String,
    pub with_gc: bool,
    /// With GC: the level bodies start at ("gc" or "precise"); `None` without GC.
    pub start_level: Option<String>,
    /// Simulated time, s.
    pub simulated_s: f64,
    /// Tick of the interleaving loop (the smallest `dt` of any model in the scene), s.
    pub tick_s: f64,
    /// The tool's script, if any, and the script time the run started at, s.
    pub script: Option<String>,
    pub script_offset_s: f64,
    /// Wall time of the whole run, s.
    pub wall_s: f64,
    /// The per-step CSV.
    pub csv: String,
    pub bodies: Vec<BodyRow>,
    /// Organ-to-organ collision detection (`None`: collision off).
    pub collision: Option<CollisionRow>,
    /// A control run (collision off): the deepest any surface vertex went into another body,
    /// mm. Not in the report (the control's figures go into the timed run's [`CollisionRow`]).
    #[serde(skip)]
    control_interpenetration_mm: Option<f64>,
}

/// One timed step.
struct Sample {
    body: usize,
    iteration: usize,
    time: f64,
    kind: ModelKind,
    us: f64,
    /// The body had contact springs (organ-to-organ collision) in this step.
    colliding: bool,
}

/// One timed collision detection.
struct Detection {
    /// Tick (round) number, from 1.
    round: usize,
    /// Simulated time of the positions it saw, s.
    time: f64,
    us: f64,
    penetrations: usize,
    max_depth: f64,
    /// Hierarchies built from scratch (the others were refitted).
    tree_builds: usize,
}

/// How a run is made.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Mode {
    /// The trial as specified, timed.
    Timed,
    /// A collision trial's control: collision off, the interpenetration measured after every
    /// round (by a detector of its own, untimed); only the motion is reported.
    Control,
}

/// Everything timed in one run.
struct Trace {
    samples: Vec<Sample>,
    detections: Vec<Detection>,
}

/// Runs every trial and configuration; writes a CSV per run and an SVG per trial.
pub fn run(quick: bool, out: &Path, files: &mut Vec<String>) -> Result<Vec<RunRow>> {
    let mut rows = Vec::new();
    for trial in &TRIALS {
        let base = shipped_scene(trial.scene)?;
        let mut traces = Vec::new();
        for (precise, with_gc) in configurations(trial, base.bodies.len()) {
            let (mut row, trace) = run_one(&base, trial, &precise, with_gc, quick, Mode::Timed)?;
            if let Some(c) = &mut row.collision {
                // The control: the same push without collision, to tell the pushed body's
                // motion from what it does on its own, and to show how far the pusher would go
                // into it unopposed.
                let (control, _) = run_one(&base, trial, &precise, with_gc, quick, Mode::Control)?;
                c.add_control(&row.bodies, &control);
            }
            write_csv(&out.join(&row.csv), &row, &trace.samples)?;
            files.push(listed(out, &row.csv));
            if let Some(c) = &row.collision {
                write_detection_csv(&out.join(&c.csv), &trace.detections)?;
                files.push(listed(out, &c.csv));
            }
            traces.push((row, trace));
        }
        let name = format!("part1-{}-{}.svg", trial.scene, trial.name);
        write_svg(&out.join(&name), trial, &traces)?;
        files.push(listed(out, &name));
        rows.extend(traces.into_iter().map(|(r, _)| r));
    }
    Ok(rows)
}

fn run_one(
    base: &Scene,
    trial: &Trial,
    precise: &[Precise],
    with_gc: bool,
    quick: bool,
    mode: Mode,
) -> Result<(RunRow, Trace)> {
    let key = format!(
        "{}-{}-{}",
        trial.scene,
        trial.name,
        config_key(precise, with_gc)
    );
    let collide = trial.collision && mode == Mode::Timed;
    eprintln!(
        "lop: part 1: {key}{}",
        if mode == Mode::Control {
            " (control: collision off)"
        } else {
            ""
        }
    );
    let mut scene = base.clone();
    for (b, p) in scene.bodies.iter_mut().zip(precise) {
        b.importance = p.importance();
        b.model = if with_gc { ModelPin::Auto } else { p.pin() };
    }
    // Fig. 6.5: under gravity alone the bodies start precise and hand over once settled (from
    // the cage nothing would ever happen); under interaction they start as cages (§4.4).
    let start = if trial.scripted() {
        StartLevel::Gc
    } else {
        StartLevel::Precise
    };
    if with_gc {
        scene.lop.start = start;
    }
    let script = match trial.script {
        Some(name) => {
            let path = workspace_root().join("config/scripts").join(name);
            Some((MockScript::load(&path).map_err(anyhow::Error::from)?, path))
        }
        None => None,
    };
    let workspace = scene.tool().workspace.transform();
    let laws = ToolLaws::new(
        &scene,
        DeviceClamp {
            max_stiffness_n_per_mm: MockDevice::omni_limits().max_stiffness_n_per_mm,
        },
    );
    // The rounds as the deformation process runs them, every step due taken (the thesis'
    // trials never drop time), the tool pushing the nearest surface.
    let mut world_rounds = Rounds::catching_up(laws);
    let collision_spec = scene.collision.clone();
    let loaded = lop_scene::load(scene)?;
    let mut world = loaded.world;
    // The thesis' trials time the deformation alone: no heat model.
    world.disable_heat();
    if collide {
        if !world.collisions_enabled() {
            bail!("{key}: the scene's [collision] is disabled; the collision trial needs it on");
        }
    } else {
        // The thesis' trials without object-to-object collision (§6.3.1, §6.3.2, §6.3.4), and
        // the collision trial's control.
        world.disable_collisions();
    }
    // The control's interpenetration gauge: every depth, no skin.
    let mut gauge = (mode == Mode::Control).then(|| {
        let surfaces: Vec<&[[u32; 3]]> = world.bodies.iter().map(|b| &b.mesh.surface[..]).collect();
        Collisions::new(&surfaces)
    });
    let mut max_interpenetration: f64 = 0.0;
    let n = world.bodies.len();
    let rest: Vec<Vec<[f64; 3]>> = world.bodies.iter().map(|b| b.mesh.nodes.clone()).collect();
    let tick = world
        .bodies
        .iter()
        .flat_map(|b| std::iter::once(b.model.dt()).chain(b.lop.as_ref().map(|l| l.parked().dt())))
        .fold(f64::INFINITY, f64::min);
    let seconds = if quick {
        QUICK_SECONDS
    } else if trial.scripted() {
        INTERACTION_SECONDS
    } else {
        GRAVITY_SECONDS
    };
    let offset = if quick { trial.quick_offset } else { 0.0 };
    let ticks = (seconds / tick).round() as usize;
    let mut samples = Vec::with_capacity(ticks * n * 2);
    let mut detections = Vec::with_capacity(if trial.collision { ticks } else { 0 });
    let mut iterations = vec![0usize; n];
    let mut switch_logs: Vec<Vec<SwitchRow>> = vec![Vec::new(); n];
    let mut max_disp = vec![0.0f64; n];
    let mut max_dx = vec![0.0f64; n];
    let mut max_force = vec![0.0f64; n];
    let mut max_force_x = vec![0.0f64; n];
    let wall = Instant::now();
    let mut before = vec![ModelKind::Gc; n];
    // The bodies' part of each round's report, copied out so the bodies can be read mutably.
    let mut rounds: Vec<BodyRound> = Vec::with_capacity(n);
    for k in 1..=ticks {
        let t = k as f64 * tick;
        // One round of the world, as `lopd deform` runs it: organ-to-organ contacts at the
        // current shapes (timed on its own in the report), then the bodies due. The tool is
        // placed from the script at the round's start; the script plays once, and after its end
        // the tool is lifted out of the scene (§6.3.2: "removing the scalpel from the model").
        let now = world
            .bodies
            .iter()
            .map(|b| b.time)
            .fold(f64::INFINITY, f64::min);
        let tool = script.as_ref().and_then(|(s, _)| {
            let st = now + offset;
            (st <= s.duration()).then(|| TickTool {
                center: workspace.device_to_scene(s.sample(st).position_mm),
                coupling: Coupling::Nearest,
                heat: false,
                cut: false,
                stiffness: None,
            })
        });
        for (k, b) in before.iter_mut().zip(&world.bodies) {
            *k = b.model.kind();
        }
        world_rounds.advance(&mut world, t, tool.as_slice(), &[], false, || {
            wall.elapsed().as_nanos() as u64
        });
        let report = world.last_round();
        if report.detected {
            let stats = report.collisions.unwrap_or_default();
            detections.push(Detection {
                round: k,
                time: now,
                us: report.collision_ns as f64 * 1e-3,
                penetrations: stats.penetrations,
                max_depth: stats.max_depth,
                tree_builds: stats.tree_builds,
            });
        }
        rounds.clone_from(&report.bodies);
        for (i, r) in rounds.iter().enumerate().filter(|(_, r)| r.steps > 0) {
            let colliding = !world.contact_springs(i).is_empty();
            let f = contact_force(world.contact_springs(i), world.bodies[i].model.positions());
            max_force[i] = max_force[i].max(super::norm3(f));
            max_force_x[i] = max_force_x[i].max(f[0].abs());
            let b = &mut world.bodies[i];
            let after = b.model.kind();
            // Switches go cage ↔ precise: a switch to the precise model happens before the
            // step (the precise model takes it), a switch to the cage after it.
            let kind = if before[i] == ModelKind::Gc {
                after
            } else {
                before[i]
            };
            for _ in 0..r.steps {
                iterations[i] += 1;
                samples.push(Sample {
                    body: i,
                    iteration: iterations[i],
                    time: b.time,
                    kind,
                    us: r.step_ns as f64 * 1e-3 / r.steps as f64,
                    colliding,
                });
            }
            for (x, r) in b.model.positions().iter().zip(&rest[i]) {
                let d = [x[0] - r[0], x[1] - r[1], x[2] - r[2]];
                max_disp[i] = max_disp[i].max(super::norm3(d));
                max_dx[i] = max_dx[i].max(d[0]);
            }
            if let Some(sw) = b.lop.as_mut().and_then(|l| l.take_switch()) {
                switch_logs[i].push(SwitchRow {
                    time_s: sw.time,
                    from: kind_label(sw.from).into(),
                    to: kind_label(sw.to).into(),
                    reason: format!("{:?}", sw.reason),
                    jump_mm: sw.jump * 1e3,
                    residual_mm: sw.residual * 1e3,
                });
            }
        }
        if let Some(g) = &mut gauge {
            g.detect(&world.collision_bodies());
            max_interpenetration = max_interpenetration.max(g.stats().max_depth);
        }
        if pipeline::interrupted() {
            bail!("interrupted");
        }
    }
    let wall_s = wall.elapsed().as_secs_f64();

    let mut bodies = Vec::with_capacity(n);
    for (i, b) in world.bodies.iter().enumerate() {
        let mine: Vec<&Sample> = samples.iter().filter(|s| s.body == i).collect();
        let mut gc: Vec<f64> = mine
            .iter()
            .filter(|s| s.kind == ModelKind::Gc)
            .map(|s| s.us)
            .collect();
        let mut pr: Vec<f64> = mine
            .iter()
            .filter(|s| s.kind != ModelKind::Gc)
            .map(|s| s.us)
            .collect();
        let mut colliding: Vec<f64> = mine.iter().filter(|s| s.colliding).map(|s| s.us).collect();
        let mut all: Vec<f64> = mine.iter().map(|s| s.us).collect();
        all.sort_by(f64::total_cmp);
        let steps = all.len();
        bodies.push(BodyRow {
            body: b.name.clone(),
            precise: precise[i].label().into(),
            nodes: b.mesh.nodes.len(),
            steps,
            gc_steps: gc.len(),
            precise_steps: pr.len(),
            median_gc_us: median(&mut gc),
            median_precise_us: median(&mut pr),
            colliding_steps: colliding.len(),
            median_colliding_us: median(&mut colliding),
            mean_us: all.iter().sum::<f64>() / steps.max(1) as f64,
            p99_us: quantile_sorted(&all, 0.99),
            max_us: all.last().copied().unwrap_or(0.0),
            gc_share: mine.iter().filter(|s| s.kind == ModelKind::Gc).count() as f64
                / steps.max(1) as f64,
            switches: b.lop.as_ref().map_or(0, |l| l.switches()),
            switch_log: std::mem::take(&mut switch_logs[i]),
            final_model: kind_label(b.model.kind()).into(),
            resets: b.resets,
            max_displacement_mm: max_disp[i] * 1e3,
            max_dx_mm: max_dx[i] * 1e3,
            max_contact_force_mn: max_force[i] * 1e3,
            max_contact_force_x_mn: max_force_x[i] * 1e3,
        });
    }
    let collision = (trial.collision && mode == Mode::Timed).then(|| {
        let mut d: Vec<f64> = detections.iter().map(|x| x.us).collect();
        d.sort_by(f64::total_cmp);
        let total: f64 = d.iter().sum();
        let steps_total: f64 = samples.iter().map(|s| s.us).sum();
        let pushed = trial
            .pushed
            .and_then(|name| bodies.iter().find(|b| b.body == name));
        CollisionRow {
            stiffness_n_per_m: collision_spec.stiffness,
            skin_mm: collision_spec.skin * 1e3,
            depth_limit_mm: collision_spec.depth_limit * 1e3,
            detections: d.len(),
            median_us: median(&mut d.clone()).unwrap_or(0.0),
            median_contact_us: median(
                &mut detections
                    .iter()
                    .filter(|x| x.penetrations > 0)
                    .map(|x| x.us)
                    .collect::<Vec<_>>(),
            ),
            median_apart_us: median(
                &mut detections
                    .iter()
                    .filter(|x| x.penetrations == 0)
                    .map(|x| x.us)
                    .collect::<Vec<_>>(),
            ),
            mean_us: total / d.len().max(1) as f64,
            p99_us: quantile_sorted(&d, 0.99),
            max_us: d.last().copied().unwrap_or(0.0),
            contact_detections: detections.iter().filter(|x| x.penetrations > 0).count(),
            max_penetrations: detections.iter().map(|x| x.penetrations).max().unwrap_or(0),
            max_depth_mm: detections.iter().map(|x| x.max_depth).fold(0.0, f64::max) * 1e3,
            share_pct: 100.0 * total / (total + steps_total).max(f64::MIN_POSITIVE),
            pushed: pushed.map(|b| b.body.clone()),
            control_pushed_max_dx_mm: None,
            control_max_interpenetration_mm: None,
            propagated: false,
            csv: format!("part1-{key}-collision.csv"),
        }
    });
    let control_interpenetration_mm = gauge.is_some().then_some(max_interpenetration * 1e3);
    let row = RunRow {
        csv: format!("part1-{key}.csv"),
        key,
        scene: trial.scene.into(),
        trial: trial.name.into(),
        configuration: config_label(precise),
        with_gc,
        start_level: with_gc.then(|| {
            match start {
                StartLevel::Gc => "gc",
                StartLevel::Precise => "precise",
            }
            .to_string()
        }),
        simulated_s: ticks as f64 * tick,
        tick_s: tick,
        script: script.map(|(_, p)| p.display().to_string()),
        script_offset_s: offset,
        wall_s,
        bodies,
        collision,
        control_interpenetration_mm,
    };
    Ok((
        row,
        Trace {
            samples,
            detections,
        },
    ))
}

impl CollisionRow {
    /// Takes in the control run of the same configuration; `bodies` are the timed run's.
    fn add_control(&mut self, bodies: &[BodyRow], control: &RunRow) {
        let dx = |rows: &[BodyRow]| {
            self.pushed
                .as_ref()
                .and_then(|name| rows.iter().find(|b| &b.body == name))
                .map(|b| b.max_dx_mm)
        };
        self.control_pushed_max_dx_mm = dx(&control.bodies);
        self.control_max_interpenetration_mm = control.control_interpenetration_mm;
        self.propagated = match (dx(bodies), self.control_pushed_max_dx_mm) {
            (Some(with), Some(without)) => with - without >= PROPAGATED_M * 1e3,
            _ => false,
        };
    }
}

/// Total force of contact springs on positions `x`, N: each pushes `stiffness × gap` along its
/// normal while its gap is positive (the springs' law, evaluated at the end of the step in
/// which they were integrated).
fn contact_force(springs: &[ContactSpring], x: &[[f64; 3]]) -> [f64; 3] {
    let mut total = [0.0; 3];
    for s in springs {
        let mut p = [0.0; 3];
        for k in 0..3 {
            let Some(xk) = x.get(s.nodes[k] as usize) else {
                continue;
            };
            for c in 0..3 {
                p[c] += s.weights[k] * xk[c];
            }
        }
        let gap = s.target - (0..3).map(|c| s.normal[c] * p[c]).sum::<f64>();
        if gap > 0.0 {
            for (t, n) in total.iter_mut().zip(s.normal) {
                *t += s.stiffness * gap * n;
            }
        }
    }
    total
}
