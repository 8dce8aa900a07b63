//! `lop-bench latency`: end-to-end latency of the real pipeline with the mock device.
//!
//! The bench starts `lopd run --device mock --quiet` under a private service prefix
//! (`lopbench-<pid>`), attaches read-only like any viewer (`lop_client::Attachment`), waits for the
//! first frame, lets one second pass as warm-up, then measures for `--seconds`, and stops the
//! daemon with SIGTERM (SIGKILL after 5 s; on every error path too). Every figure is reported as
//! count, p50, p99, p99.9 and max in µs. All timestamps are `CLOCK_MONOTONIC`, which is
//! system-wide, so stamps taken in different processes can be subtracted.
//!
//! | row | meaning | measured |
//! |---|---|---|
//! | haptic period jitter | \|actual wake-up − deadline\| of the 1 kHz loop | by the haptic loop itself (`HapticTelemetry::total_jitter`) |
//! | machine wake-up latency (cyclictest) | how late a bare `SCHED_FIFO` thread wakes on this machine, the floor under the row above | `cyclictest`, run concurrently during the window (see `cyclictest.rs`) |
//! | haptic tick compute | wake-up → device written → tool state published, one tick | haptic loop (`total_compute`) |
//! | frame age at haptic loop | how old the newest surface was when a tick rendered against it | haptic loop (`total_frame_age`) |
//! | frame age in contact | the same over the ticks that rendered a contact (pressing or holding a body): how old the surface under the hand was | haptic loop (`total_frame_age_contact`) |
//! | tool → deform latency | how old the tool state was when the deformation step read it (`tool_read_ns − tool_stamp_ns` of each frame header; frames with no tool state yet are skipped) | bench, from every frame received in the window |
//! | deform → client latency | frame published → received by this bench (`received_ns − publish_ns`) | bench, from every frame received in the window; **includes the bench's polling interval** (it sleeps `--poll-us` between polls) |
//! | device → tissue latency | a device sample → the frame of the tissue that responded to it (`publish_ns − tool_stamp_ns`; the tool state carries the device sample's tick time), over the frames whose contact patch pressed a body: how late the tissue the eye sees (and the surface the hand touches next) answers the hand | bench, from the frames in contact |
//! | touched body: frame interval | time between two frames in contact (`publish_ns` differences): the rate at which the touched body's surface reaches the haptic loop | bench, consecutive frames in contact |
//! | deform round | wall time of the round behind each frame (`FrameHeader::step_ns`: collision, every body due, heat), every frame in the window: at the haptic rate a round longer than a millisecond delays the next frame | bench, from every frame received in the window |
//! | touched body: step | wall time of the touched body's last step (`BodyFrame::step_ns` of tool 0's `ContactFrame::body`), once per frame in contact | bench, from the frames in contact |
//!
//! Below the table: the periods the touched body stepped at in the frames in contact
//! (`BodyFrame::period_us`: longer than configured where its step costs more on this machine)
//! and the lowest real-time factor they carried (`BodyFrame::real_time_factor`, simulated over
//! wall time per second).
//!
//! The haptic rows come from the loop's own preallocated histograms, which cover everything from
//! one second after the haptic process started (its own warm-up) to the last telemetry sample
//! taken after the window ends; the bench's window starts one second after the first frame, so
//! both leave out start-up. The tick count, overruns and the achieved rate are counted over the
//! window, as the difference between the first telemetry sample inside it and the last one (the
//! haptic loop publishes telemetry about 4× a second). `rt_flags` says whether the loop ran
//! under `SCHED_FIFO`, pinned and with locked memory: without those privileges the jitter is
//! that of a normal thread.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use clap::Args;
use hdrhistogram::Histogram;
use lop_client::{clock, Attachment, HapticTelemetry, CONTRACT_VERSION, NO_CONTACT};
use lop_ipc::{RT_FLAG_FIFO, RT_FLAG_MLOCKED, RT_FLAG_PINNED};
use serde::Serialize;

use crate::cyclictest;
use crate::pipeline::{self, Lopd, LopdOptions};
use crate::scenes::scene_with_tools;
use crate::table::{self, Row};

/// Warm-up after the first frame, s.
const WARMUP_S: f64 = 1.0;
/// `--duration` given to `lopd run` beyond the window: a backstop only (the bench stops it with
/// SIGTERM), generous so a slow scene load can never cut the window short.
const BACKSTOP_EXTRA_S: f64 = 10.0;
/// How long to wait for the daemon's services and its first frame.
const ATTACH_TIMEOUT: Duration = Duration::from_secs(15);

/// Options of `lop-bench latency`.
#[derive(Args, Debug, Clone)]
pub struct LatencyArgs {
    /// Seconds to measure (after a 1 s warm-up).
    #[arg(long, default_value_t = 10.0)]
    seconds: f64,
    /// Scene name (see `lopd scenes`) or path to a scene TOML.
    #[arg(long, default_value = "organs")]
    scene: String,
    /// Also write the figures as JSON to this file.
    #[arg(long)]
    json: Option<PathBuf>,
    /// The `lopd` binary (default: the `lopd` next to this executable).
    #[arg(long)]
    lopd: Option<PathBuf>,
    /// A daemon configuration for `lopd run` (e.g. `[haptic] local_model = false` to compare
    /// the haptic tick without the local model in the same session).
    #[arg(long)]
    config: Option<PathBuf>,
    /// Do not run cyclictest beside the pipeline.
    #[arg(long)]
    no_cyclictest: bool,
    /// Sleep between two polls for frames, µs (part of the deform → client figure).
    #[arg(long, default_value_t = 150)]
    poll_us: u64,
    /// Also run the scene with 2 up to this many devices, one tool each (the scene's first
    /// tool copied, each copy's device mapped 30 mm further along x, all mock devices playing
    /// the scene's script), each for the same seconds: the haptic tick's compute and jitter
    /// per device count, beside the one device's of the same run.
    #[arg(long, default_value_t = 1)]
    devices: usize,
    /// The scene on another host instead: `lopd run --remote` and a far side (`lopd remote
    /// attach` into an iceoryx2 domain of its own, over loopback), with 0, 1, 4 and 16 far
    /// viewers for --seconds each: frame latency far and local from the same frames, bytes a
    /// frame and a second, the rig's haptic tick per phase.
    #[arg(long)]
    remote: bool,
}

/// Whether and how the loop got its real-time privileges.
#[derive(Debug, Clone, Serialize)]
pub struct RtReport {
    /// `SCHED_FIFO`.
    pub sched_fifo: bool,
    /// Pinned to a core.
    pub pinned: bool,
    /// The core, if pinned.
    pub pinned_core: Option<i32>,
    /// `mlockall`.
    pub mlocked: bool,
}

/// cyclictest's part of the report.
#[derive(Debug, Clone, Serialize)]
pub struct CyclictestReport {
    /// `ran`, `disabled`, `not installed` or `failed`.
    pub status: String,
    /// Why it did not run, or how to install it.
    pub note: Option<String>,
    /// What it measured (its row is also in `rows`).
    pub result: Option<cyclictest::Outcome>,
}

/// Everything `lop-bench latency` reports (the JSON file).
#[derive(Debug, Clone, Serialize)]
pub struct LatencyReport {
    /// Scene name.
    pub scene: String,
    /// Scene file.
    pub scene_path: String,
    /// Device (always the mock).
    pub device: String,
    /// The measuring window, s (as requested).
    pub seconds: f64,
    /// Warm-up before the window, s.
    pub warmup_seconds: f64,
    /// Service prefix used.
    pub prefix: String,
    /// The haptic rate the scene asks for, Hz.
    pub target_rate_hz: f64,
    /// Achieved: ticks in the window / its length, Hz.
    pub rate_hz: f64,
    /// Haptic ticks counted over the window (between two telemetry samples).
    pub window_ticks: u64,
    /// Length of that window, s.
    pub window_seconds: f64,
    /// Overruns in the window.
    pub window_overruns: u64,
    /// Ticks since the haptic loop started (last telemetry).
    pub ticks: u64,
    /// Overruns since the haptic loop started.
    pub overruns: u64,
    /// Ticks whose frame was stale, since the haptic loop started.
    pub stale_ticks: u64,
    /// Device faults since the haptic loop started.
    pub device_faults: u64,
    /// Real-time privileges of the haptic loop.
    pub rt: RtReport,
    /// The periods the touched body stepped at in the frames in contact, ms, shortest first.
    pub touched_periods_ms: Vec<f64>,
    /// The lowest real-time factor of the touched body in the frames in contact (simulated
    /// over wall time per second; `None` before a second of it).
    pub touched_real_time_factor_min: Option<f64>,
    /// Frames received in the window.
    pub frames_received: u64,
    /// Frames published in the window but never received (sequence gaps).
    pub frames_missed: u64,
    /// Frames received without a tool state (left out of tool → deform).
    pub frames_without_tool: u64,
    /// Sleep between polls, µs (part of deform → client).
    pub poll_interval_us: u64,
    /// The figures, in table order.
    pub rows: Vec<Row>,
    /// cyclictest's status and result.
    pub cyclictest: CyclictestReport,
}

enum CtPlan {
    Disabled,
    NotInstalled,
    Unavailable(String),
    Ready(cyclictest::Plan),
}

/// Runs the benchmark, prints the table and writes the JSON.
pub fn run(a: LatencyArgs) -> Result<()> {
    if a.remote {
        return crate::remote::run(
            &a.scene,
            a.seconds,
            a.lopd.as_deref(),
            a.config.as_deref(),
            a.json.as_deref(),
        );
    }
    if !(1..=lop_ipc::MAX_TOOLS).contains(&a.devices) {
        bail!("--devices {}: 1 to {}", a.devices, lop_ipc::MAX_TOOLS);
    }
    let (mut report, stopped) = measure_scene(&a)?;
    // The haptic loop's rows name the device count they were measured with.
    for row in report.rows.iter_mut().filter(|r| is_haptic(r)) {
        row.devices = Some(1);
    }
    let one = haptic_rows(&report.rows);
    let mut more = Vec::new();
    for n in 2..=a.devices {
        // Each further device 30 mm along x: apart, and still over the tissue.
        let scene = scene_with_tools(Path::new(&report.scene_path), n, 0.03)?;
        let run = LatencyArgs {
            scene: scene.path().display().to_string(),
            json: None,
            no_cyclictest: true,
            devices: 1,
            ..a.clone()
        };
        let (r, s) = measure_scene(&run)?;
        s.with_context(|| format!("the run with {n} devices"))?;
        for row in haptic_rows(&r.rows) {
            more.push(row.with_devices(n as u32));
        }
    }
    let period_us = (1e6 / report.target_rate_hz).round().max(1.0) as u64;
    print!("{}", render(&report, period_us));
    report.rows.extend(more.iter().cloned());
    if !more.is_empty() {
        println!("\nthe haptic tick with several devices (same run; one device above):");
        println!("{}", table::header());
        for row in one.iter().chain(&more) {
            let label = format!("{}, {} device(s)", row.label, row.devices.unwrap_or(1));
            println!(
                "{}",
                table::line(&Row {
                    label,
                    ..row.clone()
                })
            );
        }
        let p99 = |rows: &[Row], key: &str| {
            rows.iter()
                .find(|r| r.key == key)
                .map_or(f64::NAN, |r| r.p99_us)
        };
        for n in 2..=a.devices {
            let of_n: Vec<Row> = more
                .iter()
                .filter(|r| r.devices == Some(n as u32))
                .cloned()
                .collect();
            println!(
                "{n} devices: tick compute p99 {:.1} µs, {:.2} × one device's (target ≤ 1.5); \
                 jitter p99 {:.1} µs against {:.1} µs",
                p99(&of_n, "haptic_compute"),
                p99(&of_n, "haptic_compute") / p99(&one, "haptic_compute"),
                p99(&of_n, "haptic_jitter"),
                p99(&one, "haptic_jitter"),
            );
        }
    }
    if let Some(path) = &a.json {
        let text = serde_json::to_string_pretty(&report)?;
        std::fs::write(path, text + "\n").with_context(|| format!("writing {}", path.display()))?;
        println!("JSON written to {}", path.display());
    }
    // The figures stand, but a daemon that did not stop cleanly is a failure worth an exit code.
    stopped
}

impl LatencyArgs {
    /// A run of `scene` for `seconds` with the mock device and no cyclictest (how other
    /// benchmarks measure a scene of their own), with an optional daemon configuration.
    pub fn quiet(
        scene: &Path,
        seconds: f64,
        lopd: Option<PathBuf>,
        config: Option<PathBuf>,
    ) -> LatencyArgs {
        LatencyArgs {
            seconds,
            scene: scene.display().to_string(),
            json: None,
            lopd,
            config,
            no_cyclictest: true,
            poll_us: 150,
            devices: 1,
            remote: false,
        }
    }
}

/// Whether `row` is one of the haptic loop's rows (`haptic_jitter`, `haptic_compute`), the
/// ones measured per device count.
fn is_haptic(row: &Row) -> bool {
    row.key == "haptic_jitter" || row.key == "haptic_compute"
}

/// The haptic loop's rows of a report.
fn haptic_rows(rows: &[Row]) -> Vec<Row> {
    rows.iter().filter(|r| is_haptic(r)).cloned().collect()
}

/// One measured run of the pipeline, printed nowhere: the report, and whether the daemon then
/// stopped cleanly (the figures stand either way).
pub fn measure_scene(a: &LatencyArgs) -> Result<(LatencyReport, Result<()>)> {
    if !(a.seconds.is_finite() && a.seconds >= 0.5 && a.seconds <= 86_400.0) {
        bail!("--seconds {}: must be between 0.5 and 86400", a.seconds);
    }
    if a.poll_us > 100_000 {
        bail!("--poll-us {}: at most 100000", a.poll_us);
    }
    let lopd_path = pipeline::find_lopd(a.lopd.as_deref())?;
    let scene_path = lop_config::resolve_scene(&a.scene)?;
    let scene = lop_config::load_scene(&scene_path)
        .with_context(|| format!("loading scene {}", scene_path.display()))?;
    let target_rate = scene.rates.haptic_hz;
    let period_us = (1e6 / target_rate).round().max(1.0) as u64;

    // One priority below the haptic loop's, so the yardstick never delays what it is compared to.
    let ct_priority = lop_config::DaemonConfig::default()
        .haptic
        .rt_priority
        .saturating_sub(1)
        .max(1);
    let ct_plan = if a.no_cyclictest {
        CtPlan::Disabled
    } else {
        match cyclictest::find() {
            None => CtPlan::NotInstalled,
            Some(exe) => match cyclictest::probe(&exe, ct_priority) {
                Ok(plan) => CtPlan::Ready(plan),
                Err(e) => CtPlan::Unavailable(format!("{e:#}")),
            },
        }
    };

    let prefix = pipeline::unique_prefix();
    let mut lopd = Lopd::spawn(&LopdOptions {
        lopd: lopd_path,
        scene: scene_path.display().to_string(),
        device: "mock".into(),
        duration: Duration::from_secs_f64(WARMUP_S + a.seconds + BACKSTOP_EXTRA_S),
        prefix: prefix.clone(),
        extra_args: a
            .config
            .iter()
            .flat_map(|c| ["--config".to_string(), c.display().to_string()])
            .collect(),
        log: None,
    })?;
    let measured = measure(&mut lopd, a, period_us, &ct_plan);
    // Stop the pipeline whatever happened (the guard would also do it on drop).
    let stopped = lopd.stop();
    let m = measured?;

    let tel_first = m.tel_first;
    let tel = m.tel_last;
    let (Some(window_ticks), Some(window_overruns)) = (
        tel.ticks.checked_sub(tel_first.ticks),
        tel.overruns.checked_sub(tel_first.overruns),
    ) else {
        bail!("the haptic process restarted during the window (its tick count went back)");
    };
    let window_seconds = (tel.stamp_ns - tel_first.stamp_ns) as f64 * 1e-9;
    let rate_hz = window_ticks as f64 / window_seconds;
    let rt = RtReport {
        sched_fifo: tel.rt_flags & RT_FLAG_FIFO != 0,
        pinned: tel.rt_flags & RT_FLAG_PINNED != 0,
        pinned_core: (tel.rt_flags & RT_FLAG_PINNED != 0 && tel.pinned_core >= 0)
            .then_some(tel.pinned_core),
        mlocked: tel.rt_flags & RT_FLAG_MLOCKED != 0,
    };

    let mut rows = vec![Row::from_percentiles(
        "haptic_jitter",
        "haptic period jitter",
        &tel.total_jitter,
    )];
    let ct_report = match (&ct_plan, m.cyclictest) {
        (CtPlan::Disabled, _) => CyclictestReport {
            status: "disabled".into(),
            note: Some("--no-cyclictest".into()),
            result: None,
        },
        (CtPlan::NotInstalled, _) => CyclictestReport {
            status: "not installed".into(),
            note: Some(
                "cyclictest not found on PATH; install it with `apt-get install rt-tests` to \
                 compare the haptic jitter with this machine's wake-up latency"
                    .into(),
            ),
            result: None,
        },
        (CtPlan::Unavailable(e), _) => CyclictestReport {
            status: "failed".into(),
            note: Some(e.clone()),
            result: None,
        },
        (CtPlan::Ready(_), Some(Ok(outcome))) => {
            rows.push(outcome.row.clone());
            CyclictestReport {
                status: "ran".into(),
                note: None,
                result: Some(outcome),
            }
        }
        (CtPlan::Ready(_), Some(Err(e))) => CyclictestReport {
            status: "failed".into(),
            note: Some(format!("{e:#}")),
            result: None,
        },
        (CtPlan::Ready(_), None) => CyclictestReport {
            status: "failed".into(),
            note: Some("did not start".into()),
            result: None,
        },
    };
    rows.push(Row::from_percentiles(
        "haptic_compute",
        "haptic tick compute",
        &tel.total_compute,
    ));
    rows.push(Row::from_percentiles(
        "frame_age",
        "frame age at haptic loop",
        &tel.total_frame_age,
    ));
    rows.push(Row::from_percentiles(
        "frame_age_contact",
        "frame age in contact",
        &tel.total_frame_age_contact,
    ));
    let measured_rows = [
        ("tool_to_deform", "tool → deform latency", &m.tool_to_deform),
        (
            "deform_to_client",
            "deform → client latency",
            &m.deform_to_client,
        ),
        (
            "device_to_tissue",
            "device → tissue latency",
            &m.device_to_tissue,
        ),
        (
            "touched_frame_interval",
            "touched body: frame interval",
            &m.touched_interval,
        ),
        ("deform_round", "deform round", &m.deform_round),
        ("touched_step", "touched body: step", &m.touched_step),
    ];
    for (key, label, h) in measured_rows {
        rows.push(Row::from_histogram_ns(key, label, h));
    }

    let report = LatencyReport {
        scene: scene.name.clone(),
        scene_path: scene_path.display().to_string(),
        device: "mock".into(),
        seconds: a.seconds,
        warmup_seconds: WARMUP_S,
        prefix,
        target_rate_hz: target_rate,
        rate_hz,
        window_ticks,
        window_seconds,
        window_overruns,
        ticks: tel.ticks,
        overruns: tel.overruns,
        stale_ticks: tel.stale_ticks,
        device_faults: tel.device_faults,
        rt,
        touched_periods_ms: m
            .touched_periods_us
            .iter()
            .map(|&us| f64::from(us) * 1e-3)
            .collect(),
        touched_real_time_factor_min: m.touched_rt_min,
        frames_received: m.frames_received,
        frames_missed: m.frames_missed,
        frames_without_tool: m.frames_without_tool,
        poll_interval_us: a.poll_us,
        rows,
        cyclictest: ct_report,
    };
    Ok((report, stopped.map(|_| ())))
}

/// What the measuring loop collected.
struct Measured {
    tel_first: HapticTelemetry,
    tel_last: HapticTelemetry,
    tool_to_deform: Histogram<u64>,
    deform_to_client: Histogram<u64>,
    device_to_tissue: Histogram<u64>,
    deform_round: Histogram<u64>,
    touched_interval: Histogram<u64>,
    touched_step: Histogram<u64>,
    touched_periods_us: std::collections::BTreeSet<u32>,
    touched_rt_min: Option<f64>,
    frames_received: u64,
    frames_missed: u64,
    frames_without_tool: u64,
    cyclictest: Option<Result<cyclictest::Outcome>>,
}

fn telemetry(att: &mut Attachment) -> Option<HapticTelemetry> {
    att.telemetry()
        .filter(|t| t.contract_version == CONTRACT_VERSION)
}

fn measure(lopd: &mut Lopd, a: &LatencyArgs, period_us: u64, ct: &CtPlan) -> Result<Measured> {
    let mut att = lopd.attach(ATTACH_TIMEOUT)?;
    let poll = Duration::from_micros(a.poll_us);

    // The first frame starts the warm-up.
    let waiting = Instant::now();
    let first_ns = loop {
        lopd.check_alive()?;
        if !att.frames()?.is_empty() {
            break clock::monotonic_ns();
        }
        if waiting.elapsed() > ATTACH_TIMEOUT {
            bail!(
                "no frame from lopd within {ATTACH_TIMEOUT:?}; {}",
                lopd.log_tail(20)
            );
        }
        std::thread::sleep(Duration::from_millis(1));
    };
    let window_ns = (a.seconds * 1e9) as u64;
    let start_ns = first_ns + (WARMUP_S * 1e9) as u64;
    let end_ns = start_ns + window_ns;

    let mut tool_to_deform = table::latency_histogram();
    let mut deform_to_client = table::latency_histogram();
    let mut device_to_tissue = table::latency_histogram();
    let mut deform_round = table::latency_histogram();
    let mut touched_interval = table::latency_histogram();
    let mut touched_step = table::latency_histogram();
    let mut touched_periods_us = std::collections::BTreeSet::new();
    let mut touched_rt_min: Option<f64> = None;
    let mut last_touched: Option<(u32, u64)> = None;
    let mut frames_received = 0u64;
    let mut frames_missed = 0u64;
    let mut frames_without_tool = 0u64;
    let mut last_seq: Option<u64> = None;
    let mut tel_first: Option<HapticTelemetry> = None;
    let mut tel_last: Option<HapticTelemetry> = None;
    let mut running_ct: Option<cyclictest::Running> = None;
    let mut ct_start_err: Option<anyhow::Error> = None;
    let mut last_check = Instant::now();

    loop {
        let now = clock::monotonic_ns();
        if now >= end_ns {
            break;
        }
        if now >= start_ns && running_ct.is_none() && ct_start_err.is_none() {
            if let CtPlan::Ready(plan) = ct {
                let loops = (window_ns / (period_us * 1000)).max(1);
                match cyclictest::start(plan, period_us, loops) {
                    Ok(r) => running_ct = Some(r),
                    Err(e) => ct_start_err = Some(e),
                }
            }
        }
        for f in att.frames()? {
            if f.received_ns < start_ns || f.received_ns >= end_ns {
                last_seq = Some(f.header.sequence);
                continue;
            }
            if let Some(prev) = last_seq {
                let gap = f.header.sequence.saturating_sub(prev + 1);
                frames_missed += gap;
                if gap > 0 {
                    // The interval would span the missed frames.
                    last_touched = None;
                }
            }
            last_seq = Some(f.header.sequence);
            frames_received += 1;
            let h = &f.header;
            if h.tool_stamp_ns == 0 {
                frames_without_tool += 1;
            } else {
                tool_to_deform.saturating_record(h.tool_read_ns.saturating_sub(h.tool_stamp_ns));
            }
            deform_to_client.saturating_record(f.received_ns.saturating_sub(h.publish_ns));
            deform_round.saturating_record(h.step_ns);
            // The scene's one tool: tool 0.
            let contact_body = h.contact(0).map_or(NO_CONTACT, |c| c.body);
            let touched = f
                .bodies()
                .get(contact_body as usize)
                .filter(|_| contact_body != NO_CONTACT);
            match touched {
                Some(body) => {
                    if h.tool_stamp_ns != 0 {
                        device_to_tissue
                            .saturating_record(h.publish_ns.saturating_sub(h.tool_stamp_ns));
                    }
                    touched_step.saturating_record(u64::from(body.step_ns));
                    touched_periods_us.insert(body.period_us);
                    if body.real_time_factor > 0.0 {
                        let f = f64::from(body.real_time_factor);
                        touched_rt_min = Some(touched_rt_min.map_or(f, |m| m.min(f)));
                    }
                    if let Some((b, at)) = last_touched {
                        if b == contact_body {
                            touched_interval.saturating_record(h.publish_ns.saturating_sub(at));
                        }
                    }
                    last_touched = Some((contact_body, h.publish_ns));
                }
                None => last_touched = None,
            }
        }
        if last_check.elapsed() >= Duration::from_millis(10) {
            last_check = Instant::now();
            if let Some(t) = telemetry(&mut att) {
                if tel_first.is_none() && t.stamp_ns >= start_ns {
                    tel_first = Some(t);
                }
                tel_last = Some(t);
            }
            lopd.check_alive()?;
        }
        std::thread::sleep(poll);
    }

    // One more telemetry sample, taken after the window ended, so the haptic figures cover it.
    let waiting = Instant::now();
    while waiting.elapsed() < Duration::from_secs(2) {
        if let Some(t) = telemetry(&mut att) {
            tel_last = Some(t);
            if t.stamp_ns >= end_ns {
                break;
            }
        }
        lopd.check_alive()?;
        std::thread::sleep(Duration::from_millis(5));
    }
    let cyclictest = match (running_ct, ct_start_err) {
        (Some(r), _) => Some(r.finish(
            Duration::from_secs(5),
            "cyclictest",
            "machine wake-up latency (cyclictest)",
        )),
        (None, Some(e)) => Some(Err(e)),
        (None, None) => None,
    };
    drop(att);

    let (Some(tel_first), Some(tel_last)) = (tel_first, tel_last) else {
        bail!(
            "no haptic telemetry from lopd during the window (prefix {}); {}",
            lopd.prefix,
            lopd.log_tail(20)
        );
    };
    if tel_last.stamp_ns <= tel_first.stamp_ns {
        bail!("only one haptic telemetry sample in the window; measure longer (--seconds)");
    }
    Ok(Measured {
        tel_first,
        tel_last,
        tool_to_deform,
        deform_to_client,
        device_to_tissue,
        deform_round,
        touched_interval,
        touched_step,
        touched_periods_us,
        touched_rt_min,
        frames_received,
        frames_missed,
        frames_without_tool,
        cyclictest,
    })
}

fn yes_no(b: bool) -> &'static str {
    if b {
        "yes"
    } else {
        "no"
    }
}

/// The printed report: headline, table, counts and notes.
fn render(r: &LatencyReport, period_us: u64) -> String {
    let spin_us = lop_config::DaemonConfig::default().haptic.spin_us;
    let pinned = match (r.rt.pinned, r.rt.pinned_core) {
        (true, Some(c)) => format!("pinned core {c}"),
        (true, None) => "pinned yes".into(),
        (false, _) => "pinned no".into(),
    };
    let mut s = format!(
        "lop-bench latency — scene {}, {} device, {:.1} s (after {:.0} s warm-up), haptic {:.1} Hz, \
         SCHED_FIFO {}, {pinned}, mlocked {}\n",
        r.scene,
        r.device,
        r.seconds,
        r.warmup_seconds,
        r.rate_hz,
        yes_no(r.rt.sched_fifo),
        yes_no(r.rt.mlocked)
    );
    s += &table::render(&r.rows);
    s += "\n";
    s += &format!(
        "overruns: {} of {} ticks in the window ({:.2} s, {} since start); stale-frame ticks since start: {}; device faults: {}\n",
        r.window_overruns, r.window_ticks, r.window_seconds, r.overruns, r.stale_ticks, r.device_faults
    );
    if !r.touched_periods_ms.is_empty() {
        let periods: Vec<String> = r
            .touched_periods_ms
            .iter()
            .map(|p| format!("{p}"))
            .collect();
        s += &format!(
            "touched body: stepped at {} ms; real-time factor at least {}\n",
            periods.join(", "),
            r.touched_real_time_factor_min
                .map_or("(not yet measured)".into(), |f| format!("{f:.3}"))
        );
    }
    s += &format!(
        "frames received: {} ({:.1}/s), missed: {}, without a tool state: {}\n",
        r.frames_received,
        r.frames_received as f64 / r.seconds,
        r.frames_missed,
        r.frames_without_tool
    );
    s += "notes:\n";
    const W: usize = 100;
    let haptic_count = r.rows.first().map_or(0, |row| row.count);
    s += &table::note(
        &format!(
            "haptic rows: the loop's own histograms, everything after its 1 s warm-up \
             ({haptic_count} ticks)."
        ),
        W,
    );
    s += &table::note(
        &format!(
            "deform → client includes this bench's polling interval (it sleeps {} µs between \
             polls, plus timer slack).",
            r.poll_interval_us
        ),
        W,
    );
    match r.cyclictest.status.as_str() {
        "ran" => {
            if let Some(o) = &r.cyclictest.result {
                let who = match o.priority {
                    Some(p) => format!("SCHED_FIFO {p}"),
                    None => "default-priority".into(),
                };
                let overflow = if o.overflows > 0 {
                    format!(", {} samples beyond the histogram", o.overflows)
                } else {
                    String::new()
                };
                s += &table::note(
                    &format!(
                        "cyclictest: a bare {who} thread waking every {period_us} µs during the \
                         window (unpinned, power management untouched; min {:.0}, avg {:.0} \
                         µs{overflow}). On a shared VM this floor is the honest yardstick for \
                         the haptic jitter; the haptic loop busy-waits the last {spin_us:.0} µs \
                         before each deadline, which hides wake-up latency up to that much.",
                        o.min_us, o.avg_us
                    ),
                    W,
                );
            }
        }
        "disabled" => {}
        "not installed" => {
            s += &table::note(
                "cyclictest is not installed: `apt-get install rt-tests` adds the machine's \
                 wake-up latency as a yardstick for the haptic jitter.",
                W,
            );
        }
        _ => {
            s += &table::note(
                &format!(
                    "cyclictest did not run: {}",
                    r.cyclictest.note.as_deref().unwrap_or("unknown error")
                ),
                W,
            );
        }
    }
    s
}
