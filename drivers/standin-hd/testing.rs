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

/// One row of a stand-in event log (`LOP_STANDIN_LOG_DIR`).
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

/// The stand-in log files in `dir`, oldest session first.
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
