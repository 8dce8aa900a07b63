//! Building a stand-in vendor library (`drivers/standin-hd`, `drivers/standin-dhd`) for a test.
//!
//! `cargo test` does not reliably produce a `cdylib` of another workspace member, and a nested
//! `cargo build` would contend for the build lock, so a stand-in (one file, std only) is
//! compiled with `rustc` directly into the test's scratch directory. Each stand-in's
//! `testing.rs` calls this once per test process.

use std::path::{Path, PathBuf};
use std::process::Command;

/// Builds `drivers/standin-NAME/src/lib.rs` as the cdylib `liblop_standin_NAME.so` in a fresh
/// directory under `target_tmpdir`; returns its path. `manifest_dir` is the calling test
/// crate's (`env!("CARGO_MANIFEST_DIR")`): a workspace member beside `drivers/`, or the drivers
/// crate itself. Panics if the build fails (a test cannot go on without it).
pub fn build_standin(manifest_dir: &str, target_tmpdir: &str, name: &str) -> PathBuf {
    let beside = Path::new(manifest_dir)
        .join("..")
        .join(format!("drivers/standin-{name}/src/lib.rs"));
    let source = if beside.exists() {
        beside
    } else {
        // The drivers crate itself.
        Path::new(manifest_dir).join(format!("standin-{name}/src/lib.rs"))
    };
    let dir = Path::new(target_tmpdir).join(format!("standin-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("stand-in build directory");
    let crate_name = format!("lop_standin_{name}");
    let out = dir.join(format!("lib{crate_name}.so"));
    let rustc = std::env::var_os("RUSTC").unwrap_or_else(|| "rustc".into());
    let status = Command::new(rustc)
        .args([
            "--edition",
            "2021",
            "--crate-type",
            "cdylib",
            "--crate-name",
        ])
        .arg(&crate_name)
        .args(["-C", "opt-level=1", "-o"])
        .arg(&out)
        .arg(&source)
        .status()
        .unwrap_or_else(|e| panic!("run rustc to build the stand-in {crate_name}: {e}"));
    assert!(
        status.success(),
        "building the stand-in {crate_name} failed"
    );
    out
}
