//! Shared by the tests that run the `lopd` binary: the command, its outcome, scratch folders.
#![allow(dead_code)] // each test binary uses what it needs

use std::path::PathBuf;
use std::process::Command;

/// `lopd` with no backtraces and warnings-only logs.
pub fn lopd() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_lopd"));
    c.env("RUST_BACKTRACE", "0").env("LOP_LOG", "warn");
    c
}

/// Runs `c` to its end: exit code (-1 if killed), standard output, standard error.
pub fn run(c: &mut Command) -> (i32, String, String) {
    let out = c.output().expect("run lopd");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// A fresh, empty scratch folder `lopd-<test>-<name>-<pid>` (unique per process, so concurrent
/// runs of the suite do not clash).
pub fn temp_dir(test: &str, name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("lopd-{test}-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}
