//! The scene on another host through iceoryx2's Zenoh link tunnel (`lopd run --remote` on the
//! rig, `lopd remote attach` on the far side), tested as two hosts on one machine: the far side
//! is an iceoryx2 domain of its own (a working directory whose `config/iceoryx2.toml` sets
//! another global prefix, so it shares no shared memory with the rig), joined over loopback.
//!
//! Invariants guarded:
//! - a client on the far side gets the rig's topology (same id) and then every frame it
//!   receives in order (sequence strictly increasing), `lop-record` records there unchanged;
//! - the far domain holds the rig's prefix only: topology, frames, frame-ready, tool states,
//!   telemetry; never the control service, never another prefix's services;
//! - frames a far host publishes into its `PREFIX/scene/frame` never reach the rig's frame
//!   service (which the haptic loop renders forces from);
//! - killing the rig's tunnel or the whole far side leaves the rig running (frames and haptic
//!   telemetry keep coming); the rig's tunnel is restarted and the far side receives again.
//! - through a Zenoh router (a classroom: rig and far side both its clients, never connected to
//!   each other), a far client gets the topology and every frame in order.
//!
//! The tunnel is the workspace's `lop-tunnel`, which lopd finds beside itself (`cargo test
//! --workspace` builds it).

use std::net::TcpListener;
use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

use iceoryx2::config::Config;
use iceoryx2::prelude::*;
use lop_client::services::{self, Role};
use lop_client::{Attachment, ServiceNames};
use lop_system_tests::{find_processes, lopd_path, sibling_binary, unique_prefix, Daemon};

const PROBE: &str = env!("CARGO_BIN_EXE_lop-remote-probe");
const INJECTED_TOPOLOGY: u64 = 0xBAD0_BAD0_BAD0_BAD0;

fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .expect("a free loopback port")
        .port()
}

/// A working directory whose iceoryx2 domain is apart from the rig's.
fn far_domain(tag: &str) -> std::path::PathBuf {
    let dir = lop_test_support::fixtures::temp_dir(&format!("lop-remote-{tag}"));
    std::fs::create_dir_all(dir.join("config")).unwrap();
    std::fs::write(
        dir.join("config/iceoryx2.toml"),
        format!(
            "[global]\nprefix = \"lopfar{}{tag}_\"\n",
            std::process::id()
        ),
    )
    .unwrap();
    dir
}

struct Probe {
    topology: u64,
    sequences: Vec<u64>,
    services: Vec<String>,
}

/// `lop-remote-probe read` in the far domain.
fn probe_read(dir: &Path, prefix: &str, frames: usize, context: &dyn Fn() -> String) -> Probe {
    let out = Command::new(PROBE)
        .args(["read", prefix, &frames.to_string(), "90"])
        .current_dir(dir)
        .output()
        .expect("lop-remote-probe");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "far-side reader failed: {}\n{stdout}\n{}\n{}",
        out.status,
        String::from_utf8_lossy(&out.stderr),
        context()
    );
    let mut p = Probe {
        topology: 0,
        sequences: Vec::new(),
        services: Vec::new(),
    };
    for line in stdout.lines() {
        let w: Vec<&str> = line.split_whitespace().collect();
        match w[..] {
            ["topology", id, _] => p.topology = u64::from_str_radix(&id[2..], 16).unwrap(),
            ["frame", seq, id, _] if u64::from_str_radix(&id[2..], 16).unwrap() == p.topology => {
                p.sequences.push(seq.parse().unwrap())
            }
            ["service", name] => p.services.push(name.to_string()),
            _ => {}
        }
    }
    assert_eq!(p.sequences.len(), frames, "{stdout}");
    p
}

/// Every frame the rig's own frame service carries for `d`; returns their topology ids.
fn rig_frames(names: &ServiceNames, d: Duration) -> Vec<u64> {
    let node = services::node("systest-remote-rig-reader").unwrap();
    let sub = services::frame_service(&node, names, Role::Client)
        .unwrap()
        .subscriber_builder()
        .buffer_size(services::FRAME_BUFFER)
        .create()
        .unwrap();
    let start = Instant::now();
    let mut ids = Vec::new();
    while start.elapsed() < d {
        while let Ok(Some(s)) = sub.receive() {
            ids.push(s.user_header().topology_id);
        }
        std::thread::sleep(Duration::from_micros(300));
    }
    ids
}

/// `lopd run --scene abdomen --prefix PREFIX --quiet` and `extra`, with a local client attached
/// once the topology is there: the daemon, the client and the topology id.
fn rig(prefix: &str, extra: &[&str], limit: Duration) -> (Daemon, Attachment, u64) {
    let mut args = vec!["run", "--scene", "abdomen", "--prefix", prefix, "--quiet"];
    args.extend_from_slice(extra);
    let rig = Daemon::spawn(&args, prefix, limit);
    let mut local = Attachment::open(prefix, Duration::from_secs(90))
        .unwrap_or_else(|e| panic!("attach: {e}\n{}", rig.log_text()));
    let topology = local
        .wait_topology(Duration::from_secs(90))
        .expect("topology")
        .header
        .topology_id;
    (rig, local, topology)
}

/// `lopd remote attach --prefix PREFIX` and `extra` in the far domain `far`.
fn far_side(prefix: &str, far: &Path, extra: &[&str]) -> Daemon {
    let mut args = vec!["remote", "attach", "--prefix", prefix];
    args.extend_from_slice(extra);
    Daemon::spawn_in(&args, prefix, Duration::from_secs(300), Some(far), "-far")
}

#[test]
fn the_scene_reaches_a_far_domain_in_order_read_only_and_the_rig_outlives_every_tunnel() {
    // lopd runs the tunnel it finds beside itself: this build's.
    sibling_binary("lop-tunnel");
    let prefix = unique_prefix("remote");
    let names = ServiceNames::new(&prefix).unwrap();
    let endpoint = format!("tcp/127.0.0.1:{}", free_port());
    let (mut rig, mut local, topology) = rig(
        &prefix,
        &["--remote", "--remote-listen", &endpoint],
        Duration::from_secs(300),
    );
    // Opens the telemetry subscription (its first call finds nothing yet).
    let _ = local.telemetry();

    // Another prefix's service in the rig's export domain: it must not cross.
    let decoy_names = ServiceNames::new(&format!("{prefix}-decoy")).unwrap();
    let mut export = Config::global_config().clone();
    export.global.prefix =
        FileName::new(format!("lopx_{}", Config::global_config().global.prefix).as_bytes())
            .unwrap();
    let decoy_node = services::node_in("systest-remote-decoy", &export).unwrap();
    let _decoy = services::frame_service(&decoy_node, &decoy_names, Role::Owner).unwrap();

    let far = far_domain("a");
    let mut attach = far_side(&prefix, &far, &["--connect", &endpoint]);
    let logs = || format!("rig:\n{}\nfar:\n{}", rig.log_text(), attach.log_text());

    // Every frame in order, the rig's topology, only the rig's renderer-facing services.
    let p = probe_read(&far, &prefix, 300, &logs);
    assert_eq!(p.topology, topology);
    assert!(
        p.sequences.windows(2).all(|w| w[1] > w[0]),
        "frames out of order on the far side: {:?}",
        p.sequences
    );
    for want in [
        &names.topology,
        &names.frame,
        &names.frame_ready,
        &names.tool,
        &names.haptic_telemetry,
    ] {
        assert!(
            p.services.contains(want),
            "{want} missing: {:?}",
            p.services
        );
    }
    let ours = |s: &String| s.starts_with(&format!("{prefix}/"));
    assert!(
        p.services
            .iter()
            .filter(|s| !s.starts_with("iox2"))
            .all(ours),
        "services of another prefix crossed: {:?}",
        p.services
    );
    assert!(
        !p.services.iter().any(|s| s.contains("control")),
        "{:?}",
        p.services
    );
    assert!(!p.services.contains(&names.tool_latest), "{:?}", p.services);

    // lop-record attaches on the far side as on the rig.
    let rec = far.join("rec");
    let out = Command::new(sibling_binary("lop-record"))
        .args([
            "--prefix", &prefix, "--frames", "5", "--wait", "60", "--out",
        ])
        .arg(&rec)
        .current_dir(&far)
        .output()
        .expect("lop-record");
    assert!(
        out.status.success(),
        "lop-record on the far side: {}\n{}",
        String::from_utf8_lossy(&out.stderr),
        logs()
    );

    // Frames a far host publishes never reach the rig's frame service.
    let injector = Command::new(PROBE)
        .args(["inject", &prefix, "3"])
        .current_dir(&far)
        .spawn()
        .expect("lop-remote-probe inject");
    let seen = rig_frames(&names, Duration::from_secs(4));
    let injected = injector.wait_with_output().expect("injector");
    assert!(injected.status.success(), "{injected:?}");
    assert!(
        seen.len() > 100,
        "{} rig frames in 4 s\n{}",
        seen.len(),
        logs()
    );
    assert!(
        seen.iter()
            .all(|&id| id == topology && id != INJECTED_TOPOLOGY),
        "a far host's frame reached the rig"
    );

    // The rig's tunnel killed: the rig goes on, the tunnel comes back, the far side receives.
    let tunnels = find_processes(&["--listener", &names.frame_ready]);
    assert_eq!(
        tunnels.len(),
        1,
        "the rig's tunnel: {tunnels:?}\n{}",
        logs()
    );
    // SAFETY: kill on a process this test's daemon started.
    unsafe { libc::kill(tunnels[0], libc::SIGKILL) };
    let seen = rig_frames(&names, Duration::from_secs(2));
    assert!(
        seen.len() > 100,
        "{} rig frames in 2 s after the tunnel died",
        seen.len()
    );
    let p = probe_read(&far, &prefix, 50, &logs);
    assert_eq!(p.topology, topology);
    let again = find_processes(&["--listener", &names.frame_ready]);
    assert!(again.len() == 1 && again[0] != tunnels[0], "{again:?}");

    // The whole far side killed: the rig goes on.
    let telemetry_before = local.telemetry().map(|t| t.ticks);
    attach.signal(libc::SIGKILL);
    attach.wait(Duration::from_secs(10)).expect("far side gone");
    let seen = rig_frames(&names, Duration::from_secs(2));
    assert!(
        seen.len() > 100,
        "{} rig frames in 2 s after the far side died",
        seen.len()
    );
    let telemetry_after = local.telemetry().map(|t| t.ticks);
    assert!(
        telemetry_after > telemetry_before,
        "haptic telemetry stopped: {telemetry_before:?} -> {telemetry_after:?}"
    );

    drop(local);
    let log = lop_system_tests::interrupt(&mut rig);
    assert!(log.contains("started the Zenoh link tunnel"), "{log}");
    assert!(!log.contains("panicked"), "{log}");
    let _ = std::fs::remove_dir_all(&far);
    let _ = lopd_path();
}

#[test]
fn a_rig_whose_tunnel_cannot_run_says_why_and_runs_without_it() {
    let prefix = unique_prefix("remote-bad");
    let dir = lop_test_support::fixtures::temp_dir("lop-remote-bad");
    let config = dir.join("lopd.toml");
    std::fs::write(&config, "[remote]\ntunnel = \"bin/no-such-tunnel\"\n").unwrap();
    let (mut rig, mut local, _) = rig(
        &prefix,
        &["--remote", "--config", config.to_str().unwrap()],
        Duration::from_secs(200),
    );
    local
        .next_frame(Duration::from_secs(30))
        .expect("the rig runs");
    drop(local);
    let log = lop_system_tests::interrupt(&mut rig);
    let want = format!(
        "the Zenoh link tunnel \"{}\" was not found",
        dir.join("bin/no-such-tunnel").display()
    );
    assert!(log.contains(&want), "{log}");
    assert!(log.contains("the rig runs without it"), "{log}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A process killed when dropped.
struct Killed(std::process::Child);

impl Drop for Killed {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

#[test]
fn a_classroom_through_a_zenoh_router_gets_the_scene_in_order() {
    // The router: a Zenoh session in router mode (what `zenohd` runs), here `lop-tunnel`'s own
    // in an iceoryx2 domain of its own, bridging nothing. The rig and the far side are both
    // clients of it and never connect to each other.
    let prefix = unique_prefix("remote-router");
    let router_port = free_port();
    let router_endpoint = format!("tcp/127.0.0.1:{router_port}");
    let router_dir = far_domain("router");
    let zenoh = router_dir.join("router.json5");
    std::fs::write(
        &zenoh,
        format!(
            "{{ mode: \"router\", listen: {{ endpoints: [\"{router_endpoint}\"] }}, \
             scouting: {{ multicast: {{ enabled: false }} }} }}"
        ),
    )
    .unwrap();
    let _router = Killed(
        Command::new(sibling_binary("lop-tunnel"))
            .arg("--zenoh-config")
            .arg(&zenoh)
            .args(["--allow", "no-service-of-this-test"])
            .current_dir(&router_dir)
            .stdin(std::process::Stdio::null())
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .expect("the router"),
    );

    let config = router_dir.join("lopd.toml");
    std::fs::write(
        &config,
        format!(
            "[remote]\nenabled = true\nmode = \"client\"\n\
             connect = [\"{router_endpoint}\"]\n"
        ),
    )
    .unwrap();
    let (mut rig, local, topology) = rig(
        &prefix,
        &["--config", config.to_str().unwrap()],
        Duration::from_secs(300),
    );

    let far = far_domain("classroom");
    let mut attach = far_side(
        &prefix,
        &far,
        &["--mode", "client", "--connect", &router_endpoint],
    );
    let logs = || format!("rig:\n{}\nfar:\n{}", rig.log_text(), attach.log_text());
    let p = probe_read(&far, &prefix, 200, &logs);
    assert_eq!(p.topology, topology);
    assert!(
        p.sequences.windows(2).all(|w| w[1] > w[0]),
        "frames out of order through the router: {:?}",
        p.sequences
    );
    assert!(
        !p.services.iter().any(|s| s.contains("control")),
        "{:?}",
        p.services
    );

    attach.signal(libc::SIGTERM);
    attach
        .wait(Duration::from_secs(10))
        .expect("far side stops");
    drop(local);
    let log = lop_system_tests::interrupt(&mut rig);
    assert!(log.contains("started the Zenoh link tunnel"), "{log}");
    assert!(!log.contains("panicked"), "{log}");
    let _ = std::fs::remove_dir_all(&far);
    let _ = std::fs::remove_dir_all(&router_dir);
}
