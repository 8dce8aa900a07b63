//! Part 3 of `lop-bench lop`: how far a Green-coordinates cage is from the precise model it
//! stands for, under the same loads (thesis §6.4, Fig. 6.13). See the parent module's docs for
//! the set-up; this file runs it, `effectiveness/output.rs` writes the CSV and SVG files and
//! the tables.

mod output;

use std::path::Path;

use anyhow::{anyhow, bail, Context, Result};
use lop_config::{BodySpec, ModelPin, Scene};
use lop_scene::smallest_extent;
use lop_sim::lop::{CageDynamics, CageModel, CageShape, CageSprings, GcParameters};
use lop_sim::mesh::TetMesh;
use lop_sim::model::Model;
use serde::Serialize;

use super::{
    dist3, gc_variant, listed, placed_bodies, shape_key, shape_label, shipped_scene, DynKind,
    SHAPES,
};
use crate::pipeline;
use crate::plot;

use output::{panel, write_csv};
pub use output::{render, targets};

/// The load ramps up over this long, s, …
const RAMP_END: f64 = 0.5;
/// … is held until this time, then released, s …
const HOLD_END: f64 = 1.5;
/// … and the run lasts this long, s (`--quick`: [`QUICK_SECONDS`]).
const SECONDS: f64 = 5.0;
const QUICK_SECONDS: f64 = 0.5;
/// Direction of the lateral load.
const LOAD_DIRECTION: [f64; 3] = [1.0, 0.0, 0.0];
/// The tuned mass-spring cage's calibration load: the same nodes pushed diagonally, between +x
/// and +z, with half the force, so that the evaluated load (+x, full force) is not the one it
/// was tuned on.
const CALIBRATION_DIRECTION: [f64; 3] = [
    std::f64::consts::FRAC_1_SQRT_2,
    0.0,
    std::f64::consts::FRAC_1_SQRT_2,
];
const CALIBRATION_FORCE_FACTOR: f64 = 0.5;
/// The search for the tuned cage's parameters: at most this many calibration runs, and it stops
/// once its step in every parameter is below this factor.
const TUNE_MAX_RUNS: usize = 400;
const TUNE_MIN_FACTOR: f64 = 1.02;

/// The thesis' bounds (§6.4): box cage with mass-spring dynamics, max error over the run, % of
/// the smallest dimension, against FEM and against MSD; and the projected dynamics' bound
/// against FEM.
const TARGET_BOX_MS_FEM: f64 = 4.0;
const TARGET_BOX_MS_MSD: f64 = 8.0;
const TARGET_PROJECTED_FEM: f64 = 2.0;

/// One body of the study.
struct Case {
    name: &'static str,
    scene: &'static str,
    body: &'static str,
    /// Total lateral load while held, N, against the FEM: a few mm of lateral deflection of the
    /// corotational FEM (this cylinder, E = 600 Pa, bends by about 0.1 m under 0.05 N; the
    /// liver moves about 11 mm under 0.02 N) …
    force: f64,
    /// … and against the MSD, whose Table 6.1 cylinder is about 80× stiffer than the FEM one:
    /// loaded for a few mm of motion too, so that the comparison is not vacuous.
    msd_force: f64,
}

const CASES: [Case; 2] = [
    Case {
        name: "cylinder",
        scene: "cylinders",
        body: "cylinder_a",
        force: 0.002,
        msd_force: 1.0,
    },
    Case {
        name: "liver",
        scene: "organs",
        body: "liver",
        force: 0.01,
        msd_force: 0.01,
    },
];

/// The two references.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Reference {
    Fem,
    Msd,
}

impl Reference {
    fn key(self) -> &'static str {
        match self {
            Reference::Fem => "fem",
            Reference::Msd => "msd",
        }
    }
    fn label(self) -> &'static str {
        match self {
            Reference::Fem => "FEM (corotational)",
            Reference::Msd => "MSD (implicit Euler)",
        }
    }
}

/// A reference run.
#[derive(Debug, Clone, Serialize)]
pub struct ReferenceRow {
    /// "fem" or "msd".
    pub reference: String,
    pub label: String,
    pub dt: f64,
    pub steps: usize,
    /// Total lateral load while held, N.
    pub total_force_n: f64,
    /// Largest nodal displacement from rest over the run, mm and % of the smallest extent.
    pub max_displacement_mm: f64,
    pub max_displacement_pct: f64,
    /// Largest nodal displacement at the end of the hold (just before the release), mm.
    pub hold_end_displacement_mm: f64,
    /// Largest nodal displacement at the end of the run, mm.
    pub final_displacement_mm: f64,
    pub blow_ups: usize,
    /// The per-iteration CSV of this reference and its approximations.
    pub csv: String,
}

/// One approximation of one reference.
#[derive(Debug, Clone, Serialize)]
pub struct VariantRow {
    /// "fem" or "msd".
    pub reference: String,
    /// Stable machine name: `gc-<shape>-projected`, `gc-<shape>-mass-spring`, `rest`.
    pub variant: String,
    pub label: String,
    /// Cage shape key, dynamics ("projected", "galerkin", "mass-spring", or "fit": the cage
    /// fitted to the reference every iteration, the bound for any dynamics); `None` for the
    /// rest shape.
    pub shape: Option<String>,
    pub dynamics: Option<String>,
    pub cage_vertices: Option<usize>,
    /// Max over the run of the per-iteration max error, % of the smallest extent, and when.
    pub max_error_pct: f64,
    pub max_error_at_s: f64,
    /// `max_error_pct` over the reference's largest displacement (also % of the smallest
    /// extent): the error relative to the motion it approximates (1 = no better than the rest
    /// shape at its worst).
    pub max_error_relative: f64,
    /// Mean over the run of the per-iteration mean error, %.
    pub mean_error_pct: f64,
    /// Max error at the end of the hold (just before the release), %.
    pub hold_end_max_error_pct: f64,
    /// Max error at the end of the run, %.
    pub final_max_error_pct: f64,
    pub blow_ups: usize,
    /// For the tuned mass-spring cage: the parameters the search found.
    pub tuned: Option<Tuned>,
}

/// The thesis picked its cage's mass-spring parameters "empirically" (§6.5: "it is necessary to
/// perform a search for new parameters"); `lop-bench` does that search automatically. A pattern
/// search over the logarithms of stiffness, density and damping, from the body's `[body.gc]`
/// values (Table 6.1/6.2), minimises the max error against the reference on a calibration load
/// ([`CALIBRATION_DIRECTION`], [`CALIBRATION_FORCE_FACTOR`] of the force); the tuned cage is
/// then evaluated on the study's load like every other variant.
#[derive(Debug, Clone, Serialize)]
pub struct Tuned {
    /// Spring stiffness, N/m; cage density, kg/m³; per-vertex damping, N·s/m.
    pub stiffness: f64,
    pub density: f64,
    pub damping: f64,
    /// Calibration runs the search took.
    pub runs: usize,
    /// Max error on the calibration load, %: with the starting (table) values and tuned.
    pub calibration_start_pct: f64,
    pub calibration_pct: f64,
}

/// One body's study.
#[derive(Debug, Clone, Serialize)]
pub struct CaseReport {
    /// "cylinder" or "liver".
    pub case: String,
    pub scene: String,
    pub body: String,
    pub nodes: usize,
    pub tets: usize,
    /// The error's yardstick: the body's smallest rest extent, m.
    pub smallest_extent_m: f64,
    pub gravity: [f64; 3],
    /// Nodes sharing the lateral load, its direction and its total while held, N.
    pub loaded_nodes: usize,
    pub load_direction: [f64; 3],
    pub ramp_end_s: f64,
    pub hold_end_s: f64,
    pub simulated_s: f64,
    pub references: Vec<ReferenceRow>,
    pub variants: Vec<VariantRow>,
    pub svg: String,
}

/// The free surface nodes on the body's −x side and upper half (relative to its bounding box
/// centre).
fn side_nodes(mesh: &TetMesh) -> Vec<usize> {
    let info = mesh.info();
    let c: [f64; 3] = std::array::from_fn(|a| 0.5 * (info.bbox_min[a] + info.bbox_max[a]));
    let mut fixed = vec![false; mesh.nodes.len()];
    for &f in &mesh.fixed {
        fixed[f as usize] = true;
    }
    let mut out: Vec<usize> = mesh
        .surface
        .iter()
        .flatten()
        .map(|&k| k as usize)
        .filter(|&k| !fixed[k] && mesh.nodes[k][0] < c[0] && mesh.nodes[k][1] > c[1])
        .collect();
    out.sort_unstable();
    out.dedup();
    out
}

/// Total lateral load at time `t`, as a fraction of its held value.
fn load_factor(t: f64) -> f64 {
    if t < RAMP_END {
        t / RAMP_END
    } else if t < HOLD_END {
        1.0
    } else {
        0.0
    }
}

impl VariantRow {
    /// A row with its metrics still to be measured.
    fn new(
        reference: Reference,
        variant: String,
        label: String,
        shape: Option<String>,
        dynamics: Option<String>,
        cage_vertices: Option<usize>,
    ) -> VariantRow {
        VariantRow {
            reference: reference.key().into(),
            variant,
            label,
            shape,
            dynamics,
            cage_vertices,
            max_error_pct: 0.0,
            max_error_at_s: 0.0,
            max_error_relative: 0.0,
            mean_error_pct: 0.0,
            hold_end_max_error_pct: 0.0,
            final_max_error_pct: 0.0,
            blow_ups: 0,
            tuned: None,
        }
    }
}

impl Runner {
    fn new(row: VariantRow, model: Option<Model>, fit: bool) -> Runner {
        Runner {
            row,
            model,
            fit,
            mean: vec![0.0],
            max: vec![0.0],
        }
    }
}

/// One approximation being stepped.
struct Runner {
    row: VariantRow,
    model: Option<Model>,
    /// Not stepped: fitted to the reference every iteration (the cage's best shape).
    fit: bool,
    /// Per iteration: mean and max error, %.
    mean: Vec<f64>,
    max: Vec<f64>,
}

/// Runs both cases; writes a CSV per case × reference and an SVG per case.
pub fn run(quick: bool, out: &Path, files: &mut Vec<String>) -> Result<Vec<CaseReport>> {
    let seconds = if quick { QUICK_SECONDS } else { SECONDS };
    let mut reports = Vec::new();
    for case in &CASES {
        let scene = shipped_scene(case.scene)?;
        let (spec, mesh) = placed_bodies(&scene)?
            .into_iter()
            .find(|(s, _)| s.name == case.body)
            .with_context(|| format!("scene {} has no body {}", case.scene, case.body))?;
        let smallest = smallest_extent(&mesh.nodes);
        let nodes = side_nodes(&mesh);
        if nodes.is_empty() {
            bail!("{}: no free surface node on the loaded side", case.body);
        }
        let mut references = Vec::new();
        let mut variants = Vec::new();
        let mut panels = Vec::new();
        for reference in [Reference::Fem, Reference::Msd] {
            let (rrow, runners, disp) = run_reference(
                &scene, case, &spec, &mesh, reference, &nodes, smallest, seconds,
            )?;
            let csv = rrow.csv.clone();
            write_csv(&out.join(&csv), rrow.dt, &disp, &runners)?;
            files.push(listed(out, &csv));
            panels.push(panel(reference, rrow.dt, &disp, &runners, seconds));
            references.push(rrow);
            variants.extend(runners.into_iter().map(|r| r.row));
        }
        let svg = format!("part3-{}.svg", case.name);
        plot::line_grid(
            &out.join(&svg),
            &format!(
                "Fig. 6.13 analogue: {}, max error per iteration (% of {:.0} mm), load {} mN \
                 (FEM), {} mN (MSD)",
                case.body,
                smallest * 1e3,
                case.force * 1e3,
                case.msd_force * 1e3
            ),
            &panels,
            2,
            (620, 380),
        )?;
        files.push(listed(out, &svg));
        reports.push(CaseReport {
            case: case.name.into(),
            scene: case.scene.into(),
            body: case.body.into(),
            nodes: mesh.nodes.len(),
            tets: mesh.tets.len(),
            smallest_extent_m: smallest,
            gravity: scene.gravity,
            loaded_nodes: nodes.len(),
            load_direction: LOAD_DIRECTION,
            ramp_end_s: RAMP_END,
            hold_end_s: HOLD_END,
            simulated_s: seconds,
            references,
            variants,
            svg,
        });
    }
    Ok(reports)
}

/// The reference model's displacement per iteration (max over nodes, %), with index 0 = rest.
type Displacements = Vec<f64>;

#[allow(clippy::too_many_arguments)]
fn run_reference(
    scene: &Scene,
    case: &Case,
    spec: &BodySpec,
    mesh: &TetMesh,
    reference: Reference,
    nodes: &[usize],
    smallest: f64,
    seconds: f64,
) -> Result<(ReferenceRow, Vec<Runner>, Displacements)> {
    let mut ref_spec = spec.clone();
    ref_spec.model = match reference {
        Reference::Fem => ModelPin::Fem,
        Reference::Msd => ModelPin::Msd,
    };
    if let Some(f) = ref_spec.fem.as_mut() {
        f.mode = lop_config::FemMode::Corotational;
    }
    let mut precise = lop_scene::precise_model(scene, &ref_spec, mesh)?;
    let dt = precise.dt();
    let steps = (seconds / dt).round() as usize;
    let force = match reference {
        Reference::Fem => case.force,
        Reference::Msd => case.msd_force,
    };
    let per_node = force / nodes.len() as f64;

    // The approximations: every cage shape × dynamics, at the reference's dt, then the rest
    // shape.
    let mut runners = Vec::new();
    for shape in SHAPES {
        for dynamics in [DynKind::Projected, DynKind::Galerkin, DynKind::MassSpring] {
            let params = gc_variant(spec, mesh, shape, dynamics, dt);
            let gc = CageModel::from_precise_under(mesh, params, &precise, scene.gravity).map_err(
                |e| {
                    anyhow!(
                        "{}: {} cage, {} dynamics: {e}",
                        case.body,
                        shape_label(shape),
                        dynamics.key()
                    )
                },
            )?;
            let vertices = gc.coordinates().vertex_count();
            let (variant, label) = variant_names(shape, dynamics);
            runners.push(Runner::new(
                VariantRow::new(
                    reference,
                    variant,
                    label,
                    Some(shape_key(shape)),
                    Some(dynamics.key().into()),
                    Some(vertices),
                ),
                Some(Model::Gc(Box::new(gc))),
                false,
            ));
        }
    }
    // The thesis' box cage with its mass-spring parameters searched for, as the thesis did by
    // hand, on the calibration load.
    {
        let load = Load {
            nodes,
            per_node: per_node * CALIBRATION_FORCE_FACTOR,
            direction: CALIBRATION_DIRECTION,
        };
        let calibration = record(scene, &precise, &load, steps)?;
        let base = gc_variant(spec, mesh, CageShape::Box, DynKind::MassSpring, dt);
        let tuned = Calibration {
            scene,
            mesh,
            precise: &precise,
            base,
            load: &load,
            trajectory: &calibration,
            smallest,
        }
        .tune()
        .with_context(|| format!("{}: tuning the mass-spring box cage", case.body))?;
        let params = GcParameters {
            dynamics: CageDynamics::MassSpring(CageSprings {
                stiffness: tuned.stiffness,
                density: tuned.density,
                damping: tuned.damping,
            }),
            ..base
        };
        let gc = CageModel::from_precise(mesh, params, &precise)
            .map_err(|e| anyhow!("{}: tuned mass-spring box cage: {e}", case.body))?;
        let mut row = VariantRow::new(
            reference,
            "gc-box-mass-spring-tuned".into(),
            format!(
                "GC {}, mass-spring tuned (thesis' way)",
                shape_label(CageShape::Box)
            ),
            Some(shape_key(CageShape::Box)),
            Some("mass-spring-tuned".into()),
            Some(gc.coordinates().vertex_count()),
        );
        row.tuned = Some(tuned);
        runners.push(Runner::new(row, Some(Model::Gc(Box::new(gc))), false));
    }
    for shape in SHAPES {
        let params = gc_variant(spec, mesh, shape, DynKind::Projected, dt);
        let gc = CageModel::from_precise_under(mesh, params, &precise, scene.gravity)
            .map_err(|e| anyhow!("{}: {} cage: {e}", case.body, shape_label(shape)))?;
        let vertices = gc.coordinates().vertex_count();
        runners.push(Runner::new(
            VariantRow::new(
                reference,
                format!("gc-{}-fit", shape_key(shape)),
                format!("GC {}, best fit (bound)", shape_label(shape)),
                Some(shape_key(shape)),
                Some("fit".into()),
                Some(vertices),
            ),
            Some(Model::Gc(Box::new(gc))),
            true,
        ));
    }
    runners.push(Runner::new(
        VariantRow::new(
            reference,
            "rest".into(),
            "no deformation (rest shape)".into(),
            None,
            None,
            None,
        ),
        None,
        false,
    ));

    eprintln!(
        "lop: part 3: {} vs {} ({} steps of {} s, {} approximations)",
        case.body,
        reference.label(),
        steps,
        dt,
        runners.len()
    );
    let mut loads = vec![[0.0; 3]; mesh.nodes.len()];
    let mut disp: Displacements = vec![0.0];
    let mut ref_blow_ups = 0;
    let mut hold_end_disp = 0.0;
    let hold_end_step = (HOLD_END / dt).round() as usize;
    let pct = 100.0 / smallest;
    let load = Load {
        nodes,
        per_node,
        direction: LOAD_DIRECTION,
    };
    for k in 1..=steps {
        load.at(k, dt, &mut loads);
        if precise.step(scene.gravity, &loads, None).is_err() {
            ref_blow_ups += 1;
        }
        let xr = precise.positions();
        let d = xr
            .iter()
            .zip(&mesh.nodes)
            .map(|(p, q)| dist3(*p, *q))
            .fold(0.0, f64::max);
        disp.push(d * pct);
        if k == hold_end_step {
            hold_end_disp = d;
        }
        for r in &mut runners {
            let x: &[[f64; 3]] = match &mut r.model {
                Some(Model::Gc(g)) if r.fit => {
                    g.take_over(xr, precise.velocities(), 0.0);
                    g.positions()
                }
                Some(m) => {
                    if m.step(scene.gravity, &loads, None).is_err() {
                        r.row.blow_ups += 1;
                    }
                    m.positions()
                }
                None => &mesh.nodes,
            };
            let (mut sum, mut max) = (0.0, 0.0f64);
            for (p, q) in x.iter().zip(xr) {
                let e = dist3(*p, *q);
                sum += e;
                max = max.max(e);
            }
            r.mean.push(sum / xr.len() as f64 * pct);
            r.max.push(max * pct);
        }
        if pipeline::interrupted() {
            bail!("interrupted");
        }
    }
    let ref_max = disp.iter().copied().fold(0.0, f64::max);
    for r in &mut runners {
        let (at, max) =
            r.max
                .iter()
                .enumerate()
                .fold((0, 0.0f64), |b, (k, &v)| if v > b.1 { (k, v) } else { b });
        r.row.max_error_pct = max;
        r.row.max_error_at_s = at as f64 * dt;
        r.row.max_error_relative = if ref_max > 0.0 { max / ref_max } else { 0.0 };
        r.row.mean_error_pct = r.mean[1..].iter().sum::<f64>() / steps.max(1) as f64;
        r.row.hold_end_max_error_pct = r.max.get(hold_end_step).copied().unwrap_or(0.0);
        r.row.final_max_error_pct = *r.max.last().unwrap_or(&0.0);
    }
    let final_disp = disp.last().copied().unwrap_or(0.0) / pct;
    let row = ReferenceRow {
        reference: reference.key().into(),
        label: reference.label().into(),
        dt,
        steps,
        total_force_n: force,
        max_displacement_mm: disp.iter().copied().fold(0.0, f64::max) / pct * 1e3,
        max_displacement_pct: disp.iter().copied().fold(0.0, f64::max),
        hold_end_displacement_mm: hold_end_disp * 1e3,
        final_displacement_mm: final_disp * 1e3,
        blow_ups: ref_blow_ups,
        csv: format!("part3-{}-vs-{}.csv", case.name, reference.key()),
    };
    Ok((row, runners, disp))
}

/// A lateral load: `per_node` N along `direction` on `nodes` while held (see [`load_factor`]).
struct Load<'a> {
    nodes: &'a [usize],
    per_node: f64,
    direction: [f64; 3],
}

impl Load<'_> {
    /// Fills `loads` for step `k` (time `k dt`).
    fn at(&self, k: usize, dt: f64, loads: &mut [[f64; 3]]) {
        let f = self.per_node * load_factor(k as f64 * dt);
        for &i in self.nodes {
            loads[i] = self.direction.map(|d| d * f);
        }
    }
}

/// The positions of a fresh copy of `precise` after each of `steps` steps under `load`.
fn record(scene: &Scene, precise: &Model, load: &Load, steps: usize) -> Result<Vec<Vec<[f64; 3]>>> {
    let mut model = precise.clone();
    model.reset();
    let dt = model.dt();
    let mut loads = vec![[0.0; 3]; model.positions().len()];
    let mut out = Vec::with_capacity(steps);
    for k in 1..=steps {
        load.at(k, dt, &mut loads);
        model
            .step(scene.gravity, &loads, None)
            .map_err(|e| anyhow!("calibration reference blew up at step {k}: {e:?}"))?;
        out.push(model.positions().to_vec());
    }
    Ok(out)
}

/// What the mass-spring cage is tuned against: `trajectory`, the reference's positions per step
/// under `load`.
struct Calibration<'a> {
    scene: &'a Scene,
    mesh: &'a TetMesh,
    precise: &'a Model,
    /// The cage's parameters but the three tuned ones.
    base: GcParameters,
    load: &'a Load<'a>,
    trajectory: &'a [Vec<[f64; 3]>],
    /// The error's yardstick, m.
    smallest: f64,
}

impl Calibration<'_> {
    /// Max error over the run, %, of a mass-spring cage with parameters `exp(log_p)` (stiffness,
    /// density, damping); infinite if it cannot be built or blows up.
    fn error(&self, log_p: [f64; 3]) -> f64 {
        let [stiffness, density, damping] = log_p.map(f64::exp);
        let params = GcParameters {
            dynamics: CageDynamics::MassSpring(CageSprings {
                stiffness,
                density,
                damping,
            }),
            ..self.base
        };
        let Ok(mut gc) = CageModel::from_precise(self.mesh, params, self.precise) else {
            return f64::INFINITY;
        };
        let mut loads = vec![[0.0; 3]; self.mesh.nodes.len()];
        let mut worst = 0.0f64;
        for (k, xr) in self.trajectory.iter().enumerate() {
            self.load.at(k + 1, self.base.dt, &mut loads);
            if gc.step(self.scene.gravity, &loads, None).is_err() {
                return f64::INFINITY;
            }
            for (p, q) in gc.positions().iter().zip(xr) {
                worst = worst.max(dist3(*p, *q));
            }
        }
        worst * 100.0 / self.smallest
    }

    /// The search of [`Tuned`]: coordinate pattern search on the logarithms of the three
    /// parameters, from `base`'s, first steps ×/÷ 4, halved (in the logarithm) whenever no move
    /// helps.
    fn tune(&self) -> Result<Tuned> {
        let CageDynamics::MassSpring(CageSprings {
            stiffness,
            density,
            damping,
        }) = self.base.dynamics
        else {
            bail!("not a mass-spring cage");
        };
        let mut p = [stiffness, density, damping].map(f64::ln);
        let start = self.error(p);
        let mut best = start;
        let mut runs = 1;
        let mut step = 4.0f64.ln();
        while step > TUNE_MIN_FACTOR.ln() && runs < TUNE_MAX_RUNS {
            let mut moved = false;
            'axes: for axis in 0..3 {
                for sign in [-1.0, 1.0] {
                    let mut q = p;
                    q[axis] += sign * step;
                    let e = self.error(q);
                    runs += 1;
                    if e < best {
                        (p, best, moved) = (q, e, true);
                        break 'axes;
                    }
                }
            }
            if !moved {
                step *= 0.5;
            }
        }
        if !best.is_finite() {
            bail!("no stable parameters found");
        }
        let [stiffness, density, damping] = p.map(f64::exp);
        Ok(Tuned {
            stiffness,
            density,
            damping,
            runs,
            calibration_start_pct: start,
            calibration_pct: best,
        })
    }
}

fn variant_names(shape: CageShape, dynamics: DynKind) -> (String, String) {
    (
        format!("gc-{}-{}", shape_key(shape), dynamics.key()),
        format!("GC {}, {}", shape_label(shape), dynamics.label()),
    )
}
