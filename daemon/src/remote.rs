//! The scene on other hosts: `lopd run --remote` (rig side, `lopd remote serve`) and
//! `lopd remote attach` (far side), over iceoryx2's Zenoh link tunnel, run as a separate
//! program: `lop-tunnel` (this workspace's `tunnel/`, built from iceoryx2's own link-tunnel
//! crates, found beside `lopd` or on `PATH`). iceoryx2's `iox2-link-tunnel-zenoh` takes the same
//! command line and works too, slower (`[remote] tunnel`).
//!
//! # The rig side never opens its own services to the network
//!
//! The tunnel carries publish–subscribe and events *both ways*: it publishes into every service
//! it bridges whatever the peers publish there. Bridged directly, a far host could put frames
//! into `PREFIX/scene/frame`, which the haptic loop renders forces from, and flood
//! `PREFIX/scene/frame/ready`, which wakes a thread on the haptic core. So the tunnel never sees
//! the rig's iceoryx2 domain: `lopd remote serve` copies the renderer-facing services
//! (topology, frames, the frame-ready event, tool states, haptic telemetry) into an *export
//! domain* of their own (the rig's iceoryx2 config with [`EXPORT_DOMAIN_PREFIX`] put before its
//! global prefix), under the same service names, and runs the tunnel there.
//! Whatever a far host publishes lands in the export domain, which nothing on the rig reads.
//! The control service (request–response) does not cross at all: the tunnel carries
//! publish–subscribe and events only, and the blackboard of tool states stays on the rig.
//!
//! # The far side
//!
//! `lopd remote attach` runs the tunnel into the far host's own iceoryx2 domain (the one its
//! clients use: `config/iceoryx2.toml` in the working directory, the user's or the system's),
//! importing the services of one prefix only. The tunnel creates the far services with its
//! iceoryx2 config's *defaults*, so the far side runs it with that domain's config and the
//! defaults raised to the contract's QoS ([`far_config`]): room for every client's subscriber
//! buffer, and a history of one sample, so a viewer that starts later still gets the topology.
//! The clients (`lop-view`, `lop-record`, the Python consumer) then attach as on the rig, with
//! the same prefix.
//!
//! The topology is published once per scene load, and the tunnel keeps nothing for a far host
//! that connects later, so the relay publishes it again every [`TOPOLOGY_REPEAT`]: a far side
//! that joins gets it within that time (clients take a topology with the id they hold as the
//! same one).
//!
//! # What goes on, and how often
//!
//! Frames at most `[remote] frame_rate_hz` a second (default 120; the newest, in order), the
//! newest state of each tool with them, the haptic telemetry (a status of one-second windows)
//! at 10 Hz. The relay wakes the rig's tunnel once a round, not once a sample (a wake of
//! `lop-tunnel` propagates what is pending; its service discovery runs on its own interval),
//! and the thousand tool states and telemetry samples a second the haptic loop publishes stay
//! on the rig.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use iceoryx2::config::Config;
use iceoryx2::prelude::*;
use lop_config::{RemoteConfig, ZenohMode};
use lop_ipc::services::{self, Role};
use lop_ipc::types::{FrameHeader, HapticTelemetry, NodeSample, ToolState, TopologyHeader};
use lop_ipc::{ServiceNames, ICEORYX2_VERSION};

use crate::signals;
use crate::supervisor::Supervised;

/// Put before the rig's iceoryx2 global prefix for the export domain (`iox2_` → `lopx_iox2_`).
/// Before, not after: no file of the export domain then begins with the rig's prefix (iceoryx2
/// finds a domain's files by their prefix; its listings were checked not to mix `iox2_` and
/// `iox2_lopx_` on 2026-11-30, but nothing needs to rely on that).
pub const EXPORT_DOMAIN_PREFIX: &str = "lopx_";

/// How often the relay publishes the topology again for far hosts that join later.
pub const TOPOLOGY_REPEAT: Duration = Duration::from_secs(1);

/// The longest the relay sleeps between two looks at the tool states and telemetry (frames wake
/// it at once). The haptic loop publishes both at 1 kHz into buffers of at least 16 samples.
const RELAY_WAKE: Duration = Duration::from_millis(5);

/// The interval between two haptic telemetry samples sent on (each is a status over the
/// loop's last second).
const TELEMETRY_INTERVAL: Duration = Duration::from_millis(100);

/// How often the rig's tunnel looks for new services (its discovery interval), ms. The relay
/// wakes it through the frame-ready event once it has published a round (frame, tool states,
/// telemetry), and a wake propagates at once. A round of discovery lists every service of the
/// domain (1.5–4 ms here) and holds up propagation meanwhile, so the tunnel runs it in the quiet
/// after a round, in the gap before the next frame (`lop-tunnel`'s `Rounds`).
const RIG_TUNNEL_POLL_MS: u64 = 100;

/// How often the far side's tunnel looks for new services, ms; samples wake it as they arrive
/// (`--reactive`). Longer than the rig's: the far side's discovery lists its viewers' ports too
/// (p90 3.8 ms, p99 6.9 ms, up to 20 ms with 16 viewers, 2026-12-07), and it only has to notice
/// the rig's services coming and going (bridged within two intervals, 1 s). At 100 ms the far
/// frames' p99 with 16 viewers was 2.4–5.7 ms above the local client's in four runs; at 500 ms
/// 2.2–2.9 ms in three (`docs/benchmarks.md`).
const FAR_TUNNEL_POLL_MS: u64 = 500;

/// The rig's export domain: `rig` with [`EXPORT_DOMAIN_PREFIX`] before its global prefix.
pub fn export_config(rig: &Config) -> Result<Config> {
    let mut c = rig.clone();
    let prefix = format!("{EXPORT_DOMAIN_PREFIX}{}", rig.global.prefix);
    c.global.prefix = FileName::new(prefix.as_bytes())
        .map_err(|e| anyhow::anyhow!("iceoryx2 prefix {prefix:?} for the export domain: {e:?}"))?;
    Ok(c)
}

/// The far side's tunnel config: `local` (the far clients' domain) with its publish–subscribe
/// and event defaults raised to what lop's services need, since the tunnel creates its mirrors
/// with the defaults.
pub fn far_config(local: &Config) -> Config {
    let mut c = local.clone();
    let ps = &mut c.defaults.publish_subscribe;
    // Every client's subscriber, plus the tunnel's own.
    ps.max_subscribers = ps.max_subscribers.max(services::MAX_SUBSCRIBERS + 1);
    ps.max_publishers = ps.max_publishers.max(2);
    ps.max_nodes = ps.max_nodes.max(services::MAX_SUBSCRIBERS + 4);
    // The largest buffer a client asks for (tool states).
    ps.subscriber_max_buffer_size = ps
        .subscriber_max_buffer_size
        .max(services::TOOL_BUFFER)
        .max(services::FRAME_BUFFER)
        .max(services::TELEMETRY_BUFFER);
    ps.subscriber_max_borrowed_samples = ps.subscriber_max_borrowed_samples.max(2);
    // A late viewer gets the newest topology (and frame) from the mirror.
    ps.publisher_history_size = ps.publisher_history_size.max(1);
    ps.enable_safe_overflow = true;
    let ev = &mut c.defaults.event;
    ev.max_listeners = ev.max_listeners.max(services::MAX_SUBSCRIBERS + 1);
    ev.max_notifiers = ev.max_notifiers.max(2);
    ev.max_nodes = ev.max_nodes.max(services::MAX_SUBSCRIBERS + 4);
    c
}

/// A Zenoh configuration (JSON, which Zenoh reads as JSON5) for `mode`, listening on `listen`
/// and connecting to `connect`.
pub fn zenoh_config(
    mode: ZenohMode,
    listen: &[String],
    connect: &[String],
    multicast: bool,
) -> String {
    let doc = serde_json::json!({
        "mode": mode.as_str(),
        "listen": { "endpoints": listen },
        "connect": { "endpoints": connect },
        "scouting": { "multicast": { "enabled": multicast } },
    });
    serde_json::to_string_pretty(&doc).expect("a JSON value serialises")
}

/// The tunnel program, found and checked: at the path, or a bare name beside the running
/// `lopd` (where cargo builds `lop-tunnel`) and then on `PATH`; built against lop's iceoryx2
/// version (the last word of its `--version`).
pub fn check_tunnel(program: &Path) -> Result<PathBuf> {
    let bare = program.components().count() == 1;
    let found = if !bare {
        program.is_file().then(|| program.to_path_buf())
    } else {
        let beside = std::env::current_exe()
            .ok()
            .and_then(|exe| exe.parent().map(|d| d.join(program)));
        let on_path: Vec<PathBuf> = std::env::var_os("PATH")
            .map(|paths| {
                std::env::split_paths(&paths)
                    .map(|d| d.join(program))
                    .collect()
            })
            .unwrap_or_default();
        beside.into_iter().chain(on_path).find(|p| p.is_file())
    };
    let Some(path) = found else {
        bail!(
            "the Zenoh link tunnel {:?} was not found{}: build it with `cargo build --release -p \
             lop-tunnel` (cargo puts it beside lopd), or name it in [remote] tunnel",
            program.display().to_string(),
            if bare { " beside lopd or on PATH" } else { "" }
        );
    };
    let out = Command::new(&path)
        .arg("--version")
        .output()
        .with_context(|| format!("running {} --version", path.display()))?;
    let text = String::from_utf8_lossy(&out.stdout);
    let version = text.split_whitespace().last().unwrap_or("");
    if !out.status.success() || version != ICEORYX2_VERSION {
        bail!(
            "{} is not the iceoryx2 {ICEORYX2_VERSION} Zenoh link tunnel (its --version says \
             {:?}): every process sharing lop's services runs iceoryx2 {ICEORYX2_VERSION}; \
             build `lop-tunnel` from this workspace (`cargo build --release -p lop-tunnel`)",
            path.display(),
            text.trim()
        );
    }
    Ok(path)
}

/// A working directory for one tunnel: `config/iceoryx2.toml` (the tunnel, like every iceoryx2
/// program, reads its domain from there) and `zenoh.json5`. Removed on drop.
struct TunnelDir(PathBuf);

impl TunnelDir {
    fn new(tag: &str, iceoryx: &Config, zenoh: Option<&str>) -> Result<TunnelDir> {
        let base = std::env::var_os("XDG_RUNTIME_DIR")
            .map(PathBuf::from)
            .filter(|d| d.is_dir())
            .unwrap_or_else(std::env::temp_dir);
        let dir = base.join(format!("lop-tunnel-{tag}-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("config"))
            .with_context(|| format!("creating {}", dir.display()))?;
        let toml = toml_edit::ser::to_string_pretty(iceoryx)
            .context("writing the tunnel's iceoryx2 config")?;
        std::fs::write(dir.join("config/iceoryx2.toml"), toml)
            .with_context(|| format!("writing {}/config/iceoryx2.toml", dir.display()))?;
        if let Some(z) = zenoh {
            std::fs::write(dir.join("zenoh.json5"), z)
                .with_context(|| format!("writing {}/zenoh.json5", dir.display()))?;
        }
        Ok(TunnelDir(dir))
    }
}

impl Drop for TunnelDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// The tunnel as a supervised child (restarted with back-off when it exits), run in `dir`.
fn tunnel(program: PathBuf, args: Vec<String>, dir: &TunnelDir) -> Supervised {
    Supervised::program("the Zenoh link tunnel", program, args, dir.0.clone())
}

/// Starts the tunnel when due and reaps it when it exited; a failed start is retried after the
/// back-off.
fn tend(t: &mut Supervised) {
    t.check();
    if let Err(e) = t.maybe_start() {
        tracing::error!("{e:#}");
    }
}

/// SIGTERM, then SIGKILL after 3 s.
fn stop(t: &mut Supervised) {
    t.terminate();
    t.wait_or_kill(Instant::now() + Duration::from_secs(3));
}

/// The tunnel's Zenoh config: the user's file as is, or one written from `[remote]`.
fn zenoh_for(remote: &RemoteConfig) -> Result<(Option<String>, PathBuf)> {
    match &remote.zenoh_config {
        Some(path) => Ok((
            None,
            std::fs::canonicalize(path).with_context(|| format!("{}", path.display()))?,
        )),
        None => Ok((
            Some(zenoh_config(
                remote.mode,
                &remote.listen,
                &remote.connect,
                remote.multicast_scouting,
            )),
            PathBuf::from("zenoh.json5"),
        )),
    }
}

/// `lopd remote serve`: copies the rig's renderer-facing services into the export domain and
/// runs the tunnel there, until SIGINT / SIGTERM. Started by `lopd run --remote`.
pub fn serve(names: &ServiceNames, remote: &RemoteConfig) -> Result<i32> {
    let program = check_tunnel(&remote.tunnel)?;
    let export = export_config(Config::global_config())?;
    let (zenoh_text, zenoh_path) = zenoh_for(remote)?;
    let dir = TunnelDir::new("rig", &export, zenoh_text.as_deref())?;
    let carries = |group: &str| remote.services.iter().any(|s| s == group);
    let relay = Relay::open(
        names,
        &export,
        remote.frame_rate_hz,
        carries("tool"),
        carries("telemetry"),
    )?;
    let mut args = vec![
        "--zenoh-config".to_string(),
        zenoh_path.display().to_string(),
        "--listener".to_string(),
        names.frame_ready.clone(),
        "--poll".to_string(),
        RIG_TUNNEL_POLL_MS.to_string(),
    ];
    // Only what the relay exports is there to cross; the allow-list says so once more.
    let mut allow = vec![format!("{}/scene/*", names.prefix)];
    if carries("tool") {
        allow.push(names.tool.clone());
    }
    if carries("telemetry") {
        allow.push(names.haptic_telemetry.clone());
    }
    for a in allow {
        args.extend(["--allow".to_string(), a]);
    }
    let mut tunnel = tunnel(program, args, &dir);
    let result = relay.run(|| tend(&mut tunnel));
    stop(&mut tunnel);
    result.map(|()| 0)
}

/// Options of `lopd remote attach`.
#[derive(Debug, Clone)]
pub struct AttachOptions {
    /// The rig's service prefix: only its services are imported.
    pub prefix: String,
    /// `[remote]`-like settings for this side (endpoints, mode, tunnel program).
    pub remote: RemoteConfig,
    /// Stop after this long.
    pub duration: Option<Duration>,
}

/// `lopd remote attach`: the far side's tunnel into this host's iceoryx2 domain, importing one
/// rig's prefix, until SIGINT / SIGTERM (restarted when it exits).
pub fn attach(opts: &AttachOptions) -> Result<i32> {
    let names = ServiceNames::new(&opts.prefix)?;
    let program = check_tunnel(&opts.remote.tunnel)?;
    let far = far_config(Config::global_config());
    let (zenoh_text, zenoh_path) = zenoh_for(&opts.remote)?;
    let dir = TunnelDir::new("far", &far, zenoh_text.as_deref())?;
    let args = vec![
        "--zenoh-config".to_string(),
        zenoh_path.display().to_string(),
        "--allow".to_string(),
        format!("{}/*", names.prefix),
        "--reactive".to_string(),
        "--poll".to_string(),
        FAR_TUNNEL_POLL_MS.to_string(),
    ];
    let mut tunnel = tunnel(program, args, &dir);
    println!(
        "lopd remote attach: the services of {:?} arrive in this host's iceoryx2 domain \
         (prefix {:?}); attach clients with --prefix {}",
        names.prefix,
        Config::global_config().global.prefix.to_string(),
        names.prefix
    );
    let _ = std::io::stdout().flush();
    let start = Instant::now();
    while !signals::stop_requested() && opts.duration.is_none_or(|d| start.elapsed() < d) {
        tend(&mut tunnel);
        std::thread::sleep(Duration::from_millis(20));
    }
    stop(&mut tunnel);
    println!(
        "lopd remote attach: stopped; tunnel restarts {}",
        tunnel.restarts()
    );
    Ok(0)
}

/// Copies the rig's renderer-facing services into the export domain.
struct Relay {
    // The nodes outlive their ports (declared last).
    topology_sub: services::TopologySubscriber,
    frame_sub: services::FrameSubscriber,
    tool: Option<(services::ToolSubscriber, services::ToolPublisher)>,
    telemetry: Option<(services::TelemetrySubscriber, services::TelemetryPublisher)>,
    frame_ready: Option<iceoryx2::port::listener::Listener<ipc::Service>>,
    topology_pub: services::TopologyPublisher,
    frame_pub: services::FramePublisher,
    frame_notify: iceoryx2::port::notifier::Notifier<ipc::Service>,
    /// The shortest time between two frames sent on (`[remote] frame_rate_hz`); zero: all.
    frame_interval: Duration,
    _rig: Node<ipc::Service>,
    _export: Node<ipc::Service>,
}

/// How long the relay waits for the rig's services at its start (the pipeline loads first).
const RIG_WAIT: Duration = Duration::from_secs(120);

impl Relay {
    fn open(
        names: &ServiceNames,
        export: &Config,
        frame_rate_hz: u32,
        tool: bool,
        telemetry: bool,
    ) -> Result<Relay> {
        let rig = services::node("lopd-remote")?;
        let out = services::node_in("lopd-remote", export)?;
        let sub_err = |service: &str| {
            let service = service.to_string();
            move |e| lop_ipc::limits::subscriber_create_error(&service, e)
        };
        let topology_sub = services::open_retry(&names.topology, RIG_WAIT, || {
            services::topology_service(&rig, names, Role::Client)?
                .subscriber_builder()
                .create()
                .map_err(sub_err(&names.topology))
        })?;
        let frame_sub = services::open_retry(&names.frame, RIG_WAIT, || {
            services::frame_service(&rig, names, Role::Client)?
                .subscriber_builder()
                .buffer_size(services::FRAME_BUFFER)
                .create()
                .map_err(sub_err(&names.frame))
        })?;
        let tool = if tool {
            let sub = services::open_retry(&names.tool, RIG_WAIT, || {
                services::tool_service(&rig, names, Role::Client)?
                    .subscriber_builder()
                    .buffer_size(services::TOOL_BUFFER)
                    .create()
                    .map_err(sub_err(&names.tool))
            })?;
            let publisher = services::tool_service(&out, names, Role::Owner)?
                .publisher_builder()
                .create()
                .context("export tool publisher")?;
            Some((sub, publisher))
        } else {
            None
        };
        let telemetry = if telemetry {
            let sub = services::open_retry(&names.haptic_telemetry, RIG_WAIT, || {
                services::telemetry_service(&rig, names, Role::Client)?
                    .subscriber_builder()
                    .buffer_size(services::TELEMETRY_BUFFER)
                    .create()
                    .map_err(sub_err(&names.haptic_telemetry))
            })?;
            let publisher = services::telemetry_service(&out, names, Role::Owner)?
                .publisher_builder()
                .create()
                .context("export telemetry publisher")?;
            Some((sub, publisher))
        } else {
            None
        };
        let frame_ready = match services::frame_ready_service(&rig, names)
            .map_err(anyhow::Error::from)
            .and_then(|s| Ok(s.listener_builder().create()?))
        {
            Ok(l) => Some(l),
            Err(e) => {
                tracing::warn!("frame-ready event unavailable ({e:#}): the relay polls");
                None
            }
        };
        let topology_pub = services::topology_service(&out, names, Role::Owner)?
            .publisher_builder()
            .allocation_strategy(AllocationStrategy::PowerOfTwo)
            .create()
            .context("export topology publisher")?;
        let frame_pub = services::frame_service(&out, names, Role::Owner)?
            .publisher_builder()
            .allocation_strategy(AllocationStrategy::PowerOfTwo)
            .max_loaned_samples(2)
            .create()
            .context("export frame publisher")?;
        let frame_notify = services::frame_ready_service(&out, names)?
            .notifier_builder()
            .create()
            .context("export frame-ready notifier")?;
        Ok(Relay {
            topology_sub,
            frame_sub,
            tool,
            telemetry,
            frame_ready,
            topology_pub,
            frame_pub,
            frame_notify,
            frame_interval: if frame_rate_hz == 0 {
                Duration::ZERO
            } else {
                Duration::from_secs_f64(1.0 / f64::from(frame_rate_hz))
            },
            _rig: rig,
            _export: out,
        })
    }

    /// Copies until a stop signal, calling `tend` (the tunnel's keeper) on each round.
    fn run(&self, mut tend: impl FnMut()) -> Result<()> {
        let mut topology: Option<(TopologyHeader, Vec<u32>)> = None;
        let mut last_topology = Instant::now();
        let mut frames = 0u64;
        let mut next_frame = Instant::now();
        let mut next_tools = Instant::now();
        let mut next_telemetry = Instant::now();
        let mut tools: [Option<ToolState>; lop_ipc::MAX_TOOLS] = [None; lop_ipc::MAX_TOOLS];
        let mut telemetry: Option<HapticTelemetry> = None;
        while !signals::stop_requested() {
            tend();
            match &self.frame_ready {
                Some(l) => {
                    let _ = l.timed_wait(|_| {}, RELAY_WAKE);
                }
                None => std::thread::sleep(Duration::from_millis(1)),
            }
            let mut fresh = false;
            while let Ok(Some(s)) = self.topology_sub.receive() {
                topology = Some((*s.user_header(), s.payload().to_vec()));
                fresh = true;
            }
            if let Some((header, words)) = &topology {
                if fresh || last_topology.elapsed() >= TOPOLOGY_REPEAT {
                    let mut out = self
                        .topology_pub
                        .loan_slice_uninit(words.len())
                        .context("loan an export topology")?;
                    *out.user_header_mut() = *header;
                    out.write_from_slice(words)
                        .send()
                        .context("send the export topology")?;
                    last_topology = Instant::now();
                }
            }
            let frames_before = frames;
            // Every frame, or the newest once the next is due (at the configured rate on
            // average); always in order.
            let mut newest = None;
            while let Ok(Some(s)) = self.frame_sub.receive() {
                if self.frame_interval.is_zero() {
                    self.forward_frame(&s)?;
                    frames += 1;
                } else {
                    newest = Some(s);
                }
            }
            let now = Instant::now();
            if let Some(s) = newest.filter(|_| now >= next_frame) {
                self.forward_frame(&s)?;
                frames += 1;
                next_frame = if next_frame + self.frame_interval < now {
                    now + self.frame_interval
                } else {
                    next_frame + self.frame_interval
                };
            }
            // Tool states: the newest of each tool, at the frames' pace (every one when every
            // frame goes); telemetry (a status of one-second windows): the newest, at 10 Hz.
            if let Some((sub, publisher)) = &self.tool {
                while let Ok(Some(s)) = sub.receive() {
                    let t = (s.tool as usize).min(tools.len() - 1);
                    tools[t] = Some(*s);
                }
                if now >= next_tools {
                    for t in tools.iter_mut().filter_map(Option::take) {
                        let _ = publisher.send_copy(t);
                    }
                    next_tools = now + self.frame_interval;
                }
            }
            if let Some((sub, publisher)) = &self.telemetry {
                while let Ok(Some(s)) = sub.receive() {
                    telemetry = Some(*s);
                }
                if now >= next_telemetry {
                    if let Some(t) = telemetry.take() {
                        let _ = publisher.send_copy(t);
                    }
                    next_telemetry = now + TELEMETRY_INTERVAL;
                }
            }
            // One wake of the tunnel for the round, once a frame went out.
            if frames > frames_before {
                let _ = self.frame_notify.notify();
            }
        }
        tracing::info!("remote relay stopped after {frames} frames");
        Ok(())
    }

    /// Publishes a copy of `s` in the export domain.
    fn forward_frame(
        &self,
        s: &iceoryx2::sample::Sample<ipc::Service, [NodeSample], FrameHeader>,
    ) -> Result<()> {
        let header: FrameHeader = *s.user_header();
        let nodes: &[NodeSample] = s.payload();
        let mut out = self
            .frame_pub
            .loan_slice_uninit(nodes.len())
            .context("loan an export frame")?;
        *out.user_header_mut() = header;
        out.write_from_slice(nodes)
            .send()
            .context("send an export frame")?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_export_domain_is_apart_from_the_rig_s() {
        let rig = Config::default();
        let export = export_config(&rig).unwrap();
        assert_eq!(
            export.global.prefix.to_string(),
            format!("{EXPORT_DOMAIN_PREFIX}{}", rig.global.prefix)
        );
        assert_eq!(export.defaults, rig.defaults);
        // Neither domain's prefix begins the other's.
        let (a, b) = (
            rig.global.prefix.to_string(),
            export.global.prefix.to_string(),
        );
        assert!(!a.starts_with(&b) && !b.starts_with(&a), "{a} {b}");
    }

    #[test]
    fn the_far_defaults_hold_every_client_of_the_contract() {
        let far = far_config(&Config::default());
        let ps = &far.defaults.publish_subscribe;
        assert!(ps.subscriber_max_buffer_size >= services::TOOL_BUFFER);
        assert!(ps.max_subscribers > services::MAX_SUBSCRIBERS);
        assert!(ps.publisher_history_size >= 1);
        assert!(far.defaults.event.max_listeners > services::MAX_SUBSCRIBERS);
        // The far domain itself is the clients' own.
        assert_eq!(far.global, Config::default().global);
        // It survives the trip through the file the tunnel reads.
        let dir = TunnelDir::new("unit-test", &far, None).unwrap();
        let file = dir.0.join("config/iceoryx2.toml");
        let path = FilePath::new(file.to_str().unwrap().as_bytes()).unwrap();
        assert_eq!(Config::from_file(&path).unwrap(), far);
    }

    #[test]
    fn the_zenoh_config_names_mode_and_endpoints() {
        let text = zenoh_config(
            ZenohMode::Peer,
            &["tcp/127.0.0.1:7447".to_string()],
            &[],
            false,
        );
        let v: serde_json::Value = serde_json::from_str(&text).unwrap();
        assert_eq!(v["mode"], "peer");
        assert_eq!(v["listen"]["endpoints"][0], "tcp/127.0.0.1:7447");
        assert_eq!(v["scouting"]["multicast"]["enabled"], false);
    }

    #[test]
    fn a_missing_tunnel_is_named_with_its_install_command() {
        let e = check_tunnel(Path::new("no-such-lop-tunnel"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("\"no-such-lop-tunnel\" was not found beside lopd or on PATH"),
            "{e}"
        );
        assert!(e.contains("cargo build --release -p lop-tunnel"), "{e}");
        // A program of another kind (its --version is not 0.10.0).
        let e = check_tunnel(Path::new("/bin/true"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("/bin/true is not the iceoryx2 0.10.0 Zenoh link tunnel"),
            "{e}"
        );
    }
}
