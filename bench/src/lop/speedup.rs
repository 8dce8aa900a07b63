//! Part 2 of `lop-bench lop`: what a Green-coordinates cage step costs against the
//! corotational FEM step it stands in for, per body and cage shape. See the parent module's
//! docs for the set-up.

use std::fmt::Write as _;
use std::time::Instant;

use anyhow::{anyhow, bail, Result};
use lop_config::{BodySpec, ModelPin, Scene};
use lop_sim::lop::{CageModel, CageShape};
use lop_sim::mesh::TetMesh;
use lop_sim::model::Model;
use serde::Serialize;

use super::{
    dist3, gc_variant, median, placed_bodies, quantile_sorted, shape_key, shape_label,
    shipped_scene, DynKind, Target, SHAPES,
};
use crate::models::us;
use crate::pipeline;
use crate::table::{table, Align};

/// Total amplitude of the sinusoidal load, N, …
const LOAD_AMPLITUDE: f64 = 0.001;
/// … its frequency, Hz, …
const LOAD_HZ: f64 = 1.0;
/// … and how many nodes share it.
const LOADED_NODES: usize = 4;
/// The target: a cage step at least this many times faster than the FEM step on the organs.
const TARGET_SPEEDUP: f64 = 50.0;

/// Timed steps (after warm-up), full and `--quick`.
const STEPS: (usize, usize) = (2000, 30);
const WARMUP: (usize, usize) = (20, 3);

/// One model on one body.
#[derive(Debug, Clone, Serialize)]
pub struct SpeedRow {
    pub scene: String,
    pub body: String,
    pub nodes: usize,
    pub tets: usize,
    /// Stable machine name: `fem-corotational`, `msd-implicit-euler`, `gc-<shape>` (loaded),
    /// `gc-<shape>-no-load`.
    pub variant: String,
    pub label: String,
    /// Cage size (GC rows).
    pub cage_vertices: Option<usize>,
    pub cage_triangles: Option<usize>,
    /// Whether the sinusoidal load was applied.
    pub loaded: bool,
    /// Time step, s.
    pub dt: f64,
    /// Construction time (FEM: assembly and first factorisation; GC: binding, Jacobian,
    /// projection), ms.
    pub setup_ms: f64,
    /// Timed steps.
    pub steps: usize,
    pub median_us: f64,
    pub p99_us: f64,
    pub mean_us: f64,
    pub max_us: f64,
    /// Largest nodal displacement over the timed steps, mm (the body did move).
    pub peak_displacement_mm: f64,
    /// The same body's FEM median over this row's median.
    pub speedup_vs_fem: f64,
    /// Steps that blew up (the model reset itself).
    pub blow_ups: usize,
}

/// The free surface nodes farthest from the fixed nodes' centroid (from the body's centre
/// when nothing is fixed): where a load moves the body most.
fn loaded_nodes(mesh: &TetMesh, count: usize) -> Vec<usize> {
    let n = mesh.nodes.len();
    let mut fixed = vec![false; n];
    for &f in &mesh.fixed {
        fixed[f as usize] = true;
    }
    let anchor_set: Vec<[f64; 3]> = if mesh.fixed.is_empty() {
        mesh.nodes.clone()
    } else {
        mesh.fixed.iter().map(|&f| mesh.nodes[f as usize]).collect()
    };
    let mut anchor = [0.0; 3];
    for p in &anchor_set {
        for a in 0..3 {
            anchor[a] += p[a] / anchor_set.len() as f64;
        }
    }
    let mut surface: Vec<usize> = mesh
        .surface
        .iter()
        .flatten()
        .map(|&k| k as usize)
        .filter(|&k| !fixed[k])
        .collect();
    surface.sort_unstable();
    surface.dedup();
    surface.sort_by(|&a, &b| dist3(mesh.nodes[b], anchor).total_cmp(&dist3(mesh.nodes[a], anchor)));
    surface.truncate(count);
    surface
}

struct Timed {
    us: Vec<f64>,
    peak: f64,
    blow_ups: usize,
}

/// Steps `model` `warmup + steps` times under `gravity` and, if `loaded`, the sinusoidal load on
/// `nodes`; times the last `steps`.
fn time_model(
    model: &mut Model,
    gravity: [f64; 3],
    nodes: &[usize],
    loaded: bool,
    warmup: usize,
    steps: usize,
) -> Result<Timed> {
    let rest = model.positions().to_vec();
    let mut loads = vec![[0.0; 3]; rest.len()];
    let dt = model.dt();
    let per_node = LOAD_AMPLITUDE / nodes.len().max(1) as f64;
    let mut us = Vec::with_capacity(steps);
    let mut peak: f64 = 0.0;
    let mut blow_ups = 0;
    for k in 1..=warmup + steps {
        if loaded {
            let f = per_node * (2.0 * std::f64::consts::PI * LOAD_HZ * k as f64 * dt).sin();
            for &i in nodes {
                loads[i] = [f, 0.0, 0.0];
            }
        }
        let t0 = Instant::now();
        let r = model.step(gravity, &loads, None);
        let elapsed = t0.elapsed().as_secs_f64() * 1e6;
        if r.is_err() {
            blow_ups += 1;
        }
        if k > warmup {
            us.push(elapsed);
            let x = model.positions();
            for (p, q) in x.iter().zip(&rest) {
                peak = peak.max(dist3(*p, *q));
            }
        }
        if pipeline::interrupted() {
            bail!("interrupted");
        }
    }
    Ok(Timed { us, peak, blow_ups })
}

#[allow(clippy::too_many_arguments)]
fn row(
    scene: &Scene,
    spec: &BodySpec,
    mesh: &TetMesh,
    variant: String,
    label: String,
    cage: Option<(usize, usize)>,
    loaded: bool,
    dt: f64,
    setup_ms: f64,
    timed: Timed,
) -> SpeedRow {
    let mut v = timed.us;
    let med = median(&mut v).unwrap_or(0.0);
    SpeedRow {
        scene: scene.name.clone(),
        body: spec.name.clone(),
        nodes: mesh.nodes.len(),
        tets: mesh.tets.len(),
        variant,
        label,
        cage_vertices: cage.map(|c| c.0),
        cage_triangles: cage.map(|c| c.1),
        loaded,
        dt,
        setup_ms,
        steps: v.len(),
        median_us: med,
        p99_us: quantile_sorted(&v, 0.99),
        mean_us: v.iter().sum::<f64>() / v.len().max(1) as f64,
        max_us: v.last().copied().unwrap_or(0.0),
        peak_displacement_mm: timed.peak * 1e3,
        speedup_vs_fem: 0.0,
        blow_ups: timed.blow_ups,
    }
}

/// Times every variant on every body of `organs` and `cylinders`.
pub fn run(quick: bool) -> Result<Vec<SpeedRow>> {
    let (steps, warmup) = if quick {
        (STEPS.1, WARMUP.1)
    } else {
        (STEPS.0, WARMUP.0)
    };
    let mut rows = Vec::new();
    for scene_name in ["organs", "cylinders"] {
        let scene = shipped_scene(scene_name)?;
        for (spec, mesh) in placed_bodies(&scene)? {
            let nodes = loaded_nodes(&mesh, LOADED_NODES);
            let mut body_rows = Vec::new();

            // The precise models, pinned, corotational FEM.
            let mut fem_spec = spec.clone();
            fem_spec.model = ModelPin::Fem;
            if let Some(f) = fem_spec.fem.as_mut() {
                f.mode = lop_config::FemMode::Corotational;
            }
            let t0 = Instant::now();
            let fem = lop_scene::precise_model(&scene, &fem_spec, &mesh)?;
            let fem_setup = t0.elapsed().as_secs_f64() * 1e3;
            if !matches!(fem, Model::Fem(_)) {
                bail!("scene {scene_name}: body {} has no [body.fem]", spec.name);
            }
            eprintln!("lop: part 2: {} / FEM corotational", spec.name);
            let mut m = fem.clone();
            let timed = time_model(&mut m, scene.gravity, &nodes, true, warmup, steps)?;
            body_rows.push(row(
                &scene,
                &spec,
                &mesh,
                "fem-corotational".into(),
                "FEM corotational".into(),
                None,
                true,
                fem.dt(),
                fem_setup,
                timed,
            ));

            let mut msd_spec = spec.clone();
            msd_spec.model = ModelPin::Msd;
            if msd_spec.msd.is_some() {
                let t0 = Instant::now();
                let mut msd = lop_scene::precise_model(&scene, &msd_spec, &mesh)?;
                let setup = t0.elapsed().as_secs_f64() * 1e3;
                eprintln!("lop: part 2: {} / MSD", spec.name);
                let dt = msd.dt();
                let timed = time_model(&mut msd, scene.gravity, &nodes, true, warmup, steps)?;
                body_rows.push(row(
                    &scene,
                    &spec,
                    &mesh,
                    "msd-implicit-euler".into(),
                    "MSD (scene's [body.msd])".into(),
                    None,
                    true,
                    dt,
                    setup,
                    timed,
                ));
            }

            let gc_dt = lop_scene::gc_parameters(&spec, &mesh, fem.dt()).dt;
            for loaded in [true, false] {
                for shape in SHAPES {
                    let params = gc_variant(&spec, &mesh, shape, DynKind::Projected, gc_dt);
                    let t0 = Instant::now();
                    let gc = CageModel::from_precise_under(&mesh, params, &fem, scene.gravity)
                        .map_err(|e| {
                            anyhow!("body {}: {} cage: {e}", spec.name, shape_label(shape))
                        })?;
                    let setup = t0.elapsed().as_secs_f64() * 1e3;
                    let cage = (
                        gc.coordinates().vertex_count(),
                        gc.coordinates().triangle_count(),
                    );
                    eprintln!(
                        "lop: part 2: {} / GC {}{}",
                        spec.name,
                        shape_label(shape),
                        if loaded { "" } else { ", no load" }
                    );
                    let mut m = Model::Gc(Box::new(gc));
                    let timed = time_model(&mut m, scene.gravity, &nodes, loaded, warmup, steps)?;
                    let (variant, label) = gc_names(shape, loaded);
                    body_rows.push(row(
                        &scene,
                        &spec,
                        &mesh,
                        variant,
                        label,
                        Some(cage),
                        loaded,
                        gc_dt,
                        setup,
                        timed,
                    ));
                }
            }
            let fem_median = body_rows[0].median_us;
            for r in &mut body_rows {
                r.speedup_vs_fem = if r.median_us > 0.0 {
                    fem_median / r.median_us
                } else {
                    0.0
                };
            }
            rows.extend(body_rows);
        }
    }
    Ok(rows)
}

fn gc_names(shape: CageShape, loaded: bool) -> (String, String) {
    (
        format!(
            "gc-{}{}",
            shape_key(shape),
            if loaded { "" } else { "-no-load" }
        ),
        format!(
            "GC {}, projected{}",
            shape_label(shape),
            if loaded { "" } else { ", no load" }
        ),
    )
}

/// Part 2's table for stdout.
pub fn render(rows: &[SpeedRow]) -> String {
    let mut s = format!(
        "Part 2: GC step vs corotational FEM step (scene gravity; sinusoidal load {} mN total \
         along +x at {} Hz on the {} free surface nodes farthest from the fixed ones, except \
         \"no load\"), µs\n",
        LOAD_AMPLITUDE * 1e3,
        LOAD_HZ,
        LOADED_NODES
    );
    let mut last = String::new();
    let mut cells: Vec<Vec<String>> = Vec::new();
    let flush = |s: &mut String, cells: &mut Vec<Vec<String>>| {
        if cells.is_empty() {
            return;
        }
        *s += &table(
            &[
                ("model", Align::Left),
                ("cage V/T", Align::Right),
                ("dt (s)", Align::Right),
                ("steps", Align::Right),
                ("median", Align::Right),
                ("p99", Align::Right),
                ("mean", Align::Right),
                ("FEM/this", Align::Right),
                ("peak disp mm", Align::Right),
                ("setup ms", Align::Right),
                ("blow-ups", Align::Right),
            ],
            cells,
        );
        cells.clear();
    };
    for r in rows {
        let id = format!("{}/{}", r.scene, r.body);
        if id != last {
            flush(&mut s, &mut cells);
            let _ = writeln!(
                s,
                "\n{} ({}): {} nodes, {} tets",
                r.body, r.scene, r.nodes, r.tets
            );
            last = id;
        }
        cells.push(vec![
            r.label.clone(),
            match (r.cage_vertices, r.cage_triangles) {
                (Some(v), Some(t)) => format!("{v}/{t}"),
                _ => "-".into(),
            },
            format!("{:.3}", r.dt),
            r.steps.to_string(),
            us(r.median_us),
            us(r.p99_us),
            us(r.mean_us),
            format!("{:.1}x", r.speedup_vs_fem),
            format!("{:.2}", r.peak_displacement_mm),
            format!("{:.1}", r.setup_ms),
            r.blow_ups.to_string(),
        ]);
    }
    flush(&mut s, &mut cells);
    s
}

/// The speed-up target: per cage shape, the smallest speed-up over the four organs (loaded,
/// projected dynamics).
pub fn targets(rows: &[SpeedRow]) -> Vec<Target> {
    let mut out = Vec::new();
    for shape in SHAPES {
        let (variant, _) = gc_names(shape, true);
        let organ: Vec<&SpeedRow> = rows
            .iter()
            .filter(|r| r.scene == "organs" && r.variant == variant)
            .collect();
        if organ.is_empty() {
            continue;
        }
        let min = organ
            .iter()
            .map(|r| r.speedup_vs_fem)
            .fold(f64::INFINITY, f64::min);
        let each: Vec<String> = organ
            .iter()
            .map(|r| format!("{} {:.0}x", r.body, r.speedup_vs_fem))
            .collect();
        out.push(Target {
            target: format!(
                "GC step ≥ {TARGET_SPEEDUP:.0}x faster than FEM, organs, {} cage",
                shape_label(shape)
            ),
            measured: each.join(", "),
            value: min,
            limit: TARGET_SPEEDUP,
            met: min >= TARGET_SPEEDUP,
        });
    }
    out
}
