//! Part 2 of `lop-bench haptics`: the block's press on the `abdomen` scene's liver.
//!
//! The liver is built by `lop_scene::load` from `config/scenes/abdomen.toml` as `lopd` builds it
//! (mesh, placement, the `.bnd` posterior patch fixed, E 4.1 kPa, ν 0.45, ρ, α, Δt 10 ms), alone
//! (no other organ can push it) and pinned to FEM in the **linear** mode: the scene runs it
//! corotational under its levels-of-precision controller, but the reference is linear
//! elasticity, and linear against linear is what this comparison can judge. The tool is the
//! scene's (R 3 mm) with the scene's law against the liver (`lop_scene::ToolLaws`, the mock
//! Omni's clamp: linear 300 N/m).
//!
//! The contact point is the poke script's target (`config/scripts/abdomen-poke.toml`: node 435
//! of `liver.node`, 1-based, on the liver's front, +z): the surface node nearest to it (434,
//! 0-based), with the area-weighted outward normal of the triangles around it. The liver's
//! surface edges there are 13 mm long, far coarser than the 3 mm tool, so the sphere soon rests
//! on the faces around the node rather than on the node: the reference presses the nodes and
//! 741 samples inside each face at the node (`face_samples` 40, see `reference.rs`), with a
//! penalty 1000 × the candidates' point stiffness. The block's nodes-only reference is shown
//! beside it (and how deep its faces cut into the sphere). lop's contact patch presses nodes
//! and faces too, but lets a face into the sphere by `min(h²/6r, r/20)` (0.15 mm here, `h` the
//! longest edge) so that face points do not fight the nodes of a fine mesh; `ref(d-a)` is the
//! reference that much less deep — a diagnosis, not the target.
//!
//! The press (`press_in_steps`): the device descends along `−n` through the point `c + n R`,
//! at 1 mm/s from 0.5 mm off the surface, stops each time the proxy's indentation
//! `d = R − (proxy − c)·n` reaches the next depth, and holds still until the damped body has
//! settled (the last part of the hold is measured: mean depth, mean force along `n`, and how
//! much the force still drifted over it). The reference is solved at each held depth.

use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use glam::DVec3;
use lop_config::ModelPin;
use lop_drivers::mock::MockDevice;
use lop_scene::session::RoundInput;
use lop_scene::{DeviceClamp, OfflineSession, ToolLaws};
use lop_sim::contact::ToolSphere;
use lop_sim::haptic::hand_force;
use lop_sim::mesh::TetMesh;
use lop_sim::world::World;
use serde::Serialize;

use super::reference::{closest_bary, vertex_normal, Contact, ContactReference, Material, Penalty};
use crate::models::workspace_root;
use crate::plot::{self, Panel, Series};

/// The scene.
pub const SCENE: &str = "config/scenes/abdomen.toml";
/// The body.
pub const BODY: &str = "liver";
/// The poke script's target (`config/scripts/abdomen-poke.toml`: node 435 of
/// `assets/meshes/liver.node`), scene coordinates, m.
pub const SCRIPT_TARGET: [f64; 3] = [-0.0722, 0.0670, 0.0463];
/// The outward normal the script gives there.
pub const SCRIPT_NORMAL: [f64; 3] = [0.106, -0.047, 0.993];
/// Depths at which the press holds, m (full run and `--quick`).
const DEPTHS: [f64; 6] = [0.5e-3, 1.0e-3, 1.5e-3, 2.0e-3, 2.5e-3, 3.0e-3];
const QUICK_DEPTHS: [f64; 2] = [1.0e-3, 3.0e-3];
/// Device speed while descending, m/s.
const SPEED: f64 = 1e-3;
/// The proxy's gap to the surface at the start, m.
const START_GAP: f64 = 0.5e-3;
/// Hold at each depth, s, and the part of it measured at its end.
const HOLD: f64 = 3.0;
const MEASURED: f64 = 0.5;
/// Haptic tick, s.
const TICK: f64 = 1e-3;
/// Limit on `|lop / reference − 1|` (the block's same-mesh target).
pub const LIMIT: f64 = 0.10;
/// Face samples per triangle edge of the reference (`k`: `(k−1)(k−2)/2` points inside each
/// face at the contact node; 13 mm edges / 40 = 0.33 mm apart). The sphere sinks between
/// samples by about their spacing² / (6R): measured at 1.5 mm, 40 per edge give 116.9 mN, 80
/// give 118.4 (1.2 % more) and 160 give 118.2. 80 would be better, but its active set cycles
/// at 2.4 mm (5000 iterations); 40 settles at every depth, so the reference is ~1 % soft.
const FACE_SAMPLES: usize = 40;
/// The reference's penalty per point, in units of the candidates' point stiffness.
const PENALTY_FACTOR: f64 = 1e3;
/// Depths of the reference's curve in the plot, m.
const CURVE_STEP: f64 = 0.25e-3;
const CURVE_MAX: f64 = 3.5e-3;

/// Everything measured on the liver, for `--json`.
#[derive(Debug, Serialize)]
pub struct LiverReport {
    pub scene: String,
    pub body: String,
    /// The FEM mode the scene gives the liver, and the one pressed here.
    pub scene_fem_mode: String,
    pub fem_mode: String,
    pub young_pa: f64,
    pub poisson: f64,
    pub nodes: usize,
    pub tets: usize,
    pub fixed_nodes: usize,
    /// The contact node (0-based), its position (mm) and its outward normal; its distance to
    /// the script's target (mm) and the angle between the normals (degrees).
    pub contact_node: u32,
    pub contact_mm: [f64; 3],
    pub normal: [f64; 3],
    pub target_distance_mm: f64,
    pub normal_angle_deg: f64,
    /// Mean length of the surface edges at the contact node, mm.
    pub surface_edge_mm: f64,
    pub tool_radius_mm: f64,
    pub tool_stiffness_n_per_m: f64,
    /// Reference: candidate nodes, free DOFs, seconds to assemble, factorise and condense.
    pub candidates: usize,
    pub face_samples: usize,
    pub dofs: usize,
    pub reference_setup_s: f64,
    pub press_s: f64,
    pub rows: Vec<LiverRow>,
    /// The reference's F(d) for the plot (mm, mN), and the nodes-only one's (up to where it
    /// fails).
    pub reference_curve: Vec<(f64, f64)>,
    pub nodes_only_curve: Vec<(f64, f64)>,
    /// lop's contact patch lets a face into the sphere by at most `min(h²/6r, r/20)` (`h` the
    /// face's longest edge): the smallest over the faces at the contact node, mm.
    pub face_allowance_mm: f64,
    /// Largest `|lop / reference − 1|` over the holds, and whether it is within [`LIMIT`].
    pub worst_error: f64,
    pub limit: f64,
    pub pass: bool,
}

/// One hold.
#[derive(Debug, Serialize)]
pub struct LiverRow {
    /// The depth the press stopped at, and the mean held depth, mm.
    pub target_mm: f64,
    pub depth_mm: f64,
    /// lop's force on the hand along the outward normal, and its magnitude, mN.
    pub lop_mn: f64,
    pub lop_magnitude_mn: f64,
    /// `|F − (F·n) n| / |F|` of lop's mean force.
    pub sideways: f64,
    /// `(F_end − F_start) / F` over the measured part of the hold: what the body was still
    /// settling.
    pub drift: f64,
    /// The proxy's distance from the press axis, mm.
    pub lateral_mm: f64,
    /// The reference (sphere against the nodes and the faces' samples) at the held depth:
    /// force along `n`, mN; `|F_t|/|F|` of its force; points in contact, of which face
    /// samples; the deepest cut of its deformed surface triangles into the sphere, mm (between
    /// samples).
    pub reference_mn: f64,
    pub reference_sideways: f64,
    pub reference_active: usize,
    pub reference_active_samples: usize,
    pub face_penetration_mm: f64,
    /// The block's reference (sphere against the nodes only) at the same depth, and how deep
    /// its faces cut into the sphere; `None` if it fails.
    pub nodes_only_mn: Option<f64>,
    pub nodes_only_face_penetration_mm: Option<f64>,
    /// `lop / reference − 1`.
    pub error: f64,
    /// The reference at the held depth less the largest face allowance lop's patch could give
    /// these faces by their size (it gives none to faces larger than the tool), mN, and lop
    /// against it: the diagnosis of a tool sinking into the faces, not the target.
    pub shifted_mn: f64,
    pub shifted_error: f64,
}

/// The liver as the scene sets it up, alone and linear, with its tool law.
struct Liver {
    world: World,
    mesh: TetMesh,
    law: ToolSphere,
    material: Material,
    scene_mode: String,
}

fn load_liver() -> Result<Liver> {
    let path = workspace_root().join(SCENE);
    let full = lop_config::load_scene(&path).with_context(|| format!("loading {SCENE}"))?;
    let index = full
        .bodies
        .iter()
        .position(|b| b.name == BODY)
        .with_context(|| format!("{SCENE} has no body {BODY:?}"))?;
    let laws = ToolLaws::new(
        &full,
        DeviceClamp {
            max_stiffness_n_per_mm: MockDevice::omni_limits().max_stiffness_n_per_mm,
        },
    );
    let law = laws.bodies[index];
    let mut spec = full.bodies[index].clone();
    let fem = spec
        .fem
        .as_mut()
        .with_context(|| format!("{SCENE}: {BODY} has no [body.fem]"))?;
    let scene_mode = format!("{:?}", fem.mode).to_lowercase();
    fem.mode = lop_config::FemMode::Linear;
    let material = Material {
        young: fem.young,
        poisson: fem.poisson,
    };
    spec.model = ModelPin::Fem;
    let mut scene = full.clone();
    scene.bodies = vec![spec];
    let loaded = lop_scene::load(scene)?;
    let mut world = loaded.world;
    // No cautery here: the heat model would only cost time.
    world.disable_heat();
    let mesh = world.bodies[0].mesh.clone();
    Ok(Liver {
        world,
        mesh,
        law,
        material,
        scene_mode,
    })
}

/// One tick of the liver press.
#[derive(Debug, Clone, Copy)]
struct Tick {
    t: f64,
    depth: f64,
    force: [f64; 3],
    /// Index of the depth being approached or held, and whether holding.
    step: usize,
    holding: bool,
}

/// A held depth through lop.
#[derive(Debug, Clone, Copy)]
struct Held {
    target: f64,
    depth: f64,
    force: [f64; 3],
    drift: f64,
    lateral: f64,
}

/// Presses `world`'s body 0 along `−normal` at `contact`, holding at each of `depths`.
fn press_in_steps(
    world: World,
    law: ToolSphere,
    contact: [f64; 3],
    normal: [f64; 3],
    depths: &[f64],
) -> Result<(Vec<Tick>, Vec<Held>)> {
    let (c, n) = (v(contact), v(normal));
    let r = law.radius;
    let mut session = OfflineSession::new(world, ToolLaws::uniform(law, 1)).catching_up();
    let start = c + n * (r + START_GAP);
    let mut travel = 0.0;
    let mut ticks = Vec::new();
    let mut held = Vec::new();
    let (mut step, mut holding, mut hold_start) = (0usize, false, 0.0);
    let mut tick = 0usize;
    // The device never needs more than the depths plus the tissue's give: bounded travel.
    let max_travel = START_GAP + 4.0 * depths.last().copied().unwrap_or(0.0) + 5e-3;
    while step < depths.len() {
        tick += 1;
        let t = tick as f64 * TICK;
        if !holding {
            travel += SPEED * TICK;
        }
        let device = (start - n * travel).to_array();
        let state = session.probe(device, false);
        let force = hand_force(&state, law.law, law.stiffness, 0.0, [0.0; 3]);
        let depth = r - (v(state.proxy) - c).dot(n);
        ticks.push(Tick {
            t,
            depth,
            force,
            step,
            holding,
        });
        session.advance(t, Some(RoundInput::at(device)), &[], || 0);
        if !holding && depth >= depths[step] {
            holding = true;
            hold_start = t;
        } else if holding && t - hold_start >= HOLD - 1e-9 {
            let part: Vec<&Tick> = ticks
                .iter()
                .filter(|k| k.step == step && k.holding && k.t > t - MEASURED)
                .collect();
            let m = part.len() as f64;
            let mean = |f: &dyn Fn(&Tick) -> f64| part.iter().map(|k| f(k)).sum::<f64>() / m;
            let force = [0, 1, 2].map(|a| mean(&|k| k.force[a]));
            let along = |k: &Tick| v(k.force).dot(n);
            let f = v(force).dot(n);
            let tenth = (part.len() / 10).max(1);
            let first = part[..tenth].iter().map(|k| along(k)).sum::<f64>() / tenth as f64;
            let last = part[part.len() - tenth..]
                .iter()
                .map(|k| along(k))
                .sum::<f64>()
                / tenth as f64;
            let rel = v(state.proxy) - c;
            held.push(Held {
                target: depths[step],
                depth: mean(&|k| k.depth),
                force,
                drift: (last - first) / f,
                lateral: (rel - n * rel.dot(n)).length(),
            });
            step += 1;
            holding = false;
        }
        if travel > max_travel {
            bail!(
                "the liver press did not reach {} mm within {} mm of travel",
                depths[step] * 1e3,
                max_travel * 1e3
            );
        }
    }
    Ok((ticks, held))
}

/// Runs part 2.
pub fn run(quick: bool, out: &Path) -> Result<LiverReport> {
    let Liver {
        world,
        mesh,
        law,
        material,
        scene_mode,
    } = load_liver()?;
    let surface = mesh.surface_nodes();
    let node = surface
        .iter()
        .copied()
        .min_by(|&a, &b| {
            let d = |i: u32| (v(mesh.nodes[i as usize]) - v(SCRIPT_TARGET)).length();
            d(a).total_cmp(&d(b))
        })
        .context("the liver has no surface")?;
    let contact = mesh.nodes[node as usize];
    let normal = vertex_normal(&mesh, node).context("contact node off the surface")?;
    let target_distance = (v(contact) - v(SCRIPT_TARGET)).length();
    if target_distance > 1e-3 {
        bail!(
            "no liver surface node within 1 mm of the poke script's target {SCRIPT_TARGET:?} \
             (nearest {} mm): has the mesh or the scene's placement changed?",
            target_distance * 1e3
        );
    }
    let angle = v(normal)
        .dot(v(SCRIPT_NORMAL).normalize())
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees();
    let surface_edge = surface_edge_at(&mesh, node);
    let depths: &[f64] = if quick { &QUICK_DEPTHS } else { &DEPTHS };
    let deepest = depths.last().copied().unwrap_or(0.0).max(CURVE_MAX);
    let r = law.radius;
    println!(
        "\nlop-bench haptics, part 2: the abdomen scene's liver ({SCENE})\n\
         {} nodes, {} tets, {} fixed (posterior patch); E {} kPa, nu {}; the scene runs it {}, \
         pressed here as linear FEM (the reference is linear), alone, dt {} s\n\
         tool R {} mm, linear spring {} N/m (the scene's law against the liver); contact: node \
         {node} at ({:.1}, {:.1}, {:.1}) mm, {:.2} mm from the poke script's target, outward \
         normal ({:.3}, {:.3}, {:.3}) ({:.1}° from the script's), surface edges there {:.1} mm\n\
         press along -n at {} mm/s, hold {} s at each depth (last {} s measured)\n",
        mesh.nodes.len(),
        mesh.tets.len(),
        mesh.fixed.len(),
        material.young * 1e-3,
        material.poisson,
        scene_mode,
        world.bodies[0].model.dt(),
        r * 1e3,
        law.stiffness,
        contact[0] * 1e3,
        contact[1] * 1e3,
        contact[2] * 1e3,
        target_distance * 1e3,
        normal[0],
        normal[1],
        normal[2],
        angle,
        surface_edge * 1e3,
        SPEED * 1e3,
        HOLD,
        MEASURED
    );
    let t0 = Instant::now();
    let candidate_radius = super::transparency::candidate_radius(r, deepest);
    let reference = ContactReference::new(
        &mesh,
        material,
        r,
        contact,
        normal,
        candidate_radius,
        FACE_SAMPLES,
    )
    .context("the reference on the liver")?;
    let nodes_only =
        ContactReference::new(&mesh, material, r, contact, normal, candidate_radius, 0)
            .context("the nodes-only reference on the liver")?;
    // Neighbouring face samples are nearly the same constraint (exact multipliers make the
    // contact system singular): a penalty 1000 times the candidates' point stiffness, which
    // lets the sphere in by ~ F / (active samples × k_p), micrometres.
    let penalty = Penalty::Stiffness(PENALTY_FACTOR * reference.point_stiffness());
    let setup_s = t0.elapsed().as_secs_f64();
    let t0 = Instant::now();
    let (ticks, held) = press_in_steps(world, law, contact, normal, depths)?;
    let press_s = t0.elapsed().as_secs_f64();
    let n = v(normal);
    let allowance = face_allowance(&mesh, node, r);
    let mut rows = Vec::new();
    for h in &held {
        let c = reference.solve(h.depth, penalty)?;
        let fr = v(c.force_on_tool);
        let bare = nodes_only.solve(h.depth, Penalty::Exact).ok();
        let shifted = reference.solve(h.depth - allowance, penalty)?;
        let f = v(h.force);
        let lop = f.dot(n);
        rows.push(LiverRow {
            target_mm: h.target * 1e3,
            depth_mm: h.depth * 1e3,
            lop_mn: lop * 1e3,
            lop_magnitude_mn: f.length() * 1e3,
            sideways: (f - n * lop).length() / f.length(),
            drift: h.drift,
            lateral_mm: h.lateral * 1e3,
            reference_mn: c.force() * 1e3,
            reference_sideways: (fr - n * c.force()).length() / fr.length(),
            reference_active: c.active,
            reference_active_samples: c.active_samples,
            face_penetration_mm: face_penetration(&reference, &mesh, &c) * 1e3,
            nodes_only_mn: bare.as_ref().map(|b| b.force() * 1e3),
            nodes_only_face_penetration_mm: bare
                .as_ref()
                .map(|b| face_penetration(&nodes_only, &mesh, b) * 1e3),
            error: lop / c.force() - 1.0,
            shifted_mn: shifted.force() * 1e3,
            shifted_error: lop / shifted.force() - 1.0,
        });
    }
    let mut curve = Vec::new();
    let mut bare_curve = Vec::new();
    let step = if quick { 2.0 * CURVE_STEP } else { CURVE_STEP };
    let steps = (CURVE_MAX / step).round() as usize;
    for k in 1..=steps {
        let d = k as f64 * step;
        if let Ok(c) = nodes_only.solve(d, Penalty::Exact) {
            if bare_curve.len() == k - 1 {
                bare_curve.push((d * 1e3, c.force() * 1e3));
            }
        }
        // Deep in, the node may slip round the sphere and the solve fail: the curve ends there.
        match reference.solve(d, penalty) {
            Ok(c) => curve.push((d * 1e3, c.force() * 1e3)),
            Err(_) => break,
        }
    }
    let worst = rows
        .iter()
        .map(|r| r.error.abs())
        .fold(if rows.is_empty() { f64::NAN } else { 0.0 }, f64::max);
    let report = LiverReport {
        scene: SCENE.into(),
        body: BODY.into(),
        scene_fem_mode: scene_mode,
        fem_mode: "linear".into(),
        young_pa: material.young,
        poisson: material.poisson,
        nodes: mesh.nodes.len(),
        tets: mesh.tets.len(),
        fixed_nodes: mesh.fixed.len(),
        contact_node: node,
        contact_mm: contact.map(|x| x * 1e3),
        normal,
        target_distance_mm: target_distance * 1e3,
        normal_angle_deg: angle,
        surface_edge_mm: surface_edge * 1e3,
        tool_radius_mm: r * 1e3,
        tool_stiffness_n_per_m: law.stiffness,
        candidates: reference.candidates(),
        face_samples: reference.samples(),
        dofs: reference.stiffness().n_dof(),
        reference_setup_s: setup_s,
        press_s,
        rows,
        reference_curve: curve,
        nodes_only_curve: bare_curve,
        face_allowance_mm: allowance * 1e3,
        worst_error: worst,
        limit: LIMIT,
        pass: worst <= LIMIT,
    };
    print_table(&report);
    write_csv(out, &report, &ticks)?;
    plot_liver(out, &report, &ticks)?;
    println!(
        "\nwrote {0}/liver.csv, {0}/liver_press.csv, {0}/liver_force_vs_depth.svg",
        out.display()
    );
    Ok(report)
}

/// The smallest face allowance of lop's contact patch by face size alone (`sim/src/patch.rs`:
/// `min(h²/(6r), r/20)`, `h` the longest edge; the patch fades it out for faces reaching
/// beyond the tool) over the surface triangles at `node`, m.
fn face_allowance(mesh: &TetMesh, node: u32, r: f64) -> f64 {
    mesh.surface
        .iter()
        .filter(|t| t.contains(&node))
        .map(|t| {
            let p = t.map(|k| v(mesh.nodes[k as usize]));
            let h = (0..3)
                .map(|k| (p[k] - p[(k + 1) % 3]).length())
                .fold(0.0, f64::max);
            (h * h / (6.0 * r)).min(r / 20.0)
        })
        .fold(f64::INFINITY, f64::min)
}

/// Mean length of the surface edges at `node`, m.
fn surface_edge_at(mesh: &TetMesh, node: u32) -> f64 {
    let mut edges: Vec<(u32, u32)> = Vec::new();
    for t in mesh.surface.iter().filter(|t| t.contains(&node)) {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            if a == node || b == node {
                edges.push((a.min(b), a.max(b)));
            }
        }
    }
    edges.sort_unstable();
    edges.dedup();
    let sum: f64 = edges
        .iter()
        .map(|&(a, b)| (v(mesh.nodes[a as usize]) - v(mesh.nodes[b as usize])).length())
        .sum();
    sum / edges.len() as f64
}

/// How deep the reference's deformed surface triangles cut into its sphere, m (0 if none): the
/// reference keeps nodes outside the sphere, not faces.
fn face_penetration(reference: &ContactReference, mesh: &TetMesh, c: &Contact) -> f64 {
    let u = reference.displacements(c);
    let s = v(reference.sphere_center(c.depth));
    let sphere_r = reference.radius();
    let mut deepest: f64 = 0.0;
    for t in &mesh.surface {
        let p = t.map(|k| v(mesh.nodes[k as usize]) + v(u[k as usize]));
        let d = (bary_point(p, closest_bary(s, p)) - s).length();
        deepest = deepest.max(sphere_r - d);
    }
    deepest
}

fn print_table(r: &LiverReport) {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "Reference on the liver mesh: {} free DOFs, {} candidate nodes, {} face samples, setup \
         {:.2} s; the press through lop took {:.1} s",
        r.dofs, r.candidates, r.face_samples, r.reference_setup_s, r.press_s
    );
    let _ = writeln!(
        s,
        "\nForce along the outward normal at each held depth, mN. lop: force on the hand, mean of \
         the measured hold (side: |F_t|/|F|; drift: change over the measured part; off: the \
         proxy's distance from the press line). ref: static FE reference on the same mesh at \
         lop's held depth, sphere against nodes and face samples (pts: points in contact / of \
         which samples). ref(d-a): the same {:.3} mm less deep (a face allowance by size; lop \
         gives none to faces larger than the tool). \
         nodes-only: the block's reference, sphere against nodes only, and how deep its faces \
         cut into the sphere",
        r.face_allowance_mm
    );
    let _ = writeln!(
        s,
        "{:>7} {:>6} {:>7} {:>6} {:>7} {:>6} {:>7} {:>7} {:>6} {:>5} {:>8} {:>7} {:>10} {:>8}",
        "stop mm",
        "d mm",
        "lop mN",
        "side",
        "drift",
        "off mm",
        "ref mN",
        "diff",
        "side",
        "pts",
        "ref(d-a)",
        "diff",
        "nodes-only",
        "cut mm"
    );
    for row in &r.rows {
        let _ = writeln!(
            s,
            "{:>7.2} {:>6.3} {:>7.2} {:>5.1}% {:>+6.2}% {:>6.3} {:>7.2} {:>+6.1}% {:>5.1}% {:>5} {:>8.2} {:>+6.1}% {:>10} {:>8}",
            row.target_mm,
            row.depth_mm,
            row.lop_mn,
            row.sideways * 100.0,
            row.drift * 100.0,
            row.lateral_mm,
            row.reference_mn,
            row.error * 100.0,
            row.reference_sideways * 100.0,
            format!("{}/{}", row.reference_active, row.reference_active_samples),
            row.shifted_mn,
            row.shifted_error * 100.0,
            opt(row.nodes_only_mn, 2),
            opt(row.nodes_only_face_penetration_mm, 3)
        );
    }
    let _ = writeln!(
        s,
        "  {:<4} liver: max |lop / same-mesh reference − 1| over the holds {:>8} (limit {:.0} %)",
        if r.pass { "PASS" } else { "FAIL" },
        if r.worst_error.is_finite() {
            format!("{:.1} %", r.worst_error * 100.0)
        } else {
            "-".into()
        },
        r.limit * 100.0
    );
    print!("{s}");
}

fn opt(x: Option<f64>, digits: usize) -> String {
    x.filter(|x| x.is_finite())
        .map_or("-".into(), |x| format!("{x:.digits$}"))
}

fn write_csv(out: &Path, r: &LiverReport, ticks: &[Tick]) -> Result<()> {
    let file = out.join("liver.csv");
    let mut text = String::from(
        "stop_mm,depth_mm,lop_mn,lop_magnitude_mn,reference_mn,error,sideways,drift,lateral_mm,\
         reference_sideways,reference_active,reference_active_samples,face_penetration_mm,\
         shifted_mn,shifted_error,nodes_only_mn,nodes_only_face_penetration_mm\n",
    );
    for row in &r.rows {
        let _ = writeln!(
            text,
            "{:.3},{:.5},{:.4},{:.4},{:.4},{:.5},{:.5},{:.5},{:.5},{:.5},{},{},{:.5},{:.4},{:.5},{},{}",
            row.target_mm,
            row.depth_mm,
            row.lop_mn,
            row.lop_magnitude_mn,
            row.reference_mn,
            row.error,
            row.sideways,
            row.drift,
            row.lateral_mm,
            row.reference_sideways,
            row.reference_active,
            row.reference_active_samples,
            row.face_penetration_mm,
            row.shifted_mn,
            row.shifted_error,
            opt(row.nodes_only_mn, 4),
            opt(row.nodes_only_face_penetration_mm, 5)
        );
    }
    std::fs::write(&file, text).with_context(|| format!("writing {}", file.display()))?;
    let file = out.join("liver_press.csv");
    let n = v(r.normal);
    let mut text = String::from("t_s,depth_mm,f_normal_mn,fx_mn,fy_mn,fz_mn,stop_mm,phase\n");
    let stops: Vec<f64> = r.rows.iter().map(|row| row.target_mm).collect();
    for k in ticks {
        let _ = writeln!(
            text,
            "{:.4},{:.6},{:.5},{:.5},{:.5},{:.5},{:.2},{}",
            k.t,
            k.depth * 1e3,
            v(k.force).dot(n) * 1e3,
            k.force[0] * 1e3,
            k.force[1] * 1e3,
            k.force[2] * 1e3,
            stops.get(k.step).copied().unwrap_or(f64::NAN),
            if k.holding { "hold" } else { "descend" }
        );
    }
    std::fs::write(&file, text).with_context(|| format!("writing {}", file.display()))
}

fn plot_liver(out: &Path, r: &LiverReport, ticks: &[Tick]) -> Result<()> {
    let n = v(r.normal);
    let press: Vec<(f64, f64)> = ticks
        .iter()
        .filter(|k| k.depth > 0.0)
        .map(|k| (k.depth * 1e3, v(k.force).dot(n) * 1e3))
        .collect();
    let held: Vec<(f64, f64)> = r
        .rows
        .iter()
        .map(|row| (row.depth_mm, row.lop_mn))
        .collect();
    let y_max = r
        .reference_curve
        .iter()
        .map(|p| p.1)
        .chain(press.iter().map(|p| p.1))
        .fold(0.0, f64::max)
        * 1.4;
    plot::line_grid(
        &out.join("liver_force_vs_depth.svg"),
        "Liver (abdomen scene): tool force vs indentation, lop against the static reference",
        &[Panel {
            title: format!(
                "node {} (poke target), E {} kPa, nu {}, linear FEM, R {} mm",
                r.contact_node,
                r.young_pa * 1e-3,
                r.poisson,
                r.tool_radius_mm
            ),
            x_desc: "indentation d along -n, mm".into(),
            y_desc: "force along n, mN".into(),
            x_range: (0.0, CURVE_MAX * 1e3),
            y_range: (0.0, y_max),
            series: vec![
                Series {
                    label: "lop (god-object; descend 1 mm/s, hold, ...)".into(),
                    points: press,
                    color: 0,
                },
                Series {
                    label: "lop, held (settled)".into(),
                    points: held,
                    color: 3,
                },
                Series {
                    label: "static FE reference, same mesh (nodes and faces)".into(),
                    points: r.reference_curve.clone(),
                    color: 1,
                },
                Series {
                    label: "the same, nodes only (the block's)".into(),
                    points: r
                        .nodes_only_curve
                        .iter()
                        .copied()
                        .take_while(|p| p.1 > 0.0)
                        .collect(),
                    color: 2,
                },
            ],
        }],
        1,
        (720, 480),
    )
}

/// The point of triangle `t` with barycentric weights `w`.
fn bary_point(t: [DVec3; 3], w: [f64; 3]) -> DVec3 {
    t[0] * w[0] + t[1] * w[1] + t[2] * w[2]
}

/// A point as a glam vector.
fn v(a: [f64; 3]) -> DVec3 {
    DVec3::from_array(a)
}

#[cfg(test)]
mod tests {
    //! The liver's reference rests on face samples with a penalty: its answer must not depend
    //! on either, or it would be no reference.

    use super::*;

    #[test]
    fn the_face_reference_does_not_depend_on_the_samples_or_the_penalty() {
        let liver = load_liver().unwrap();
        let mesh = &liver.mesh;
        let node = mesh
            .surface_nodes()
            .into_iter()
            .min_by(|&a, &b| {
                let d = |i: u32| (v(mesh.nodes[i as usize]) - v(SCRIPT_TARGET)).length();
                d(a).total_cmp(&d(b))
            })
            .unwrap();
        let (c, n) = (
            mesh.nodes[node as usize],
            vertex_normal(mesh, node).unwrap(),
        );
        let r = liver.law.radius;
        let radius = crate::haptics::transparency::candidate_radius(r, CURVE_MAX);
        let force = |samples: usize, factor: f64, d: f64| {
            let reference =
                ContactReference::new(mesh, liver.material, r, c, n, radius, samples).unwrap();
            let k = factor * reference.point_stiffness();
            reference.solve(d, Penalty::Stiffness(k)).unwrap().force()
        };
        // Measured at 1.5 mm: 40 samples per edge give 116.9 mN, 80 give 118.4, 160 give
        // 118.2; a penalty 4 times stiffer moves 80's by +0.05 %.
        let d = 1.5e-3;
        let base = force(FACE_SAMPLES, PENALTY_FACTOR, d);
        let finer = force(2 * FACE_SAMPLES, PENALTY_FACTOR, d);
        let stiffer = force(2 * FACE_SAMPLES, 4.0 * PENALTY_FACTOR, d);
        assert!((finer / base - 1.0).abs() < 0.015, "{base} vs {finer}");
        assert!((stiffer / finer - 1.0).abs() < 5e-3, "{finer} vs {stiffer}");
    }
}
