//! `lop-bench interaction`: the cost of tool interaction (thesis §6.3.4, figs. 6.10–6.12).
//!
//! - **Haptic tick** (god-object + force): the contact part of the 1 kHz tick — refresh of the
//!   bodies the tool can reach when a frame arrives, the god-object's move, the force law — on
//!   `organs` and `cylinders`, with the scene's mock poke and grab scripts moving the device and
//!   the bodies deforming under the tool as in `lopd` (frames at 100 Hz: one world pass every
//!   10 ticks, untimed). Target: p99 ≤ 20 µs on `organs`. IPC and the device are left out:
//!   `lop-bench latency` measures the whole live tick.
//! - **Haptic tick against one body of growing size**: the same contact part of the tick on
//!   the test block of `lop-bench haptics` meshed at 0.8, 0.4 and 0.2 mm under the tool (up to
//!   ~32k tetrahedra), frames written on the other core. Target: p99 ≤ 20 µs whatever the
//!   size (the tick copies only the surface the tool can reach).
//! - **Collision detection** per world step, with the contact springs built from it (`World::detect_collisions`, all body pairs, the scene's `[collision]`); the springs' solve is inside each body's step.
//! - **Heat step** per body (`lop_sim::heat`, one implicit step, cautery on) and for the whole
//!   scene (bodies plus the links between touching organs).
//!
//! Times are per call, one core, release build; CSV, SVG and an aligned table.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::Args;
use hdrhistogram::Histogram;
use lop_config::Scene;
use lop_drivers::mock::{MockDevice, MockScript};
use lop_drivers::BUTTON_GRAB;
use lop_scene::{DeviceClamp, Rounds, TickTool, ToolLaws};
use lop_sim::contact::ForceLaw;
use lop_sim::haptic::{hand_force, GodObject, GodState, SurfaceSet};
use lop_sim::model::ToolAnchor;
use lop_sim::world::Coupling;
use serde::Serialize;

use crate::lop::shipped_scene;
use crate::models::workspace_root;
use crate::plot;
use crate::table::{self, Row};

/// Options of `lop-bench interaction`.
#[derive(Args, Debug)]
pub struct InteractionArgs {
    /// Small and fast (for the smoke test): 2 s of simulated interaction per script.
    #[arg(long)]
    quick: bool,
    /// Where the CSV and SVG files go (created if missing).
    #[arg(long, default_value = "target/lop-bench/interaction")]
    out: PathBuf,
    /// Also write every number as JSON to this file.
    #[arg(long)]
    json: Option<PathBuf>,
}

#[derive(Serialize)]
struct Report {
    rows: Vec<Row>,
}

/// Ticks per frame (1 kHz haptics, 100 Hz frames).
const TICKS_PER_FRAME: u64 = 10;
/// Bodies within this of the device or the god-object are refreshed (as in the haptic loop), m.
const REACH: f64 = 0.02;

/// The tool sphere pressed into the block, m (the haptics bench's 3 mm sphere).
const BLOCK_TOOL_RADIUS: f64 = 0.003;
/// How far the device goes below the undeformed top face, and how deep the tissue's dimple
/// follows it, m.
const BLOCK_PRESS: f64 = 0.0004;
const BLOCK_DIMPLE: f64 = 0.0003;

/// Runs the benchmark.
pub fn run(a: InteractionArgs) -> Result<()> {
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let seconds = if a.quick { 2.0 } else { 12.0 };
    let mut rows = Vec::new();
    for scene in ["organs", "cylinders"] {
        for script in ["poke", "grab"] {
            rows.push(haptic_ticks(scene, script, seconds)?);
        }
        rows.push(collision_steps(scene, if a.quick { 50 } else { 500 })?);
        rows.extend(heat_steps(scene, if a.quick { 50 } else { 500 })?);
    }
    // The tick against one body of growing size: the test block of `lop-bench haptics`.
    let sizes: &[f64] = if a.quick {
        &[0.0008]
    } else {
        &[0.0008, 0.0004, 0.0002]
    };
    for &size in sizes {
        rows.extend(block_ticks(size, seconds)?);
    }
    println!("lop-bench interaction (one core; µs per call)\n");
    println!("{}", table::render(&rows));
    let csv = a.out.join("interaction.csv");
    let mut text = String::from("key,label,count,p50_us,p99_us,p999_us,max_us\n");
    for r in &rows {
        text += &format!(
            "{},{},{},{:.3},{:.3},{:.3},{:.3}\n",
            r.key, r.label, r.count, r.p50_us, r.p99_us, r.p999_us, r.max_us
        );
    }
    std::fs::write(&csv, text).with_context(|| format!("writing {}", csv.display()))?;
    let bars: Vec<(String, f64)> = rows.iter().map(|r| (r.key.clone(), r.p99_us)).collect();
    let svg = a.out.join("interaction_p99.svg");
    plot::bars(&svg, "Interaction costs, p99 per call", "µs", &bars)?;
    println!("\nwrote {} and {}", csv.display(), svg.display());
    if let Some(path) = a.json {
        let body = serde_json::to_string_pretty(&Report { rows })?;
        std::fs::write(&path, body).with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}

fn script_of(scene: &Scene, name: &str) -> Result<MockScript> {
    let path = workspace_root()
        .join("config/scripts")
        .join(format!("{}-{name}.toml", scene.name));
    MockScript::load(&path).with_context(|| format!("loading {}", path.display()))
}

/// The scene's tool laws on the mock device (an Omni's stiffness limit), as the haptic loop
/// derives them.
fn omni_laws(scene: &lop_config::Scene) -> ToolLaws {
    ToolLaws::new(
        scene,
        DeviceClamp {
            max_stiffness_n_per_mm: MockDevice::omni_limits().max_stiffness_n_per_mm,
        },
    )
}

/// The contact part of the haptic tick against a deforming scene.
fn haptic_ticks(scene_name: &str, script_name: &str, seconds: f64) -> Result<Row> {
    let scene = shipped_scene(scene_name)?;
    let script = script_of(&scene, script_name)?;
    let workspace = scene.tool().workspace.transform();
    let laws = omni_laws(&scene);
    let loaded = lop_scene::load(scene)?;
    let mut world = loaded.world;
    let offsets = loaded.topology.node_offsets();
    let tris: Vec<Vec<[u32; 3]>> = world
        .bodies
        .iter()
        .zip(&offsets)
        .map(|(b, &o)| {
            b.mesh
                .surface
                .iter()
                .map(|t| t.map(|v| v + o as u32))
                .collect()
        })
        .collect();
    let slices: Vec<&[[u32; 3]]> = tris.iter().map(|t| t.as_slice()).collect();
    let node_count: usize = world.bodies.iter().map(|b| b.mesh.nodes.len()).sum();
    let mut set = SurfaceSet::new(node_count, &slices);
    let mut god = GodObject::new(laws.tool.radius, set.triangles().len());
    let mut frame: Vec<[f64; 3]> = vec![[0.0; 3]; node_count];
    let mut bounds = vec![([0.0; 3], [0.0; 3]); world.bodies.len()];
    let mut hist = Histogram::<u64>::new_with_bounds(1, 1_000_000_000, 3)?;
    let ticks = (seconds * 1000.0) as u64;
    let mut sequence = 0;
    let mut coupling = Coupling::GodObject(None);
    let mut rounds = Rounds::catching_up(laws.clone());
    for tick in 0..ticks {
        let t = tick as f64 * 1e-3;
        let sample = script.sample(t);
        let device = workspace.device_to_scene(sample.position_mm);
        let new_frame = tick % TICKS_PER_FRAME == 0;
        if new_frame {
            // The deformation process's side (not timed): one round, publish.
            let tool = TickTool {
                center: device,
                coupling,
                heat: false,
                cut: false,
                stiffness: None,
            };
            rounds.advance(&mut world, t, std::slice::from_ref(&tool), &[], false, || 0);
            for (b, body) in world.bodies.iter().enumerate() {
                let x = body.model.positions();
                frame[offsets[b]..offsets[b] + x.len()].copy_from_slice(x);
                bounds[b] = lop_sim::mesh::bounds(x);
            }
            sequence += 1;
        }
        let t0 = Instant::now();
        let grab = sample.pressed(BUTTON_GRAB);
        let g = contact(
            &mut set,
            &mut god,
            sequence,
            device,
            grab,
            |b| bounds[b],
            |i| frame[i],
        );
        let k = g
            .anchor
            .map_or(laws.tool.stiffness, |a| laws.stiffness(a.body));
        let f = hand_force(&g, laws.tool.law, k, laws.damping, [0.0; 3]);
        let ns = t0.elapsed().as_nanos() as u64;
        std::hint::black_box(f);
        hist.saturating_record(ns.max(1));
        // Hand the contact to the tissue as the deformation process does.
        coupling = Coupling::GodObject(g.anchor.and_then(|a| {
            let b = a.body;
            let local = a.triangle - set.body_triangles(b).start;
            let body = &world.bodies[b];
            ToolAnchor::from_proxy(
                &body.mesh.surface,
                body.model.positions(),
                local as u32,
                a.bary,
                g.proxy,
                g.grabbing,
            )
            .map(|anchor| (b, anchor))
        }));
    }
    let stats = set.stats();
    Ok(Row::from_histogram_ns(
        &format!("tick_{scene_name}_{script_name}"),
        &format!(
            "tick {scene_name} {script_name} ({}/{} walks fell back)",
            stats.fallbacks, stats.walks
        ),
        &hist,
    ))
}

/// Collision detection per world step while the poke deforms the scene.
/// The contact part of the haptic tick against one body of growing size: the test block of
/// `lop-bench haptics` (40 × 40 × 20 mm, meshed by gmsh at `size` under the tool), pressed
/// 0.4 mm at its top face's centre while circling 0.5 mm, frames every 10 ticks. The tissue's
/// side is a prescribed dimple under the device (Gaussian, 1.5 mm wide, 0.3 mm deep, fading to
/// the clamped bottom) instead of a world step: what the tick pays for is the frame's copy and
/// the queries, which depend on the body's size, not on how it was deformed; stepping the
/// 32k-tet block itself takes ~0.1 s a frame. The frame is written on the second core and
/// read on the first, as live.
fn block_ticks(size: f64, seconds: f64) -> Result<[Row; 2]> {
    use crate::haptics::block::{block, cache_dir, CONTACT, HEIGHT};
    use std::sync::{mpsc, Mutex};
    let b = block(size, &cache_dir())?;
    let rest = &b.mesh.nodes;
    let slices: [&[[u32; 3]]; 1] = [&b.mesh.surface];
    let mut set = SurfaceSet::new(rest.len(), &slices);
    let mut god = GodObject::new(BLOCK_TOOL_RADIUS, set.triangles().len());
    // The frame as shared memory holds it (single precision), written on the other core as
    // the deformation process writes it: reading it costs the tick what it costs live.
    let frame = Mutex::new(vec![[0f32; 3]; rest.len()]);
    let bounds = Mutex::new(lop_sim::mesh::bounds(rest));
    // Ticks that take a new frame, and the others.
    let mut framed = Histogram::<u64>::new_with_bounds(1, 1_000_000_000, 3)?;
    let mut between = framed.clone();
    let ticks = (seconds * 1000.0) as u64;
    let mut contacts = 0u64;
    let width2 = 2.0 * 0.0015f64.powi(2);
    std::thread::scope(|scope| -> Result<()> {
        let (ask, asked) = mpsc::channel::<(f64, f64, f64)>();
        let (done, finished) = mpsc::channel::<()>();
        let (frame, bounds) = (&frame, &bounds);
        scope.spawn(move || {
            pin_to_cpu(1);
            for (dx, dy, depth) in asked {
                let mut f = frame.lock().unwrap_or_else(|e| e.into_inner());
                let mut lo = [f64::INFINITY; 3];
                let mut hi = [f64::NEG_INFINITY; 3];
                for (x, r) in f.iter_mut().zip(rest) {
                    let d2 = (r[0] - dx).powi(2) + (r[1] - dy).powi(2);
                    let p = [
                        r[0],
                        r[1],
                        r[2] - depth * (-d2 / width2).exp() * r[2] / HEIGHT,
                    ];
                    for k in 0..3 {
                        lo[k] = lo[k].min(p[k]);
                        hi[k] = hi[k].max(p[k]);
                    }
                    *x = p.map(|c| c as f32);
                }
                *bounds.lock().unwrap_or_else(|e| e.into_inner()) = (lo, hi);
                drop(f);
                if done.send(()).is_err() {
                    return;
                }
            }
        });
        pin_to_cpu(0);
        let mut sequence = 0;
        for tick in 0..ticks {
            let t = tick as f64 * 1e-3;
            // Press over the first third, hold, release over the last third.
            let s = (3.0 * t / seconds)
                .min(3.0 - 3.0 * t / seconds)
                .clamp(0.0, 1.0);
            let turn = std::f64::consts::TAU * 0.5 * t;
            let (dx, dy) = (5e-4 * turn.cos() * s, 5e-4 * turn.sin() * s);
            let device = [
                CONTACT[0] + dx,
                CONTACT[1] + dy,
                CONTACT[2] + BLOCK_TOOL_RADIUS - BLOCK_PRESS * s,
            ];
            let new_frame = tick % TICKS_PER_FRAME == 0;
            if new_frame {
                // The deformation process's side (not timed): the dimple under the device.
                ask.send((dx, dy, BLOCK_DIMPLE * s))?;
                finished.recv()?;
                sequence += 1;
            }
            let f = frame.lock().unwrap_or_else(|e| e.into_inner());
            let bb = *bounds.lock().unwrap_or_else(|e| e.into_inner());
            let t0 = Instant::now();
            let g = contact(
                &mut set,
                &mut god,
                sequence,
                device,
                false,
                |_| bb,
                |i| f[i].map(f64::from),
            );
            let force = hand_force(&g, ForceLaw::Linear, 200.0, 0.0, [0.0; 3]);
            let ns = t0.elapsed().as_nanos() as u64;
            drop(f);
            std::hint::black_box(force);
            if new_frame { &mut framed } else { &mut between }.saturating_record(ns.max(1));
            contacts += u64::from(g.anchor.is_some());
        }
        Ok(())
    })?;
    let stats = set.stats();
    anyhow::ensure!(
        contacts > ticks / 4,
        "block {}: the tool touched in only {contacts} of {ticks} ticks",
        b.label()
    );
    let label = format!(
        "block {} ({} nodes; {} surface triangles; {}/{} walks fell back; {} refits)",
        b.label(),
        rest.len(),
        b.mesh.surface.len(),
        stats.fallbacks,
        stats.walks,
        stats.refits
    );
    let key = format!("tick_block_{}mm", crate::haptics::block::size_mm(size));
    Ok([
        Row::from_histogram_ns(&key, &format!("tick between frames: {label}"), &between),
        Row::from_histogram_ns(
            &format!("{key}_frame"),
            &format!("tick taking a frame: {label}"),
            &framed,
        ),
    ])
}

/// The timed contact part of a tick up to the god-object's state: the surface refresh of the
/// bodies within [`REACH`] (positions `at`, bounds `bounds`, once per frame `sequence`), the
/// proxy carried with the tissue, the god-object's move.
fn contact(
    set: &mut SurfaceSet,
    god: &mut GodObject,
    sequence: u64,
    device: [f64; 3],
    grab: bool,
    bounds: impl Fn(usize) -> ([f64; 3], [f64; 3]),
    at: impl FnMut(usize) -> [f64; 3],
) -> GodState {
    let proxy = god.proxy();
    if set.refresh_reachable(|_| sequence, &[device, proxy], REACH, bounds, at) {
        god.follow_surface(set);
    }
    god.update(set, device, grab)
}

/// Pins the calling thread to `cpu` (best effort: a machine with fewer cores or a refusal
/// leaves it where the scheduler puts it).
fn pin_to_cpu(cpu: usize) {
    // SAFETY: a zeroed `cpu_set_t` is a valid empty set; the call only reads it.
    unsafe {
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        libc::CPU_SET(cpu, &mut set);
        libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &set);
    }
}

fn collision_steps(scene_name: &str, steps: usize) -> Result<Row> {
    let scene = shipped_scene(scene_name)?;
    let script = script_of(&scene, "poke")?;
    let workspace = scene.tool().workspace.transform();
    let laws = omni_laws(&scene);
    let loaded = lop_scene::load(scene)?;
    let mut world = loaded.world;
    world.disable_heat();
    if !world.collisions_enabled() {
        anyhow::bail!("scene {scene_name}: [collision] is off");
    }
    let mut rounds = Rounds::catching_up(laws);
    let mut hist = Histogram::<u64>::new_with_bounds(1, 1_000_000_000, 3)?;
    let dt = world
        .bodies
        .iter()
        .map(|b| b.model.dt())
        .fold(f64::INFINITY, f64::min);
    for step in 0..steps {
        let t = (step + 1) as f64 * dt + 1.0;
        let tool = TickTool {
            center: workspace.device_to_scene(script.sample(t).position_mm),
            coupling: Coupling::Nearest,
            heat: false,
            cut: false,
            stiffness: None,
        };
        // One round: detection and the contact springs (timed in the report), then the
        // bodies' steps (the springs' solve is part of them).
        let clock = Instant::now();
        rounds.advance(
            &mut world,
            t,
            std::slice::from_ref(&tool),
            &[],
            false,
            || clock.elapsed().as_nanos() as u64,
        );
        let report = world.last_round();
        std::hint::black_box(report.collisions);
        hist.saturating_record(report.collision_ns.max(1));
    }
    Ok(Row::from_histogram_ns(
        &format!("collide_{scene_name}"),
        &format!("collision detection + springs, {scene_name}"),
        &hist,
    ))
}

/// One heat step per body (cautery on the first body's surface) and for the whole scene.
fn heat_steps(scene_name: &str, steps: usize) -> Result<Vec<Row>> {
    let scene = shipped_scene(scene_name)?;
    let power = scene.tool().heat_power;
    let loaded = lop_scene::load(scene.clone())?;
    let mut heat = lop_scene::heat_world(&scene, &loaded.world)?;
    let mut rows = Vec::new();
    let links = heat.links().len();
    for b in 0..loaded.world.bodies.len() {
        let tri = loaded.world.bodies[b].mesh.surface[0];
        let mut hist = Histogram::<u64>::new_with_bounds(1, 1_000_000_000, 3)?;
        let body = heat.body_mut(b)?;
        for _ in 0..steps {
            body.heat_point(tri, [1.0 / 3.0; 3], power)?;
            let t0 = Instant::now();
            body.step()?;
            hist.saturating_record((t0.elapsed().as_nanos() as u64).max(1));
        }
        rows.push(Row::from_histogram_ns(
            &format!("heat_{scene_name}_{}", loaded.world.bodies[b].name),
            &format!(
                "heat step, {} ({} nodes)",
                loaded.world.bodies[b].name,
                loaded.world.bodies[b].mesh.nodes.len()
            ),
            &hist,
        ));
    }
    let mut hist = Histogram::<u64>::new_with_bounds(1, 1_000_000_000, 3)?;
    for _ in 0..steps {
        let t0 = Instant::now();
        heat.step()?;
        hist.saturating_record((t0.elapsed().as_nanos() as u64).max(1));
    }
    rows.push(Row::from_histogram_ns(
        &format!("heat_{scene_name}_all"),
        &format!("heat step, {scene_name}, {links} links"),
        &hist,
    ));
    Ok(rows)
}
