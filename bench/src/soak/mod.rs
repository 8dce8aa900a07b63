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
//! - the supervisor restarted every killed deformation process, the haptic loop never
//!   restarted;
//! - no bad control request accepted, no good one refused as bad, the viewer's access rules
//!   held in every session;
//! - the recording readable and complete;
//! - after the run, no process, iceoryx2 service or node of the run left (`leftovers.rs`);
//! - the resident memory and the thread count of every process flat after its warm-up
//!   (`memory.rs` states the bound and why).
//!
//! The plan fixes what is injected and when; what the pipeline does in return (frame timing,
//! which ticks a stop catches in contact) varies from run to run, so two runs with one seed
//! agree in their injections, not in every figure.

mod control;
mod forces;
mod leftovers;
mod memory;
mod schedule;
mod script;
mod viewers;

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use clap::Args;
use lop_client::{clock, Attachment, HapticTelemetry, ServiceNames};
use lop_drivers::mock::{MockDevice, SampleFault};
use serde::Serialize;

use crate::pipeline::{self, Lopd, LopdOptions};
use control::{CtlReport, HammerReport};
use forces::{ForceAudit, ForceLog};
use leftovers::Leftovers;
use memory::{ProcessWatch, Verdict};
use schedule::{DeformFault, Schedule, ViewerKind};
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
/// A stop or kill of the deformation process is answered by a stale-frame episode that began
/// at most this long after it (the stale limit is 100 ms; the rest is scheduling slack).
const ANSWER_WITHIN_NS: u64 = 2_000_000_000;
/// Least share of the haptic ticks the bench must have seen for the stream checks to mean
/// something.
const MIN_COVERAGE: f64 = 0.5;
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

/// One delivered (or skipped) deformation-process fault.
#[derive(Debug, Clone, Serialize)]
pub struct Injection {
    /// Planned time, s after the first frame.
    pub planned_s: f64,
    /// When it was delivered, s after the first frame (`None`: skipped).
    pub at_s: Option<f64>,
    /// `kill` or `stop`.
    pub kind: &'static str,
    /// Planned stop length, s.
    pub stop_s: Option<f64>,
    /// The deformation process it hit.
    pub pid: u32,
    /// `CLOCK_MONOTONIC` at delivery, ns.
    #[serde(skip)]
    pub start_ns: u64,
    /// Whether a stale-frame ramp answered it (`None`: the bench saw no tool state then).
    pub answered: Option<bool>,
}

/// Sends `sig` to `pid` if it is still a deformation process of the run.
fn signal_deform(pid: u32, prefix: &str, sig: i32) -> bool {
    let args = memory::cmdline(pid);
    let ours = args.iter().any(|a| a == "deform") && args.iter().any(|a| a == prefix);
    // SAFETY: kill on a grandchild of this bench, checked to be the run's deformation process.
    ours && unsafe { libc::kill(pid as i32, sig) } == 0
}

/// A stopped deformation process, continued when dropped (on every path, errors included).
struct StoppedDeform {
    pid: u32,
    prefix: String,
    resume_at: Instant,
}

impl Drop for StoppedDeform {
    fn drop(&mut self) {
        signal_deform(self.pid, &self.prefix, libc::SIGCONT);
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
    rate_hz: f64,
    script_parts: Vec<String>,
    script_period_s: f64,
    warmup_s: f64,
    hammer_ms: u64,
    view: String,
}

/// A PASS/FAIL line.
#[derive(Debug, Clone, Serialize)]
pub struct Check {
    /// What is checked.
    pub name: String,
    /// Whether it held.
    pub pass: bool,
    /// The figures behind it.
    pub detail: String,
}

/// The recording's part of the report.
#[derive(Debug, Clone, Default, Serialize)]
struct RecordingReport {
    path: Option<String>,
    /// Records the haptic process said it wrote.
    logged_records: Option<u64>,
    /// Samples it said it lost (writer behind).
    logged_lost: u64,
    /// Records the reader read back.
    read_records: Option<u64>,
    /// The reader's refusal.
    error: Option<String>,
}

/// What the supervisor's log says.
#[derive(Debug, Clone, Default, Serialize)]
struct SupervisorReport {
    exit: String,
    haptic_restarts: Option<u64>,
    deform_restarts: Option<u64>,
    no_service_left: bool,
    haptic_ticks: Option<u64>,
}

/// Everything `soak.json` holds.
#[derive(Debug, Clone, Serialize)]
struct SoakReport {
    settings: Settings,
    plan: Schedule,
    injections: Vec<Injection>,
    tool_stream: ToolStreamReport,
    force_log: Option<ForceLog>,
    recording: RecordingReport,
    supervisor: SupervisorReport,
    hammer: HammerReport,
    ctl: CtlReport,
    viewers: ViewerReport,
    memory: Vec<Verdict>,
    leftovers: Leftovers,
    telemetry: Option<TelemetryReport>,
    checks: Vec<Check>,
    pass: bool,
}

#[derive(Debug, Clone, Serialize)]
struct TelemetryReport {
    ticks: u64,
    overruns: u64,
    stale_ticks: u64,
    device_faults: u64,
}

#[derive(Debug, Clone, Serialize)]
struct ToolStreamReport {
    received: u64,
    missed: u64,
    coverage: f64,
    segments: u64,
    max_force_n: f64,
    loaded_ticks: u64,
    stale_ticks: u64,
    device_error_ticks: u64,
    unexpected_device_errors: u64,
    episodes: u64,
    episodes_loaded: u64,
    episodes_stale: u64,
    episodes_device: u64,
    episodes_gapped: u64,
    longest_episode_ticks: u64,
    planned_samples: usize,
    planned_samples_seen: usize,
    planned_samples_flagged: usize,
    violations: forces::ViolationCounts,
    first_violations: Vec<String>,
}

fn free_port() -> Result<u16> {
    let l = std::net::TcpListener::bind("127.0.0.1:0").context("finding a free port")?;
    Ok(l.local_addr()?.port())
}

/// The first line of `log` containing every one of `parts`.
fn log_line(log: &str, parts: &[&str]) -> Option<String> {
    log.lines()
        .rev()
        .find(|l| parts.iter().all(|p| l.contains(p)))
        .map(str::to_string)
}

/// The number right after `label` in `line`.
fn number_after(line: &str, label: &str) -> Option<u64> {
    let rest = &line[line.find(label)? + label.len()..];
    let digits: String = rest
        .trim_start()
        .chars()
        .take_while(char::is_ascii_digit)
        .collect();
    digits.parse().ok()
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
        .min(scene.tool.max_force)
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
    let supervisor = SupervisorReport {
        exit: match &stopped {
            Ok(s) => s.to_string(),
            Err(e) => format!("{e:#}"),
        },
        haptic_restarts: log_line(&log, &["lopd run: stopped"])
            .and_then(|l| number_after(&l, "haptic restarts")),
        deform_restarts: log_line(&log, &["lopd run: stopped"])
            .and_then(|l| number_after(&l, "deform restarts")),
        no_service_left: log_line(&log, &["no service left under"]).is_some(),
        haptic_ticks: log_line(&log, &["haptic loop stopped after"])
            .and_then(|l| number_after(&l, "stopped after")),
    };
    let force_log = std::fs::read_to_string(&force_log)
        .map_err(|e| e.to_string())
        .and_then(|t| ForceLog::parse(&t, clamp));
    let recording = read_recording(&log, &recording);
    let mut pids: BTreeSet<u32> = obs.watch.pids().into_iter().collect();
    pids.extend(&obs.ctl.pids);
    pids.insert(std::process::id());
    let leftovers = leftovers::find(&prefix, &pids, Duration::from_secs(5));

    // 4. Judge and report.
    let report = judge(
        settings, plan, obs, force_log, recording, supervisor, leftovers,
    );
    let text = render(&report);
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

/// The recording named in the log, read back with the replay reader.
fn read_recording(log: &str, planned: &Path) -> RecordingReport {
    let mut r = RecordingReport::default();
    let line = log_line(log, &["recorded", "device samples to"]);
    let path = line
        .as_deref()
        .and_then(|l| l.split("device samples to ").nth(1))
        .map(|rest| {
            let p = rest.split(" (").next().unwrap_or(rest).trim();
            PathBuf::from(p)
        })
        .unwrap_or_else(|| planned.to_path_buf());
    r.path = Some(path.display().to_string());
    r.logged_records = line.as_deref().and_then(|l| number_after(l, "recorded"));
    r.logged_lost = line
        .as_deref()
        .and_then(|l| l.rsplit(" (").next())
        .and_then(|tail| number_after(&format!(" {tail}"), " "))
        .filter(|_| line.as_deref().is_some_and(|l| l.contains(" lost")))
        .unwrap_or(0);
    match lop_drivers::replay::Recording::load(&path) {
        Ok(rec) => r.read_records = Some(rec.records().len() as u64),
        Err(e) => r.error = Some(e.to_string()),
    }
    r
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
    let audit = ForceAudit::new(settings.clamp_n, settings.ramp_ticks, &plan.samples);
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

/// The main thread's part of the run: delivers the deformation faults on time, samples the
/// processes once a second, and checks that `lopd run` and the tool monitor are alive.
fn drive(
    lopd: &mut Lopd,
    settings: &Settings,
    plan: &Schedule,
    t0: Instant,
    epoch: Instant,
    watch: &mut ProcessWatch,
    tools: &std::thread::JoinHandle<Result<(ForceAudit, Option<HapticTelemetry>)>>,
) -> Result<Vec<Injection>> {
    let mut injections = Vec::new();
    let mut next = 0;
    let mut stopped: Option<StoppedDeform> = None;
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
        if let (None, Some(e)) = (&stopped, plan.deform.get(next)) {
            if now >= e.at_s {
                watch.sample(epoch.elapsed().as_secs_f64());
                let (kind, stop_s) = match e.fault {
                    DeformFault::Kill => ("kill", None),
                    DeformFault::Stop { seconds } => ("stop", Some(seconds)),
                };
                let mut inj = Injection {
                    planned_s: e.at_s,
                    at_s: None,
                    kind,
                    stop_s,
                    pid: 0,
                    start_ns: 0,
                    answered: None,
                };
                let target = watch.live("deform");
                if let Some(pid) = target {
                    let sig = match e.fault {
                        DeformFault::Kill => libc::SIGKILL,
                        DeformFault::Stop { .. } => libc::SIGSTOP,
                    };
                    inj.start_ns = clock::monotonic_ns();
                    if signal_deform(pid, &settings.prefix, sig) {
                        inj.at_s = Some(now);
                        inj.pid = pid;
                        if let DeformFault::Stop { seconds } = e.fault {
                            stopped = Some(StoppedDeform {
                                pid,
                                prefix: settings.prefix.clone(),
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

/// Whether a stale-frame episode answered the injection: one that overlaps its moment and began
/// at most [`ANSWER_WITHIN_NS`] after it. `None` if the bench missed the tool states then.
fn answered(inj: &Injection, audit: &ForceAudit) -> Option<bool> {
    inj.at_s?;
    let (from, to) = (inj.start_ns, inj.start_ns + ANSWER_WITHIN_NS);
    let hit = audit
        .episodes
        .iter()
        .any(|e| e.stale && e.first_ns <= to && e.last_ns >= from);
    if hit {
        return Some(true);
    }
    let blind = audit.gaps.iter().any(|&(a, b)| a <= to && b >= from);
    (!blind).then_some(false)
}

fn check(name: &str, pass: bool, detail: String) -> Check {
    Check {
        name: name.into(),
        pass,
        detail,
    }
}

fn kib(k: u64) -> String {
    format!("{:.1} MiB", k as f64 / 1024.0)
}

#[allow(clippy::too_many_arguments)] // one of each part of the report
fn judge(
    settings: Settings,
    plan: Schedule,
    mut obs: Observed,
    force_log: std::result::Result<ForceLog, String>,
    recording: RecordingReport,
    supervisor: SupervisorReport,
    leftovers: Leftovers,
) -> SoakReport {
    let a = &obs.audit;
    for i in 0..obs.injections.len() {
        obs.injections[i].answered = answered(&obs.injections[i], a);
    }
    let (seen, flagged) = a.planned_samples();
    let coverage = a.received as f64 / (a.received + a.missed).max(1) as f64;
    let tool = ToolStreamReport {
        received: a.received,
        missed: a.missed,
        coverage,
        segments: a.segments,
        max_force_n: a.max_force,
        loaded_ticks: a.loaded_ticks,
        stale_ticks: a.stale_ticks,
        device_error_ticks: a.device_error_ticks,
        unexpected_device_errors: a.unexpected_device_errors,
        episodes: a.episodes.len() as u64,
        episodes_loaded: a.episodes.iter().filter(|e| e.loaded()).count() as u64,
        episodes_stale: a.episodes.iter().filter(|e| e.stale).count() as u64,
        episodes_device: a.episodes.iter().filter(|e| e.device).count() as u64,
        episodes_gapped: a.episodes.iter().filter(|e| e.gapped).count() as u64,
        longest_episode_ticks: a.episodes.iter().map(|e| e.ticks).max().unwrap_or(0),
        planned_samples: plan.samples.len(),
        planned_samples_seen: seen,
        planned_samples_flagged: flagged,
        violations: a.counts.clone(),
        first_violations: a.violations.clone(),
    };
    let warmup = settings.warmup_s;
    let memory = obs.watch.verdicts(warmup);
    let mut checks = Vec::new();

    // Forces.
    let (log_ok, log_detail) = match &force_log {
        Ok(l) => (
            l.non_finite == 0 && l.over_clamp == 0 && l.rows > 0,
            format!(
                "force log {} rows (the device's last {:.0} s), {} with a force, max {:.3} N, {} \
                 non-finite, {} over",
                l.rows,
                l.rows as f64 / settings.rate_hz,
                l.loaded_rows,
                l.max_force,
                l.non_finite,
                l.over_clamp
            ),
        ),
        Err(e) => (false, format!("force log unreadable: {e}")),
    };
    checks.push(check(
        "every force finite and within the clamp",
        a.counts.non_finite == 0 && a.counts.over_clamp == 0 && log_ok,
        format!(
            "{} tool states ({} with a force on the hand), max |F| {:.3} N, clamp {:.2} N, {} \
             non-finite, {} over; {log_detail}",
            a.received,
            a.loaded_ticks,
            a.max_force,
            settings.clamp_n,
            a.counts.non_finite,
            a.counts.over_clamp
        ),
    ));
    let last = force_log.as_ref().ok().and_then(|l| l.last);
    checks.push(check(
        "zero force written when the haptic process stopped",
        last == Some([0.0; 3]),
        format!(
            "last force in the device's record: {last:?}; haptic exits: 1 (at the end){}",
            match supervisor.haptic_restarts {
                Some(n) if n > 0 => format!(" + {n} restarts (earlier force logs overwritten)"),
                _ => String::new(),
            }
        ),
    ));
    let e = &tool;
    checks.push(check(
        "force ramped down on every stale frame and broken sample (not cut, not held, zero in time)",
        a.counts.ramp() == 0 && e.episodes > 0,
        format!(
            "{} episodes ({} with a force on the hand), {} stale-frame, {} broken-sample, longest \
             {} ticks; violations: {} not flagged ramping, {} cut, {} held, {} late (ramp {} \
             ticks: at most {:.3} N a tick, zero from its {}th tick)",
            e.episodes,
            e.episodes_loaded,
            e.episodes_stale,
            e.episodes_device,
            e.longest_episode_ticks,
            a.counts.not_ramping,
            a.counts.cut,
            a.counts.held,
            a.counts.late,
            settings.ramp_ticks,
            settings.clamp_n / settings.ramp_ticks as f64,
            settings.ramp_ticks
        ),
    ));
    let by_kind = |k: SampleFault| plan.samples.iter().filter(|s| s.fault == k).count();
    checks.push(check(
        "every planned broken sample caught, and no other device error",
        a.counts.sample_not_flagged == 0 && flagged == seen && a.unexpected_device_errors == 0,
        format!(
            "{} runs planned ({} NaN, {} out of the workspace), {seen} seen, {flagged} flagged on \
             every tick; {} planned ticks not flagged; {} device-error ticks elsewhere",
            plan.samples.len(),
            by_kind(SampleFault::Nan),
            by_kind(SampleFault::OutOfWorkspace),
            a.counts.sample_not_flagged,
            a.unexpected_device_errors
        ),
    ));
    let delivered = |k: &str| {
        obs.injections
            .iter()
            .filter(|i| i.kind == k && i.at_s.is_some())
            .count()
    };
    let unanswered = obs
        .injections
        .iter()
        .filter(|i| i.answered == Some(false))
        .count();
    let blind = obs
        .injections
        .iter()
        .filter(|i| i.at_s.is_some() && i.answered.is_none())
        .count();
    let skipped = obs.injections.iter().filter(|i| i.at_s.is_none()).count();
    let kills = delivered("kill");
    checks.push(check(
        "every deformation stop and kill answered by a stale-frame ramp",
        unanswered == 0 && kills + delivered("stop") > 0,
        format!(
            "{kills} kills, {} stops (0.3–3 s) delivered, {skipped} skipped (no process), \
             {unanswered} without a stale-frame episode, {blind} unseen (the bench missed those \
             ticks)",
            delivered("stop")
        ),
    ));
    checks.push(check(
        "supervisor restarted every killed deformation process; the haptic loop never restarted",
        supervisor.deform_restarts == Some(kills as u64)
            && supervisor.haptic_restarts == Some(0)
            && a.segments == 0,
        format!(
            "deform restarts {:?} for {kills} kills, haptic restarts {:?}, {} deformation \
             processes in all",
            supervisor.deform_restarts,
            supervisor.haptic_restarts,
            obs.watch.instances_of("deform")
        ),
    ));
    let h = &obs.hammer;
    checks.push(check(
        "control: no bad request accepted, no good one refused as bad",
        h.bad_accepted == 0
            && h.good_refused == 0
            && obs.ctl.wrong == 0
            && h.answered > 0
            && h.violations.is_empty(),
        format!(
            "{} requests ({:.0}/s), {} answered, {} unanswered (deformation process stopped or \
             restarting), {} bad ones sent, {} accepted, {} good ones refused as bad; lopd ctl: \
             {} runs, {} with a wrong exit code",
            h.sent,
            h.sent as f64 / settings.seconds,
            h.answered,
            h.unanswered,
            h.bad_sent,
            h.bad_accepted,
            h.good_refused,
            obs.ctl.runs,
            obs.ctl.wrong
        ),
    ));
    let v = &obs.viewers;
    let tally = |k: ViewerKind| v.kinds.get(&k).cloned().unwrap_or_default();
    let (tok, none, wrong, cross) = (
        tally(ViewerKind::Token),
        tally(ViewerKind::NoToken),
        tally(ViewerKind::WrongToken),
        tally(ViewerKind::CrossOrigin),
    );
    checks.push(check(
        "viewers: served through every fault; control only with the printed token; other origins refused",
        v.wrong == 0 && tok.sessions + none.sessions + wrong.sessions + cross.sessions > 0,
        format!(
            "{} sessions with the token ({} controlled, {} daemon busy or down), {} without and \
             {} with a wrong token ({} refused read-only), {} from another origin ({} refused \
             with 403); {} got frames, {} dropped without a close; {} broke a rule",
            tok.sessions,
            tok.control_ok,
            tok.control_error + tok.control_unanswered,
            none.sessions,
            wrong.sessions,
            none.control_read_only + wrong.control_read_only,
            cross.sessions,
            cross.refused_403,
            tok.framed + none.framed + wrong.framed,
            tok.abrupt + none.abrupt + wrong.abrupt,
            v.wrong
        ),
    ));
    let rec_ok = recording.error.is_none()
        && recording.logged_lost == 0
        && recording.read_records.is_some()
        && recording.read_records == recording.logged_records;
    checks.push(check(
        "recording written, complete and readable",
        rec_ok,
        format!(
            "{}: {:?} records written, {} lost, {:?} read back{}",
            recording.path.as_deref().unwrap_or("?"),
            recording.logged_records,
            recording.logged_lost,
            recording.read_records,
            match &recording.error {
                Some(e) => format!("; the reader refused it: {e}"),
                None => String::new(),
            }
        ),
    ));
    checks.push(check(
        "nothing left behind (processes, iceoryx2 services and nodes of the run)",
        leftovers.clean(),
        format!(
            "{} processes, {} services, {} nodes left{}",
            leftovers.processes.len(),
            leftovers.services.len(),
            leftovers.nodes.len(),
            if leftovers.clean() {
                String::new()
            } else {
                format!(
                    ": {:?} {:?} {:?}",
                    leftovers.processes, leftovers.services, leftovers.nodes
                )
            }
        ),
    ));
    let judged: Vec<&Verdict> = memory.iter().filter(|m| m.rss_flat.is_some()).collect();
    let grew: Vec<String> = judged
        .iter()
        .filter(|m| m.rss_flat == Some(false) || m.threads_flat == Some(false))
        .map(|m| {
            format!(
                "{} {}: peak {} in the first half, {} in the second ({:+.1} MiB over {:.1} min, \
                 allowed {}), threads {} then {}",
                m.role,
                m.pid,
                kib(m.first_half_max_kib),
                kib(m.second_half_max_kib),
                m.growth_kib as f64 / 1024.0,
                m.observed_min,
                kib(m.allowance_kib),
                m.threads_max.0,
                m.threads_max.1
            )
        })
        .collect();
    let long_lived = ["run", "haptic", "view"]
        .iter()
        .all(|r| judged.iter().any(|m| m.role == *r));
    checks.push(check(
        "memory and threads of every process flat after warm-up",
        grew.is_empty() && long_lived,
        format!(
            "{} of {} process instances judged (warm-up {:.0} s, then at least {:.0} s \
             watched): the RSS peak of the second half of the watched time over the first's \
             at most {} + {} per minute of half (the others did not live that long){}",
            judged.len(),
            memory.len(),
            warmup,
            memory::MIN_OBSERVED_S,
            kib(memory::RSS_ALLOWANCE_KIB),
            kib(memory::RSS_ALLOWANCE_KIB_PER_MIN),
            if grew.is_empty() {
                if long_lived {
                    String::new()
                } else {
                    "; lopd run, haptic and view must each be judged: run longer".into()
                }
            } else {
                format!("; grew: {}", grew.join("; "))
            }
        ),
    ));
    checks.push(check(
        "lopd run stopped cleanly and removed its services",
        supervisor.exit.contains("exit status: 0") && supervisor.no_service_left,
        format!(
            "exit: {}; \"no service left\" logged: {}",
            supervisor.exit, supervisor.no_service_left
        ),
    ));
    checks.push(check(
        "the tool stream was observed",
        coverage >= MIN_COVERAGE,
        format!(
            "{} of {} tool states received ({:.2} %), {} haptic ticks in all",
            a.received,
            a.received + a.missed,
            100.0 * coverage,
            supervisor
                .haptic_ticks
                .map_or("?".into(), |t| t.to_string())
        ),
    ));

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

/// The printed report (also `soak.txt`).
fn render(r: &SoakReport) -> String {
    const W: usize = 100;
    let s = &r.settings;
    let mut out = format!(
        "\nlop-bench soak — scene {}, {:.1} min after the first frame, seed {}, haptic {:.0} Hz, \
         clamp {:.2} N, ramp {} ticks, stale limit {:.0} ms\n",
        s.scene,
        s.seconds / 60.0,
        s.seed,
        s.rate_hz,
        s.clamp_n,
        s.ramp_ticks,
        s.stale_ms
    );
    let p = &r.plan;
    out += &crate::table::note(
        &format!(
            "injected: {} deformation kills and {} stops, {} runs of broken samples ({} ticks), \
             {} viewer sessions, {} lopd ctl bursts, control requests every {} ms; the script \
             loops every {:.1} s",
            r.injections
                .iter()
                .filter(|i| i.kind == "kill" && i.at_s.is_some())
                .count(),
            r.injections
                .iter()
                .filter(|i| i.kind == "stop" && i.at_s.is_some())
                .count(),
            p.samples.len(),
            p.samples.iter().map(|e| e.ticks).sum::<u64>(),
            p.viewers.len(),
            p.ctl.len(),
            s.hammer_ms,
            s.script_period_s
        ),
        W,
    );
    out += "\n";
    for c in &r.checks {
        out += &format!("{} {}\n", if c.pass { "PASS" } else { "FAIL" }, c.name);
        out += &crate::table::note(&c.detail, W);
    }
    out += "\nmemory (VmRSS) of the process instances judged (peaks of the two halves of the \
            time watched after warm-up):\n";
    out += &format!(
        "  {:<7} {:>8} {:>9} {:>10} {:>10} {:>10} {:>10} {:>9} {:>8}  {}\n",
        "process",
        "pid",
        "watched",
        "start",
        "warm",
        "1st half",
        "2nd half",
        "growth",
        "threads",
        "verdict"
    );
    for m in r.memory.iter().filter(|m| m.rss_flat.is_some()) {
        out += &format!(
            "  {:<7} {:>8} {:>8.0}s {:>10} {:>10} {:>10} {:>10} {:>9} {:>8}  {}\n",
            m.role,
            m.pid,
            m.watched_s,
            kib(m.start.rss_kib),
            m.warm.map_or("-".into(), |w| kib(w.rss_kib)),
            kib(m.first_half_max_kib),
            kib(m.second_half_max_kib),
            format!("{:+.1}M", m.growth_kib as f64 / 1024.0),
            format!("{}/{}", m.threads_max.0, m.threads_max.1),
            match (m.rss_flat, m.threads_flat) {
                (Some(true), Some(true)) => "flat",
                _ => "GREW",
            }
        );
    }
    let short: Vec<&Verdict> = r.memory.iter().filter(|m| m.rss_flat.is_none()).collect();
    if !short.is_empty() {
        let watched = short.iter().map(|m| m.watched_s);
        let end = short.iter().map(|m| m.end.rss_kib);
        out += &format!(
            "  not judged: {} instances ({}) killed {:.0}–{:.0} s after they started, RSS at \
             their end {}–{}\n",
            short.len(),
            short
                .iter()
                .map(|m| m.role.as_str())
                .collect::<BTreeSet<_>>()
                .into_iter()
                .collect::<Vec<_>>()
                .join(", "),
            watched.clone().fold(f64::INFINITY, f64::min),
            watched.fold(0.0, f64::max),
            kib(end.clone().min().unwrap_or(0)),
            kib(end.max().unwrap_or(0))
        );
    }
    let mut violations: Vec<&String> = r.tool_stream.first_violations.iter().collect();
    violations.extend(&r.hammer.violations);
    violations.extend(&r.ctl.violations);
    violations.extend(&r.viewers.violations);
    if !violations.is_empty() {
        out += "\nfirst violations:\n";
        for v in violations {
            out += &crate::table::note(v, W);
        }
    }
    out += &format!(
        "\n{}\n",
        if r.pass {
            "soak: every check passed"
        } else {
            "soak: FAILED"
        }
    );
    out
}
