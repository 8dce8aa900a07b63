//! Record and replay, through the command line.
//!
//! - `lopd haptic --record` stores exactly the device stream the loop read: every recorded
//!   sample of the mock poke equals the mock script's sample at `tick / rate`, bit for bit.
//! - `lopd simulate --device replay:REC` replays one recording twice into byte-identical final
//!   positions, and the replayed poke moves the tissue (more than gravity alone does).
//! - A live replay re-recorded is the same stream again, bit for bit; an existing recording is
//!   never overwritten.
//! - A damaged recording is bad input (exit 2) naming the file and the byte.

use crate::lopd_cli;

use std::path::{Path, PathBuf};
use std::process::Command;

use lopd_cli::lopd;

use lop_drivers::mock::MockScript;
use lop_drivers::replay::Recording;

fn ok(c: &mut Command) -> String {
    let o = c.output().expect("run lopd");
    assert!(
        o.status.success(),
        "{}\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn max_displacement(summary: &Path, body: &str) -> f64 {
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(summary).unwrap()).unwrap();
    v["bodies"]
        .as_array()
        .unwrap()
        .iter()
        .find(|b| b["name"] == body)
        .unwrap()["max_displacement_m"]
        .as_f64()
        .unwrap()
}

#[test]
fn record_then_replay_offline_twice_bit_identical() {
    let dir = std::env::temp_dir().join(format!("lopd-record-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let rec = dir.join("session.lrec");
    let prefix = format!("rec-{}", std::process::id());

    // Record 3.3 s of the mock poke (the push lasts from 1.5 s to 3.2 s).
    ok(lopd()
        .args([
            "haptic",
            "--scene",
            "cylinders",
            "--device",
            "mock:cylinders-poke",
        ])
        .args(["--duration", "3.3", "--prefix", &prefix, "--record"])
        .arg(&rec));
    let recording = Recording::load(&rec).unwrap();
    let h = recording.header();
    assert_eq!(h.rate_hz, 1000.0);
    assert_eq!(h.get("scene"), Some("cylinders"));
    assert_eq!(h.get("device"), Some("mock:cylinders-poke"));
    assert_eq!(h.limits, lop_drivers::mock::MockDevice::omni_limits());
    let records = recording.records();
    assert_eq!(records.len(), 3300, "one record per tick");
    let script = MockScript::load(&repo().join("config/scripts/cylinders-poke.toml")).unwrap();
    for (k, r) in records.iter().enumerate() {
        assert_eq!(r.tick, k as u64);
        assert_eq!(r.error, None);
        assert_eq!(r.sample, script.sample(k as f64 / 1000.0), "tick {k}");
    }
    assert!(records.windows(2).all(|w| w[1].time_ns >= w[0].time_ns));
    let deepest = records
        .iter()
        .map(|r| r.sample.position_mm[0])
        .fold(f64::NEG_INFINITY, f64::max);
    assert_eq!(deepest, -55.0, "the recording holds the push to x = -55 mm");

    // Offline replay, twice: byte-identical final positions; the poke moved cylinder_a.
    let simulate = |out: &str| {
        let out = dir.join(out);
        let table = ok(lopd()
            .args([
                "simulate",
                "--scene",
                "cylinders",
                "--steps",
                "150",
                "--out",
            ])
            .arg(&out)
            .arg("--device")
            .arg(format!("replay:{}", rec.display())));
        (out, table)
    };
    let (a, table) = simulate("a");
    let (b, _) = simulate("b");
    let fa = std::fs::read(a.join("final_positions.csv")).unwrap();
    let fb = std::fs::read(b.join("final_positions.csv")).unwrap();
    assert!(fa.len() > 10_000);
    assert_eq!(fa, fb, "two replays of one recording differ");
    assert!(
        table
            .lines()
            .any(|l| l.starts_with("cylinder_a") && l.contains(" FEM ")),
        "{table}"
    );
    let still = dir.join("still");
    ok(lopd()
        .args([
            "simulate",
            "--scene",
            "cylinders",
            "--steps",
            "150",
            "--out",
        ])
        .arg(&still));
    let poked = max_displacement(&a.join("summary.json"), "cylinder_a");
    let gravity_only = max_displacement(&still.join("summary.json"), "cylinder_a");
    assert!(
        poked > 0.005 && poked > 2.0 * gravity_only,
        "replayed poke moved cylinder_a {poked} m (gravity alone {gravity_only} m)"
    );

    // Live replay, re-recorded to the same name: a new file, with the same stream.
    ok(lopd()
        .args([
            "haptic",
            "--scene",
            "cylinders",
            "--duration",
            "1.5",
            "--prefix",
            &prefix,
        ])
        .arg("--device")
        .arg(format!("replay:{}", rec.display()))
        .arg("--record")
        .arg(&rec));
    let again = Recording::load(&dir.join("session-1.lrec")).expect("session-1.lrec");
    assert_eq!(
        Recording::load(&rec).unwrap().records().len(),
        3300,
        "not overwritten"
    );
    assert_eq!(again.records().len(), 1500);
    for (x, y) in again.records().iter().zip(records) {
        assert_eq!((x.tick, x.sample, x.error), (y.tick, y.sample, y.error));
    }

    // Damage is bad input, located.
    let bytes = std::fs::read(&rec).unwrap();
    let cut = dir.join("cut.lrec");
    std::fs::write(&cut, &bytes[..bytes.len() - 5]).unwrap();
    for args in [
        vec!["simulate", "--scene", "cylinders", "--out", "/tmp/unused"],
        vec!["haptic", "--scene", "cylinders", "--duration", "1"],
    ] {
        let o = lopd()
            .args(&args)
            .arg("--device")
            .arg(format!("replay:{}", cut.display()))
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(
            err.contains("cut.lrec") && err.contains("truncated at byte"),
            "{err}"
        );
        assert!(err.contains("record 3299 has 67 of 72 bytes"), "{err}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
