//! Smoke test of `lop-bench soak`: 45 s (the shortest soak of the default scene) of the real
//! pipeline (`lopd run --view --record` on `abdomen`) under the whole fault plan — the
//! deformation process killed and stopped, NaN and out-of-workspace samples, control hammered,
//! viewers of every kind coming and going — must pass every check, and the report must show
//! that each kind of fault was injected. No wall-clock bound: the watchdog is for a hang only.

mod common;

use std::path::PathBuf;
use std::time::Duration;

/// A binary of the same build: cargo puts every workspace binary into the same target dir.
fn beside_bench(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_lop-bench")).with_file_name(name)
}

#[test]
fn soak_of_45_seconds_passes_every_check() {
    let lopd = beside_bench("lopd");
    // Not a skip: a test that passes without running hides the pipeline's safety from CI.
    // `cargo test --workspace` builds them; `cargo test -p lop-bench` alone does not.
    for bin in [&lopd, &beside_bench("lop-view")] {
        assert!(
            bin.is_file(),
            "{} does not exist, so the soak smoke test cannot run: build it first \
             (`cargo build -p lop-daemon -p lop-view`), or run `cargo test --workspace`",
            bin.display()
        );
    }
    let out = std::env::temp_dir().join(format!("lopbench-soak-smoke-{}", std::process::id()));
    let stdout = common::run_bench(
        &[
            "soak".as_ref(),
            "--seconds".as_ref(),
            "45".as_ref(),
            "--seed".as_ref(),
            "1".as_ref(),
            "--out".as_ref(),
            out.as_os_str(),
            "--lopd".as_ref(),
            lopd.as_os_str(),
        ],
        Duration::from_secs(300),
    );
    assert!(stdout.contains("soak: every check passed"), "{stdout}");

    let text = std::fs::read_to_string(out.join("soak.json")).expect("soak.json written");
    let v: serde_json::Value = serde_json::from_str(&text).expect("valid JSON");
    assert_eq!(v["pass"], true, "{text}");
    let checks = v["checks"].as_array().expect("checks");
    assert!(checks.len() >= 12, "{text}");
    for c in checks {
        assert_eq!(c["pass"], true, "{c}");
    }
    // Every kind of fault was injected into both processes, and answered.
    let injections = v["injections"].as_array().expect("injections");
    for process in ["deform", "haptic"] {
        for kind in ["kill", "stop"] {
            assert!(
                injections
                    .iter()
                    .any(|i| i["process"] == process && i["kind"] == kind && i["answered"] == true),
                "no answered {process} {kind}: {text}"
            );
        }
    }
    let tool = &v["tool_stream"];
    // The haptic loop came back twice (a new process, a stopped one), from zero each time.
    assert!(tool["restarts"].as_u64().unwrap() >= 2, "{text}");
    assert_eq!(tool["violations"]["not_from_zero"], 0, "{text}");
    assert_eq!(tool["violations"]["jump"], 0, "{text}");
    assert!(tool["episodes_stale"].as_u64().unwrap() >= 2, "{text}");
    assert!(
        tool["planned_samples_flagged"].as_u64().unwrap() >= 4,
        "{text}"
    );
    assert!(v["hammer"]["bad_sent"].as_u64().unwrap() > 0, "{text}");
    assert!(v["ctl"]["runs"].as_u64().unwrap() > 0, "{text}");
    for kind in ["token", "no_token", "wrong_token", "cross_origin"] {
        assert!(
            v["viewers"]["kinds"][kind]["sessions"]
                .as_u64()
                .unwrap_or(0)
                > 0,
            "no {kind} viewer session: {text}"
        );
    }
    let _ = std::fs::remove_dir_all(&out);
}
