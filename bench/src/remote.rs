//! `lop-bench latency --remote`: the scene on other hosts through the Zenoh tunnel, as two
//! hosts on one machine (a far iceoryx2 domain of its own, joined over loopback).
//!
//! One `lopd run --remote` on the scene and one far side (`lopd remote attach` in a working
//! directory whose `config/iceoryx2.toml` sets another iceoryx2 prefix). Then phases of
//! `--seconds` each: no far viewer, then 1, 4 and 16 far viewers (this binary's hidden
//! `remote-reader`, each with its own frame subscriber in the far domain). In every phase this
//! process reads every frame in the rig's own domain beside them, so the local and far figures
//! come from the same frames' `publish_ns` on one monotonic clock:
//! - **frame latency**: receipt − publish, p50/p99, local and far (`frame_latency_local`,
//!   `remote_frame_latency`), with the count and the frames received out of order;
//! - **bytes** per frame (the frame header and 20 bytes per node) and per second per viewer;
//! - the rig's **haptic tick** compute and jitter over the phase: the largest p99 of the
//!   telemetry's one-second windows, read once a second, and the overruns.
//!
//! A last phase, `kills`, has no far viewer: a third of the way in it kills (SIGKILL) the rig's
//! `lop-tunnel`, two thirds in the far side (`lopd remote attach` and its tunnel), and reports
//! the same tick figures, the frames the local reader still got, and whether the rig's
//! supervisor started its tunnel again; compare it with the first phase of the same run.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use clap::Args;
use lop_client::services::{self, Role};
use lop_client::{clock, Attachment, ServiceNames};
use lop_client::{FrameHeader, HapticTelemetry, NodeSample};
use serde::Serialize;

use crate::pipeline::{find_lopd, ChildGuard};
use crate::stats::{median, quantile_sorted};

/// Far viewers per phase after the one without any.
pub const VIEWERS: [usize; 3] = [1, 4, 16];

/// How often a far reader looks for frames. Its figures are late by up to this much (half on
/// average), so they overstate the tunnel's latency a little. Not finer: on a real rig the far
/// viewers run on other hosts, while here 16 readers share the rig's 2 cores, and polling every
/// 100 us made them wake 160,000 times a second (16 far viewers: far p99 15-18 ms, against
/// about 5 ms with one). Not the frame-ready event the tunnel carries either: on the far side
/// it did not wake a reader for each frame (2026-12-07).
const READER_POLL: Duration = Duration::from_millis(1);

/// Options of the hidden `lop-bench remote-reader` (run in the far domain).
#[derive(Args, Debug, Clone)]
pub struct ReaderArgs {
    /// The rig's service prefix.
    #[arg(long)]
    prefix: String,
    /// Seconds to read after the topology arrived.
    #[arg(long)]
    seconds: f64,
}

/// One row of the JSON: frame latency of one kind of client in one phase.
#[derive(Debug, Clone, Serialize)]
pub struct LatencyRow {
    /// `frame_latency_local` or `remote_frame_latency`.
    pub name: &'static str,
    /// Far viewers in the phase.
    pub viewers: usize,
    /// Median receipt − publish, µs.
    pub p50_us: f64,
    /// 99th percentile, µs.
    pub p99_us: f64,
    /// Frames received (over all viewers of the kind).
    pub count: usize,
    /// Frames received after a later one (per viewer).
    pub reordered: usize,
}

/// The rig during one phase.
#[derive(Debug, Clone, Serialize)]
pub struct PhaseRow {
    /// Far viewers.
    pub viewers: usize,
    /// The phase that kills (SIGKILL) the rig's tunnel a third of the way in and the far side
    /// two thirds in, with no far viewer.
    pub kills: bool,
    /// In that phase: the rig's supervisor started a new tunnel after the kill.
    pub rig_tunnel_restarted: bool,
    /// Frames the local reader received during the phase.
    pub local_frames: usize,
    /// Haptic tick compute: the largest p99 of the telemetry's one-second windows read during
    /// the phase (once a second), µs.
    pub haptic_compute_p99_us: f64,
    /// Haptic period jitter: the largest p99 of the same windows, µs.
    pub haptic_jitter_p99_us: f64,
    /// The median of the same windows' compute p99s, µs: steadier than the largest from phase
    /// to phase, so the figure to compare phases by.
    pub haptic_compute_p99_median_us: f64,
    /// The median of the same windows' jitter p99s, µs.
    pub haptic_jitter_p99_median_us: f64,
    /// Overruns of the haptic loop during the phase.
    pub haptic_overruns: u64,
    /// Frames a second one far viewer received (mean over the viewers).
    pub far_frames_per_s: f64,
    /// Bytes a second to one far viewer (frames only).
    pub far_bytes_per_s: f64,
}

/// The whole report (`--json`).
#[derive(Debug, Clone, Serialize)]
pub struct RemoteReport {
    /// The scene.
    pub scene: String,
    /// Nodes per frame.
    pub nodes: usize,
    /// Bytes per frame: header and nodes.
    pub bytes_per_frame: usize,
    /// Seconds per phase.
    pub seconds: f64,
    /// Latency rows.
    pub rows: Vec<LatencyRow>,
    /// The rig per phase.
    pub phases: Vec<PhaseRow>,
}

/// `lop-bench remote-reader`: prints `SEQUENCE LATENCY_NS` for every frame of the topology
/// (after `topology`), then `done`.
pub fn reader(a: ReaderArgs) -> Result<()> {
    // One node with one topology and one frame subscriber: a viewer's share of the far
    // services' limits (16 viewers and the tunnel fit).
    let names = ServiceNames::new(&a.prefix)?;
    let node = services::node(&format!("lop-bench-remote-reader-{}", std::process::id()))?;
    let wait = Duration::from_secs(60);
    let topology_sub = services::open_retry(&names.topology, wait, || {
        services::topology_service(&node, &names, Role::Client)?
            .subscriber_builder()
            .create()
            .map_err(|e| lop_client::limits::subscriber_create_error(&names.topology, e))
    })?;
    let sub = services::open_retry(&names.frame, wait, || {
        services::frame_service(&node, &names, Role::Client)?
            .subscriber_builder()
            .buffer_size(services::FRAME_BUFFER)
            .create()
            .map_err(|e| lop_client::limits::subscriber_create_error(&names.frame, e))
    })?;
    let start = Instant::now();
    let topology = loop {
        if let Ok(Some(s)) = topology_sub.receive() {
            break s.user_header().topology_id;
        }
        if start.elapsed() > wait {
            bail!("no topology in {wait:?}");
        }
        std::thread::sleep(Duration::from_millis(2));
    };
    println!("topology");
    let end = Instant::now() + Duration::from_secs_f64(a.seconds);
    let mut out = String::new();
    while Instant::now() < end {
        while let Ok(Some(s)) = sub.receive() {
            let h = s.user_header();
            if h.topology_id == topology {
                let latency = clock::monotonic_ns() as i64 - h.publish_ns as i64;
                out.push_str(&format!("{} {latency}\n", h.sequence));
            }
        }
        std::thread::sleep(READER_POLL);
    }
    print!("{out}");
    println!("done");
    Ok(())
}

struct Frames {
    latencies_us: Vec<f64>,
    reordered: usize,
}

impl Frames {
    fn new() -> Frames {
        Frames {
            latencies_us: Vec::new(),
            reordered: 0,
        }
    }
}

/// A temporary far domain: a working directory with its own iceoryx2 prefix.
struct FarDomain(PathBuf);

impl FarDomain {
    fn new() -> Result<FarDomain> {
        let dir = std::env::temp_dir().join(format!("lop-bench-far-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("config"))?;
        std::fs::write(
            dir.join("config/iceoryx2.toml"),
            format!(
                "[global]\nprefix = \"lopbenchfar{}_\"\n",
                std::process::id()
            ),
        )?;
        Ok(FarDomain(dir))
    }
}

impl Drop for FarDomain {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn free_port() -> Result<u16> {
    Ok(std::net::TcpListener::bind("127.0.0.1:0")?
        .local_addr()?
        .port())
}

/// `lop-bench latency --remote`.
pub fn run(
    scene: &str,
    seconds: f64,
    lopd: Option<&Path>,
    config: Option<&Path>,
    json: Option<&Path>,
) -> Result<()> {
    let lopd = find_lopd(lopd)?;
    let me = std::env::current_exe().context("locating lop-bench")?;
    let prefix = format!("bench-remote-{}", std::process::id());
    let names = ServiceNames::new(&prefix)?;
    let endpoint = format!("tcp/127.0.0.1:{}", free_port()?);
    let mut cmd = Command::new(&lopd);
    cmd.args(["run", "--scene", scene, "--prefix", &prefix, "--quiet"])
        .args(["--remote", "--remote-listen", &endpoint])
        .stdin(Stdio::null());
    if let Some(c) = config {
        cmd.arg("--config").arg(c);
    }
    let mut rig = ChildGuard::spawn("lopd run --remote", cmd, Duration::from_secs(10))?;
    let far = FarDomain::new()?;
    let mut cmd = Command::new(&lopd);
    cmd.args([
        "remote",
        "attach",
        "--prefix",
        &prefix,
        "--connect",
        &endpoint,
    ])
    .current_dir(&far.0)
    .stdin(Stdio::null())
    .stdout(Stdio::null());
    let mut attach = ChildGuard::spawn("lopd remote attach", cmd, Duration::from_secs(5))?;

    let mut local =
        Attachment::open(&prefix, Duration::from_secs(120)).context("attaching to the rig")?;
    let nodes = local
        .wait_topology(Duration::from_secs(120))?
        .header
        .node_count as usize;
    let bytes_per_frame =
        std::mem::size_of::<FrameHeader>() + nodes * std::mem::size_of::<NodeSample>();
    let node = services::node("lop-bench-remote-local")?;
    let local_sub = services::frame_service(&node, &names, Role::Client)?
        .subscriber_builder()
        .buffer_size(services::FRAME_BUFFER)
        .create()
        .map_err(|e| lop_client::limits::subscriber_create_error(&names.frame, e))?;
    // Frames through the tunnel before measuring: one far reader must see the topology.
    warm_up(&me, &far.0, &prefix)?;

    let mut rows = Vec::new();
    let mut phases = Vec::new();
    let plan = std::iter::once((0, false))
        .chain(VIEWERS.map(|v| (v, false)))
        .chain([(0, true)]);
    for (viewers, kills) in plan {
        if rig.try_wait().is_some() || attach.try_wait().is_some() {
            bail!("the rig or the far side exited during the run");
        }
        if kills {
            eprintln!(
                "lop-bench: the rig's tunnel killed at {:.1} s, the far side at {:.1} s, of {seconds} s",
                seconds / 3.0,
                seconds * 2.0 / 3.0
            );
        } else {
            eprintln!("lop-bench: {viewers} far viewer(s), {seconds} s");
        }
        let mut readers = Vec::new();
        for _ in 0..viewers {
            let mut cmd = Command::new(&me);
            cmd.args(["remote-reader", "--prefix", &prefix, "--seconds"])
                .arg(format!("{seconds}"))
                .current_dir(&far.0)
                .stdout(Stdio::piped())
                .stdin(Stdio::null());
            readers.push(ChildGuard::spawn(
                "remote-reader",
                cmd,
                Duration::from_secs(5),
            )?);
        }
        // Every reader has its topology before the phase's clock starts.
        let mut outs = Vec::new();
        for r in &mut readers {
            let stdout = r
                .child_mut()
                .and_then(|c| c.stdout.take())
                .context("reader stdout")?;
            let mut lines = BufReader::new(stdout).lines();
            match lines.next() {
                Some(Ok(l)) if l == "topology" => outs.push(lines),
                other => bail!("a far reader got no topology: {other:?}"),
            }
        }
        let mut tick = TickWindows::new(local.telemetry());
        let mut local_frames = Frames::new();
        let mut last_seq = 0;
        let start = Instant::now();
        let end = start + Duration::from_secs_f64(seconds);
        let mut rig_tunnel = None;
        let mut far_killed = false;
        while Instant::now() < end {
            tick.look(&mut local);
            if kills {
                let t = start.elapsed().as_secs_f64();
                if rig_tunnel.is_none() && t >= seconds / 3.0 {
                    let pid = kill_rig_tunnel(rig.id())?;
                    rig_tunnel = Some(pid);
                }
                if !far_killed && t >= seconds * 2.0 / 3.0 {
                    // SIGKILL: `lopd remote attach`'s tunnel dies with it.
                    // SAFETY: kill(2) on our own child's pid.
                    unsafe { libc::kill(attach.id() as i32, libc::SIGKILL) };
                    far_killed = true;
                }
            }
            while let Ok(Some(s)) = local_sub.receive() {
                let h = s.user_header();
                let latency = clock::monotonic_ns() as i64 - h.publish_ns as i64;
                local_frames.latencies_us.push(latency as f64 / 1e3);
                if h.sequence <= last_seq {
                    local_frames.reordered += 1;
                }
                last_seq = h.sequence;
            }
            std::thread::sleep(Duration::from_micros(100));
        }
        tick.look(&mut local);
        let restarted = match rig_tunnel {
            Some(killed) => {
                let now = tunnels_under(rig.id());
                if now.is_empty() || now.contains(&killed) {
                    bail!("the rig's tunnel was not started again after its kill: {now:?}");
                }
                true
            }
            None => false,
        };
        let mut far_frames = Frames::new();
        let mut per_viewer = Vec::new();
        for lines in outs {
            let mut last = 0u64;
            let mut n = 0usize;
            let mut done = false;
            for l in lines {
                let l = l?;
                if l == "done" {
                    done = true;
                    break;
                }
                let mut w = l.split_whitespace();
                let seq: u64 = w.next().unwrap_or("0").parse()?;
                let latency: f64 = w.next().unwrap_or("0").parse()?;
                far_frames.latencies_us.push(latency / 1e3);
                if seq <= last {
                    far_frames.reordered += 1;
                }
                last = seq;
                n += 1;
            }
            if !done {
                bail!("a far reader stopped early");
            }
            per_viewer.push(n as f64 / seconds);
        }
        for r in &mut readers {
            r.wait_for(Duration::from_secs(10));
        }
        let local_count = local_frames.latencies_us.len();
        if !kills {
            rows.push(latency_row("frame_latency_local", viewers, local_frames));
        }
        if viewers > 0 {
            rows.push(latency_row("remote_frame_latency", viewers, far_frames));
        }
        let far_frames_per_s = if per_viewer.is_empty() {
            0.0
        } else {
            per_viewer.iter().sum::<f64>() / per_viewer.len() as f64
        };
        phases.push(PhaseRow {
            viewers,
            kills,
            rig_tunnel_restarted: restarted,
            local_frames: local_count,
            haptic_compute_p99_us: largest(&tick.computes),
            haptic_jitter_p99_us: largest(&tick.jitters),
            haptic_compute_p99_median_us: median(&mut tick.computes).unwrap_or(f64::NAN),
            haptic_jitter_p99_median_us: median(&mut tick.jitters).unwrap_or(f64::NAN),
            haptic_overruns: tick.overruns(),
            far_frames_per_s,
            far_bytes_per_s: far_frames_per_s * bytes_per_frame as f64,
        });
    }
    drop(local_sub);
    drop(node);
    drop(local);
    attach.stop();
    rig.stop();

    let report = RemoteReport {
        scene: scene.to_string(),
        nodes,
        bytes_per_frame,
        seconds,
        rows,
        phases,
    };
    print!("{}", render(&report));
    if let Some(path) = json {
        std::fs::write(path, serde_json::to_string_pretty(&report)?)
            .with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}

/// One far reader until it has the topology and a second of frames.
fn warm_up(me: &Path, far: &Path, prefix: &str) -> Result<()> {
    let out = Command::new(me)
        .args(["remote-reader", "--prefix", prefix, "--seconds", "1"])
        .current_dir(far)
        .stdin(Stdio::null())
        .output()
        .context("warm-up reader")?;
    let text = String::from_utf8_lossy(&out.stdout);
    if !out.status.success() || text.lines().count() < 3 {
        bail!(
            "no frames reached the far side in the warm-up: {}\n{text}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    Ok(())
}

/// The haptic loop's telemetry over a phase: the largest window p99s seen and the overruns.
struct TickWindows {
    /// Every window's compute and jitter p99 read, µs.
    computes: Vec<f64>,
    jitters: Vec<f64>,
    first_overruns: Option<u64>,
    last_overruns: Option<u64>,
    last_look: Instant,
}

impl TickWindows {
    fn new(first: Option<HapticTelemetry>) -> TickWindows {
        let mut w = TickWindows {
            computes: Vec::new(),
            jitters: Vec::new(),
            first_overruns: None,
            last_overruns: None,
            last_look: Instant::now(),
        };
        if let Some(t) = first {
            w.first_overruns = Some(t.overruns);
            w.last_overruns = Some(t.overruns);
        }
        w
    }

    /// Reads the newest telemetry, at most once a second (a window is one second).
    fn look(&mut self, local: &mut Attachment) {
        if self.last_look.elapsed() < Duration::from_secs(1) {
            return;
        }
        self.last_look = Instant::now();
        if let Some(t) = local.telemetry() {
            self.computes.push(t.window_compute.p99 as f64 / 1e3);
            self.jitters.push(t.window_jitter.p99 as f64 / 1e3);
            self.first_overruns.get_or_insert(t.overruns);
            self.last_overruns = Some(t.overruns);
        }
    }

    fn overruns(&self) -> u64 {
        match (self.first_overruns, self.last_overruns) {
            (Some(a), Some(b)) => b.saturating_sub(a),
            _ => 0,
        }
    }
}

/// The largest of `v` (NaN when empty).
fn largest(v: &[f64]) -> f64 {
    v.iter().copied().fold(f64::NAN, f64::max)
}

/// The `lop-tunnel` processes under `lopd run` (pid `rig`): its `lopd remote serve` child's.
fn tunnels_under(rig: u32) -> Vec<u32> {
    crate::soak::children(rig)
        .into_iter()
        .flat_map(crate::soak::children)
        .filter(|&pid| {
            crate::soak::cmdline(pid)
                .first()
                .is_some_and(|exe| exe.ends_with("lop-tunnel"))
        })
        .collect()
}

/// Kills (SIGKILL) the rig's tunnel; its pid.
fn kill_rig_tunnel(rig: u32) -> Result<u32> {
    let Some(&pid) = tunnels_under(rig).first() else {
        bail!("no lop-tunnel found under the rig (lopd run, pid {rig}) to kill");
    };
    // SAFETY: kill(2) on a pid just read from /proc, a grandchild of ours.
    unsafe { libc::kill(pid as i32, libc::SIGKILL) };
    Ok(pid)
}

fn latency_row(name: &'static str, viewers: usize, mut f: Frames) -> LatencyRow {
    f.latencies_us.sort_by(f64::total_cmp);
    let q = |p: f64| {
        if f.latencies_us.is_empty() {
            f64::NAN
        } else {
            quantile_sorted(&f.latencies_us, p)
        }
    };
    LatencyRow {
        name,
        viewers,
        p50_us: q(0.5),
        p99_us: q(0.99),
        count: f.latencies_us.len(),
        reordered: f.reordered,
    }
}

fn render(r: &RemoteReport) -> String {
    let mut s = format!(
        "remote frames: scene {}, {} nodes, {} bytes a frame, {} s a phase\n\n",
        r.scene, r.nodes, r.bytes_per_frame, r.seconds
    );
    s.push_str("viewers  client  frames  latency p50 / p99 (us)  reordered\n");
    for row in &r.rows {
        s.push_str(&format!(
            "{:>7}  {:<6}  {:>6}  {:>9.0} / {:<9.0}      {}\n",
            row.viewers,
            if row.name == "remote_frame_latency" {
                "far"
            } else {
                "local"
            },
            row.count,
            row.p50_us,
            row.p99_us,
            row.reordered
        ));
    }
    s.push_str(
        "\nhaptic tick p99 over the phase's one-second windows: median / largest\n\
         viewers  compute p99 (us)  jitter p99 (us)  overruns  far frames/s  far kB/s\n",
    );
    for p in &r.phases {
        s.push_str(&format!(
            "{:>7}  {:>16}  {:>15}  {:>8}  {:>12.1}  {:>8.0}{}\n",
            if p.kills {
                "kills".to_string()
            } else {
                p.viewers.to_string()
            },
            format!(
                "{:.1} / {:.1}",
                p.haptic_compute_p99_median_us, p.haptic_compute_p99_us
            ),
            format!(
                "{:.1} / {:.1}",
                p.haptic_jitter_p99_median_us, p.haptic_jitter_p99_us
            ),
            p.haptic_overruns,
            p.far_frames_per_s,
            p.far_bytes_per_s / 1e3,
            match (p.kills, p.rig_tunnel_restarted) {
                (true, restarted) => format!(
                    "  (local frames {}; rig tunnel {})",
                    p.local_frames,
                    if restarted {
                        "restarted"
                    } else {
                        "NOT restarted"
                    }
                ),
                _ => String::new(),
            }
        ));
    }
    s
}
