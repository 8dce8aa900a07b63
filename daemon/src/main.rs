//! `lopd`: command-line glue over the `lop_daemon` library. Errors end in `anyhow` here and map to
//! exit codes: 0 success, 1 runtime failure, 2 bad input (arguments, config, scene, mesh).

use std::io::IsTerminal;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use anyhow::{bail, Context, Result};
use clap::{Args, Parser, Subcommand};
use lop_config::{
    load_daemon_config, load_scene, resolve_scene, resolve_script, DaemonConfig, Scene,
};
use lop_daemon::haptic_process::{self, Device, HapticProcess};
use lop_daemon::{deform, signals, supervisor};
use lop_drivers::forcedimension::ForceDimensionDevice;
use lop_drivers::hand::HandDevice;
use lop_drivers::mock::{MockDevice, MockScript};
use lop_drivers::openhaptics::OpenHapticsDevice;
use lop_drivers::replay::ReplayDevice;
use lop_drivers::DeviceSpec;
use lop_ipc::ServiceNames;

mod remote_cli;

#[derive(Parser)]
#[command(
    name = "lopd",
    version,
    about = "lop: real-time haptics for surgical soft-tissue simulation"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Start and supervise the haptic and deformation processes (the main job).
    Run(RunArgs),
    /// The 1 kHz haptic process alone (normally started by `lopd run`).
    Haptic(HapticArgs),
    /// The deformation process alone (normally started by `lopd run`).
    Deform(CommonArgs),
    /// Run a scene offline (no device, no IPC) and write timings, final positions and a summary.
    Simulate(SimulateArgs),
    /// Mesh tools.
    Mesh {
        #[command(subcommand)]
        command: MeshCommand,
    },
    /// Scene tools.
    Scene {
        #[command(subcommand)]
        command: SceneCommand,
    },
    /// List the shipped scenes and mock scripts.
    Scenes,
    /// Check this machine for a rig (real-time limits, CPUs, device library and device,
    /// shared memory, stale IPC) and print a fix for each problem. Exit code 1 on a FAIL.
    Doctor(DoctorArgs),
    /// Runtime control of a running daemon: get/set body parameters, pin/release, reset, pause,
    /// resume (`lopd ctl get liver`, `lopd ctl set liver fem.young 300`).
    Ctl(CtlArgs),
    /// The web viewer alone (normally started by `lopd run --view`): runs `lop-view`.
    View(ViewArgs),
    /// The scene on other hosts over Zenoh (iceoryx2's link tunnel): `attach` on the far host;
    /// `serve` is what `lopd run --remote` starts on the rig.
    Remote {
        #[command(subcommand)]
        command: remote_cli::RemoteCommand,
    },
}

#[derive(Args, Clone)]
struct DoctorArgs {
    /// Daemon configuration (default: /etc/lop/lopd.toml if it exists).
    #[arg(long)]
    config: Option<PathBuf>,
    /// The rig's device: openhaptics[:NAME] | dhd[:ID] | mock[:SCRIPT] | hand[:SCRIPT] |
    /// replay:PATH; repeatable, one per tool of --scene in order, as `lopd run` takes them.
    /// Default: openhaptics.
    #[arg(long, value_name = "DEVICE")]
    device: Vec<String>,
    /// The scene whose tools the devices drive (names them in the findings; checks there are
    /// not more devices than tools).
    #[arg(long)]
    scene: Option<String>,
    /// Service prefix to look for stale services under.
    #[arg(long, default_value = lop_ipc::SERVICE_PREFIX_DEFAULT)]
    prefix: String,
    /// Remove the resources of dead iceoryx2 nodes.
    #[arg(long)]
    clean: bool,
    /// Print the findings as JSON.
    #[arg(long)]
    json: bool,
}

#[derive(Args, Clone)]
struct CtlArgs {
    /// Service prefix of the daemon to control.
    #[arg(long, default_value = lop_ipc::SERVICE_PREFIX_DEFAULT)]
    prefix: String,
    /// get BODY | set BODY KEY VALUE | pin BODY gc|msd|fem | release BODY | reset | pause | resume
    #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
    words: Vec<String>,
}

#[derive(Args, Clone)]
struct ViewArgs {
    /// Service prefix of the daemon to show.
    #[arg(long, default_value = lop_ipc::SERVICE_PREFIX_DEFAULT)]
    prefix: String,
    /// Address and port the web viewer listens on.
    #[arg(long, default_value = lop_daemon::supervisor::VIEW_BIND_DEFAULT)]
    bind: String,
    /// Another origin allowed to open the viewer's WebSocket; repeatable. (The control token
    /// comes from LOP_VIEW_TOKEN.)
    #[arg(long = "allow-origin", value_name = "URL")]
    allow_origin: Vec<String>,
}

#[derive(Subcommand)]
enum MeshCommand {
    /// Print counts, bounds, volume and element quality of meshes, or the error that stops them
    /// from loading.
    Info {
        /// TetGen base path (or .node/.ele), Gmsh .msh, or legacy VTK .vtk.
        #[arg(required = true)]
        paths: Vec<PathBuf>,
        /// Also show which nodes a fixed-node selector picks, in the mesh file's coordinates:
        /// a `[[body.fix]]` table inline, e.g.
        /// 'kind = "sphere", center = [0, 0, 0], radius = 0.01'.
        #[arg(long, value_name = "SELECTOR")]
        select: Option<String>,
    },
    /// Fill a triangle surface (STL, OBJ, PLY, VTK) with about N tetrahedra (--tets) of good
    /// shape, after checking it (closed, manifold, consistently wound, no degenerate
    /// triangles, no self-intersections; --repair meshes a defective one anyway), and write
    /// PREFIX.node/.ele/.face/.bnd in metres.
    Tetrahedralize(TetrahedralizeArgs),
}

#[derive(Args, Clone)]
struct TetrahedralizeArgs {
    /// The surface: STL (ASCII or binary), OBJ, PLY, VTK legacy POLYDATA or .vtp.
    surface: PathBuf,
    /// Output base path: writes PREFIX.node, PREFIX.ele, PREFIX.face, PREFIX.bnd.
    #[arg(long, value_name = "PREFIX")]
    out: PathBuf,
    /// The surface's length unit; the output is always in metres.
    #[arg(long, value_enum, default_value = "m")]
    units: lop_daemon::tetrahedralize::Units,
    /// The mesher: gmsh (default), ftetwild (PyPI pytetwild) or tetgen (the default when a
    /// TetGen switch, --quality, --max-volume or --keep-surface, is given).
    #[arg(long, value_enum)]
    mesher: Option<lop_daemon::mesher::Mesher>,
    /// About this many tetrahedra (±20 %; the default for gmsh and ftetwild is 2000).
    #[arg(long, value_name = "N", conflicts_with_all = ["edge", "max_volume"])]
    tets: Option<usize>,
    /// Target edge length instead, in m or with a unit: 0.008, 8mm, 0.8cm (TetGen: -a of a
    /// regular tetrahedron, L³/(6√2)).
    #[arg(long, value_name = "L", value_parser = lop_daemon::tetrahedralize::parse_length)]
    edge: Option<f64>,
    /// Largest tetrahedron volume (TetGen -a), in m³ or with a unit: 5e-7, 0.5cm3, 500mm3.
    #[arg(long, value_name = "VOLUME", value_parser = lop_daemon::tetrahedralize::parse_volume, conflicts_with = "edge")]
    max_volume: Option<f64>,
    /// Radius-edge ratio bound (TetGen -q, default 1.4), > 1: lower is better-shaped and finer.
    #[arg(long)]
    quality: Option<f64>,
    /// Close holes bounded by at most this many edges before the check (a triangle or a fan
    /// from the hole's centroid).
    #[arg(long, value_name = "MAX_EDGES")]
    close_holes: Option<usize>,
    /// Keep the surface triangles exactly as given (TetGen -Y: no points added on it).
    #[arg(long)]
    keep_surface: bool,
    /// Mesh a surface that fails the checks (crossing triangles, holes, gaps) with fTetWild
    /// inside an envelope of 1e-3 of its size, and report what was repaired.
    #[arg(long)]
    repair: bool,
}

#[derive(Subcommand)]
enum SceneCommand {
    /// Write a scene for your own tetrahedral meshes: bodies placed side by side in metres,
    /// tissue parameters from the library, a posterior patch fixed, a mock poke at the first
    /// body; then load it as `lopd run --scene` does.
    New(SceneNewArgs),
}

#[derive(Args, Clone)]
struct SceneNewArgs {
    /// Scene name.
    name: String,
    /// A tetrahedral mesh (TetGen base path or .node, Gmsh .msh, VTK .vtk); one body each.
    #[arg(long, required = true, num_args = 1..)]
    mesh: Vec<PathBuf>,
    /// Tissue from the library (liver, spleen, stomach, pancreas, kidney): once for every
    /// body, or once per mesh in order. Default: liver.
    #[arg(long)]
    tissue: Vec<String>,
    /// The meshes' length unit (meshes from `lopd mesh tetrahedralize` are in metres).
    #[arg(long, value_enum, default_value = "m")]
    units: lop_daemon::tetrahedralize::Units,
    /// The scene file to write (default NAME.toml); the poke script goes beside it as
    /// NAME-poke.toml.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Overwrite existing files.
    #[arg(long)]
    force: bool,
    /// Draw the bodies by their meshes' boundaries, not by the surfaces `lopd mesh
    /// tetrahedralize` kept beside the meshes (MESH.render.obj).
    #[arg(long)]
    no_render_surface: bool,
}

#[derive(Args, Clone)]
struct CommonArgs {
    /// Scene name (see `lopd scenes`) or path to a scene TOML. The default, `abdomen`, has
    /// soft-tissue parameters from the literature; `organs` is the thesis' reproduction.
    #[arg(long, default_value = "abdomen")]
    scene: String,
    /// Service prefix, so several rigs or tests can share a machine.
    #[arg(long, default_value = lop_ipc::SERVICE_PREFIX_DEFAULT)]
    prefix: String,
    /// Daemon configuration TOML.
    #[arg(long)]
    config: Option<PathBuf>,
    /// Stop after this many seconds.
    #[arg(long)]
    duration: Option<f64>,
}

#[derive(Args, Clone)]
struct HapticArgs {
    #[command(flatten)]
    common: CommonArgs,
    /// mock[:SCRIPT] | hand[:SCRIPT] | replay:PATH | openhaptics[:NAME] | dhd[:ID]; repeatable,
    /// one per tool in the scene's order (a tool without one gets `mock`, playing the tool's
    /// script). Default: `mock`.
    #[arg(long, value_name = "DEVICE")]
    device: Vec<String>,
    /// Write every force the device received as CSV at exit (mock and hand devices);
    /// repeatable, one file per device in the order of --device.
    #[arg(long, value_name = "PATH")]
    force_log: Vec<PathBuf>,
    /// Record the device stream (poses, buttons, ticks, times) for `--device replay:PATH`.
    /// An existing file is never overwritten: the recording takes the first free `NAME-N.EXT`.
    #[arg(long)]
    record: Option<PathBuf>,
}

#[derive(Args, Clone)]
struct SimulateArgs {
    /// Scene name or path (the same default as `lopd run`, so a session recorded there
    /// replays on its scene).
    #[arg(long, default_value = "abdomen")]
    scene: String,
    /// Steps of every body (the cap with --until-converged).
    #[arg(long, default_value_t = 1000)]
    steps: u64,
    /// Stop each body once it has settled (max nodal speed under 1e-4 m/s for 20 steps).
    #[arg(long)]
    until_converged: bool,
    /// Solve the static equilibrium (K u = f) of the FEM bodies instead of stepping.
    #[arg(long = "static")]
    static_solve: bool,
    /// Mock script (name or path) that moves a tool on simulated time; repeatable, one per
    /// tool of the scene in order (tools left without one have no device).
    #[arg(long, conflicts_with = "device")]
    script: Vec<String>,
    /// A tool's trajectory from a device stream instead; repeatable, one per tool in order,
    /// as `lopd run` takes them. `mock[:SCRIPT]` (as --script; without a script the tool's
    /// own from the scene); or, as the only one, `replay:PATH` (a session recording, by tick
    /// index) or `hand[:SCRIPT]`: the simulated hand holds the stylus and the haptic loop and
    /// the deformation run closed-loop for one pass of the script (`hand.csv`: every tick's
    /// force, stylus and the energy at the device port; `hand_summary.json`).
    #[arg(long)]
    device: Vec<String>,
    /// Output directory.
    #[arg(long)]
    out: PathBuf,
}

#[derive(Args, Clone)]
struct RunArgs {
    #[command(flatten)]
    haptic: HapticArgs,
    /// No live status line.
    #[arg(long)]
    quiet: bool,
    /// Also start the web viewer (`lop-view`) and print its URL.
    #[arg(long)]
    view: bool,
    /// Where the web viewer listens (with --view).
    #[arg(long, default_value = lop_daemon::supervisor::VIEW_BIND_DEFAULT)]
    view_bind: String,
    /// The viewer's control token (16+ characters of A-Z a-z 0-9 . _ ~ -) instead of a
    /// generated one; also read from LOP_VIEW_TOKEN. Required for control on a non-loopback
    /// --view-bind.
    #[arg(long)]
    view_token: Option<String>,
    /// Another origin allowed to open the viewer's WebSocket (e.g. http://rig.local:8733);
    /// repeatable.
    #[arg(long = "view-allow-origin", value_name = "URL")]
    view_allow_origin: Vec<String>,
    /// Carry the scene to other hosts over Zenoh (`[remote]` of the daemon config; far hosts
    /// run `lopd remote attach --connect tcp/RIG:7447`). Read-only: nothing a far host sends
    /// reaches the rig's services.
    #[arg(long)]
    remote: bool,
    /// With --remote: a Zenoh endpoint to listen on instead of `[remote] listen`; repeatable.
    #[arg(long, value_name = "ENDPOINT", requires = "remote")]
    remote_listen: Vec<String>,
}

/// Bad input: exit code 2.
#[derive(Debug)]
struct BadInput(anyhow::Error);

impl std::fmt::Display for BadInput {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{:#}", self.0)
    }
}
impl std::error::Error for BadInput {}

fn bad<T, E: Into<anyhow::Error>>(r: std::result::Result<T, E>) -> Result<T> {
    r.map_err(|e| anyhow::Error::new(BadInput(e.into())))
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let logs = tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_env("LOP_LOG")
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info")),
        )
        .with_writer(std::io::stderr)
        .with_ansi(std::io::stderr().is_terminal())
        .with_target(false);
    // Under systemd stderr goes to the journal, which stamps every line itself.
    if std::env::var_os("JOURNAL_STREAM").is_some() {
        logs.without_time().init();
    } else {
        logs.init();
    }
    signals::install();
    let result = match cli.command {
        Command::Run(a) => cmd_run(a),
        Command::Haptic(a) => cmd_haptic(a).map(|()| 0),
        Command::Deform(a) => cmd_deform(a).map(|()| 0),
        Command::Simulate(a) => cmd_simulate(a).map(|()| 0),
        Command::Mesh {
            command: MeshCommand::Info { paths, select },
        } => cmd_mesh_info(&paths, select.as_deref()),
        Command::Mesh {
            command: MeshCommand::Tetrahedralize(a),
        } => cmd_tetrahedralize(a),
        Command::Scene {
            command: SceneCommand::New(a),
        } => cmd_scene_new(a),
        Command::Scenes => cmd_scenes().map(|()| 0),
        Command::Doctor(a) => cmd_doctor(a),
        Command::Ctl(a) => cmd_ctl(a),
        Command::View(a) => cmd_view(a),
        Command::Remote { command } => remote_cli::run(command),
    };
    match result {
        Ok(code) => ExitCode::from(code as u8),
        Err(e) => {
            eprintln!("lopd: error: {e:#}");
            if e.downcast_ref::<BadInput>().is_some() {
                ExitCode::from(2)
            } else {
                ExitCode::from(1)
            }
        }
    }
}

fn load_common(a: &CommonArgs) -> Result<(Scene, DaemonConfig, ServiceNames, Option<Duration>)> {
    let path = bad(resolve_scene(&a.scene))?;
    let scene = bad(load_scene(&path))?;
    let config = match &a.config {
        Some(p) => bad(load_daemon_config(p))?,
        None => DaemonConfig::default(),
    };
    let names = bad(ServiceNames::new(&a.prefix))?;
    let duration = match a.duration {
        Some(s) if s.is_finite() && s > 0.0 => Some(Duration::from_secs_f64(s)),
        Some(s) => bad(Err(anyhow::anyhow!(
            "--duration {s}: must be a positive number of seconds"
        )))?,
        None => None,
    };
    Ok((scene, config, names, duration))
}

/// The device of every tool of `scene`: the `--device` values in order, then `mock` for the
/// tools left (each playing its tool's script). More devices than tools is bad input.
fn tool_devices(given: &[String], scene: &Scene) -> Result<Vec<(DeviceSpec, String)>> {
    if given.len() > scene.tools.len() {
        bad(Err(anyhow::anyhow!(
            "{} --device options for the {} tool(s) of scene {:?} ({}): give at most one per tool",
            given.len(),
            scene.tools.len(),
            scene.name,
            scene.path.display()
        )))?;
    }
    (0..scene.tools.len())
        .map(|t| {
            let text = given.get(t).map_or("mock", String::as_str);
            let spec: DeviceSpec = bad(text
                .parse()
                .map_err(|e| anyhow::anyhow!("--device {text:?}: {e}")))?;
            Ok((spec, text.to_string()))
        })
        .collect()
}

/// The script a scripted device (`mock`, `hand`) driving tool `tool` plays: the one named,
/// else the tool's default in the scene, else `None` (hold still at the device origin).
fn device_script(
    script: Option<&str>,
    scene: &Scene,
    tool: usize,
) -> Result<Option<(MockScript, PathBuf)>> {
    let path = match script {
        Some(s) => bad(resolve_script(s))?,
        None => match scene.tool_script(tool) {
            Some(p) => p.to_path_buf(),
            None => return Ok(None),
        },
    };
    let script = bad(MockScript::load(&path))?;
    Ok(Some((script, path)))
}

/// Opens the device `spec` for tool `tool` of `scene`.
fn open_device(
    spec: &DeviceSpec,
    scene: &Scene,
    tool: usize,
    config: &DaemonConfig,
) -> Result<Device> {
    match spec {
        DeviceSpec::Mock { script } => {
            let script = match device_script(script.as_deref(), scene, tool)? {
                Some((script, path)) => {
                    tracing::info!(
                        "mock device of tool {:?} playing {}",
                        scene.tools[tool].name,
                        path.display()
                    );
                    script
                }
                None => MockScript::stationary([0.0, 0.0, 0.0]),
            };
            Ok(Device::Mock(MockDevice::new(
                script,
                MockDevice::omni_limits(),
            )))
        }
        DeviceSpec::Hand { script } => {
            let script = match device_script(script.as_deref(), scene, tool)? {
                Some((script, path)) => {
                    tracing::info!(
                        "simulated hand following {}{}",
                        path.display(),
                        if script.hand().is_some() {
                            " (with its [hand] parameters)"
                        } else {
                            ""
                        }
                    );
                    script
                }
                None => MockScript::stationary([0.0, 0.0, 0.0]),
            };
            Ok(Device::Hand(Box::new(HandDevice::new(
                script,
                MockDevice::omni_limits(),
            ))))
        }
        DeviceSpec::Replay { path } => {
            let device = bad(ReplayDevice::open(path)
                .with_context(|| format!("--device replay:{}", path.display())))?;
            let r = device.recording();
            tracing::info!(
                "replaying {} ({} samples, {:.1} s at {} Hz, scene {})",
                path.display(),
                r.records().len(),
                r.duration(),
                r.header().rate_hz,
                r.header().get("scene").unwrap_or("?")
            );
            Ok(Device::Replay(device))
        }
        DeviceSpec::OpenHaptics { name } => {
            let device = bad(OpenHapticsDevice::open(
                name.as_deref(),
                config.device.hd_library.as_deref(),
            ))?;
            Ok(Device::OpenHaptics(Box::new(device)))
        }
        DeviceSpec::ForceDimension { id } => {
            let device = bad(ForceDimensionDevice::open(
                *id,
                config.device.dhd_library.as_deref(),
            ))?;
            Ok(Device::ForceDimension(Box::new(device)))
        }
    }
}

fn cmd_run(a: RunArgs) -> Result<i32> {
    // Validate everything up front so a typo fails here, not in a child.
    let (scene, config, _names, duration) = load_common(&a.haptic.common)?;
    // The meshes read and every fixed-node selector picks nodes (cheap: no models built).
    bad(lop_scene::place_bodies(&scene))?;
    // Every device opened (not started) and checked to run together, here rather than in
    // the haptic child the supervisor would restart on the same error.
    let mut devices = Vec::new();
    for (t, (spec, text)) in tool_devices(&a.haptic.device, &scene)?
        .into_iter()
        .enumerate()
    {
        devices.push((open_device(&spec, &scene, t, &config)?, text));
    }
    bad(haptic_process::check_devices(
        &scene,
        &devices,
        a.haptic.record.is_some(),
        a.haptic.force_log.len(),
    ))?;
    drop(devices);
    let view_token = a.view_token.clone().or_else(|| {
        std::env::var(supervisor::VIEW_TOKEN_ENV)
            .ok()
            .filter(|t| !t.is_empty())
    });
    if let Some(t) = &view_token {
        bad(supervisor::check_view_token(t).map_err(|e| anyhow::anyhow!("--view-token: {e}")))?;
    }
    if let Some(o) = a
        .view_allow_origin
        .iter()
        .find(|o| !(o.starts_with("http://") || o.starts_with("https://")))
    {
        bad(Err::<(), _>(anyhow::anyhow!(
            "--view-allow-origin {o:?}: not an http:// or https:// origin"
        )))?;
    }
    // The tunnel is checked here; when it cannot run, the rig runs without it.
    let remote = if a.remote || config.remote.enabled {
        remote_cli::rig_child(
            &a.haptic.common.prefix,
            a.haptic.common.config.as_deref(),
            &config,
            &a.remote_listen,
        )?
    } else {
        None
    };
    supervisor::run(supervisor::RunOptions {
        remote,
        scene: scene.path.clone(),
        devices: a.haptic.device.clone(),
        duration,
        prefix: a.haptic.common.prefix.clone(),
        config: a.haptic.common.config.clone(),
        force_log: a.haptic.force_log.clone(),
        record: a.haptic.record.clone(),
        status_interval: Duration::from_millis(config.status_interval_ms),
        status: !a.quiet,
        view: a.view.then(|| a.view_bind.clone()),
        view_token,
        view_allow_origins: a.view_allow_origin.clone(),
    })
}

fn cmd_haptic(a: HapticArgs) -> Result<()> {
    let (scene, config, names, duration) = load_common(&a.common)?;
    let mut devices = Vec::new();
    for (t, (spec, text)) in tool_devices(&a.device, &scene)?.into_iter().enumerate() {
        devices.push((open_device(&spec, &scene, t, &config)?, text));
    }
    HapticProcess::builder(scene, config, names, devices)
        .duration(duration)
        .record(a.record)
        .force_log(a.force_log)
        .run()
}

fn cmd_deform(a: CommonArgs) -> Result<()> {
    let (scene, config, names, duration) = load_common(&a)?;
    deform::run(deform::DeformOptions {
        scene,
        names,
        config,
        duration,
    })
}

fn cmd_simulate(a: SimulateArgs) -> Result<()> {
    let path = bad(resolve_scene(&a.scene))?;
    let scene = bad(load_scene(&path))?;
    let mut scripts = (a.script.iter())
        .map(|s| bad(resolve_script(s)))
        .collect::<Result<Vec<_>>>()?;
    let mut replay = None;
    if a.script.len().max(a.device.len()) > scene.tools.len() {
        bad(Err(anyhow::anyhow!(
            "{} tool trajectories (--script or --device) for the {} tool(s) of scene {:?} \
             ({}): give at most one per tool",
            a.script.len().max(a.device.len()),
            scene.tools.len(),
            scene.name,
            path.display()
        )))?;
    }
    for (tool, d) in a.device.iter().enumerate() {
        let spec = bad(d.parse::<DeviceSpec>())?;
        match spec {
            DeviceSpec::Mock { script: name } => {
                let Some((_, path)) = device_script(name.as_deref(), &scene, tool)? else {
                    bad(Err(anyhow::anyhow!(
                        "--device {d}: tool {tool} of the scene has no script of its own; \
                         name one (mock:SCRIPT)"
                    )))?
                };
                scripts.push(path);
            }
            DeviceSpec::Hand { .. } | DeviceSpec::Replay { .. } if a.device.len() > 1 => {
                bad(Err(anyhow::anyhow!(
                    "--device {d}: a simulated hand or a replay drives the one tool of an \
                     offline run; give it as the only --device"
                )))?
            }
            DeviceSpec::Hand { script: name } => {
                let Some((script, path)) = device_script(name.as_deref(), &scene, 0)? else {
                    bad(Err(anyhow::anyhow!(
                        "--device hand: the scene has no default script; name one (hand:SCRIPT)"
                    )))?
                };
                tracing::info!("simulated hand following {}", path.display());
                lop_scene::closed_loop::simulate(scene, script, &a.out)?;
                return Ok(());
            }
            DeviceSpec::Replay { path } => {
                // Validate here so a bad recording is bad input (exit 2), named with its byte.
                bad(lop_drivers::replay::Recording::load(&path))?;
                replay = Some(path);
            }
            other => bad(Err(anyhow::anyhow!(
                "--device {other}: an offline run takes its tools from `mock[:SCRIPT]`, \
                 `replay:PATH` or `hand[:SCRIPT]`"
            )))?,
        }
    }
    if a.steps == 0 && !a.static_solve {
        bad(Err(anyhow::anyhow!("--steps 0: nothing to simulate")))?;
    }
    lop_daemon::simulate::run(lop_daemon::simulate::SimulateOptions {
        scene,
        steps: a.steps,
        until_converged: a.until_converged,
        static_solve: a.static_solve,
        scripts,
        replay,
        out: a.out,
    })?;
    Ok(())
}

fn cmd_mesh_info(paths: &[PathBuf], select: Option<&str>) -> Result<i32> {
    let selector = match select {
        Some(text) => Some(bad(lop_config::parse_selector(text))?),
        None => None,
    };
    let mut failed = 0;
    for p in paths {
        match lop_sim::mesh::read_mesh(p) {
            Ok(mesh) => {
                println!("{}\n{}", p.display(), mesh.info());
                if let Some(s) = &selector {
                    println!("{}", selection_summary(&mesh, s));
                }
            }
            Err(e) => {
                eprintln!("{}: error: {e}", p.display());
                failed += 1;
            }
        }
    }
    Ok(if failed > 0 { 2 } else { 0 })
}

/// Count, bounds and first indices of the nodes a selector picks, in the mesh's coordinates.
fn selection_summary(mesh: &lop_sim::mesh::TetMesh, s: &lop_sim::mesh::NodeSelector) -> String {
    const SHOWN: usize = 20;
    let picked = s.select(&mesh.nodes, &mesh.surface);
    if picked.is_empty() {
        return "selected:          no node (as [[body.fix]] in a scene, this is an error)"
            .to_owned();
    }
    let points: Vec<[f64; 3]> = picked.iter().map(|&i| mesh.nodes[i as usize]).collect();
    let (lo, hi) = lop_sim::mesh::bounds(&points);
    let surface = mesh.surface_nodes();
    let on_surface = picked
        .iter()
        .filter(|i| surface.binary_search(i).is_ok())
        .count();
    let first: Vec<String> = picked.iter().take(SHOWN).map(u32::to_string).collect();
    format!(
        "selected:          {} nodes ({on_surface} on the surface)\n\
         selected bounds:   [{:.6}, {:.6}, {:.6}] .. [{:.6}, {:.6}, {:.6}] (mesh coordinates)\n\
         selected nodes:    {}{} (0-based)",
        picked.len(),
        lo[0],
        lo[1],
        lo[2],
        hi[0],
        hi[1],
        hi[2],
        first.join(" "),
        if picked.len() > SHOWN { " ..." } else { "" }
    )
}

fn cmd_tetrahedralize(a: TetrahedralizeArgs) -> Result<i32> {
    use lop_daemon::tetrahedralize::{run, Size, TetrahedralizeOptions};
    let size = match (a.tets, a.edge, a.max_volume) {
        (Some(n), _, _) => Size::Tets(n),
        (_, Some(l), _) => Size::Edge(l),
        (_, _, Some(v)) => Size::MaxVolume(v),
        _ => Size::Auto,
    };
    let opts = TetrahedralizeOptions {
        surface: a.surface,
        out: a.out,
        units: a.units,
        mesher: a.mesher,
        size,
        quality: a.quality,
        close_holes: a.close_holes,
        keep_surface: a.keep_surface,
        repair: a.repair,
    };
    match run(&opts) {
        Ok(done) => {
            println!("{}", done.summary(&opts));
            Ok(0)
        }
        Err(e) if e.is_bad_input() => bad(Err(e)),
        Err(e) => Err(e.into()),
    }
}

fn cmd_scene_new(a: SceneNewArgs) -> Result<i32> {
    use lop_daemon::scene_new::{run, SceneNewInputError, SceneNewOptions};
    let out = a
        .out
        .unwrap_or_else(|| PathBuf::from(format!("{}.toml", a.name)));
    let opts = SceneNewOptions {
        name: a.name,
        meshes: a.mesh,
        tissues: a.tissue,
        units: a.units,
        out,
        force: a.force,
        render_surface: !a.no_render_surface,
    };
    match run(&opts) {
        Ok(done) => {
            println!(
                "wrote {} and {}",
                done.scene.display(),
                done.script.display()
            );
            for (name, tissue, nodes, fixed) in &done.bodies {
                println!("  {name:<16} {tissue:<9} {nodes} nodes, {fixed} fixed");
            }
            println!(
                "run it: lopd run --scene {} --device mock",
                done.scene.display()
            );
            Ok(0)
        }
        Err(e) if e.downcast_ref::<SceneNewInputError>().is_some() => bad(Err(e)),
        Err(e) => Err(e),
    }
}

fn cmd_scenes() -> Result<()> {
    // Names in a column as wide as the longest.
    let print = |list: Vec<(String, std::path::PathBuf)>| {
        let w = list
            .iter()
            .map(|(n, _)| n.chars().count())
            .max()
            .unwrap_or(0);
        for (name, path) in list {
            println!("  {name:<w$} {}", path.display());
        }
    };
    println!("scenes:");
    print(lop_config::list_scenes());
    println!("mock scripts (--device mock:NAME):");
    print(lop_config::list_scripts());
    Ok(())
}

fn cmd_doctor(a: DoctorArgs) -> Result<i32> {
    let given = if a.device.is_empty() {
        vec!["openhaptics".to_string()]
    } else {
        a.device.clone()
    };
    let devices = given
        .iter()
        .map(|d| {
            d.parse::<DeviceSpec>()
                .map_err(|e| anyhow::anyhow!("--device {d:?}: {e}"))
        })
        .collect::<Result<Vec<_>>>();
    let devices = bad(devices)?;
    let tools: Vec<String> = match &a.scene {
        Some(s) => {
            let scene = bad(load_scene(&bad(resolve_scene(s))?))?;
            if devices.len() > scene.tools.len() {
                bad(Err(anyhow::anyhow!(
                    "{} --device options for the {} tool(s) of scene {:?}: give at most one per tool",
                    devices.len(),
                    scene.tools.len(),
                    scene.name
                )))?;
            }
            scene.tools.iter().map(|t| t.name.clone()).collect()
        }
        None => (1..=devices.len()).map(|k| format!("tool{k}")).collect(),
    };
    bad(ServiceNames::new(&a.prefix))?;
    let findings = lop_daemon::doctor::run(&lop_daemon::doctor::DoctorOptions {
        config: a.config,
        devices,
        tools,
        prefix: a.prefix,
        clean: a.clean,
    });
    let failed = lop_daemon::doctor::print(&findings, a.json);
    Ok(if failed { 1 } else { 0 })
}

fn cmd_ctl(a: CtlArgs) -> Result<i32> {
    let names = bad(ServiceNames::new(&a.prefix))?;
    let cmd = bad(lop_daemon::ctl::CtlCommand::parse(&a.words))?;
    lop_daemon::ctl::run(&names, &cmd)
}

/// Replaces this process with the `lop-view` binary next to `lopd`, so the supervisor can start
/// the viewer as one of its children like the other two.
fn cmd_view(a: ViewArgs) -> Result<i32> {
    use std::os::unix::process::CommandExt;
    bad(ServiceNames::new(&a.prefix))?;
    let exe = std::env::current_exe().context("locating the lopd binary")?;
    let view = exe.with_file_name("lop-view");
    if !view.exists() {
        bail!(
            "{} not found: lop-view is built with the workspace (`cargo build --workspace`)",
            view.display()
        );
    }
    let mut cmd = std::process::Command::new(&view);
    cmd.args(["--prefix", &a.prefix, "--bind", &a.bind]);
    for o in &a.allow_origin {
        cmd.args(["--allow-origin", o]);
    }
    let err = cmd.exec();
    Err(anyhow::Error::new(err).context(format!("starting {}", view.display())))
}
