//! Part 1 of `lop-bench models`: time per step of every model on the shipped meshes (with
//! their scenes' parameters, the liver pressed by the tool), and its table.

use std::fmt::Write as _;
use std::time::Instant;

use anyhow::{Context, Result};
use lop_config::{BodySpec, Scene, ToolSpec};
use lop_sim::contact::{triangle_normal, ToolSphere};
use lop_sim::mesh::{read_mesh, TetMesh};
use lop_sim::model::ToolContact;
use serde::Serialize;

use super::common::{build, dt_text, time_model, us, workspace_root, Bench, Budget, Timing};
use crate::table::{table, Align};

// ---------------------------------------------------------------------------------------------
// Part 1.

/// A shipped mesh and the scene that gives its parameters.
pub(super) struct MeshCase {
    pub(super) mesh: &'static str,
    pub(super) scene: &'static str,
    /// Press the tool on it during the timing.
    press: bool,
}

pub(super) const MESH_CASES: [MeshCase; 3] = [
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
pub(super) fn scene_body(scene_name: &str, mesh: &str) -> Result<(Scene, BodySpec)> {
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
pub(super) fn shipped_mesh(name: &str, body: Option<&BodySpec>) -> Result<TetMesh> {
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

pub(super) fn step_times(quick: bool) -> Result<(Vec<MeshRow>, Vec<StepRow>)> {
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
        let msd = body.msd.with_context(|| {
            format!("scene {}: body {} has no [body.msd]", case.scene, body.name)
        })?;
        let fem = body.fem.with_context(|| {
            format!("scene {}: body {} has no [body.fem]", case.scene, body.name)
        })?;
        let pressed = if case.press {
            Some(press(&mesh, scene.tool())?)
        } else {
            None
        };
        let contact = pressed.as_ref().map(|(tool, cand, _)| ToolContact {
            tool: *tool,
            surface: &mesh.surface,
            candidates: cand,
            anchor: None,
            patch: None,
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

pub(super) fn render_step_times(meshes: &[MeshRow], rows: &[StepRow]) -> String {
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
