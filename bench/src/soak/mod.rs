//! `lop-bench soak`: the whole pipeline for minutes or hours under randomised faults, and the
//! safety invariants checked all along.
//!
//! The bench starts `lopd run` on the scene (default `abdomen`) with the mock device playing the
//! scene's four shipped scripts in a loop (`script.rs`), the web viewer (`--view`), a recording
//! of the device stream (`--record`) and the device's force record (`--force-log`), all under a
//! private service prefix. From the first frame on it injects, on a plan drawn from `--seed`
//! (`schedule.rs`):
//! - the deformation process killed (SIGKILL; the supervisor restarts it) or stopped (SIGSTOP
//!   for 0.3–3 s, then SIGCONT), which makes the frames go stale;
//! - the haptic process killed (the supervisor restarts it) or stopped (0.2–1.5 s), wherever
//!   the stylus is then (in the tissue too);
//! - NaN and out-of-workspace device samples, 1–40 ticks long (the script's `[[fault]]` windows
//!   with `sample =`);
//! - control requests hammered through `PREFIX/control`, and bursts of `lopd ctl`
//!   (`control.rs`);
//! - viewers connecting and disconnecting, with the printed token, without, with a wrong one,
//!   and from another origin (`viewers.rs`).
//!
//! and checks, printing PASS/FAIL with the figures, writing `soak.json` and `soak.txt`, and
//! exiting non-zero on any FAIL:
//! - every force published (`PREFIX/tool`, every tick) and every force the device received
//!   (`--force-log`: the mock's ring of the last two minutes) finite and within the clamp;
//! - zero force written last, when the haptic process stopped;
//! - the force ramped down — not cut, not held, zero in time — on every stale frame and every
//!   broken sample, every planned broken sample caught, and every stop and kill of the
//!   deformation process answered by a stale-frame ramp (`forces.rs`);
//! - the force never rose faster than the safety's step limit plus what the stylus's motion
//!   explains, and every killed or stopped haptic loop came back with its force from zero
//!   (`steps.rs`);
//! - the supervisor restarted every killed process, and no other;
//! - no bad control request accepted, no good one refused as bad, the viewer's access rules
//!   held in every session;
//! - the recording readable and complete;
//! - after the run, no process, iceoryx2 service or node of the run left (`leftovers.rs`);
//! - the resident memory and the thread count of every process flat after its warm-up
//!   (`memory.rs` states the bound and why).
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
use control::{CtlReport, HammerReport};
use forces::{ForceAudit, ForceLog, ToolStreamReport};
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
    /// Seconds to run after the first frame (short runs, CI); at least one loop of the script
    /// plus 20 s (45 s on `abdomen`).
    #[arg(long)]
    seconds: Option<f64>,
    /// Seed of the fault plan.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// A shipped scene (its poke, grab, heat and drag scripts are played).
    #[arg(long, default_value = "abdomen")]
    scene: String,
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
        Ok(s)
    }
}

/// Everything observed while the pipeline ran.
struct Observed {
    audit: ForceAudit,
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
    seconds: f64,
    seed: u64,
    prefix: String,
    clamp_n: f64,
    ramp_ticks: u64,
    stale_ms: f64,
    /// The safety's step limit, N a tick beyond the stylus's motion.
    max_step_n: f64,
    /// The scene's tool spring, N/m.
    tool_stiffness: f64,
    rate_hz: f64,
    script_parts: Vec<String>,
    script_period_s: f64,
    warmup_s: f64,
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
    let scene_path = lop_config::resolve_scene(&a.scene)?;
    let scene = lop_config::load_scene(&scene_path)
        .with_context(|| format!("loading scene {}", scene_path.display()))?;
    let rate = scene.rates.haptic_hz;
    let haptic = lop_config::DaemonConfig::default().haptic;
    let clamp = haptic
        .max_force_n
        .min(scene.tool().max_force)
        .min(MockDevice::omni_limits().max_force_n);
    let ramp_ticks = ((haptic.ramp_ms * 1e-3 * rate).round() as u64).max(1);
    let plan = Schedule::draw(a.seed, seconds, rate);
    let soak_script = script::build(&scene.name, &plan.samples, rate)?;
    let shortest = (memory::warmup_s(soak_script.period_s) + memory::MIN_OBSERVED_S + 1.0).ceil();
    if seconds < shortest {
        bail!(
            "a soak of {} runs at least {shortest:.0} s (asked: {seconds} s): its processes' \
             memory is judged after a warm-up of one loop of the script ({:.1} s) and {:.0} s of \
             start-up, then watched for at least {:.0} s",
            scene.name,
            soak_script.period_s,
            memory::WARMUP_LOAD_S,
            memory::MIN_OBSERVED_S
        );
    }
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let out = a.out.canonicalize()?;
    // A recording never overwrites (a second one to the same name gets `-1`): clear the last
    // run's outputs first.
    for entry in std::fs::read_dir(&out)?.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        let ours = matches!(
            name.as_str(),
            "soak.json" | "soak.txt" | "forces.csv" | "lopd.log" | "soak-script.toml"
        ) || (name.starts_with("session") && name.ends_with(".rec"));
        if ours {
            let _ = std::fs::remove_file(entry.path());
        }
    }
    let script_path = out.join("soak-script.toml");
    std::fs::write(&script_path, &soak_script.text)
        .with_context(|| format!("writing {}", script_path.display()))?;
    let force_log = out.join("forces.csv");
    let recording = out.join("session.rec");
    let log_path = out.join("lopd.log");
    let bind = format!("127.0.0.1:{}", free_port()?);
    let prefix = pipeline::unique_prefix();
    let settings = Settings {
        scene: scene.name.clone(),
        seconds,
        seed: a.seed,
        prefix: prefix.clone(),
        clamp_n: clamp,
        ramp_ticks,
        stale_ms: haptic.stale_frame_ms,
        max_step_n: haptic.max_force_step_n,
        tool_stiffness: scene.tool().stiffness,
        rate_hz: rate,
        script_parts: soak_script
            .parts
            .iter()
            .map(|p| p.display().to_string())
            .collect(),
        script_period_s: soak_script.period_s,
        warmup_s: memory::warmup_s(soak_script.period_s),
        hammer_ms: a.hammer_ms,
        view: bind.clone(),
    };
    println!(
        "lop-bench soak — scene {}, {:.0} s, seed {}, prefix {prefix}, out {}",
        scene.name,
        seconds,
        a.seed,
        out.display()
    );

    // 2. The pipeline, and the run with it.
    let epoch = Instant::now();
    let mut lopd = Lopd::spawn(&LopdOptions {
        lopd: lopd_path.clone(),
        scene: scene_path.display().to_string(),
        device: format!("mock:{}", script_path.display()),
        duration: Duration::from_secs_f64(seconds + BACKSTOP_EXTRA_S),
        prefix: prefix.clone(),
        extra_args: vec![
            "--force-log".into(),
            force_log.display().to_string(),
            "--record".into(),
            recording.display().to_string(),
            "--view".into(),
            "--view-bind".into(),
            bind.clone(),
        ],
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
    let force_log = std::fs::read_to_string(&force_log)
        .map_err(|e| e.to_string())
        .and_then(|t| ForceLog::parse(&t, clamp));
    let recording = recording::read_recording(&log, &recording);
    let mut pids: BTreeSet<u32> = obs.watch.pids().into_iter().collect();
    pids.extend(&obs.ctl.pids);
    pids.insert(std::process::id());
    let leftovers = leftovers::find(&prefix, &pids, Duration::from_secs(5));

    // 4. Judge and report.
    let report = judge(
        settings, plan, obs, force_log, recording, supervisor, leftovers,
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
    mut audit: ForceAudit,
    stop: Arc<AtomicBool>,
) -> Result<(ForceAudit, Option<HapticTelemetry>)> {
    let mut att = Attachment::open(&prefix, START_TIMEOUT)?;
    let mut buf = Vec::with_capacity(1024);
    let mut telemetry = None;
    loop {
        let done = stop.load(Ordering::Relaxed);
        buf.clear();
        att.tool_states(&mut buf);
        for s in &buf {
            audit.feed(s);
        }
        if let Some(t) = att.telemetry() {
            telemetry = Some(t);
        }
        if done {
            break;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    audit.finish();
    Ok((audit, telemetry))
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
    let audit = ForceAudit::new(
        settings.clamp_n,
        settings.ramp_ticks,
        &plan.samples,
        StepLimits {
            max_step: settings.max_step_n,
            stiffness: settings.tool_stiffness,
            stale_ns: (settings.stale_ms * 1e6) as u64,
        },
    );
    let tools = {
        let (prefix, stop) = (settings.prefix.clone(), stop.clone());
        std::thread::Builder::new()
            .name("soak-tools".into())
            .spawn(move || watch_tools(prefix, audit, stop))?
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
    let (audit, telemetry) = match tools {
        Ok(r) => r?,
        Err(_) => bail!("the tool-state monitor panicked"),
    };
    Ok(Observed {
        audit,
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
    tools: &std::thread::JoinHandle<Result<(ForceAudit, Option<HapticTelemetry>)>>,
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
    force_log: std::result::Result<ForceLog, String>,
    recording: RecordingReport,
    supervisor: SupervisorReport,
    leftovers: Leftovers,
) -> SoakReport {
    for inj in &mut obs.injections {
        inj.answered = injections::answered(inj, &obs.audit);
    }
    let tool = ToolStreamReport::new(&obs.audit, &plan);
    let memory = obs.watch.verdicts(settings.warmup_s);
    let evidence = Evidence {
        settings: &settings,
        plan: &plan,
        audit: &obs.audit,
        tool: &tool,
        force_log: &force_log,
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
        tool_stream: tool,
        force_log: force_log.ok(),
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
