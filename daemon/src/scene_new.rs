//! `lopd scene new`: a scene file for the user's own tetrahedral meshes, ready to run.
//!
//! Every decision is written into the generated file as a comment, so the author can see and
//! change it:
//! - **Units**: each mesh is scaled to metres by its body's `scale` (`--units`).
//! - **Placement**: the bodies side by side along x, 10 mm apart, centred on the origin (each
//!   body's bounding-box centre on the x axis), so none overlaps another and the device's
//!   workspace, centred there, reaches them all.
//! - **Tissue**: parameters from the tissue library ([`lop_config::tissue`]): the `abdomen`
//!   scene's literature values, with the mass-spring spring constant and damping derived from
//!   the mesh as that scene does.
//! - **Fixed nodes**: a posterior patch, as the shipped organs are held (`assets/README.md`):
//!   the surface nodes facing backwards (−z, within 60°) in the back 15 % of the body's
//!   depth — the side away from the surgeon, where the retroperitoneum and ligaments hold an
//!   abdominal organ; the front, where the tool comes from, stays free. On a shape where that
//!   patch holds fewer than three nodes, the back tenth of the body (a slab) instead.
//! - **Device**: the workspace map of the shipped scenes (device origin on the bodies' centre,
//!   the smallest scale of 1, 1.5, 2, … at which the Omni's 160 × 120 × 70 mm reach all of
//!   them), the tool of `abdomen` (3 mm tip, linear 300 N/m, lowered above scale 2 so the stylus
//!   never feels more than 0.6 N/mm), and a mock poke script that presses 6 mm into the front
//!   (+z) of the first body at its x/y centre along the surface normal there.
//!
//! Both files are TOML documents built with `toml_edit` (the values, the fixed-node selector
//! through its serde form) with the decisions as comments, never text pasted together. The file
//! is then loaded as `lopd run --scene` loads it (validation, meshes, fixed-node selectors), and
//! the poke script as the mock device loads it.

use std::path::{Component, Path, PathBuf};

use anyhow::{bail, Context, Result};
use lop_config::{selector_toml, tissue, tissue_names, Importance, Tissue};
use lop_sim::mesh::{bounds, read_mesh, NodeSelector, TetMesh};
use toml_edit::{value, ArrayOfTables, DocumentMut, Item, Table, Value};

use crate::tetrahedralize::Units;

/// Gap between neighbouring bodies, m.
pub const BODY_GAP: f64 = 0.010;
/// How far the poke pushes past first contact, m.
pub const POKE_DEPTH: f64 = 0.006;
/// Clearance of the tip from the surface at the poke's rest point, m.
pub const POKE_CLEARANCE: f64 = 0.015;
/// The Omni's workspace, device mm (the mock device's limits).
const OMNI_MIN_MM: [f64; 3] = [-80.0, -60.0, -35.0];
const OMNI_MAX_MM: [f64; 3] = [80.0, 60.0, 35.0];
/// The tool of the shipped scenes.
const TOOL_RADIUS: f64 = 0.003;
const TOOL_STIFFNESS: f64 = 300.0;
/// Largest stiffness felt at the stylus, N/m of device motion (0.6 N/mm, under the Omni's 0.7).
const STYLUS_STIFFNESS: f64 = 600.0;

/// What to generate.
#[derive(Debug, Clone)]
pub struct SceneNewOptions {
    /// Scene name.
    pub name: String,
    /// The meshes, one body each.
    pub meshes: Vec<PathBuf>,
    /// Tissue names: one for every body, or one per body.
    pub tissues: Vec<String>,
    /// The meshes' units.
    pub units: Units,
    /// The scene file to write.
    pub out: PathBuf,
    /// Overwrite existing files.
    pub force: bool,
    /// Draw each body by the surface `lopd mesh tetrahedralize` wrote beside its mesh
    /// (`MESH.render.obj`), when there is one.
    pub render_surface: bool,
}

/// What was generated.
#[derive(Debug)]
pub struct SceneNew {
    /// The scene file.
    pub scene: PathBuf,
    /// The poke script beside it.
    pub script: PathBuf,
    /// Per body: name, tissue, node count, fixed node count.
    pub bodies: Vec<(String, &'static str, usize, usize)>,
}

/// Is the input at fault? (exit code 2): wrapped by the generator's bad-input errors.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct SceneNewInputError(pub String);

fn input<T>(msg: String) -> Result<T> {
    Err(anyhow::Error::new(SceneNewInputError(msg)))
}

struct Body {
    name: String,
    tissue: &'static Tissue,
    mesh_path: PathBuf,
    mesh: TetMesh,
    /// Mesh-file bounds, file units.
    lo: [f64; 3],
    hi: [f64; 3],
    translate: [f64; 3],
    fix: NodeSelector,
    fix_note: &'static str,
}

/// Generates the scene and its poke script (see the [module docs](self)).
pub fn run(opts: &SceneNewOptions) -> Result<SceneNew> {
    if opts.meshes.is_empty() {
        return input("--mesh: give at least one mesh".to_owned());
    }
    if opts.name.trim().is_empty() || opts.name.contains(['"', '\\', '\n']) {
        return input(format!(
            "scene name {:?}: must be non-empty, without quotes, backslashes or newlines",
            opts.name
        ));
    }
    let tissues: Vec<&'static Tissue> = match opts.tissues.len() {
        0 => vec![tissue("liver").expect("the library has a liver"); opts.meshes.len()],
        1 => vec![lookup(&opts.tissues[0])?; opts.meshes.len()],
        n if n == opts.meshes.len() => opts
            .tissues
            .iter()
            .map(|t| lookup(t))
            .collect::<Result<_>>()?,
        n => {
            return input(format!(
                "--tissue given {n} times for {} meshes: give one for all, or one per mesh",
                opts.meshes.len()
            ))
        }
    };
    let script = script_path(&opts.out);
    for p in [&opts.out, &script] {
        if p.exists() && !opts.force {
            return input(format!(
                "{} exists: choose another --out, or --force to overwrite it",
                p.display()
            ));
        }
    }
    let s = opts.units.metres();

    // Read and place the bodies side by side along x.
    let mut bodies: Vec<Body> = Vec::new();
    for (path, tissue) in opts.meshes.iter().zip(tissues) {
        let mesh = match read_mesh(path) {
            Ok(m) => m,
            Err(e) => return input(format!("--mesh {}: {e}", path.display())),
        };
        let (lo, hi) = bounds(&mesh.nodes);
        let mut name = mesh_stem(path);
        let mut k = 2;
        while bodies.iter().any(|b| b.name == name) {
            name = format!("{}_{k}", mesh_stem(path));
            k += 1;
        }
        bodies.push(Body {
            name,
            tissue,
            mesh_path: path.clone(),
            mesh,
            lo,
            hi,
            translate: [0.0; 3],
            fix: NodeSelector::Box {
                min: [0.0; 3],
                max: [0.0; 3],
            },
            fix_note: "",
        });
    }
    let width: f64 = bodies.iter().map(|b| (b.hi[0] - b.lo[0]) * s).sum::<f64>()
        + BODY_GAP * (bodies.len() - 1) as f64;
    let mut x = -width / 2.0;
    for b in &mut bodies {
        let size = [0, 1, 2].map(|k| (b.hi[k] - b.lo[k]) * s);
        let centre = [0, 1, 2].map(|k| (b.hi[k] + b.lo[k]) / 2.0 * s);
        b.translate = round_m([x + size[0] / 2.0 - centre[0], -centre[1], -centre[2]]);
        x += size[0] + BODY_GAP;
        // Place the nodes as the scene will, for the selector and the poke.
        for p in &mut b.mesh.nodes {
            *p = [0, 1, 2].map(|k| p[k] * s + b.translate[k]);
        }
        let (fix, note) = default_fix(&b.mesh);
        b.fix = fix;
        b.fix_note = note;
    }

    // Workspace: device origin on the centre of everything, the smallest scale that reaches it.
    let (lo, hi) = bounds(
        &bodies
            .iter()
            .flat_map(|b| b.mesh.nodes.clone())
            .collect::<Vec<_>>(),
    );
    let offset = round_m([0, 1, 2].map(|k| (lo[k] + hi[k]) / 2.0));
    let reach = [0, 1, 2].map(|k| (OMNI_MAX_MM[k] - OMNI_MIN_MM[k]) * 1e-3);
    let need = [
        (hi[0] - lo[0]) / reach[0],
        (hi[1] - lo[1]) / reach[1],
        (hi[2] - lo[2] + 2.0 * (POKE_CLEARANCE + TOOL_RADIUS)) / reach[2],
    ]
    .into_iter()
    .fold(1.0, f64::max);
    let scale = (need * 2.0).ceil() / 2.0;
    let stiffness = TOOL_STIFFNESS.min(STYLUS_STIFFNESS / scale).round();

    let poke = poke_waypoints(&bodies[0].mesh, offset, scale)?;

    // Write the scene and the script.
    let scene_dir = absolute_dir(&opts.out)?;
    let text = scene_text(opts, &bodies, &scene_dir, offset, scale, stiffness, &script)?;
    if let Some(d) = opts.out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(d).with_context(|| format!("creating {}", d.display()))?;
    }
    std::fs::write(&opts.out, text).with_context(|| format!("writing {}", opts.out.display()))?;
    std::fs::write(
        &script,
        script_text(&opts.name, &bodies[0].name, offset, scale, &poke),
    )
    .with_context(|| format!("writing {}", script.display()))?;

    // Load it as `lopd run` would.
    let scene = lop_config::load_scene(&opts.out).with_context(|| {
        format!(
            "the generated scene {} does not validate",
            opts.out.display()
        )
    })?;
    let placed = lop_scene::place_bodies(&scene)
        .with_context(|| format!("the generated scene {} does not load", opts.out.display()))?;
    lop_drivers::mock::MockScript::load(&script)
        .with_context(|| format!("the generated poke script {}", script.display()))?;
    Ok(SceneNew {
        scene: opts.out.clone(),
        script,
        bodies: bodies
            .iter()
            .zip(&placed)
            .map(|(b, m)| (b.name.clone(), b.tissue.name, m.nodes.len(), m.fixed.len()))
            .collect(),
    })
}

fn lookup(name: &str) -> Result<&'static Tissue> {
    match tissue(name) {
        Some(t) => Ok(t),
        None => input(format!(
            "--tissue {name:?}: not in the tissue library ({})",
            tissue_names().join(", ")
        )),
    }
}

/// `NAME-poke.toml` beside the scene file `NAME.toml`.
fn script_path(scene: &Path) -> PathBuf {
    let stem = scene
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "scene".to_owned());
    scene.with_file_name(format!("{stem}-poke.toml"))
}

/// A body name from a mesh path: `liver` for `x/liver.node`, `x/liver` or `x/liver.msh`.
fn mesh_stem(path: &Path) -> String {
    path.file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .filter(|s| !s.is_empty())
        .unwrap_or_else(|| "body".to_owned())
}

/// Rounded to the micrometre, so the file reads cleanly.
fn um(x: f64) -> f64 {
    (x * 1e6).round() / 1e6 + 0.0
}

/// [`um`] of each component.
fn round_m(v: [f64; 3]) -> [f64; 3] {
    v.map(um)
}

/// A point for a comment, rounded to the micrometre.
fn arr(v: [f64; 3]) -> String {
    format!("{:?}", round_m(v))
}

/// The posterior patch, or the back slab where the patch is too small (see the module docs).
fn default_fix(mesh: &TetMesh) -> (NodeSelector, &'static str) {
    let (lo, hi) = bounds(&mesh.nodes);
    let depth = hi[2] - lo[2];
    let centre = [(lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0];
    let slab = |fraction: f64| NodeSelector::Slab {
        point: round_m([centre[0], centre[1], lo[2] + fraction * depth]),
        normal: [0.0, 0.0, 1.0],
        thickness: None,
    };
    let patch = NodeSelector::Facing {
        direction: [0.0, 0.0, -1.0],
        angle_deg: 60.0,
        within: Some(Box::new(slab(0.15))),
    };
    if patch.select(&mesh.nodes, &mesh.surface).len() >= 3 {
        (
            patch,
            "the posterior patch: surface nodes facing backwards (-z, within 60\n\
             degrees) in the back 15 % of the body's depth",
        )
    } else {
        (
            slab(0.1),
            "the posterior slab: every node in the back tenth of the body's depth\n\
             (its posterior surface patch holds fewer than three nodes)",
        )
    }
}

/// The poke's waypoints, device mm: rest, contact, pushed (see [`script_text`]).
struct Poke {
    target: [f64; 3],
    normal: [f64; 3],
    rest: [f64; 3],
    contact: [f64; 3],
    pushed: [f64; 3],
}

/// The first body's front surface at its x/y centre (the highest hit of a ray down −z there;
/// else its most anterior surface node) and the poke along the normal there.
fn poke_waypoints(mesh: &TetMesh, offset: [f64; 3], scale: f64) -> Result<Poke> {
    let (lo, hi) = bounds(&mesh.nodes);
    let (cx, cy) = ((lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0);
    let mut best: Option<([f64; 3], [f64; 3])> = None;
    for t in &mesh.surface {
        let [a, b, c] = t.map(|i| mesh.nodes[i as usize]);
        let n = cross(sub(b, a), sub(c, a));
        if n[2] <= 0.0 {
            continue; // faces away from +z
        }
        // Barycentric coordinates of (cx, cy) in the xy projection.
        let det = (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]);
        if det == 0.0 {
            continue;
        }
        let u = ((cx - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (cy - a[1])) / det;
        let v = ((b[0] - a[0]) * (cy - a[1]) - (cx - a[0]) * (b[1] - a[1])) / det;
        if u < 0.0 || v < 0.0 || u + v > 1.0 {
            continue;
        }
        let z = a[2] + u * (b[2] - a[2]) + v * (c[2] - a[2]);
        if best.is_none_or(|(p, _)| z > p[2]) {
            best = Some(([cx, cy, z], normalize(n)));
        }
    }
    let (target, normal) = match best {
        Some(hit) => hit,
        None => {
            let normals = lop_sim::mesh::vertex_normals(&mesh.nodes, &mesh.surface);
            let i = mesh
                .surface_nodes()
                .into_iter()
                .max_by(|&i, &j| mesh.nodes[i as usize][2].total_cmp(&mesh.nodes[j as usize][2]))
                .context("the first body has no surface")?;
            (mesh.nodes[i as usize], normalize(normals[i as usize]))
        }
    };
    let along = |d: f64| [0, 1, 2].map(|k| target[k] + normal[k] * d);
    let device = |p: [f64; 3]| {
        [0, 1, 2].map(|k| ((p[k] - offset[k]) / (1e-3 * scale) * 100.0).round() / 100.0)
    };
    let poke = Poke {
        target,
        normal,
        rest: device(along(TOOL_RADIUS + POKE_CLEARANCE)),
        contact: device(along(TOOL_RADIUS)),
        pushed: device(along(TOOL_RADIUS - POKE_DEPTH)),
    };
    for p in [poke.rest, poke.contact, poke.pushed] {
        if !(0..3).all(|k| p[k] >= OMNI_MIN_MM[k] && p[k] <= OMNI_MAX_MM[k]) {
            bail!(
                "the poke's waypoint {p:?} mm is outside the Omni's workspace \
                 ({OMNI_MIN_MM:?} .. {OMNI_MAX_MM:?} mm) at workspace scale {scale}"
            );
        }
    }
    Ok(poke)
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn normalize(a: [f64; 3]) -> [f64; 3] {
    let l = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
    if l > 0.0 {
        a.map(|x| x / l)
    } else {
        [0.0, 0.0, 1.0]
    }
}

/// The directory a path will be in, absolute.
fn absolute_dir(file: &Path) -> Result<PathBuf> {
    let abs = std::path::absolute(file).with_context(|| format!("{}", file.display()))?;
    Ok(abs.parent().map(Path::to_path_buf).unwrap_or_default())
}

/// `target` relative to directory `from` (both absolute), with `..` where needed.
fn relative(target: &Path, from: &Path) -> PathBuf {
    let t: Vec<Component> = target.components().collect();
    let f: Vec<Component> = from.components().collect();
    let common = t.iter().zip(&f).take_while(|(a, b)| a == b).count();
    let mut out = PathBuf::new();
    for _ in common..f.len() {
        out.push("..");
    }
    for c in &t[common..] {
        out.push(c.as_os_str());
    }
    out
}

/// Mean tet-edge length and mean node mass of a placed mesh of density `rho`.
fn mesh_scales(mesh: &TetMesh, rho: f64) -> (f64, f64) {
    let edges = mesh.edges();
    let len = |[a, b]: [u32; 2]| {
        let d = sub(mesh.nodes[a as usize], mesh.nodes[b as usize]);
        (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
    };
    let mean_edge = edges.iter().map(|&e| len(e)).sum::<f64>() / edges.len().max(1) as f64;
    let volume: f64 = (0..mesh.tets.len()).map(|i| mesh.tet_volume(i)).sum();
    (mean_edge, rho * volume / mesh.nodes.len().max(1) as f64)
}

/// Three significant figures.
fn sig3(x: f64) -> f64 {
    if x == 0.0 || !x.is_finite() {
        return x;
    }
    let e = 10f64.powi(2 - x.abs().log10().floor() as i32);
    (x * e).round() / e
}

/// `# line` for each line of `text`, each ending in a newline: a TOML comment block.
fn comment(text: &str) -> String {
    text.lines()
        .map(|l| {
            if l.is_empty() {
                "#\n".to_owned()
            } else {
                format!("# {l}\n")
            }
        })
        .collect()
}

/// A TOML array of three floats.
fn floats(v: [f64; 3]) -> Value {
    Value::Array(v.into_iter().collect())
}

/// A table preceded by a blank line and the comment block `text` (see [`comment`]).
fn table_with(text: &str) -> Table {
    let mut t = Table::new();
    t.decor_mut().set_prefix(format!("\n{}", comment(text)));
    t
}

/// The generated scene, written by `toml_edit` (values) with the decisions as comments.
#[allow(clippy::too_many_arguments)]
fn scene_text(
    opts: &SceneNewOptions,
    bodies: &[Body],
    scene_dir: &Path,
    offset: [f64; 3],
    scale: f64,
    stiffness: f64,
    script: &Path,
) -> Result<String> {
    let mut head = format!(
        "Scene {:?}, generated by `lopd scene new` from:\n",
        opts.name
    );
    for b in bodies {
        head += &format!(
            "  {} ({}, in {})\n",
            b.mesh_path.display(),
            b.tissue.name,
            opts.units.name()
        );
    }
    head += &format!(
        "Key-by-key documentation: `cargo doc -p lop-config --open`, or the top of \
         config/src/lib.rs.\n\
         \n\
         Frame: metres, y up, +z anterior (towards the surgeon and the camera), as the shipped\n\
         organs. Each mesh is scaled to metres by its body's `scale` and placed side by side\n\
         with the others along x, {} mm apart, centred on the origin.\n\
         \n\
         Tissue values: lop's tissue library, the `abdomen` scene's literature values\n\
         (config/scenes/abdomen.toml argues each choice). nu 0.45 keeps linear tetrahedra from\n\
         locking; density 1050 kg/m^3; FEM damping alpha 30 1/s; mass-spring k = {} E l (l the\n\
         mesh's mean edge length, calibrated on the liver against its FEM) and gamma = alpha x\n\
         mean node mass. Gravity is off: a body held only by a patch would sag far beyond linear\n\
         elasticity (see abdomen.toml).\n",
        BODY_GAP * 1e3,
        lop_config::MSD_CALIBRATION
    );
    for b in bodies {
        head += &format!("\n{}:\n", b.name);
        for line in b.tissue.source.lines() {
            head += &format!("  {line}\n");
        }
    }

    let mut doc = DocumentMut::new();
    let mut scene = Table::new();
    scene
        .decor_mut()
        .set_prefix(format!("{}\n", comment(&head)));
    scene["name"] = value(opts.name.as_str());
    scene["description"] = value(format!(
        "Generated by lopd scene new: {}",
        bodies
            .iter()
            .map(|b| format!("{} ({})", b.name, b.tissue.name))
            .collect::<Vec<_>>()
            .join(", ")
    ));
    scene["gravity"] = value(floats([0.0; 3]));
    doc["scene"] = Item::Table(scene);

    let mut tool = table_with(&format!(
        "The tool of the shipped scenes: a 3 mm tip, the linear law; the stylus feels\n\
             stiffness x workspace scale = {} N/mm (an Omni renders about 0.7 N/mm stably).",
        stiffness * scale * 1e-3
    ));
    tool["radius"] = value(um(TOOL_RADIUS));
    tool["force_law"] = value("linear");
    tool["stiffness"] = value(um(stiffness));
    tool["damping"] = value(0.0);
    tool["max_force"] = value(3.0);
    tool["heat_power"] = value(20.0);
    doc["tool"] = Item::Table(tool);

    let mut workspace = table_with(
        &format!(
            "Device mapping: scene = device_mm x 0.001 x scale + offset. The device origin is on the\n\
             centre of the bodies' bounding box; scale {scale} is the smallest of 1, 1.5, 2, ... at which\n\
             the Omni's 160 x 120 x 70 mm workspace covers every body and the poke's approach."
        ));
    workspace["scale"] = value(um(scale));
    workspace["rotate_deg"] = value(floats([0.0; 3]));
    workspace["offset"] = value(floats(offset.map(um)));
    doc["workspace"] = Item::Table(workspace);

    let mut rates = table_with("");
    rates["haptic_hz"] = value(1000.0);
    rates["deform_max_hz"] = value(1000.0);
    rates["publish_hz"] = value(250.0);
    doc["rates"] = Item::Table(rates);

    let mut device = table_with(&format!(
        "The mock device's default: press {} mm into the front of {:?} (see the script).",
        POKE_DEPTH * 1e3,
        bodies[0].name
    ));
    let script = relative(&std::path::absolute(script)?, scene_dir);
    device["mock_script"] = value(script.display().to_string());
    doc["device"] = Item::Table(device);

    let mut lop = table_with("");
    lop["rest_speed"] = value(0.002);
    lop["hold"] = value(0.3);
    lop["blend"] = value(0.2);
    lop["start"] = value("gc");
    doc["lop"] = Item::Table(lop);

    let mut heat = table_with("");
    heat["air_temperature"] = value(22.0);
    heat["air_coefficient"] = value(10.0);
    heat["contact_conductance"] = value(500.0);
    doc["heat"] = Item::Table(heat);

    let mut collision = table_with(
        "Organ collision detected every 10 ms: the touched body steps every millisecond.",
    );
    collision["interval"] = value(0.01);
    doc["collision"] = Item::Table(collision);

    let mut body_tables = ArrayOfTables::new();
    for b in bodies {
        body_tables.push(body_table(opts, b, scene_dir)?);
    }
    doc["body"] = Item::ArrayOfTables(body_tables);
    Ok(doc.to_string())
}

/// One `[[body]]` table of the generated scene, with its fixed-node selector and parameter
/// tables.
fn body_table(opts: &SceneNewOptions, b: &Body, scene_dir: &Path) -> Result<Table> {
    let tissue = b.tissue;
    let mesh = relative(&std::path::absolute(&b.mesh_path)?, scene_dir);
    let (edge, node_mass) = mesh_scales(&b.mesh, tissue.density);
    let (lo, hi) = bounds(&b.mesh.nodes);
    let mut t = table_with(&format!(
        "{}: {} nodes, {} tetrahedra; in the scene {} .. {} m.",
        b.name,
        b.mesh.nodes.len(),
        b.mesh.tets.len(),
        arr(lo),
        arr(hi)
    ));
    t["name"] = value(b.name.as_str());
    t["mesh"] = value(mesh.display().to_string());
    let render = crate::tetrahedralize::render_surface_path(&b.mesh_path);
    if opts.render_surface && render.is_file() {
        let path = relative(&std::path::absolute(&render)?, scene_dir);
        t["render_surface"] = value(path.display().to_string());
    }
    t["importance"] = value(match tissue.importance {
        Importance::Important => "important",
        Importance::Normal => "normal",
    });
    t["scale"] = value(um(opts.units.metres()));
    t["translate"] = value(floats(b.translate.map(um)));
    // Through the shortest decimal of each f32, so the file reads `0.55`, not `0.550000011…`.
    t["color"] = value(Value::Array(
        tissue
            .color
            .iter()
            .map(|c| format!("{c:?}").parse::<f64>().unwrap_or(f64::from(*c)))
            .collect(),
    ));

    let mut fix = toml_edit::ser::to_document(&b.fix)
        .context("writing the fixed-node selector")?
        .as_table()
        .clone();
    fix.decor_mut().set_prefix(format!(
        "\n{}",
        comment(&format!(
            "Fixed: {}. It stands for the retroperitoneum and ligaments\n\
             that hold an abdominal organ from behind, as the shipped organs' posterior patches do;\n\
             the front, where the tool comes from, stays free.\n\
             Check what it picks: lopd mesh info MESH --select '<the table below, inline>'\n\
             (in the mesh file's coordinates: apply scale and translate first).\n\
             As an inline table: {}",
            b.fix_note,
            selector_toml(&b.fix)
        ))
    ));
    fix.set_implicit(false);
    let mut fixes = ArrayOfTables::new();
    fixes.push(fix);
    t["fix"] = Item::ArrayOfTables(fixes);

    let h = &tissue.heat;
    let mut heat = table_with("");
    heat["conductivity"] = value(h.conductivity);
    heat["specific_heat"] = value(h.specific_heat);
    heat["density"] = value(h.density);
    heat["initial"] = value(h.initial);
    heat["coagulation"] = value(h.coagulation);
    heat["burn_stiffening"] = value(h.burn_stiffening);
    t["heat"] = Item::Table(heat);

    let mut fem = table_with("");
    fem["young"] = value(tissue.young);
    fem["poisson"] = value(tissue.poisson);
    fem["density"] = value(tissue.density);
    fem["damping"] = value(tissue.fem_damping);
    fem["dt"] = value(tissue.dt);
    t["fem"] = Item::Table(fem);

    let mut msd = table_with(&format!(
        "k = {} x E x mean edge {:.1} mm; gamma = alpha x mean node mass {:.2} g.",
        lop_config::MSD_CALIBRATION,
        edge * 1e3,
        node_mass * 1e3
    ));
    msd["stiffness"] = value(sig3(tissue.msd_stiffness(edge)));
    msd["density"] = value(tissue.density);
    msd["damping"] = value(sig3(tissue.msd_damping(node_mass)));
    msd["dt"] = value(tissue.dt);
    msd["integrator"] = value("implicit-euler");
    t["msd"] = Item::Table(msd);

    let mut gc = table_with("");
    gc["cage"] = value("fitted");
    gc["dynamics"] = value("projected");
    gc["dt"] = value(tissue.gc_dt);
    t["gc"] = Item::Table(gc);
    Ok(t)
}

/// The mock poke script: rest in front of the target, approach to contact, press
/// [`POKE_DEPTH`] further along the inward normal, hold 1 s, withdraw; loops (as `abdomen-poke`).
/// Written by `toml_edit`, the waypoints' labels as comments.
fn script_text(scene: &str, body: &str, offset: [f64; 3], scale: f64, poke: &Poke) -> String {
    let mut doc = DocumentMut::new();
    let head = comment(&format!(
        "Poke for scene {scene:?}, generated by `lopd scene new`: approach the front of {body:?},\n\
         press the tip {} mm past first contact along the inward surface normal, hold 1 s,\n\
         withdraw, loop. Device mm = (scene m - offset) / (0.001 x scale), offset {}, scale {}.\n\
         Target: scene {} m, outward normal {}; the tip (radius {} mm) touches at contact.",
        POKE_DEPTH * 1e3,
        arr(offset),
        scale,
        arr(poke.target),
        arr(poke.normal.map(|x| (x * 1e3).round() / 1e3)),
        TOOL_RADIUS * 1e3,
    ));
    doc["name"] = value(format!("{scene}: poke"));
    if let Some(mut key) = doc.as_table_mut().key_mut("name") {
        key.leaf_decor_mut().set_prefix(head);
    }
    doc["description"] = value(format!(
        "Press {} mm into the front of {body}, hold 1 s, withdraw.",
        POKE_DEPTH * 1e3
    ));
    doc["end"] = value("loop");
    doc["interpolation"] = value("smooth");
    let mut waypoints = ArrayOfTables::new();
    for (time, label, p) in [
        (0.0, "rest", poke.rest),
        (0.5, "rest", poke.rest),
        (1.3, "contact", poke.contact),
        (2.0, "pushed", poke.pushed),
        (3.0, "pushed", poke.pushed),
        (3.6, "contact", poke.contact),
        (4.4, "rest", poke.rest),
    ] {
        let mut w = Table::new();
        w.decor_mut().set_prefix("\n");
        w["t"] = value(time);
        w["position"] = value(floats(p.map(|x| x + 0.0)));
        w["buttons"] = value(Value::Array(toml_edit::Array::new()));
        if let Some(mut key) = w.key_mut("t") {
            key.leaf_decor_mut().set_prefix(format!("# {label}\n"));
        }
        waypoints.push(w);
    }
    doc["waypoint"] = Item::ArrayOfTables(waypoints);
    doc.to_string()
}
