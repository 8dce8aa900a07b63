//! The OpenHaptics path end to end, across processes, against the stand-in libHD
//! (`drivers/standin-hd`, loaded through `LOP_HD_LIBRARY`): `lopd run --device openhaptics
//! --record` on the cylinders scene with the deformation process running.
//!
//! Invariants guarded:
//! - the device comes up and the servo callback is the clock; a poke into cylinder_a is felt
//!   (non-zero contact force in the forces the device received);
//! - an injected force error (`HD_EXCEEDED_MAX_FORCE`) is recoverable: the loop keeps going and
//!   the contact force comes back;
//! - an injected communication error (`HD_COMM_ERROR`) stops the haptic process safely: zero
//!   force in the next frames, then the supervisor restarts it;
//! - on every exit (the fatal error, then Ctrl-C) the last force the device rendered is exactly
//!   zero, also at `hdUnschedule`, `hdStopScheduler` and `hdDisableDevice`;
//! - `--record` stored the session's device stream (the restarted process records to a new
//!   file), with the error ticks in it; no service is left behind.

#[path = "../../drivers/standin-hd/testing.rs"]
mod standin;

use std::time::{Duration, Instant};

use lop_drivers::replay::Recording;
use lop_drivers::DeviceError;
use lop_system_tests::{unique_prefix, Daemon};
use lop_test_support::vec3::norm;
use standin::{assert_safe_exit, logs_in, read_log, standin_library, StandinEvent};

/// Device x (mm) of the stylus at servo tick `k`: rest beside cylinder_a (6 mm off its outer
/// side, outside the switch margin) until 4 s, push 9 mm in over 0.7 s, hold, withdraw from 8 s.
/// y = z = 0 mm (cylinders-poke's target).
fn x_at(k: u64) -> f64 {
    let t = k as f64 / 1000.0;
    let smooth = |u: f64| {
        let u = u.clamp(0.0, 1.0);
        u * u * (3.0 - 2.0 * u)
    };
    -70.0 + 15.0 * smooth((t - 4.0) / 0.7) - 15.0 * smooth((t - 8.0) / 0.7)
}

#[test]
fn openhaptics_run_with_standin_library_errors_and_record() {
    let prefix = unique_prefix("openhaptics");
    let dir = std::env::temp_dir().join(format!("{prefix}-files"));
    let logs = dir.join("standin");
    std::fs::create_dir_all(&logs).unwrap();
    let trajectory = dir.join("trajectory.csv");
    let mut text = String::new();
    for k in 0..12_000 {
        text.push_str(&format!("{},0.0,0.0\n", x_at(k)));
    }
    std::fs::write(&trajectory, text).unwrap();
    let record = dir.join("session.lrec");
    let record_s = record.display().to_string();
    // SAFETY: the only test in this binary; set before any thread reads the environment. The
    // variables reach lopd (and the stand-in in its haptic child) by inheritance.
    unsafe {
        std::env::set_var("LOP_HD_LIBRARY", standin_library());
        std::env::set_var("LOP_STANDIN_TRAJECTORY", &trajectory);
        std::env::set_var("LOP_STANDIN_ERRORS", "2000:0x0201,7000:0x0302");
        std::env::set_var("LOP_STANDIN_LOG_DIR", &logs);
    }
    let mut daemon = Daemon::spawn(
        &[
            "run",
            "--scene",
            "cylinders",
            "--device",
            "openhaptics",
            "--prefix",
            &prefix,
            "--quiet",
            "--record",
            &record_s,
        ],
        &prefix,
        Duration::from_secs(120),
    );

    // Session 1 ends on the communication error at servo tick 7000 (its log is written when
    // the device is disabled); the supervisor then starts session 2.
    let t0 = Instant::now();
    while logs_in(&logs).is_empty() && t0.elapsed() < Duration::from_secs(60) {
        std::thread::sleep(Duration::from_millis(50));
    }
    assert_eq!(
        logs_in(&logs).len(),
        1,
        "session 1 did not end\n{}",
        daemon.log_text()
    );
    let second = dir.join("session-1.lrec");
    while !second.exists() && t0.elapsed() < Duration::from_secs(60) {
        std::thread::sleep(Duration::from_millis(50));
    }
    assert!(
        second.exists(),
        "haptic not restarted\n{}",
        daemon.log_text()
    );
    std::thread::sleep(Duration::from_millis(1500));
    daemon.signal(libc::SIGINT);
    let status = daemon
        .wait(Duration::from_secs(20))
        .expect("lopd run did not stop");
    let log_text = daemon.log_text();
    assert!(status.success(), "exit {status}\n{log_text}");
    assert!(
        log_text.contains("device error stopped the haptic loop: device communication error"),
        "{log_text}"
    );
    assert!(lop_ipc::services::list_services(&prefix).is_empty());

    let files = logs_in(&logs);
    assert_eq!(files.len(), 2, "{files:?}");
    let s1 = read_log(&files[0]);
    let s2 = read_log(&files[1]);

    // Session 1: contact felt, the force error survived, the communication error stopped it.
    let frames: Vec<&StandinEvent> = s1.iter().filter(|e| e.event == "frame").collect();
    let errors: Vec<(u64, u32)> = s1
        .iter()
        .filter(|e| e.event == "error")
        .map(|e| (e.tick, e.code))
        .collect();
    assert_eq!(errors, [(2000, 0x0201), (7000, 0x0302)]);
    let felt = |from: u64, to: u64| {
        frames
            .iter()
            .filter(|e| e.tick >= from && e.tick < to)
            .map(|e| norm(e.force))
            .fold(0.0, f64::max)
    };
    let before = felt(0, 3900);
    let pushed = felt(4000, 6990);
    let held = frames
        .iter()
        .filter(|e| e.tick >= 6000 && e.tick < 6990)
        .map(|e| norm(e.force))
        .fold(f64::INFINITY, f64::min);
    assert_eq!(before, 0.0, "force before the poke");
    // The push peaks (the tissue lags the tool), then the FEM tissue yields and the held tool
    // feels a small steady force, as with the mock poke.
    assert!(
        pushed > 0.05 && pushed <= 3.0 + 1e-9,
        "peak contact force while pushing in: {pushed} N\n{log_text}"
    );
    assert!(held > 0.005, "steady contact force while held: {held} N");
    eprintln!("contact force: peak {pushed:.3} N while pushing, {held:.4} N held");
    // Mostly -x (out of the cylinder's outer side, back toward the user's hand).
    let push = frames.iter().find(|e| e.tick == 6000).unwrap();
    assert!(-push.force[0] > 0.9 * norm(push.force), "{push:?}");
    // After the fatal error the servo loop stops: in log order, at most the callback's frame
    // of that tick, its zero-force last frame and the shutdown's synchronous zeroing, all at
    // zero force, none after the scheduler stopped. (Counted in frames, not ticks: the stand-in's
    // scheduler keeps its wall-clock tick while the daemon shuts down, so on a loaded machine
    // the zeroing lands a few ticks later.)
    let fatal = s1
        .iter()
        .position(|e| e.event == "error" && e.code == 0x0302)
        .unwrap();
    let stopped = s1
        .iter()
        .position(|e| e.event == "stop_scheduler")
        .expect("no stop_scheduler");
    let after: Vec<&StandinEvent> = s1[fatal..].iter().filter(|e| e.event == "frame").collect();
    assert!(
        after.len() <= 3 && after.iter().all(|e| e.force == [0.0; 3]),
        "frames went on after the fatal error: {after:?}"
    );
    assert!(
        !s1[stopped..].iter().any(|e| e.event == "frame"),
        "a frame after the scheduler stopped"
    );
    assert_safe_exit(&s1, "session 1");

    // Session 2: stopped by Ctrl-C.
    assert!(s2.iter().filter(|e| e.event == "frame").count() > 500);
    assert_safe_exit(&s2, "session 2");

    // The recording of session 1: the stream, the force-error tick and the fatal tick.
    let rec = Recording::load(&record).unwrap();
    let r = rec.records();
    assert!((6900..=7000).contains(&r.len()), "{} records", r.len());
    assert_eq!(r.last().unwrap().error, Some(DeviceError::Communication));
    assert_eq!(
        r.iter()
            .filter(|x| x.error == Some(DeviceError::ForceLimitExceeded))
            .count(),
        1
    );
    let deepest = r
        .iter()
        .filter(|x| x.error.is_none())
        .map(|x| x.sample.position_mm[0])
        .fold(f64::NEG_INFINITY, f64::max);
    assert_eq!(deepest, -55.0);
    assert_eq!(rec.header().get("device"), Some("openhaptics"));
    assert!(Recording::load(&second).unwrap().records().len() > 500);
    let _ = std::fs::remove_dir_all(&dir);
    let _ = std::fs::remove_file(&daemon.log);
}
