//! Shared fixtures for the integration tests.
#![allow(dead_code)]

use std::path::PathBuf;
use std::sync::OnceLock;

/// A directory holding a fake TetGen mesh `m.node` (only its existence is checked), shared by
/// every test of the process.
pub fn fixture_dir() -> PathBuf {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("lop-config-tests");
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("m.node"), "4 3 0 0\n").unwrap();
        dir
    })
    .clone()
}

/// Where the scene under test "lives": messages name it, and `mesh = "m"` resolves next to it.
pub fn scene_path() -> PathBuf {
    fixture_dir().join("test-scene.toml")
}

/// A minimal valid scene. Lines are stable: tests replace one line to break it.
pub const GOOD: &str = r#"[scene]
name = "t"
gravity = [0.0, -9.81, 0.0]

[[body]]
name = "a"
mesh = "m"
importance = "important"

[body.fem]
young = 600.0
poisson = 0.3
density = 30.0
damping = 1.0
dt = 0.02

[body.msd]
stiffness = 700.0
density = 120.0
damping = 0.4
dt = 0.02

[[body]]
name = "b"
mesh = "m"

[body.msd]
stiffness = 700.0
node_mass = 0.001
damping = 0.4
dt = 0.02
integrator = "rk4"
"#;

/// `GOOD` with the first occurrence of `from` replaced by `to` (panics if absent, so a test
/// cannot silently test the unmodified text).
pub fn good_with(from: &str, to: &str) -> String {
    assert!(GOOD.contains(from), "fixture lacks {from:?}");
    GOOD.replacen(from, to, 1)
}

/// 1-based line of the first occurrence of `needle` in `text`.
pub fn line_of(text: &str, needle: &str) -> usize {
    let offset = text.find(needle).expect("needle in text");
    text[..offset].matches('\n').count() + 1
}
