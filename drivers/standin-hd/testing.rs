//! For tests: builds the stand-in libHD (`drivers/standin-hd`) and returns the path of the
//! shared library. Include it with
//! `#[path = "<relative>/drivers/standin-hd/testing.rs"] mod standin;`.
//!
//! `cargo test` does not reliably produce a `cdylib` of another workspace member, and a nested
//! `cargo build` would contend for the build lock, so the stand-in (one file, std only) is
//! compiled with `rustc` directly, once per test process, into the test's scratch directory.

// Each test crate uses a different part of this file.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

/// Path of a freshly built stand-in library (built once per process).
pub fn standin_library() -> PathBuf {
    static LIB: OnceLock<PathBuf> = OnceLock::new();
    LIB.get_or_init(|| {
        let source = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("..")
            .join("drivers/standin-hd/src/lib.rs");
        let source = if source.exists() {
            source
        } else {
            // The drivers crate itself.
            Path::new(env!("CARGO_MANIFEST_DIR")).join("standin-hd/src/lib.rs")
        };
        let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
            .join(format!("standin-hd-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("stand-in build directory");
        let out = dir.join("liblop_standin_hd.so");
        let rustc = std::env::var_os("RUSTC").unwrap_or_else(|| "rustc".into());
        let status = Command::new(rustc)
            .args([
                "--edition",
                "2021",
                "--crate-type",
                "cdylib",
                "--crate-name",
                "lop_standin_hd",
                "-C",
                "opt-level=1",
                "-o",
            ])
            .arg(&out)
            .arg(&source)
            .status()
            .expect("run rustc to build the stand-in libHD");
        assert!(status.success(), "building the stand-in libHD failed");
        out
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
