//! `lop-bench soak`: the whole pipeline for minutes or hours under randomised faults, and the
//! safety invariants checked all along.
//!
//! The bench starts `lopd run` on the scene (default `abdomen`) with the mock device playing the
//! scene's four shipped scripts in a loop (`script.rs`), the web viewer (`--view`), a recording
//! of the device stream (`--record`) and the device's force record (`--force-log`), all under a
//! private service prefix. With `--devices 2` the scene gets a second tool (a copy of the
//! first whose device maps 20 mm along −x, `crate::scenes`), each tool its own mock device
//! (the second plays the same loop from its second script, so both tools are in the tissue
//! at once for much of it), its own broken samples and its own force record; nothing is
//! recorded (`lopd run --record` takes one device: the recording check says N/A). From the
//! first frame on it injects, on a plan drawn from `--seed` (`schedule.rs`):
//! - the deformation process killed (SIGKILL; the supervisor restarts it) or stopped (SIGSTOP
//!   for 0.3–3 s, then SIGCONT), which makes the frames go stale;
//! - the haptic process killed (the supervisor restarts it) or stopped (0.2–1.5 s), wherever
//!   the styluses are then (in the tissue too);
//! - NaN and out-of-workspace device samples, 1–40 ticks long, on every device at its own
//!   ticks (each script's `[[fault]]` windows with `sample =`);
//! - control requests hammered through `PREFIX/control`, and bursts of `lopd ctl`
//!   (`control.rs`);
//! - viewers connecting and disconnecting, with the printed token, without, with a wrong one,
//!   and from another origin (`viewers.rs`).
//!
//! and checks, printing PASS/FAIL (N/A for a check the run cannot make, with the reason) with
//! the figures, per tool where they are a tool's, writing `soak.json` and `soak.txt`, and
//! exiting non-zero on any FAIL. The tool stream is audited per tool (`forces.rs`: states
//! grouped by their tool's index), and every check on it holds for every tool:
//! - every force published (`PREFIX/tool`, every tick) and every force each device received
//!   (`--force-log`: the mock's ring of the last two minutes) finite and within the clamp;
//! - zero force written last to every device, when the haptic process stopped;
//! - the force ramped down — not cut, not held, zero in time — on every stale frame and every
//!   broken sample, every planned broken sample caught on its own device's tool and no device
//!   error elsewhere, and every stop and kill of the deformation process answered by a
//!   stale-frame ramp on every tool (`forces.rs`);
//! - no force rose faster than the safety's step limit plus what its stylus's motion explains,
//!   and every killed or stopped haptic loop came back with every device's force from zero
//!   (`steps.rs`);
//! - the supervisor restarted every killed process, and no other;
//! - no bad control request accepted, no good one refused as bad, the viewer's access rules
//!   held in every session;
//! - the recording readable and complete (one device);
//! - after the run, no process, iceoryx2 service or node of the run left (`leftovers.rs`);
//! - the resident memory and the thread count of every process flat after its warm-up
//!   (`memory.rs` states the bound and why; a run shorter than the warm-up and a watch, 45 s
//!   on `abdomen`, says N/A).
//!
//! Each check is a `fn(&Evidence) -> Check` beside its evidence (`forces.rs`, `injections.rs`,
//! `supervisor.rs`, `control.rs`, `viewers.rs`, `recording.rs`, `leftovers.rs`, `memory.rs`;
//! the rise-and-restart audit of `steps.rs` is judged in `injections.rs`, with the haptic
//! faults);
//! this file runs the pipeline, gathers the evidence and lists the checks in the report's order
//! (`report.rs` holds the report and prints it).
//!
//! The plan fixes what is injected and when; what the pipeline does in return (frame timing,
//! which ticks a stop catches in contact) varies from run to run, so two runs with one seed
//! agree in their injections, not in every figure.

mod control;
mod forces;
mod injections;
mod leftovers;
mod memory;
mod recording;
mod report;
mod schedule;
mod script;
mod steps;
mod supervisor;
mod viewers;

pub(crate) use memory::{children, cmdline};

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use clap::Args;
use lop_client::{clock, Attachment, HapticTelemetry, ServiceNames};
use lop_drivers::mock::MockDevice;
use serde::Serialize;

use crate::pipeline::{self, Lopd, LopdOptions};
use crate::scenes;
use control::{CtlReport, HammerReport};
use forces::{ForceAudit, ForceLog, ToolAudits, ToolStreamReport};
use injections::{Injection, StoppedProcess};
use leftovers::Leftovers;
use memory::ProcessWatch;
use recording::RecordingReport;
use report::{Evidence, SoakReport, TelemetryReport};
use schedule::{ProcessEvent, ProcessFault, Schedule};
use steps::StepLimits;
use supervisor::{log_line, SupervisorReport};
use viewers::ViewerReport;

/// Options of `lop-bench soak`.
#[derive(Args, Debug, Clone)]
pub struct SoakArgs {
    /// Minutes to run after the first frame.
    #[arg(long, conflicts_with = "seconds")]
    minutes: Option<f64>,
    /// Seconds to run after the first frame (short runs, CI); at least 20 s. The processes'
    /// memory is judged from one loop of the script plus 21 s on (45 s on `abdomen`); a
    /// shorter run says N/A there.
    #[arg(long)]
    seconds: Option<f64>,
    /// Seed of the fault plan.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// A shipped scene (its poke, grab, heat and drag scripts are played).
    #[arg(long, default_value = "abdomen")]
    scene: String,
    /// Devices, 1 or 2: with 2 the scene gets a second tool (its device mapped 20 mm along
    /// −x), each tool its own mock device playing the scripts (the second from `grab` on),
    /// its own broken samples and its own force log; nothing is recorded.
    #[arg(long, default_value_t = 1)]
    devices: usize,
    /// Where soak.json, soak.txt, the script, the force log, the recording and lopd's log go.
    #[arg(long, default_value = "target/lop-bench/soak")]
    out: PathBuf,
    /// Milliseconds between two requests of the control hammer.
    #[arg(long, default_value_t = 25)]
    hammer_ms: u64,
    /// The `lopd` binary (default: the `lopd` next to this executable; `lop-view` must be
    /// beside it).
    #[arg(long)]
    lopd: Option<PathBuf>,
}

/// How long to wait for the daemon's services, topology and first frame (a debug build loads
/// the scene slowly).
const START_TIMEOUT: Duration = Duration::from_secs(120);
/// `--duration` given to `lopd run` beyond the run: a backstop only (the bench stops it).
const BACKSTOP_EXTRA_S: f64 = 300.0;
/// A planned deformation fault is skipped if no deformation process is running for this long
/// after its time (it is restarting).
const POSTPONE_S: f64 = 10.0;
/// The most devices a soak runs (`--devices`).
const MAX_DEVICES: usize = 2;
/// Where the second tool's device maps, along x from the first's, m: 20 mm to the −x side,
/// where the shipped scripts still reach the tissue and the two tools' contacts stay apart. On
/// `abdomen` (30 s runs) both hands felt a force on 28–30 % of the ticks at 15–30 mm along −x,
/// each about 40 %; 16–17 % at 0 and +12 mm; at +30 mm the second tool's grab misses the
/// liver.
const SECOND_TOOL_X_M: f64 = -0.02;

impl SoakArgs {
    fn seconds(&self) -> Result<f64> {
        let s = match (self.minutes, self.seconds) {
            (Some(m), None) => m * 60.0,
            (None, Some(s)) => s,
            _ => bail!("give the length of the run: --minutes N or --seconds N"),
        };
        if !(s.is_finite() && (schedule::MIN_SECONDS..=7.0 * 86_400.0).contains(&s)) {
            bail!(
                "run length {s} s: must be between {} s and 7 days",
                schedule::MIN_SECONDS
            );
        }
        if !(1..=10_000).contains(&self.hammer_ms) {
            bail!("--hammer-ms {}: must be 1 to 10000", self.hammer_ms);
        }
        if !(1..=MAX_DEVICES).contains(&self.devices) {
            bail!(
                "--devices {}: the soak runs with 1 or {MAX_DEVICES} devices",
                self.devices
            );
        }
        Ok(s)
    }
}

/// Everything observed while the pipeline ran.
struct Observed {
    audits: ToolAudits,
    telemetry: Option<HapticTelemetry>,
    hammer: HammerReport,
    ctl: CtlReport,
    viewers: ViewerReport,
    injections: Vec<Injection>,
    watch: ProcessWatch,
}

/// What the settings of the run are.
#[derive(Debug, Clone, Serialize)]
struct Settings {
    scene: String,
    /// Devices, one per tool.
    devices: usize,
    /// The tools' names, in the scene's order.
    tool_names: Vec<String>,
    seconds: f64,
    seed: u64,
    prefix: String,
    /// The clamp (every tool of a soak's scene is a copy of its first, so one for all), N.
    clamp_n: f64,
    ramp_ticks: u64,
    stale_ms: f64,
    /// The safety's step limit, N a tick beyond the stylus's motion.
    max_step_n: f64,
    /// The scene's tool spring, N/m.
    tool_stiffness: f64,
    rate_hz: f64,
    /// The shipped scripts each device plays, in order (device `k`'s at `k`).
    script_parts: Vec<Vec<String>>,
    script_period_s: f64,
    warmup_s: f64,
    /// The shortest run whose processes' memory is judged, s (warm-up and a watch).
    memory_from_s: f64,
    hammer_ms: u64,
    view: String,
}

fn free_port() -> Result<u16> {
    let l = std::net::TcpListener::bind("127.0.0.1:0").context("finding a free port")?;
    Ok(l.local_addr()?.port())
}

/// Runs the soak.
pub fn run(a: SoakArgs) -> Result<()> {
    // 1. Settings, plan, script.
    let seconds = a.seconds()?;
    let lopd_path = pipeline::find_lopd(a.lopd.as_deref())?;
    let view_bin = lopd_path.with_file_name("lop-view");
    if !view_bin.is_file() {
        bail!(
            "{} not found: the soak runs the web viewer; build it beside lopd \
             (`cargo build -p lop-view` in the same profile)",
            view_bin.display()
        );
    }
    let shipped = lop_config::resolve_scene(&a.scene)?;
    // With two devices, the scene with a second tool (removed when the run ends).
    let copy = match a.devices {
        1 => None,
        n => Some(scenes::scene_with_tools(&shipped, n, SECOND_TOOL_X_M)?),
    };
    let scene_path = copy
        .as_ref()
        .map_or(shipped.clone(), |c| c.path().to_path_buf());
    let scene = lop_config::load_scene(&scene_path)
        .with_context(|| format!("loading scene {}", scene_path.display()))?;
    if scene.tools.len() != a.devices {
        bail!(
            "scene {} has {} tools and the soak drives one device per tool: give --devices {}",
            scene.name,
            scene.tools.len(),
            scene.tools.len()
        );
    }
    let rate = scene.rates.haptic_hz;
    let haptic = lop_config::DaemonConfig::default().haptic;
    let clamp = haptic
        .max_force_n
        .min(scene.tool().max_force)
        .min(MockDevice::omni_limits().max_force_n);
    let ramp_ticks = ((haptic.ramp_ms * 1e-3 * rate).round() as u64).max(1);
    let plan = Schedule::draw(a.seed, seconds, rate, a.devices);
    let scripts = (0..a.devices)
        .map(|k| script::build(&scene.name, k, &plan.samples[k], rate))
        .collect::<Result<Vec<_>>>()?;
    let soak_script = &scripts[0];
    let memory_from_s = memory::shortest_judged_s(soak_script.period_s);
    if seconds < memory_from_s {
        println!(
            "lop-bench soak: a run of {seconds} s is too short to judge the processes' memory \
             (from {memory_from_s:.0} s on {}): that check will say N/A",
            scene.name
        );
    }
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let out = a.out.canonicalize()?;
    // A recording never overwrites (a second one to the same name gets `-1`): clear the last
    // run's outputs first.
    for entry in std::fs::read_dir(&out)?.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        let ours = matches!(name.as_str(), "soak.json" | "soak.txt" | "lopd.log")
            || (name.starts_with("forces") && name.ends_with(".csv"))
            || (name.starts_with("soak-script") && name.ends_with(".toml"))
            || (name.starts_with("session") && name.ends_with(".rec"));
        if ours {
            let _ = std::fs::remove_file(entry.path());
        }
    }
    // Device k's script and force log: `soak-script.toml` and `forces.csv` for the first, as
    // with one device, `soak-script-toolK.toml` and `forces-toolK.csv` for the others.
    let suffix = |k: usize| match k {
        0 => String::new(),
        k => format!("-tool{k}"),
    };
    let mut script_paths = Vec::new();
    for (k, s) in scripts.iter().enumerate() {
        let path = out.join(format!("soak-script{}.toml", suffix(k)));
        std::fs::write(&path, &s.text).with_context(|| format!("writing {}", path.display()))?;
        script_paths.push(path);
    }
    let force_logs: Vec<PathBuf> = (0..a.devices)
        .map(|k| out.join(format!("forces{}.csv", suffix(k))))
        .collect();
    let recording = out.join("session.rec");
    let log_path = out.join("lopd.log");
    let bind = format!("127.0.0.1:{}", free_port()?);
    let prefix = pipeline::unique_prefix();
    let settings = Settings {
        scene: scene.name.clone(),
        devices: a.devices,
        tool_names: scene.tools.iter().map(|t| t.name.clone()).collect(),
        seconds,
        seed: a.seed,
        prefix: prefix.clone(),
        clamp_n: clamp,
        ramp_ticks,
        stale_ms: haptic.stale_frame_ms,
        max_step_n: haptic.max_force_step_n,
        tool_stiffness: scene.tool().stiffness,
        rate_hz: rate,
        script_parts: scripts
            .iter()
            .map(|s| s.parts.iter().map(|p| p.display().to_string()).collect())
            .collect(),
        script_period_s: soak_script.period_s,
        warmup_s: memory::warmup_s(soak_script.period_s),
        memory_from_s,
        hammer_ms: a.hammer_ms,
        view: bind.clone(),
    };
    println!(
        "lop-bench soak — scene {}, {} device(s), {:.0} s, seed {}, prefix {prefix}, out {}",
        scene.name,
        a.devices,
        seconds,
        a.seed,
        out.display()
    );

    // 2. The pipeline, and the run with it.
    // Every device a mock playing its script, each with its force log (`--device` and
    // `--force-log` in the tools' order); the recording with one device only (`lopd run
    // --record` takes one).
    let mut extra_args = Vec::new();
    for path in &script_paths[1..] {
        extra_args.extend(["--device".into(), format!("mock:{}", path.display())]);
    }
    for path in &force_logs {
        extra_args.extend(["--force-log".into(), path.display().to_string()]);
    }
    if a.devices == 1 {
        extra_args.extend(["--record".into(), recording.display().to_string()]);
    }
    extra_args.extend(["--view".into(), "--view-bind".into(), bind.clone()]);
    let epoch = Instant::now();
    let mut lopd = Lopd::spawn(&LopdOptions {
        lopd: lopd_path.clone(),
        scene: scene_path.display().to_string(),
        device: format!("mock:{}", script_paths[0].display()),
        duration: Duration::from_secs_f64(seconds + BACKSTOP_EXTRA_S),
        prefix: prefix.clone(),
        extra_args,
        log: Some(log_path.clone()),
    })?;
    let observed = observe(&mut lopd, &lopd_path, &settings, &plan, epoch);
    let stopped = lopd.stop();
    let obs = observed?;

    // 3. After the run: the supervisor's log, the force log, the recording, leftovers.
    let log = std::fs::read_to_string(&log_path).unwrap_or_default();
    let exit = match &stopped {
        Ok(s) => s.to_string(),
        Err(e) => format!("{e:#}"),
    };
    let supervisor = SupervisorReport::read(exit, &log);
    let force_logs: Vec<std::result::Result<ForceLog, String>> = force_logs
        .iter()
        .map(|path| {
            std::fs::read_to_string(path)
                .map_err(|e| format!("{}: {e}", path.display()))
                .and_then(|t| ForceLog::parse(&t, clamp))
        })
        .collect();
    let recording = match a.devices {
        1 => recording::read_recording(&log, &recording),
        _ => RecordingReport::default(),
    };
    drop(copy);
    let mut pids: BTreeSet<u32> = obs.watch.pids().into_iter().collect();
    pids.extend(&obs.ctl.pids);
    pids.insert(std::process::id());
    let leftovers = leftovers::find(&prefix, &pids, Duration::from_secs(5));

    // 4. Judge and report.
    let report = judge(
        settings, plan, obs, force_logs, recording, supervisor, leftovers,
    );
    let text = report::render(&report);
    print!("{text}");
    std::fs::write(out.join("soak.txt"), &text)?;
    std::fs::write(
        out.join("soak.json"),
        serde_json::to_string_pretty(&report)? + "\n",
    )?;
    println!("report written to {}", out.join("soak.json").display());
    let failed = report.checks.iter().filter(|c| !c.pass).count();
    if failed > 0 {
        bail!(
            "{failed} of {} checks failed (lopd's log: {})",
            report.checks.len(),
            log_path.display()
        );
    }
    Ok(())
}

/// Runs the tool-state audit on its own attachment until `stop`.
fn watch_tools(
    prefix: String,
    mut audits: ToolAudits,
    stop: Arc<AtomicBool>,
) -> Result<(ToolAudits, Option<HapticTelemetry>)> {
    let mut att = Attachment::open(&prefix, START_TIMEOUT)?;
    let mut buf = Vec::with_capacity(1024);
    let mut telemetry = None;
    loop {
        let done = stop.load(Ordering::Relaxed);
        buf.clear();
        att.tool_states(&mut buf);
        for s in &buf {
            audits.feed(s);
        }
        if let Some(t) = att.telemetry() {
            telemetry = Some(t);
        }
        if done {
            break;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    audits.finish();
    Ok((audits, telemetry))
}

/// Waits for the first frame, starts the injectors and monitors, runs the plan, and stops them.
fn observe(
    lopd: &mut Lopd,
    lopd_path: &Path,
    settings: &Settings,
    plan: &Schedule,
    epoch: Instant,
) -> Result<Observed> {
    // The daemon up: topology, a frame, the viewer's URL with its token.
    let mut att = lopd.attach(START_TIMEOUT)?;
    let waiting = Instant::now();
    let bodies: Vec<String> = loop {
        lopd.check_alive()?;
        if let Ok(Some(t)) = att.poll_topology() {
            break t
                .bodies()
                .iter()
                .map(|b| b.name_str().to_string())
                .collect();
        }
        if waiting.elapsed() > START_TIMEOUT {
            bail!(
                "no topology within {START_TIMEOUT:?}; {}",
                lopd.log_tail(20)
            );
        }
        std::thread::sleep(Duration::from_millis(10));
    };
    while att.latest_frame()?.is_none() {
        lopd.check_alive()?;
        if waiting.elapsed() > START_TIMEOUT {
            bail!("no frame within {START_TIMEOUT:?}; {}", lopd.log_tail(20));
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    drop(att);
    let t0 = Instant::now();
    let token = loop {
        let log = std::fs::read_to_string(&lopd.log).unwrap_or_default();
        if let Some(l) = log_line(&log, &["lop-view: http://", "#token="]) {
            let t = l
                .split("#token=")
                .nth(1)
                .and_then(|r| r.split_whitespace().next())
                .unwrap_or("")
                .to_string();
            break t;
        }
        lopd.check_alive()?;
        if t0.elapsed() > Duration::from_secs(10) {
            bail!(
                "lopd run --view printed no URL with a token; {}",
                lopd.log_tail(20)
            );
        }
        std::thread::sleep(Duration::from_millis(50));
    };

    // Monitors and injectors, each on its own thread with its own iceoryx2 node.
    let stop = Arc::new(AtomicBool::new(false));
    // One audit per tool, each expecting its own device's broken samples.
    let audits = ToolAudits::new(
        plan.samples
            .iter()
            .map(|samples| {
                ForceAudit::new(
                    settings.clamp_n,
                    settings.ramp_ticks,
                    samples,
                    StepLimits {
                        max_step: settings.max_step_n,
                        stiffness: settings.tool_stiffness,
                        stale_ns: (settings.stale_ms * 1e6) as u64,
                    },
                )
            })
            .collect(),
    );
    let tools = {
        let (prefix, stop) = (settings.prefix.clone(), stop.clone());
        std::thread::Builder::new()
            .name("soak-tools".into())
            .spawn(move || watch_tools(prefix, audits, stop))?
    };
    let hammer = {
        let names = ServiceNames::new(&settings.prefix)?;
        let (stop, bodies, seed) = (stop.clone(), bodies.clone(), plan.hammer_seed);
        let interval = Duration::from_millis(settings.hammer_ms);
        std::thread::Builder::new()
            .name("soak-hammer".into())
            .spawn(move || match control::read_bodies(&names, &bodies, &stop) {
                Some(b) => control::hammer(names, b, seed, interval, stop),
                None => HammerReport {
                    violations: vec!["could not read the bodies' parameters".into()],
                    ..HammerReport::default()
                },
            })?
    };
    let ctl = {
        let (lopd_path, prefix, body) = (
            lopd_path.to_path_buf(),
            settings.prefix.clone(),
            bodies[0].clone(),
        );
        let (events, stop) = (plan.ctl.clone(), stop.clone());
        std::thread::Builder::new()
            .name("soak-ctl".into())
            .spawn(move || control::ctl_bursts(lopd_path, prefix, body, events, t0, stop))?
    };
    let viewers = {
        let (addr, body) = (settings.view.clone(), bodies[0].clone());
        let (events, stop) = (plan.viewers.clone(), stop.clone());
        std::thread::Builder::new()
            .name("soak-viewers".into())
            .spawn(move || viewers::churn(addr, token, body, events, t0, stop))?
    };

    // The plan's process faults, and the memory samples, on this thread.
    let mut watch = ProcessWatch::new(lopd.pid());
    let ran = drive(lopd, settings, plan, t0, epoch, &mut watch, &tools);

    stop.store(true, Ordering::Relaxed);
    let hammer = hammer.join().unwrap_or_default();
    let ctl = ctl.join().unwrap_or_default();
    let viewers = viewers.join().unwrap_or_default();
    let tools = tools.join();
    watch.sample(epoch.elapsed().as_secs_f64());
    let injections = ran?;
    let (audits, telemetry) = match tools {
        Ok(r) => r?,
        Err(_) => bail!("the tool-state monitor panicked"),
    };
    Ok(Observed {
        audits,
        telemetry,
        hammer,
        ctl,
        viewers,
        injections,
        watch,
    })
}

/// The main thread's part of the run: delivers the process faults on time (the deformation
/// and the haptic process's in one time order, a fault waiting while a stop lasts), samples
/// the processes once a second, and checks that `lopd run` and the tool monitor are alive.
fn drive(
    lopd: &mut Lopd,
    settings: &Settings,
    plan: &Schedule,
    t0: Instant,
    epoch: Instant,
    watch: &mut ProcessWatch,
    tools: &std::thread::JoinHandle<Result<(ToolAudits, Option<HapticTelemetry>)>>,
) -> Result<Vec<Injection>> {
    let mut events: Vec<(&'static str, ProcessEvent)> = plan
        .deform
        .iter()
        .map(|e| ("deform", *e))
        .chain(plan.haptic.iter().map(|e| ("haptic", *e)))
        .collect();
    events.sort_by(|a, b| a.1.at_s.total_cmp(&b.1.at_s));
    let mut injections = Vec::new();
    let mut next = 0;
    let mut stopped: Option<StoppedProcess> = None;
    let mut last_sample = f64::NEG_INFINITY;
    loop {
        lopd.check_alive()?;
        if tools.is_finished() {
            bail!("the tool-state monitor stopped early (could it attach?)");
        }
        let now = t0.elapsed().as_secs_f64();
        if now - last_sample >= 1.0 {
            watch.sample(epoch.elapsed().as_secs_f64());
            last_sample = now;
        }
        if stopped
            .as_ref()
            .is_some_and(|s| Instant::now() >= s.resume_at)
        {
            drop(stopped.take());
        }
        if now >= settings.seconds && stopped.is_none() {
            return Ok(injections);
        }
        if let (None, Some(&(role, e))) = (&stopped, events.get(next)) {
            if now >= e.at_s {
                watch.sample(epoch.elapsed().as_secs_f64());
                let (kind, stop_s) = match e.fault {
                    ProcessFault::Kill => ("kill", None),
                    ProcessFault::Stop { seconds } => ("stop", Some(seconds)),
                };
                let mut inj = Injection {
                    process: role,
                    planned_s: e.at_s,
                    at_s: None,
                    kind,
                    stop_s,
                    pid: 0,
                    start_ns: 0,
                    answered: None,
                    tools: Vec::new(),
                };
                if let Some(pid) = watch.live(role) {
                    let sig = match e.fault {
                        ProcessFault::Kill => libc::SIGKILL,
                        ProcessFault::Stop { .. } => libc::SIGSTOP,
                    };
                    inj.start_ns = clock::monotonic_ns();
                    if injections::signal_process(pid, &settings.prefix, role, sig) {
                        inj.at_s = Some(now);
                        inj.pid = pid;
                        if let ProcessFault::Stop { seconds } = e.fault {
                            stopped = Some(StoppedProcess {
                                pid,
                                prefix: settings.prefix.clone(),
                                role,
                                resume_at: Instant::now() + Duration::from_secs_f64(seconds),
                            });
                        }
                    }
                }
                if inj.at_s.is_some() || now - e.at_s > POSTPONE_S {
                    injections.push(inj);
                    next += 1;
                }
            }
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// Gathers the evidence and runs every check on it, in the report's order.
fn judge(
    settings: Settings,
    plan: Schedule,
    mut obs: Observed,
    force_logs: Vec<std::result::Result<ForceLog, String>>,
    recording: RecordingReport,
    supervisor: SupervisorReport,
    leftovers: Leftovers,
) -> SoakReport {
    let audits = &obs.audits.tools;
    for inj in &mut obs.injections {
        inj.judge(audits);
    }
    let tools: Vec<ToolStreamReport> = audits
        .iter()
        .enumerate()
        .map(|(k, a)| ToolStreamReport::new(k, &settings.tool_names[k], a, &plan))
        .collect();
    let memory = obs.watch.verdicts(settings.warmup_s);
    let evidence = Evidence {
        settings: &settings,
        plan: &plan,
        audits,
        foreign: obs.audits.foreign,
        all_loaded_ticks: obs.audits.all_loaded_ticks,
        tools: &tools,
        force_logs: &force_logs,
        injections: &obs.injections,
        supervisor: &supervisor,
        hammer: &obs.hammer,
        ctl: &obs.ctl,
        viewers: &obs.viewers,
        recording: &recording,
        leftovers: &leftovers,
        memory: &memory,
        watch: &obs.watch,
    };
    let checks: [fn(&Evidence<'_>) -> report::Check; 14] = [
        forces::within_clamp,
        forces::zero_at_stop,
        forces::ramped,
        forces::samples_caught,
        injections::check_answered,
        injections::check_haptic_restarts,
        supervisor::check_restarts,
        control::check_requests,
        viewers::check_access,
        recording::check_complete,
        leftovers::check_clean,
        memory::check_flat,
        supervisor::check_clean_exit,
        forces::stream_observed,
    ];
    let checks: Vec<report::Check> = checks.iter().map(|check| check(&evidence)).collect();

    let pass = checks.iter().all(|c| c.pass);
    let telemetry = obs.telemetry.map(|t| TelemetryReport {
        ticks: t.ticks,
        overruns: t.overruns,
        stale_ticks: t.stale_ticks,
        device_faults: t.device_faults,
    });
    SoakReport {
        settings,
        plan,
        injections: obs.injections,
        tool_streams: tools,
        ticks_every_hand_loaded: obs.audits.all_loaded_ticks,
        force_logs: force_logs.into_iter().map(|l| l.ok()).collect(),
        recording,
        supervisor,
        hammer: obs.hammer,
        ctl: obs.ctl,
        viewers: obs.viewers,
        memory,
        leftovers,
        telemetry,
        checks,
        pass,
    }
}
