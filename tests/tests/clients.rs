//! Third-party clients against a live daemon, and the limits that keep them from hurting it.
//!
//! Invariants guarded:
//! - the Python consumer example (`examples/python/consumer.py`, PyPI `iceoryx2` at the
//!   daemon's exact version, ctypes structures only) reads the topology and frames of the
//!   default scene: node count equal to the topology's, the liver's render surface decoded
//!   (1,890 vertices) and placed from each frame's nodes, finite positions;
//! - one subscriber beyond `MAX_SUBSCRIBERS` is refused with an error naming the service and
//!   the limit, and the daemon keeps publishing;
//! - a frozen subscriber (holding its borrowed samples, never receiving again) never stalls the
//!   frame publisher: the daemon's frame sequence keeps advancing for another reader.

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use lop_client::services::{self, IpcError, Role, MAX_SUBSCRIBERS};
use lop_client::{Attachment, ServiceNames};
use lop_system_tests::{unique_prefix, Daemon};

fn daemon(tag: &str, scene: &str) -> (Daemon, String) {
    let prefix = unique_prefix(tag);
    let d = Daemon::spawn(
        &["run", "--scene", scene, "--prefix", &prefix, "--quiet"],
        &prefix,
        Duration::from_secs(150),
    );
    (d, prefix)
}

#[test]
fn python_consumer_reads_frames_of_a_live_daemon() {
    let (mut daemon, prefix) = daemon("python", "abdomen");
    let mut client = Attachment::open(&prefix, Duration::from_secs(60))
        .unwrap_or_else(|e| panic!("attach: {e}\n{}", daemon.log_text()));
    let nodes = client
        .wait_topology(Duration::from_secs(60))
        .expect("topology")
        .header
        .node_count;
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/python/consumer.py");
    let mut child = Command::new("python3")
        .arg(&script)
        .args(["--prefix", &prefix, "--frames", "5", "--timeout", "30"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("python3 (installed by scripts/setup.sh)");
    let pid = child.id() as i32;
    std::thread::spawn(move || {
        std::thread::sleep(Duration::from_secs(90));
        // SAFETY: kill on a process this test started; harmless if it is gone.
        unsafe { libc::kill(pid, libc::SIGKILL) };
    });
    let _ = child.stdin.take();
    let out = child.wait_with_output().expect("consumer output");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success(),
        "consumer.py failed ({}); is the Python package iceoryx2==0.10.0 installed (scripts/setup.sh)?\n{stdout}\n{stderr}",
        out.status
    );
    let last = stdout.lines().last().unwrap_or("");
    assert_eq!(
        last,
        format!("OK frames=5 nodes={nodes} bodies=4 render_vertices=1890 finite=True"),
        "\n{stdout}"
    );
    assert!(stdout.contains("liver[0+"), "{stdout}");
    let frame_lines: Vec<&str> = stdout.lines().filter(|l| l.starts_with("frame ")).collect();
    assert_eq!(frame_lines.len(), 5);
    assert!(frame_lines
        .iter()
        .all(|l| l.contains(&format!(", {nodes} nodes, finite True"))));
    drop(client);
    daemon.signal(libc::SIGINT);
    assert!(daemon
        .wait(Duration::from_secs(20))
        .expect("stops")
        .success());
}

#[test]
fn clients_beyond_capacity_are_refused_and_frozen_clients_never_stall_the_publisher() {
    let (mut daemon, prefix) = daemon("limits", "organs");
    let names = ServiceNames::new(&prefix).unwrap();
    let mut reader = Attachment::open(&prefix, Duration::from_secs(60))
        .unwrap_or_else(|e| panic!("attach: {e}\n{}", daemon.log_text()));
    reader
        .wait_topology(Duration::from_secs(60))
        .expect("topology");
    let first = reader.next_frame(Duration::from_secs(30)).expect("frame");

    // A frozen client: takes two frames (the most it may borrow), holds them, never reads again.
    let node = services::node("systest-frozen").unwrap();
    let frozen = services::frame_service(&node, &names, Role::Client)
        .unwrap()
        .subscriber_builder()
        .buffer_size(services::FRAME_BUFFER)
        .create()
        .unwrap();
    let start = Instant::now();
    let mut held = Vec::new();
    while held.len() < 2 && start.elapsed() < Duration::from_secs(10) {
        if let Ok(Some(s)) = frozen.receive() {
            held.push(s);
        }
    }
    assert_eq!(held.len(), 2, "the frozen client got no frames");

    // Fill the frame service up to its capacity, then one more.
    let mut extra = Vec::new();
    let refused = loop {
        match Attachment::open(&prefix, Duration::from_secs(5)) {
            Ok(a) => extra.push(a),
            Err(e) => break e.to_string(),
        }
        assert!(
            extra.len() <= MAX_SUBSCRIBERS,
            "more than {MAX_SUBSCRIBERS} subscribers accepted"
        );
    };
    assert!(
        refused.contains(&names.frame) || refused.contains(&names.topology),
        "error does not name the service: {refused}"
    );
    assert!(
        refused.contains(&format!("maximum of {MAX_SUBSCRIBERS} subscribers")),
        "{refused}"
    );
    // The daemon's own subscribers (haptic loop, supervisor) plus ours make exactly the limit.
    assert!(
        !extra.is_empty() && extra.len() < MAX_SUBSCRIBERS,
        "{} accepted",
        extra.len()
    );
    let lower = services::frame_service(&node, &names, Role::Client)
        .unwrap()
        .subscriber_builder()
        .create()
        .map_err(|e| lop_client::limits::subscriber_create_error(&names.frame, e));
    assert!(matches!(
        lower,
        Err(IpcError::Full {
            limit: MAX_SUBSCRIBERS,
            ..
        })
    ));

    // The daemon notices nothing: frames keep coming, their sequence advancing past the frozen
    // client's held samples.
    let t0 = Instant::now();
    let mut newest = first.header.sequence;
    let mut frames = 0;
    let held_seq = held[1].user_header().sequence;
    while (frames < 100 || newest <= held_seq + 50) && t0.elapsed() < Duration::from_secs(30) {
        for f in reader.frames().expect("frames") {
            assert!(f.header.sequence > newest);
            newest = f.header.sequence;
            frames += 1;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    assert!(
        frames >= 100,
        "only {frames} frames while a client was frozen\n{}",
        daemon.log_text()
    );
    assert!(newest > held[1].user_header().sequence + 50);
    let log = daemon.log_text();
    assert!(!log.contains("frame not sent"), "{log}");
    assert!(!log.contains("exited"), "a daemon process exited:\n{log}");

    drop(held);
    drop(frozen);
    drop(extra);
    drop(reader);
    daemon.signal(libc::SIGINT);
    assert!(daemon
        .wait(Duration::from_secs(20))
        .expect("stops")
        .success());
}
