//! `lop-bench organs`: the organs a lab brings, felt through the live pipeline. For the shipped
//! `abdomen` liver and for organs made with the README's recipe from built closed surfaces
//! (`scripts/mesh_surfaces.py`: a 20 cm two-lobed liver, an ellipsoid, a kidney-like bean) at
//! each size asked, each run once per thread count:
//!
//! 1. `lopd mesh tetrahedralize SURFACE --units mm --tets N --out DIR/NAME-N` (the default
//!    mesher), then `lopd scene new NAME-N --mesh … --out DIR/NAME-N.toml` (liver tissue, the
//!    generated poke, which the mock device plays);
//! 2. `lopd run` on that scene with `[deform] threads = T` for `--seconds`, measured as
//!    [`crate::latency`] measures it (the same code): the periods the touched body stepped at,
//!    its lowest real-time factor, its step, the frame interval and frame age in contact, and
//!    device → tissue latency.
//!
//! One line per organ and thread count, the targets checked below the table (real-time factor
//! ≥ 0.99; touched frame interval p99 ≤ 2 ms up to 5,000 tetrahedra asked, ≤ 10 ms beyond —
//! the issue names 20k, and 10k is held to the same), an SVG of frame interval and step against
//! the tetrahedra, and `--json F` with one row per organ and thread count.
//!
//! 3. offline, the same scene's poke pressed by the simulated hand with the light grip through
//!    the closed loop (`lop_scene::closed_loop`: the frame age modelled as live, one frame per
//!    step period), the touched body stepped at 1 ms and at the longest period it took live:
//!    the held force (mean over the last 0.2 s of the poke's hold, 2.8–3.0 s: the generated
//!    poke's and `abdomen-poke`'s timing) at that period against 1 ms, and the energy
//!    generated at the device port (as `lop-bench haptics` part 3 judges it: the grip's work on
//!    the stylus going below zero; 0 for a passive coupling).
//!
//! 4. live, the same poke pressed by the same simulated hand through `lopd run --device
//!    hand:SCRIPT` (the poke with a `[hand]` table of the light grip; [`hand`]) at the same
//!    thread count: the held force over the same window against the offline 1 ms run, the
//!    energy generated at the device port (read from the hand's force log, `grip_work_j`), and
//!    the contact changes as the hand feels them (the force going to zero or back).
//!    `held_force_error` and `device_port_energy_j` are the offline figures, `live_…` the live
//!    ones.
//!
//! The live press starts with `lopd run`: the hand's clock starts with the haptic loop, so on
//! an organ whose deformation process loads for longer than the poke's approach (1.3 s) the
//! hand reaches the surface before the first frame and the live held force says so.

mod hand;

use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{bail, Context, Result};
use clap::Args;
use serde::Serialize;

use lop_config::DaemonConfig;
use lop_drivers::hand::HandParameters;
use lop_drivers::mock::{MockDevice, MockScript};
use lop_scene::closed_loop::{self, ClosedLoopOptions};

use crate::haptics::stability::{contact_changes, mean_force, ENERGY_TOLERANCE};
use crate::latency::{self, LatencyArgs, LatencyReport};
use crate::pipeline;
use crate::plot::{self, Panel, Series};
use crate::table::{self, Align};

/// The built surfaces' maker, in the source tree this bench was built from.
const SURFACE_SCRIPT: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../scripts/mesh_surfaces.py");
/// The real-time factor every organ must keep.
const RT_FACTOR_TARGET: f64 = 0.99;
/// Touched frame interval p99 up to [`SMALL_ORGAN_TETS`] tetrahedra asked, µs (the haptic
/// rate's 1 ms with a tick of slack), and beyond, µs.
const INTERVAL_TARGET_SMALL_US: f64 = 2_000.0;
const INTERVAL_TARGET_LARGE_US: f64 = 10_000.0;
const SMALL_ORGAN_TETS: usize = 5_000;
/// The poke's hold ends at 3.0 s; the held force is the mean over the 0.2 s before.
const HOLD_END_S: f64 = 3.0;
const HELD_WINDOW_S: f64 = 0.2;
/// Held force within this fraction of the 1 ms run's, offline.
const HELD_FORCE_TARGET: f64 = 0.05;

/// Options of `lop-bench organs`.
#[derive(Args, Debug, Clone)]
pub struct OrgansArgs {
    /// Tetrahedra asked of each built surface (comma-separated).
    #[arg(long, value_delimiter = ',', default_values_t = [2000usize, 5000, 10000, 20000])]
    sizes: Vec<usize>,
    /// Built surfaces to mesh (comma-separated names of `scripts/mesh_surfaces.py`'s files:
    /// liver, ellipsoid, kidney, liver_crossing, liver_holes; the last two are repaired first).
    #[arg(long, value_delimiter = ',', default_values_t = ["liver".to_string(), "ellipsoid".to_string(), "kidney".to_string()])]
    surfaces: Vec<String>,
    /// Thread counts of the touched body's step (`[deform] threads`), one run each
    /// (comma-separated; each at most this machine's cores).
    #[arg(long, value_delimiter = ',', default_values_t = [1usize, 2])]
    threads: Vec<usize>,
    /// Seconds measured per run (after a 1 s warm-up); the generated poke presses and holds.
    #[arg(long, default_value_t = 60.0)]
    seconds: f64,
    /// Leave out the shipped `abdomen` scene.
    #[arg(long)]
    no_shipped: bool,
    /// Working directory for the surfaces, meshes, scenes and configurations (kept; default a
    /// new directory under the system's temporary directory).
    #[arg(long)]
    dir: Option<PathBuf>,
    /// Write the SVG here (default DIR/organs.svg).
    #[arg(long)]
    svg: Option<PathBuf>,
    /// Also write one row per organ and thread count as JSON to this file.
    #[arg(long)]
    json: Option<PathBuf>,
    /// The `lopd` binary (default: the `lopd` next to this executable).
    #[arg(long)]
    lopd: Option<PathBuf>,
}

/// One organ at one thread count.
#[derive(Debug, Clone, Serialize)]
pub struct OrganRow {
    /// `abdomen`, or the surface and the tetrahedra asked (`liver-5000`).
    pub name: String,
    /// Tetrahedra asked (`None` for the shipped scene).
    pub asked: Option<usize>,
    /// Tetrahedra of the touched organ's mesh.
    pub tets: usize,
    /// `[deform] threads`.
    pub threads: usize,
    /// The longest period the touched body stepped at in contact, ms.
    pub period_ms: Option<f64>,
    /// Every period it stepped at in contact, ms.
    pub periods_ms: Vec<f64>,
    /// The lowest real-time factor its frames in contact carried.
    pub real_time_factor: Option<f64>,
    /// Touched body's step, µs.
    pub step_p50_us: f64,
    pub step_p99_us: f64,
    /// Touched body's frame interval, µs.
    pub frame_interval_p50_us: f64,
    pub frame_interval_p99_us: f64,
    /// Frame age at the haptic loop in contact, p99, µs.
    pub frame_age_contact_p99_us: f64,
    /// Device → tissue latency, µs.
    pub device_to_tissue_p50_us: f64,
    pub device_to_tissue_p99_us: f64,
    /// Haptic tick compute p99, µs.
    pub tick_compute_p99_us: f64,
    /// Frames in contact in the window.
    pub frames_in_contact: u64,
    /// Offline, light grip (module docs): the held force at 1 ms, N; at `period_ms` relative
    /// to it; the energy generated at the device port at `period_ms`, J (0: passive); the
    /// contact changes over the poke at `period_ms`.
    pub held_force_1ms_n: Option<f64>,
    pub held_force_error: Option<f64>,
    pub device_port_energy_j: Option<f64>,
    pub offline_contact_changes: Option<usize>,
    /// Live, light grip (module docs): the held force, N; relative to the offline 1 ms run's;
    /// the energy generated at the device port, J; the contact changes to the hold's end.
    pub live_held_force_n: Option<f64>,
    pub live_held_force_error: Option<f64>,
    pub live_device_port_energy_j: Option<f64>,
    pub live_contact_changes: Option<usize>,
}

/// The simulated hand's poke offline (module docs).
#[derive(Debug, Clone, Copy)]
struct Offline {
    held_n: f64,
    generated_j: f64,
    contact_changes: usize,
}

/// An organ to run: its name, the tetrahedra asked, the scene file.
struct Organ {
    name: String,
    asked: Option<usize>,
    scene: PathBuf,
}

pub fn run(a: OrgansArgs) -> Result<()> {
    if !(a.seconds.is_finite() && a.seconds >= 0.5 && a.seconds <= 86_400.0) {
        bail!("--seconds {}: must be between 0.5 and 86400", a.seconds);
    }
    let cores = lop_config::machine_cores();
    if let Some(&t) = a.threads.iter().find(|&&t| t == 0 || t > cores) {
        bail!("--threads {t}: must be between 1 and this machine's {cores} cores");
    }
    if let Some(&n) = a.sizes.iter().find(|&&n| !(100..=200_000).contains(&n)) {
        bail!("--sizes {n}: tetrahedra asked must be between 100 and 200000");
    }
    let lopd = pipeline::find_lopd(a.lopd.as_deref())?;
    let dir = match &a.dir {
        Some(d) => d.clone(),
        None => std::env::temp_dir().join(format!("lop-organs-{}", std::process::id())),
    };
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    println!("lop-bench organs: working in {}", dir.display());

    let organs = make_organs(&a, &lopd, &dir)?;
    let mut rows = Vec::new();
    let mut failures = Vec::new();
    let mut cache: Vec<(String, f64, Offline)> = Vec::new();
    for organ in &organs {
        let tets = touched_tets(&organ.scene)?;
        for &threads in &a.threads {
            if pipeline::interrupted() {
                bail!("interrupted");
            }
            let config = dir.join(format!("threads-{threads}.toml"));
            std::fs::write(&config, format!("[deform]\nthreads = {threads}\n"))
                .with_context(|| format!("writing {}", config.display()))?;
            eprintln!(
                "  {} ({tets} tetrahedra), {threads} thread(s), {} s …",
                organ.name, a.seconds
            );
            let args = LatencyArgs::quiet(
                &organ.scene,
                a.seconds,
                Some(lopd.clone()),
                Some(config.clone()),
            );
            match latency::measure_scene(&args) {
                Ok((report, stopped)) => {
                    if let Err(e) = stopped {
                        failures.push(format!("{} at {threads} thread(s): {e:#}", organ.name));
                    }
                    let mut r = row(organ, tets, threads, &report);
                    let period = r.period_ms.unwrap_or(1.0);
                    match (
                        offline_at(&mut cache, organ, 1.0),
                        offline_at(&mut cache, organ, period),
                    ) {
                        (Ok(one), Ok(at)) => {
                            r.held_force_1ms_n = Some(one.held_n);
                            r.held_force_error = Some(at.held_n / one.held_n - 1.0);
                            r.device_port_energy_j = Some(at.generated_j);
                            r.offline_contact_changes = Some(at.contact_changes);
                        }
                        (Err(e), _) | (_, Err(e)) => {
                            failures.push(format!("{} offline: {e:#}", organ.name))
                        }
                    }
                    eprintln!("  {} live, light grip …", organ.name);
                    let tag = format!("{}-threads-{threads}", organ.name);
                    match hand::live(&lopd, &organ.scene, &config, &dir, &tag) {
                        Ok(l) => {
                            r.live_held_force_n = Some(l.held_n);
                            r.live_held_force_error =
                                r.held_force_1ms_n.map(|one| l.held_n / one - 1.0);
                            r.live_device_port_energy_j = Some(l.generated_j);
                            r.live_contact_changes = Some(l.contact_changes);
                        }
                        Err(e) => failures.push(format!(
                            "{} live with the hand at {threads} thread(s): {e:#}",
                            organ.name
                        )),
                    }
                    rows.push(r);
                }
                Err(e) => failures.push(format!("{} at {threads} thread(s): {e:#}", organ.name)),
            }
        }
    }

    print!("{}", render(&rows));
    let svg = a.svg.clone().unwrap_or_else(|| dir.join("organs.svg"));
    plot_rows(&svg, &rows)?;
    println!("SVG written to {}", svg.display());
    if let Some(path) = &a.json {
        let text = serde_json::to_string_pretty(&rows)?;
        std::fs::write(path, text + "\n").with_context(|| format!("writing {}", path.display()))?;
        println!("JSON written to {}", path.display());
    }
    if !failures.is_empty() {
        bail!(
            "{} run(s) failed:\n  {}",
            failures.len(),
            failures.join("\n  ")
        );
    }
    Ok(())
}

/// The shipped scene, then each surface at each size: meshed and made into a scene.
fn make_organs(a: &OrgansArgs, lopd: &Path, dir: &Path) -> Result<Vec<Organ>> {
    let mut organs = Vec::new();
    if !a.no_shipped {
        organs.push(Organ {
            name: "abdomen".into(),
            asked: None,
            scene: lop_config::resolve_scene("abdomen")?,
        });
    }
    if a.surfaces.is_empty() || a.sizes.is_empty() {
        return Ok(organs);
    }
    let surfaces = dir.join("surfaces");
    let made = |s: &String| surfaces.join(format!("{s}.stl"));
    if !a.surfaces.iter().all(|s| made(s).is_file()) {
        let out = Command::new("python3")
            .arg(SURFACE_SCRIPT)
            .arg(&surfaces)
            .output()
            .with_context(|| format!("running python3 {SURFACE_SCRIPT}"))?;
        if !out.status.success() {
            bail!(
                "python3 {SURFACE_SCRIPT} {} failed (it needs numpy: `bash scripts/setup.sh`): {}",
                surfaces.display(),
                String::from_utf8_lossy(&out.stderr).trim()
            );
        }
    }
    for s in &a.surfaces {
        let surface = made(s);
        if !surface.is_file() {
            bail!(
                "--surfaces {s}: {SURFACE_SCRIPT} makes no {s}.stl (liver, ellipsoid, kidney, \
                 liver_crossing, liver_holes)"
            );
        }
        for &n in &a.sizes {
            let name = format!("{s}-{n}");
            let prefix = dir.join(&name);
            let scene = dir.join(format!("{name}.toml"));
            eprintln!("  meshing {name} …");
            let mut mesh = Command::new(lopd);
            mesh.args(["mesh", "tetrahedralize"])
                .arg(&surface)
                .args(["--units", "mm", "--tets", &n.to_string(), "--out"])
                .arg(&prefix);
            if s.contains('_') {
                mesh.arg("--repair");
            }
            checked(&mut mesh, &name)?;
            let mut new = Command::new(lopd);
            new.args(["scene", "new", &name, "--mesh"])
                .arg(&prefix)
                .args(["--force", "--out"])
                .arg(&scene);
            checked(&mut new, &name)?;
            organs.push(Organ {
                name,
                asked: Some(n),
                scene,
            });
        }
    }
    Ok(organs)
}

/// Runs a `lopd` command, failing with its last lines.
fn checked(cmd: &mut Command, what: &str) -> Result<()> {
    let out = cmd
        .output()
        .with_context(|| format!("{what}: running {cmd:?}"))?;
    if !out.status.success() {
        let text = String::from_utf8_lossy(&out.stderr);
        let tail: Vec<&str> = text.lines().rev().take(6).collect();
        bail!(
            "{what}: {cmd:?} failed:\n{}",
            tail.into_iter().rev().collect::<Vec<_>>().join("\n")
        );
    }
    Ok(())
}

/// The tetrahedra of the scene's first body: the one the poke touches (the shipped scene's
/// liver; a generated scene has one body).
fn touched_tets(scene_path: &Path) -> Result<usize> {
    let scene = lop_config::load_scene(scene_path)
        .with_context(|| format!("loading scene {}", scene_path.display()))?;
    let loaded = lop_scene::load(scene)
        .with_context(|| format!("building scene {}", scene_path.display()))?;
    Ok(loaded.topology.bodies.first().map_or(0, |b| b.tet_count))
}

fn row(organ: &Organ, tets: usize, threads: usize, r: &LatencyReport) -> OrganRow {
    let get = |key: &str| r.rows.iter().find(|row| row.key == key);
    let p = |key: &str, f: fn(&table::Row) -> f64| get(key).map_or(f64::NAN, f);
    OrganRow {
        name: organ.name.clone(),
        asked: organ.asked,
        tets,
        threads,
        period_ms: r.touched_periods_ms.iter().copied().reduce(f64::max),
        periods_ms: r.touched_periods_ms.clone(),
        real_time_factor: r.touched_real_time_factor_min,
        step_p50_us: p("touched_step", |r| r.p50_us),
        step_p99_us: p("touched_step", |r| r.p99_us),
        frame_interval_p50_us: p("touched_frame_interval", |r| r.p50_us),
        frame_interval_p99_us: p("touched_frame_interval", |r| r.p99_us),
        frame_age_contact_p99_us: p("frame_age_contact", |r| r.p99_us),
        device_to_tissue_p50_us: p("device_to_tissue", |r| r.p50_us),
        device_to_tissue_p99_us: p("device_to_tissue", |r| r.p99_us),
        tick_compute_p99_us: p("haptic_compute", |r| r.p99_us),
        frames_in_contact: get("touched_step").map_or(0, |r| r.count),
        held_force_1ms_n: None,
        held_force_error: None,
        device_port_energy_j: None,
        offline_contact_changes: None,
        live_held_force_n: None,
        live_held_force_error: None,
        live_device_port_energy_j: None,
        live_contact_changes: None,
    }
}

/// [`offline`] once per organ and period.
fn offline_at(
    cache: &mut Vec<(String, f64, Offline)>,
    organ: &Organ,
    period_ms: f64,
) -> Result<Offline> {
    if let Some(c) = cache.iter().find(|c| c.0 == organ.name && c.1 == period_ms) {
        return Ok(c.2);
    }
    eprintln!("  {} offline, light grip, {period_ms} ms …", organ.name);
    let o = offline(&organ.scene, period_ms * 1e-3)?;
    cache.push((organ.name.clone(), period_ms, o));
    Ok(o)
}

/// The scene's poke pressed by the simulated hand with the light grip, offline, the first
/// body's FEM stepped every `period` s (module docs).
fn offline(scene_path: &Path, period: f64) -> Result<Offline> {
    let mut scene = lop_config::load_scene(scene_path)
        .with_context(|| format!("loading scene {}", scene_path.display()))?;
    let script_path = scene.device.mock_script.clone().with_context(|| {
        format!(
            "{}: no [device] mock_script to press with",
            scene_path.display()
        )
    })?;
    let script = MockScript::load(&script_path)
        .with_context(|| format!("the poke {}", script_path.display()))?;
    let fem = scene
        .bodies
        .first_mut()
        .and_then(|b| b.fem.as_mut())
        .with_context(|| format!("{}: the first body has no FEM", scene_path.display()))?;
    fem.dt = period;
    let run = closed_loop::run(ClosedLoopOptions {
        scene,
        script,
        hand: Some(HandParameters::light_grip()),
        limits: MockDevice::omni_limits(),
        config: DaemonConfig::default(),
        seconds: HOLD_END_S + 0.1,
    })?;
    let ticks = &run.ticks;
    let held_n = mean_force(ticks, HOLD_END_S - HELD_WINDOW_S, HOLD_END_S);
    if held_n.is_nan() || held_n <= 0.0 {
        bail!(
            "{}: the simulated hand felt no force at the end of the hold (no contact?)",
            scene_path.display()
        );
    }
    Ok(Offline {
        held_n,
        // As `lop-bench haptics` judges it: the work the hand's grip did on the stylus never
        // below zero (the stylus's own damping and friction and a passive environment).
        generated_j: (-closed_loop::port_energy(ticks).device_min).max(0.0) + 0.0,
        contact_changes: contact_changes(ticks),
    })
}

/// The frame-interval target for an organ (module docs).
fn interval_target_us(row: &OrganRow) -> f64 {
    if row.asked.unwrap_or(row.tets) <= SMALL_ORGAN_TETS {
        INTERVAL_TARGET_SMALL_US
    } else {
        INTERVAL_TARGET_LARGE_US
    }
}

fn ms(us: f64) -> String {
    if us.is_finite() {
        format!("{:.2}", us * 1e-3)
    } else {
        "-".into()
    }
}

fn render(rows: &[OrganRow]) -> String {
    let headers = [
        ("organ", Align::Left),
        ("tets", Align::Right),
        ("threads", Align::Right),
        ("periods ms", Align::Left),
        ("RT factor min", Align::Right),
        ("step p50/p99 ms", Align::Right),
        ("frame interval p50/p99 ms", Align::Right),
        ("frame age contact p99 ms", Align::Right),
        ("device→tissue p50/p99 ms", Align::Right),
        ("tick p99 µs", Align::Right),
        ("offline held N (1 ms)", Align::Right),
        ("offline held vs 1 ms", Align::Right),
        ("offline port energy out µJ", Align::Right),
        ("offline contact changes", Align::Right),
        ("live held vs 1 ms", Align::Right),
        ("live port energy out µJ", Align::Right),
        ("live contact changes", Align::Right),
        ("targets", Align::Left),
    ];
    let cells: Vec<Vec<String>> = rows
        .iter()
        .map(|r| {
            let rt_ok = r.real_time_factor.is_some_and(|f| f >= RT_FACTOR_TARGET);
            let interval_ok = r.frame_interval_p99_us <= interval_target_us(r);
            let held_ok = |e: Option<f64>| e.is_some_and(|e| e.abs() <= HELD_FORCE_TARGET);
            let passive = |e: Option<f64>| e.is_some_and(|e| e <= ENERGY_TOLERANCE);
            let micro = |e: Option<f64>| e.map_or("-".into(), |e| format!("{:.3}", e * 1e6));
            let percent = |e: Option<f64>| e.map_or("-".into(), |e| format!("{:+.1} %", 100.0 * e));
            let count = |n: Option<usize>| n.map_or("-".into(), |n| n.to_string());
            vec![
                r.name.clone(),
                r.tets.to_string(),
                r.threads.to_string(),
                if r.periods_ms.is_empty() {
                    "-".into()
                } else {
                    r.periods_ms
                        .iter()
                        .map(|p| format!("{p}"))
                        .collect::<Vec<_>>()
                        .join(",")
                },
                r.real_time_factor.map_or("-".into(), |f| format!("{f:.2}")),
                format!("{}/{}", ms(r.step_p50_us), ms(r.step_p99_us)),
                format!(
                    "{}/{}",
                    ms(r.frame_interval_p50_us),
                    ms(r.frame_interval_p99_us)
                ),
                ms(r.frame_age_contact_p99_us),
                format!(
                    "{}/{}",
                    ms(r.device_to_tissue_p50_us),
                    ms(r.device_to_tissue_p99_us)
                ),
                format!("{:.1}", r.tick_compute_p99_us),
                r.held_force_1ms_n.map_or("-".into(), |f| format!("{f:.3}")),
                percent(r.held_force_error),
                micro(r.device_port_energy_j),
                count(r.offline_contact_changes),
                percent(r.live_held_force_error),
                micro(r.live_device_port_energy_j),
                count(r.live_contact_changes),
                [
                    ("RT", rt_ok),
                    ("interval", interval_ok),
                    ("held", held_ok(r.held_force_error)),
                    ("passive", passive(r.device_port_energy_j)),
                    ("live held", held_ok(r.live_held_force_error)),
                    ("live passive", passive(r.live_device_port_energy_j)),
                ]
                .iter()
                .map(|(k, ok)| format!("{k} {}", if *ok { "ok" } else { "MISS" }))
                .collect::<Vec<_>>()
                .join(" "),
            ]
        })
        .collect();
    let mut s = table::table(&headers, &cells);
    s += &table::note(
        &format!(
            "targets: the touched body's lowest real-time factor ≥ {RT_FACTOR_TARGET}; its \
             frame interval p99 ≤ {} ms up to {SMALL_ORGAN_TETS} tetrahedra asked, ≤ {} ms \
             beyond. Offline with the light grip: the held force at the period taken live \
             within {} % of the 1 ms run's, and no energy generated at the device port (the \
             grip's work on the stylus never below −{} µJ, rounding). Live with the same hand \
             through `lopd run`: the same two against the offline 1 ms run.",
            INTERVAL_TARGET_SMALL_US * 1e-3,
            INTERVAL_TARGET_LARGE_US * 1e-3,
            HELD_FORCE_TARGET * 100.0,
            ENERGY_TOLERANCE * 1e6
        ),
        96,
    );
    s
}

/// Frame interval p99 and step p50 against the tetrahedra, one line per surface and thread
/// count (the shipped scene a point of its own).
fn plot_rows(path: &Path, rows: &[OrganRow]) -> Result<()> {
    let mut keys: Vec<(String, usize)> = Vec::new();
    for r in rows {
        let surface = r.name.split('-').next().unwrap_or(&r.name).to_string();
        if !keys.contains(&(surface.clone(), r.threads)) {
            keys.push((surface, r.threads));
        }
    }
    let series = |f: fn(&OrganRow) -> f64| -> Vec<Series> {
        keys.iter()
            .enumerate()
            .map(|(k, (surface, threads))| {
                let mut points: Vec<(f64, f64)> = rows
                    .iter()
                    .filter(|r| {
                        r.threads == *threads
                            && r.name.split('-').next().unwrap_or(&r.name) == surface
                    })
                    .map(|r| (r.tets as f64, f(r)))
                    .filter(|p| p.1.is_finite())
                    .collect();
                points.sort_by(|a, b| a.0.total_cmp(&b.0));
                Series {
                    label: format!("{surface}, {threads} thread(s)"),
                    points,
                    color: k,
                }
            })
            .collect()
    };
    let x_hi = rows.iter().map(|r| r.tets as f64).fold(1.0, f64::max) * 1.05;
    let panel = |title: &str, f: fn(&OrganRow) -> f64| {
        let s = series(f);
        let y_hi = s
            .iter()
            .flat_map(|s| s.points.iter().map(|p| p.1))
            .fold(1.0, f64::max)
            * 1.4;
        Panel {
            title: title.into(),
            x_desc: "tetrahedra".into(),
            y_desc: "ms".into(),
            x_range: (0.0, x_hi),
            y_range: (0.0, y_hi),
            series: s,
        }
    };
    let panels = [
        panel("touched frame interval p99", |r| {
            r.frame_interval_p99_us * 1e-3
        }),
        panel("touched step p50", |r| r.step_p50_us * 1e-3),
    ];
    plot::line_grid(
        path,
        "lop-bench organs: the touched organ live",
        &panels,
        2,
        (520, 380),
    )
}
