//! For tests: builds the stand-in libHD (`drivers/standin-hd`) and returns the path of the
//! shared library. Include it with
//! `#[path = "<relative>/drivers/standin-hd/testing.rs"] mod standin;`.
//!
//! Built once per test process by `lop_test_support::standin::build_standin`.

// Each test crate uses a different part of this file.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// Path of a freshly built stand-in library (built once per process).
pub fn standin_library() -> PathBuf {
    static LIB: OnceLock<PathBuf> = OnceLock::new();
    LIB.get_or_init(|| {
        lop_test_support::standin::build_standin(
            env!("CARGO_MANIFEST_DIR"),
            env!("CARGO_TARGET_TMPDIR"),
            "hd",
        )
    })
    .clone()
}

/// One row of a stand-in device's event log (`LOP_STANDIN_LOG_DIR`).
#[derive(Clone, Debug, PartialEq)]
pub struct StandinEvent {
    pub event: String,
    pub tick: u64,
    pub code: u32,
    pub force: [f64; 3],
}

/// Reads one stand-in log file.
pub fn read_log(path: &Path) -> Vec<StandinEvent> {
    let text = std::fs::read_to_string(path).expect("stand-in log");
    text.lines()
        .skip(1)
        .map(|l| {
            let v: Vec<&str> = l.split(',').collect();
            StandinEvent {
                event: v[0].to_string(),
                tick: v[1].parse().unwrap(),
                code: v[2].parse().unwrap(),
                force: [
                    v[3].parse().unwrap(),
                    v[4].parse().unwrap(),
                    v[5].parse().unwrap(),
                ],
            }
        })
        .collect()
}

/// The stand-in log files of device `name` in `dir`, oldest session first.
pub fn logs_of(dir: &Path, name: &str) -> Vec<PathBuf> {
    let suffix = format!("-{name}.csv");
    logs_in(dir)
        .into_iter()
        .filter(|p| p.to_string_lossy().ends_with(&suffix))
        .collect()
}

/// The stand-in log files in `dir` (every device's), oldest session first.
pub fn logs_in(dir: &Path) -> Vec<PathBuf> {
    let mut files: Vec<(std::time::SystemTime, PathBuf)> = std::fs::read_dir(dir)
        .map(|d| {
            d.flatten()
                .filter(|e| e.file_name().to_string_lossy().starts_with("standin-"))
                .map(|e| (e.metadata().unwrap().modified().unwrap(), e.path()))
                .collect()
        })
        .unwrap_or_default();
    files.sort();
    files.into_iter().map(|(_, p)| p).collect()
}

/// Zero force last, in the log of one device's session (`who` names it in messages): its last
/// frame rendered zero, so did every release step (`hdUnschedule`, `hdStopScheduler`,
/// `hdDisable(HD_FORCE_OUTPUT)`, `hdDisableDevice`), the scheduler was stopped and the device
/// disabled, and no force above the device's limit was ever sent.
pub fn assert_safe_exit(log: &[StandinEvent], who: &str) {
    let last = log
        .iter()
        .rev()
        .find(|e| e.event == "frame")
        .unwrap_or_else(|| panic!("{who}: no frames"));
    assert_eq!(last.force, [0.0; 3], "{who}: last frame {last:?}");
    for step in [
        "unschedule",
        "stop_scheduler",
        "force_output_off",
        "disable_device",
    ] {
        for e in log.iter().filter(|e| e.event == step) {
            assert_eq!(e.force, [0.0; 3], "{who}: force rendered at {step}: {e:?}");
        }
    }
    for step in ["stop_scheduler", "force_output_off", "disable_device"] {
        assert!(log.iter().any(|e| e.event == step), "{who}: no {step}");
    }
    assert!(
        !log.iter().any(|e| e.event == "exceeded"),
        "{who}: a force above the device's limit was sent"
    );
}

/// Every frame of one device's session began and ended once, in pairs (`begin`, `frame`,
/// `begin`, `frame`, …), with no illegal begin or end and no force set outside a frame.
pub fn assert_frames_paired(log: &[StandinEvent], who: &str) {
    let mut open = false;
    for e in log {
        match e.event.as_str() {
            "begin" => {
                assert!(
                    !open,
                    "{who}: a begin inside an open frame at tick {}",
                    e.tick
                );
                open = true;
            }
            "frame" => {
                assert!(open, "{who}: an end without a begin at tick {}", e.tick);
                open = false;
            }
            "illegal_begin" | "illegal_end" | "set_outside_frame" => panic!("{who}: {e:?}"),
            _ => {}
        }
    }
    assert!(!open, "{who}: a frame left open");
}
