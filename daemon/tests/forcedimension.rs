//! `--device dhd[:ID]` through the `lopd` binary, against the stand-in DHD library
//! (`drivers/standin-dhd`, loaded through `LOP_DHD_LIBRARY`).
//!
//! Invariants guarded:
//! - `lopd doctor --device dhd[:ID]` lists every Force Dimension device the library sees
//!   (index, type name, serial) and marks the one `--device` opens; an index the SDK does not
//!   have, no device at all and a missing library are each a FAIL naming the library path and
//!   `LOP_DHD_LIBRARY`, with a fix, never a panic;
//! - `lopd run --device dhd:1` drives device 1 and only it (device 0 is never opened), and at
//!   exit the last force device 1 received is exactly zero, also when its motors were turned
//!   off and when it was closed;
//! - a bad `dhd:ID` is bad input (exit 2) naming the value.

#[path = "lopd_cli/mod.rs"]
mod lopd_cli;
#[path = "../../drivers/standin-dhd/testing.rs"]
mod standin_dhd;

use std::path::Path;
use std::process::Command;

use lopd_cli::{lopd, run, temp_dir};
use standin_dhd::{logs_of, read_log, standin_library};

/// `lopd` with the stand-in (or `library`) as the DHD library and `count` devices: an omega.3
/// at index 0 and a sigma.7 at index 1.
fn with_standin(library: &Path, count: usize) -> Command {
    let mut c = lopd();
    c.env("LOP_DHD_LIBRARY", library)
        .env("LOP_STANDIN_DHD_COUNT", count.to_string())
        .env("LOP_STANDIN_DHD_TYPES", "33,104")
        .env_remove("LOP_STANDIN_DHD_LOG_DIR");
    c
}

fn doctor(library: &Path, count: usize, device: &str) -> (i32, serde_json::Value, String) {
    let prefix = format!("dhd-doctor-{}", std::process::id());
    let (code, out, err) = run(with_standin(library, count)
        .args(["doctor", "--json", "--prefix", &prefix, "--device", device]));
    assert!(!err.contains("panicked"), "{err}");
    let v: serde_json::Value =
        serde_json::from_str(&out).unwrap_or_else(|e| panic!("{e}\n{out}\n{err}"));
    (code, v, err)
}

fn finding<'a>(v: &'a serde_json::Value, check: &str) -> &'a serde_json::Value {
    v.as_array()
        .unwrap()
        .iter()
        .find(|f| f["check"] == check)
        .unwrap_or_else(|| panic!("no {check} in {v}"))
}

#[test]
fn doctor_lists_every_device_and_the_one_opened() {
    let lib = standin_library();
    let (_, v, _) = doctor(&lib, 2, "dhd:1");
    let library = finding(&v, "device-library");
    assert_eq!(library["status"], "OK", "{library}");
    let text = library["value"].as_str().unwrap();
    assert!(
        text.contains(&lib.display().to_string()) && text.contains("SDK 3.17.6-0"),
        "{text}"
    );
    let device = finding(&v, "device");
    assert_eq!(device["status"], "OK", "{device}");
    let text = device["value"].as_str().unwrap();
    for needle in [
        "2 Force Dimension device(s)",
        "[0] omega.3 (lop stand-in) (type 33), serial 1000;",
        "[1] sigma.7 (lop stand-in) (type 104), serial 1001 <- --device opens this one",
        "dhd:1 answers: sigma.7, peak 12 N",
        "4 N/mm",
    ] {
        assert!(text.contains(needle), "{needle:?} not in {text}");
    }

    // `dhd` is index 0.
    let (_, v, _) = doctor(&lib, 2, "dhd");
    let text = finding(&v, "device")["value"].as_str().unwrap().to_string();
    assert!(
        text.contains("serial 1000 <- --device opens this one") && text.contains("dhd answers"),
        "{text}"
    );
}

#[test]
fn doctor_fails_clearly_without_the_device_or_the_library() {
    let lib = standin_library();
    let (code, v, _) = doctor(&lib, 2, "dhd:5");
    let device = finding(&v, "device");
    assert_eq!(device["status"], "FAIL", "{device}");
    let text = device["value"].as_str().unwrap();
    assert!(
        text.contains("opens index 5") && text.contains("sees 2") && text.contains("[1] sigma.7"),
        "{text}"
    );
    assert!(device["fix"].as_str().unwrap().contains("dhd:0 to dhd:1"));
    assert_eq!(code, 1);

    let (code, v, _) = doctor(&lib, 0, "dhd");
    let device = finding(&v, "device");
    assert_eq!(device["status"], "FAIL", "{device}");
    let text = device["value"].as_str().unwrap();
    assert!(
        text.contains("sees no Force Dimension device")
            && text.contains(&lib.display().to_string())
            && text.contains("LOP_DHD_LIBRARY"),
        "{text}"
    );
    assert!(!device["fix"].as_str().unwrap().is_empty());
    assert_eq!(code, 1);

    let dir = temp_dir("dhd", "doctor");
    let missing = dir.join("no-such/libdhd.so");
    let (code, v, _) = doctor(&missing, 1, "dhd");
    let library = finding(&v, "device-library");
    assert_eq!(library["status"], "FAIL", "{library}");
    let text = library["value"].as_str().unwrap();
    assert!(
        text.contains(&missing.display().to_string()) && text.contains("LOP_DHD_LIBRARY"),
        "{text}"
    );
    assert!(
        library["fix"].as_str().unwrap().contains("dhd_library"),
        "{library}"
    );
    assert_eq!(finding(&v, "device")["status"], "FAIL");
    assert_eq!(code, 1);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn run_drives_the_chosen_device_and_leaves_zero_force() {
    let lib = standin_library();
    let dir = temp_dir("dhd", "run");
    let prefix = format!("dhd-run-{}", std::process::id());
    let (code, _, err) = run(with_standin(&lib, 2)
        .env("LOP_STANDIN_DHD_LOG_DIR", &dir)
        .env("LOP_LOG", "info")
        .args([
            "run",
            "--scene",
            "beam",
            "--device",
            "dhd:1",
            "--duration",
            "2",
        ])
        .args(["--quiet", "--prefix", &prefix]));
    assert_eq!(code, 0, "{err}");
    assert!(
        logs_of(&dir, 0).is_empty(),
        "device 0 was opened: {:?}",
        logs_of(&dir, 0)
    );
    let sessions = logs_of(&dir, 1);
    assert_eq!(sessions.len(), 1, "{sessions:?}\n{err}");
    let log = read_log(&sessions[0]);
    let forces: Vec<[f64; 3]> = log
        .iter()
        .filter(|r| r.event == "force")
        .map(|r| r.force)
        .collect();
    assert!(forces.len() > 100, "{} forces written\n{err}", forces.len());
    // The stand-in's velocity estimator needs one read after the open: the exit log counts it.
    assert!(
        err.contains("1 reads without a velocity estimate yet"),
        "{err}"
    );
    assert_eq!(forces.last(), Some(&[0.0; 3]), "last force written");
    let events: Vec<&str> = log.iter().map(|r| r.event.as_str()).collect();
    assert_eq!(events.first(), Some(&"open"));
    assert_eq!(events.last(), Some(&"close"));
    for step in ["enable_off", "close"] {
        let row = log.iter().find(|r| r.event == step).expect(step);
        assert_eq!(row.force, [0.0; 3], "force at {step}");
    }
    let on = events.iter().position(|e| *e == "enable_on").unwrap();
    let off = events.iter().rposition(|e| *e == "enable_off").unwrap();
    assert!(on < off, "{events:?}");
    assert!(
        !events[off..].contains(&"force"),
        "a force after the motors went off"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_bad_device_id_is_bad_input() {
    let lib = standin_library();
    for bad in ["dhd:x", "dhd:200", "dhd:"] {
        let (code, _, err) =
            run(with_standin(&lib, 1).args(["run", "--duration", "1", "--device", bad]));
        assert_eq!(code, 2, "{bad}: {err}");
        assert!(err.contains(&format!("`{bad}`")), "{bad}: {err}");
    }
}
