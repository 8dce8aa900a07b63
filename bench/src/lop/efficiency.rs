//! Part 1 of `lop-bench lop`: time per iteration per body under gravity and under a scripted
//! poke, with and without the levels-of-precision controller (thesis §6.3, Figs. 6.4–6.9). See
//! the parent module's docs for the set-up; this file runs it and writes the CSV and SVG files.

use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use lop_config::{Importance, ModelPin, Scene, StartLevel};
use lop_daemon::scene::tool_sphere;
use lop_drivers::mock::MockScript;
use lop_sim::model::ModelKind;
use serde::Serialize;

use super::{kind_label, listed, median, quantile_sorted, shipped_scene, write_file};
use crate::models::{table, us, Align};
use crate::pipeline;
use crate::plot::{self, Panel, Series};

/// Simulated time of the gravity trial, s.
const GRAVITY_SECONDS: f64 = 4.0;
/// Simulated time of an interaction trial, s (the poke scripts last 4.3–4.4 s).
const INTERACTION_SECONDS: f64 = 6.0;
/// `--quick`: simulated time of every run, s …
const QUICK_SECONDS: f64 = 0.5;
/// … and where the interaction scripts start, s (past their initial rest, so the tool reaches
/// the body within the run).
const QUICK_SCRIPT_OFFSET: f64 = 1.0;

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

/// One trial: a scene, with or without the tool script.
#[derive(Debug, Clone, Copy)]
struct Trial {
    scene: &'static str,
    /// "gravity" or "interaction".
    name: &'static str,
    /// Thesis figures it reproduces.
    thesis: &'static str,
}

const TRIALS: [Trial; 3] = [
    Trial {
        scene: "cylinders",
        name: "gravity",
        thesis: "Figs. 6.4 (without GC) and 6.5 (with GC)",
    },
    Trial {
        scene: "cylinders",
        name: "interaction",
        thesis: "Fig. 6.6",
    },
    Trial {
        scene: "organs",
        name: "interaction",
        thesis: "Figs. 6.8 (with GC) and 6.9 (without GC)",
    },
];

impl Trial {
    fn scripted(&self) -> bool {
        self.name == "interaction"
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
}

/// One run (scene × trial × configuration).
#[derive(Debug, Clone, Serialize)]
pub struct RunRow {
    /// Stable machine name, e.g. `cylinders-interaction-fem-msd-gc`.
    pub key: String,
    pub scene: String,
    /// "gravity" or "interaction".
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
}

/// One timed step.
struct Sample {
    body: usize,
    iteration: usize,
    time: f64,
    kind: ModelKind,
    us: f64,
}

/// Runs every trial and configuration; writes a CSV per run and an SVG per trial.
pub fn run(quick: bool, out: &Path, files: &mut Vec<String>) -> Result<Vec<RunRow>> {
    let mut rows = Vec::new();
    for trial in &TRIALS {
        let base = shipped_scene(trial.scene)?;
        let mut traces = Vec::new();
        for (precise, with_gc) in configurations(trial, base.bodies.len()) {
            let (row, samples) = run_one(&base, trial, &precise, with_gc, quick)?;
            write_csv(&out.join(&row.csv), &row, &samples)?;
            files.push(listed(out, &row.csv));
            traces.push((row, samples));
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
) -> Result<(RunRow, Vec<Sample>)> {
    let key = format!(
        "{}-{}-{}",
        trial.scene,
        trial.name,
        config_key(precise, with_gc)
    );
    eprintln!("lop: part 1: {key}");
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
    let script = if trial.scripted() {
        let path = scene
            .device
            .mock_script
            .clone()
            .with_context(|| format!("scene {} names no mock script", scene.name))?;
        Some((MockScript::load(&path).map_err(anyhow::Error::from)?, path))
    } else {
        None
    };
    let workspace = scene.workspace.transform();
    let tool_spec = scene.tool.clone();
    let loaded = lop_daemon::scene::load(scene)?;
    let mut world = loaded.world;
    let n = world.bodies.len();
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
    let offset = if quick && trial.scripted() {
        QUICK_SCRIPT_OFFSET
    } else {
        0.0
    };
    let ticks = (seconds / tick).round() as usize;
    let mut samples = Vec::with_capacity(ticks * n * 2);
    let mut iterations = vec![0usize; n];
    let mut switch_logs: Vec<Vec<SwitchRow>> = vec![Vec::new(); n];
    let wall = Instant::now();
    for k in 1..=ticks {
        let t = k as f64 * tick;
        for i in 0..n {
            while world.body_due(i, t) {
                let body_time = world.bodies[i].time;
                // The script plays once; after its end the tool is lifted out of the scene
                // (§6.3.2: "removing the scalpel from the model").
                let tool = script.as_ref().and_then(|(s, _)| {
                    let st = body_time + offset;
                    (st <= s.duration()).then(|| {
                        tool_sphere(
                            &tool_spec,
                            workspace.device_to_scene(s.sample(st).position_mm),
                        )
                    })
                });
                let before = world.bodies[i].model.kind();
                let t0 = Instant::now();
                let _ = world.step_body(i, tool.as_ref());
                let step_us = t0.elapsed().as_secs_f64() * 1e6;
                let b = &mut world.bodies[i];
                let after = b.model.kind();
                // Switches go cage ↔ precise: a switch to the precise model happens before the
                // step (the precise model takes it), a switch to the cage after it.
                let kind = if before == ModelKind::Gc {
                    after
                } else {
                    before
                };
                iterations[i] += 1;
                samples.push(Sample {
                    body: i,
                    iteration: iterations[i],
                    time: b.time,
                    kind,
                    us: step_us,
                });
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
            mean_us: all.iter().sum::<f64>() / steps.max(1) as f64,
            p99_us: quantile_sorted(&all, 0.99),
            max_us: all.last().copied().unwrap_or(0.0),
            gc_share: mine.iter().filter(|s| s.kind == ModelKind::Gc).count() as f64
                / steps.max(1) as f64,
            switches: b.lop.as_ref().map_or(0, |l| l.switches()),
            switch_log: std::mem::take(&mut switch_logs[i]),
            final_model: kind_label(b.model.kind()).into(),
            resets: b.resets,
        });
    }
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
    };
    Ok((row, samples))
}

fn write_csv(path: &Path, row: &RunRow, samples: &[Sample]) -> Result<()> {
    let mut s = String::from("iteration,body,time_s,model,step_us\n");
    for x in samples {
        let _ = writeln!(
            s,
            "{},{},{:.6},{},{:.3}",
            x.iteration,
            row.bodies[x.body].body,
            x.time,
            kind_label(x.kind),
            x.us
        );
    }
    write_file(path, &s)
}

/// Colour of body `i` (the same in every plot of a scene).
fn body_color(i: usize) -> usize {
    [1, 5, 2, 3, 0, 6][i % 6]
}

fn write_svg(path: &Path, trial: &Trial, traces: &[(RunRow, Vec<Sample>)]) -> Result<()> {
    // One y scale per configuration (the row of panels: without GC | with GC), so the saving
    // is visible at a glance; set by the largest 99.9th percentile of the row, not its single
    // largest step (one preempted step would flatten every line). Steps above it are drawn at
    // the top edge.
    let mut panels = Vec::new();
    for pair in traces.chunks(2) {
        let mut top: f64 = 0.0;
        for (row, samples) in pair {
            for i in 0..row.bodies.len() {
                let mut v: Vec<f64> = samples
                    .iter()
                    .filter(|s| s.body == i)
                    .map(|s| s.us / 1e3)
                    .collect();
                v.sort_by(f64::total_cmp);
                top = top.max(quantile_sorted(&v, 0.999));
            }
        }
        // Headroom for the legend (upper left).
        let top = if top > 0.0 { top * 1.6 } else { 1.0 };
        for (row, samples) in pair {
            let series = row
                .bodies
                .iter()
                .enumerate()
                .map(|(i, b)| Series {
                    label: format!(
                        "{} ({}{})",
                        b.body,
                        b.precise,
                        if row.with_gc { " / GC" } else { "" }
                    ),
                    points: samples
                        .iter()
                        .filter(|s| s.body == i)
                        .map(|s| (s.iteration as f64, (s.us / 1e3).min(top)))
                        .collect(),
                    color: body_color(i),
                })
                .collect();
            let steps = row.bodies.iter().map(|b| b.steps).max().unwrap_or(1);
            panels.push(Panel {
                title: format!(
                    "{}, {}",
                    row.configuration,
                    if row.with_gc { "with GC" } else { "without GC" }
                ),
                x_desc: "iteration".into(),
                y_desc: "ms per step".into(),
                x_range: (0.0, steps as f64),
                y_range: (0.0, top),
                series,
            });
        }
    }
    plot::line_grid(
        path,
        &format!(
            "{} analogue: {}, {} — time per iteration per body (left: without GC, right: with GC)",
            trial.thesis, trial.scene, trial.name
        ),
        &panels,
        2,
        (560, 300),
    )
}

fn opt_us(v: Option<f64>) -> String {
    v.map_or("-".into(), us)
}

/// Part 1's tables for stdout.
pub fn render(rows: &[RunRow]) -> String {
    let mut s = String::from(
        "Part 1: efficiency, time per iteration per body (every World::step_body call timed, \
         no warm-up), µs\n",
    );
    for trial in &TRIALS {
        let mine: Vec<&RunRow> = rows
            .iter()
            .filter(|r| r.scene == trial.scene && r.trial == trial.name)
            .collect();
        let Some(first) = mine.first() else {
            continue;
        };
        let _ = writeln!(
            s,
            "\n{} / {} ({}): {:.1} s simulated, tick {} s{}{}",
            trial.scene,
            trial.name,
            trial.thesis,
            first.simulated_s,
            first.tick_s,
            match &first.script {
                Some(p) => format!(
                    ", tool from {}{}",
                    Path::new(p)
                        .file_name()
                        .map_or(p.clone(), |f| f.to_string_lossy().into_owned()),
                    if first.script_offset_s > 0.0 {
                        format!(" started at {} s", first.script_offset_s)
                    } else {
                        String::new()
                    }
                ),
                None => ", no tool".into(),
            },
            match mine
                .iter()
                .find(|r| r.with_gc)
                .and_then(|r| r.start_level.clone())
            {
                Some(l) => format!("; with GC the bodies start at {l}"),
                None => String::new(),
            }
        );
        let mut cells = Vec::new();
        for r in &mine {
            for b in &r.bodies {
                let log: Vec<String> = b
                    .switch_log
                    .iter()
                    .map(|w| format!("{:.2}s {}>{}", w.time_s, w.from, w.to))
                    .collect();
                cells.push(vec![
                    format!(
                        "{}, {}",
                        r.configuration,
                        if r.with_gc { "GC" } else { "no GC" }
                    ),
                    b.body.clone(),
                    b.precise.clone(),
                    b.steps.to_string(),
                    opt_us(b.median_gc_us),
                    opt_us(b.median_precise_us),
                    us(b.mean_us),
                    format!("{:.0} %", 100.0 * b.gc_share),
                    b.switches.to_string(),
                    b.final_model.clone(),
                    b.resets.to_string(),
                    log.join(", "),
                ]);
            }
        }
        s += &table(
            &[
                ("configuration", Align::Left),
                ("body", Align::Left),
                ("precise", Align::Left),
                ("steps", Align::Right),
                ("GC median", Align::Right),
                ("precise median", Align::Right),
                ("mean", Align::Right),
                ("on GC", Align::Right),
                ("switches", Align::Right),
                ("final", Align::Left),
                ("resets", Align::Right),
                ("switch log", Align::Left),
            ],
            &cells,
        );
    }
    s
}
