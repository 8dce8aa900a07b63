//! Smoke tests of `lop-bench soak` on the real pipeline (`lopd run --view` on `abdomen`) under
//! the whole fault plan — the deformation and the haptic process killed and stopped, NaN and
//! out-of-workspace samples, control hammered, viewers of every kind coming and going:
//! - one device for 45 s (the shortest soak of the default scene whose memory is judged), with
//!   `--record`: every check must pass;
//! - two devices for 20 s (the shortest soak: a haptic kill and stop, a deformation kill and
//!   stop): every check must pass per tool, the recording (one device only) and the memory (too
//!   short) must say N/A, and every haptic fault must have brought both devices back from zero.
//!
//! The report must show that each kind of fault was injected. The two never run at once (two
//! pipelines on a 2-core machine would starve each other's haptic loops). No wall-clock bound:
//! the watchdog is for a hang only.

mod common;

use std::path::PathBuf;
use std::sync::Mutex;
use std::time::Duration;

/// Held by the soak running, so the two tests take turns.
static ONE_AT_A_TIME: Mutex<()> = Mutex::new(());

/// A binary of the same build: cargo puts every workspace binary into the same target dir.
fn beside_bench(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_lop-bench")).with_file_name(name)
}

/// Runs `lop-bench soak --seconds SECONDS --seed 1 --devices DEVICES`, asserts it printed
/// that every check passed, and returns its `soak.json` (as text, and parsed).
fn soak(seconds: u32, devices: u32) -> (String, serde_json::Value) {
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
    let _turn = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let out = std::env::temp_dir().join(format!(
        "lopbench-soak-smoke-{devices}-{}",
        std::process::id()
    ));
    let (seconds, devices) = (seconds.to_string(), devices.to_string());
    let stdout = common::run_bench(
        &[
            "soak".as_ref(),
            "--seconds".as_ref(),
            seconds.as_ref(),
            "--devices".as_ref(),
            devices.as_ref(),
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
    let _ = std::fs::remove_dir_all(&out);
    (text, v)
}

/// Asserts that every kind of fault (kill, stop) was injected into both processes and
/// answered; returns the injections.
fn every_fault_answered<'a>(v: &'a serde_json::Value, text: &str) -> &'a Vec<serde_json::Value> {
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
    injections
}

#[test]
fn soak_of_45_seconds_passes_every_check() {
    let (text, v) = soak(45, 1);
    assert_eq!(v["pass"], true, "{text}");
    let checks = v["checks"].as_array().expect("checks");
    assert!(checks.len() >= 12, "{text}");
    for c in checks {
        assert_eq!(c["pass"], true, "{c}");
        assert_eq!(c["applies"], true, "{c}");
    }
    // Every kind of fault was injected into both processes, and answered.
    every_fault_answered(&v, &text);
    assert_eq!(v["settings"]["devices"], 1, "{text}");
    assert_eq!(
        v["tool_streams"].as_array().map(Vec::len),
        Some(1),
        "{text}"
    );
    let tool = &v["tool_streams"][0];
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
}

#[test]
fn soak_of_two_devices_passes_every_check_on_every_tool() {
    let (text, v) = soak(20, 2);
    assert_eq!(v["pass"], true, "{text}");
    assert_eq!(v["settings"]["devices"], 2, "{text}");
    // Every check passed, but the recording's (one device only) and the memory's (a run of
    // 20 s is shorter than the warm-up), which say why they do not apply.
    for c in v["checks"].as_array().expect("checks") {
        assert_eq!(c["pass"], true, "{c}");
        let name = c["name"].as_str().unwrap();
        let applies = !(name.starts_with("recording") || name.starts_with("memory"));
        assert_eq!(c["applies"], applies, "{c}");
    }
    // Each device broke at its own ticks.
    let samples = v["plan"]["samples"].as_array().expect("samples per device");
    assert_eq!(samples.len(), 2, "{text}");
    assert_ne!(samples[0], samples[1], "{text}");
    // Every haptic kill and stop brought both devices back, each from zero; every deformation
    // fault made both ramp.
    let injections = every_fault_answered(&v, &text);
    let max_step = v["settings"]["max_step_n"].as_f64().unwrap();
    for i in injections.iter().filter(|i| i["answered"] == true) {
        let tools = i["tools"].as_array().expect("per tool");
        assert_eq!(tools.len(), 2, "{i}");
        for t in tools {
            assert_eq!(t["answered"], true, "{i}");
            if i["process"] == "haptic" {
                assert!(t["force_before_n"].is_number(), "{i}");
                if let Some(f) = t["first_force_n"].as_f64() {
                    assert!(f <= max_step, "{i}");
                }
            }
        }
    }
    // Per tool: back twice (a new process, a stopped one), from zero each time; no pop; both
    // stale episodes; its own device's broken samples caught, no other device error; the
    // device's last force zero.
    let streams = v["tool_streams"].as_array().expect("tool_streams");
    assert_eq!(streams.len(), 2, "{text}");
    for (k, tool) in streams.iter().enumerate() {
        assert_eq!(tool["tool"], k, "{text}");
        assert!(tool["restarts"].as_u64().unwrap() >= 2, "tool {k}: {text}");
        assert_eq!(tool["segments"], 1, "tool {k}: {text}");
        assert_eq!(tool["violations"]["not_from_zero"], 0, "tool {k}: {text}");
        assert_eq!(tool["violations"]["jump"], 0, "tool {k}: {text}");
        assert!(
            tool["episodes_stale"].as_u64().unwrap() >= 2,
            "tool {k}: {text}"
        );
        assert!(
            tool["planned_samples_flagged"].as_u64().unwrap() >= 2,
            "tool {k}: {text}"
        );
        assert_eq!(tool["unexpected_device_errors"], 0, "tool {k}: {text}");
        assert!(
            tool["loaded_ticks"].as_u64().unwrap() > 0,
            "tool {k}: {text}"
        );
        assert_eq!(
            v["force_logs"][k]["last"],
            serde_json::json!([0.0, 0.0, 0.0]),
            "tool {k}: {text}"
        );
    }
}
