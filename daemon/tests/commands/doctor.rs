//! `lopd doctor` on this machine: every check reports, every WARN and FAIL carries a fix, the
//! exit code is 1 exactly when something fails, and a machine without the OpenHaptics library
//! or device (CI) gets a FAIL with the fix, not a crash. With the stand-in libHD the device
//! check passes and reports the device's limits.

use crate::standin;

use std::process::Command;

const CHECKS: [&str; 10] = [
    "config",
    "rt-priority",
    "memory-lock",
    "kernel",
    "cpu-affinity",
    "cpu-isolation",
    "device-library",
    "device",
    "shared-memory",
    "stale-ipc",
];

fn doctor(args: &[&str], library: Option<&std::path::Path>) -> (i32, String, String) {
    let mut c = Command::new(env!("CARGO_BIN_EXE_lopd"));
    c.arg("doctor")
        .args(["--prefix", &format!("doctor-{}", std::process::id())])
        .args(args)
        .env("RUST_BACKTRACE", "0")
        .env("LOP_LOG", "warn")
        .env_remove("LOP_HD_LIBRARY");
    if let Some(l) = library {
        c.env("LOP_HD_LIBRARY", l);
    }
    let o = c.output().expect("run lopd doctor");
    (
        o.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

#[test]
fn doctor_without_the_library_fails_with_fixes() {
    let missing = std::env::temp_dir().join("lop-doctor-no-such/libHD.so");
    let (code, out, err) = doctor(&[], Some(&missing));
    assert!(!err.contains("panicked"), "{err}");
    let lines: Vec<&str> = out.lines().collect();
    for check in CHECKS {
        assert!(
            lines
                .iter()
                .any(|l| l.split_whitespace().nth(1) == Some(check)),
            "no {check} line in\n{out}"
        );
    }
    // Every WARN and FAIL is followed by its fix.
    for (i, l) in lines.iter().enumerate() {
        if l.starts_with("WARN") || l.starts_with("FAIL") {
            assert!(lines[i + 1].trim_start().starts_with("fix:"), "{l}\n{out}");
        }
    }
    let library = lines.iter().find(|l| l.contains("device-library")).unwrap();
    assert!(
        library.starts_with("FAIL") && library.contains("lop-doctor-no-such"),
        "{library}"
    );
    assert!(
        out.contains("LOP_HD_LIBRARY") && out.contains("docs/deploy.md"),
        "{out}"
    );
    let fails = lines.iter().filter(|l| l.starts_with("FAIL")).count();
    assert!(fails >= 2, "{out}");
    assert_eq!(code, 1, "{out}");
    assert!(out.contains(&format!("{fails} FAIL")), "{out}");
}

#[test]
fn doctor_with_the_standin_device_and_json() {
    let lib = standin::standin_library();
    let (code, out, err) = doctor(&["--json"], Some(&lib));
    let v: serde_json::Value =
        serde_json::from_str(&out).unwrap_or_else(|e| panic!("{e}\n{out}\n{err}"));
    let findings = v.as_array().unwrap();
    assert_eq!(findings.len(), CHECKS.len(), "{out}");
    let get = |name: &str| findings.iter().find(|f| f["check"] == name).unwrap();
    assert_eq!(get("device-library")["status"], "OK");
    let device = get("device");
    assert_eq!(device["status"], "OK", "{device}");
    let value = device["value"].as_str().unwrap();
    assert!(
        value.contains("peak 3.3 N") && value.contains("0.7 N/mm"),
        "{value}"
    );
    let failed = findings.iter().any(|f| f["status"] == "FAIL");
    assert_eq!(code, if failed { 1 } else { 0 }, "{out}");
    for f in findings {
        assert!(["OK", "WARN", "FAIL"].contains(&f["status"].as_str().unwrap()));
        if f["status"] != "OK" {
            assert!(f["fix"].as_str().is_some_and(|s| !s.is_empty()), "{f}");
        }
    }
}

#[test]
fn doctor_names_a_bad_config_key_and_needs_no_library_for_mock() {
    let dir = std::env::temp_dir().join(format!("lop-doctor-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let config = dir.join("lopd.toml");
    std::fs::write(&config, "[haptic]\nrt_priority = 150\n").unwrap();
    let (code, out, _) = doctor(
        &["--device", "mock", "--config", config.to_str().unwrap()],
        None,
    );
    let line = out.lines().find(|l| l.contains(" config ")).unwrap();
    assert!(
        line.starts_with("FAIL") && line.contains("rt_priority") && line.contains("150"),
        "{line}"
    );
    let device = out.lines().find(|l| l.contains(" device ")).unwrap();
    assert!(
        device.starts_with("OK") && device.contains("mock"),
        "{device}"
    );
    assert!(!out.contains("device-library"), "{out}");
    assert_eq!(code, 1);
    // The shipped rig config is valid.
    let shipped = concat!(env!("CARGO_MANIFEST_DIR"), "/../deploy/lopd.toml");
    let (_, out, _) = doctor(&["--device", "mock", "--config", shipped], None);
    let line = out.lines().find(|l| l.contains(" config ")).unwrap();
    assert!(line.starts_with("OK"), "{line}");
    let (code, _, err) = doctor(&["--device", "phantom"], None);
    assert_eq!(code, 2, "{err}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Two devices for a two-tool scene: each device's findings name the tool it drives, a
/// `tools` line maps them, and more devices than tools is refused before any check.
#[test]
fn two_devices_are_checked_each_for_its_tool() {
    let dir = lop_test_support::fixtures::temp_dir("doctor-two-tools");
    let scene = lop_test_support::fixtures::two_tool_abdomen(&dir);
    let scene = scene.display().to_string();
    let args = [
        "--scene", &scene, "--device", "mock", "--device", "hand", "--json",
    ];
    let (_, out, err) = doctor(&args, None);
    let v: serde_json::Value =
        serde_json::from_str(&out).unwrap_or_else(|e| panic!("{e}: {out}{err}"));
    let findings = v
        .as_array()
        .or_else(|| v["findings"].as_array())
        .expect("findings");
    let device: Vec<&str> = findings
        .iter()
        .filter(|f| f["check"] == "device")
        .filter_map(|f| f["value"].as_str())
        .collect();
    assert_eq!(device.len(), 2, "{out}");
    assert!(
        device[0].starts_with("tool \"left\": --device mock"),
        "{out}"
    );
    assert!(
        device[1].starts_with("tool \"right\": --device hand"),
        "{out}"
    );
    let tools: Vec<&str> = findings
        .iter()
        .filter(|f| f["check"] == "tools")
        .filter_map(|f| f["value"].as_str())
        .collect();
    assert_eq!(tools.len(), 1, "{out}");
    assert!(
        tools[0].contains("\"left\" ← mock") && tools[0].contains("\"right\" ← hand"),
        "{out}"
    );

    let three = [
        "--scene", &scene, "--device", "mock", "--device", "mock", "--device", "mock",
    ];
    let (code, _, err) = doctor(&three, None);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("3 --device options for the 2 tool(s)"),
        "{err}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
