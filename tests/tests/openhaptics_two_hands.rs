//! Two OpenHaptics devices by name, one per tool, across processes: `lopd run` on the default
//! scene with a second tool (`lop_test_support::fixtures::two_tool_abdomen`), `--device openhaptics:Left --device
//! openhaptics:Right`, against the stand-in libHD serving both names on its one scheduler, each
//! playing the default poke (the second tool's device mapped 30 mm further along the liver).
//!
//! Invariants guarded:
//! - both devices come up by their names on one scheduler, and the one servo callback drives
//!   both tools: each tool's state presses the liver;
//! - each device received the contact force of its own tool (a clearly felt force in each
//!   device's frames), every frame of each device began and ended once;
//! - Ctrl-C ends with zero force on both devices: in each one's last frame and at every release
//!   step, and no service is left behind.

#[path = "../../drivers/standin-hd/testing.rs"]
mod standin;

use std::time::{Duration, Instant};

use lop_client::{Attachment, ToolState, TOOL_FLAG_CONTACT};
use lop_drivers::mock::MockScript;
use lop_system_tests::{interrupt, unique_prefix, Daemon};
use lop_test_support::fixtures::two_tool_abdomen;
use lop_test_support::vec3::norm;
use standin::{assert_frames_paired, assert_safe_exit, logs_of, read_log, standin_library};

const NAMES: [&str; 2] = ["Left", "Right"];

#[test]
fn two_openhaptics_devices_press_one_liver() {
    let prefix = unique_prefix("oh-two-hands");
    let dir = std::env::temp_dir().join(&prefix);
    let logs = dir.join("standin");
    std::fs::create_dir_all(&logs).unwrap();
    let scene = two_tool_abdomen(&dir);
    // Both devices play the default poke (a loop of 4.4 s) for a minute, then hold still.
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let poke = MockScript::load(&root.join("config/scripts/abdomen-poke.toml")).unwrap();
    let trajectory = dir.join("trajectory.csv");
    let mut text = String::new();
    for k in 0..60_000 {
        let p = poke.sample(k as f64 / 1000.0).position_mm;
        text.push_str(&format!("{},{},{}\n", p[0], p[1], p[2]));
    }
    std::fs::write(&trajectory, text).unwrap();
    // SAFETY: the only test in this binary; set before any thread reads the environment. The
    // variables reach lopd (and the stand-in in its haptic child) by inheritance.
    unsafe {
        std::env::set_var("LOP_HD_LIBRARY", standin_library());
        std::env::set_var("LOP_STANDIN_DEVICE_NAMES", NAMES.join(","));
        std::env::set_var("LOP_STANDIN_TRAJECTORY", &trajectory);
        std::env::set_var("LOP_STANDIN_LOG_DIR", &logs);
        std::env::remove_var("LOP_STANDIN_ERRORS");
    }
    let scene_s = scene.display().to_string();
    let mut daemon = Daemon::spawn(
        &[
            "run",
            "--scene",
            &scene_s,
            "--device",
            "openhaptics:Left",
            "--device",
            "openhaptics:Right",
            "--prefix",
            &prefix,
            "--quiet",
        ],
        &prefix,
        Duration::from_secs(120),
    );
    let mut client = Attachment::open(&prefix, Duration::from_secs(30))
        .unwrap_or_else(|e| panic!("attach: {e}\n{}", daemon.log_text()));
    client
        .wait_topology(Duration::from_secs(30))
        .unwrap_or_else(|e| panic!("topology: {e}\n{}", daemon.log_text()));

    // Both tools press the liver with more than 0.2 N for half a second or more.
    let mut states: Vec<ToolState> = Vec::new();
    let mut pressing = [0usize; 2];
    let t0 = Instant::now();
    while pressing.iter().any(|&n| n < 500) && t0.elapsed() < Duration::from_secs(40) {
        states.clear();
        client.tool_states(&mut states);
        for s in &states {
            assert!(s.tool < 2, "a tool state of tool {}", s.tool);
            if s.flags & TOOL_FLAG_CONTACT != 0 && s.contact_body == 0 && norm(s.force) > 0.2 {
                pressing[s.tool as usize] += 1;
            }
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    assert!(
        pressing.iter().all(|&n| n >= 500),
        "tool states pressing the liver over 0.2 N, per tool: {pressing:?}\n{}",
        daemon.log_text()
    );

    drop(client);
    let log = interrupt(&mut daemon);
    assert!(lop_ipc::services::list_services(&prefix).is_empty());

    let mut frame_counts = Vec::new();
    for name in NAMES {
        let files = logs_of(&logs, name);
        assert_eq!(files.len(), 1, "{name}: one session: {files:?}\n{log}");
        let events = read_log(&files[0]);
        assert_frames_paired(&events, name);
        assert_safe_exit(&events, name);
        let frames: Vec<[f64; 3]> = events
            .iter()
            .filter(|e| e.event == "frame")
            .map(|e| e.force)
            .collect();
        let peak = frames.iter().map(|&f| norm(f)).fold(0.0, f64::max);
        eprintln!("{name}: peak {peak:.3} N over {} frames", frames.len());
        assert!(
            peak > 0.2 && peak < 1.5,
            "{name}: peak force received {peak:.3} N; the poke's answer is 0.3-1 N\n{log}"
        );
        frame_counts.push(frames.len());
    }
    assert_eq!(
        frame_counts[0], frame_counts[1],
        "one frame of each device per servo tick"
    );
    let _ = std::fs::remove_dir_all(&dir);
    let _ = std::fs::remove_file(&daemon.log);
}
