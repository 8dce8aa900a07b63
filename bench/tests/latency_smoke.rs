//! Smoke test of `lop-bench latency`: a 2 s run against the real pipeline (and a second one with
//! two devices, `--devices 2`) must produce every row with samples in a sane order, the haptic
//! rows once per device count, and a tick count near the scene's 1 kHz. No wall-clock bound on
//! anything: the rate is counted over the window by the haptic loop's own telemetry, and the
//! tolerance is wide (±50 %) for small, noisy CI machines.

mod common;

use std::path::PathBuf;
use std::time::Duration;

/// The `lopd` of the same build: cargo puts every workspace binary into the same target dir.
fn lopd_beside_bench() -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_lop-bench")).with_file_name("lopd")
}

#[test]
fn latency_two_seconds_reports_every_row() {
    let lopd = lopd_beside_bench();
    // Not a skip: a test that passes without running hides the pipeline's latency from CI.
    // `cargo test --workspace` builds lopd; `cargo test -p lop-bench` alone does not.
    assert!(
        lopd.is_file(),
        "{} does not exist, so the latency smoke test cannot run: build it first \
         (`cargo build -p lop-daemon`), or run `cargo test --workspace`",
        lopd.display()
    );
    let json = std::env::temp_dir().join(format!("lopbench-smoke-{}.json", std::process::id()));
    let _ = std::fs::remove_file(&json);
    // The bench stops its own lopd (and lopd's children follow their parent), so killing a
    // hung bench leaves nothing behind.
    let stdout = common::run_bench(
        &[
            "latency".as_ref(),
            "--seconds".as_ref(),
            "2".as_ref(),
            "--no-cyclictest".as_ref(),
            "--devices".as_ref(),
            "2".as_ref(),
            "--json".as_ref(),
            json.as_os_str(),
            "--lopd".as_ref(),
            lopd.as_os_str(),
        ],
        Duration::from_secs(90),
    );
    assert!(stdout.contains("haptic period jitter"), "{stdout}");

    let text = std::fs::read_to_string(&json).expect("JSON report written");
    let _ = std::fs::remove_file(&json);
    let v: serde_json::Value = serde_json::from_str(&text).expect("valid JSON");

    let rows = v["rows"].as_array().expect("rows");
    let keys: Vec<&str> = rows.iter().filter_map(|r| r["key"].as_str()).collect();
    for want in [
        "haptic_jitter",
        "haptic_compute",
        "frame_age",
        "frame_age_contact",
        "tool_to_deform",
        "deform_to_client",
        "device_to_tissue",
        "touched_frame_interval",
        "deform_round",
        "touched_step",
    ] {
        assert!(keys.contains(&want), "row {want} missing: {keys:?}\n{text}");
    }
    assert!(
        !keys.contains(&"cyclictest"),
        "--no-cyclictest still ran it"
    );
    // `--devices 2`: the haptic loop's rows once per device count.
    for key in ["haptic_jitter", "haptic_compute"] {
        let counts: Vec<u64> = rows
            .iter()
            .filter(|r| r["key"] == key)
            .filter_map(|r| r["devices"].as_u64())
            .collect();
        assert_eq!(counts, [1, 2], "{key} per device count\n{text}");
    }
    for r in rows {
        let key = r["key"].as_str().unwrap_or("?");
        let count = r["count"].as_u64().expect("count");
        assert!(count > 0, "row {key} has no samples\n{text}");
        let q = |f: &str| r[f].as_f64().unwrap_or_else(|| panic!("{key}.{f} missing"));
        let (p50, p99, p999, max) = (q("p50_us"), q("p99_us"), q("p999_us"), q("max_us"));
        assert!(
            0.0 <= p50 && p50 <= p99 && p99 <= p999 && p999 <= max,
            "row {key} out of order: {p50} {p99} {p999} {max}"
        );
    }

    // Ticks counted over the window by the loop itself: within 50 % of the scene's 1 kHz.
    let ticks = v["window_ticks"].as_f64().expect("window_ticks");
    let secs = v["window_seconds"].as_f64().expect("window_seconds");
    assert!(secs > 0.0, "{text}");
    let rate = v["target_rate_hz"].as_f64().expect("target_rate_hz");
    assert_eq!(
        rate, 1000.0,
        "the organs scene runs the haptic loop at 1 kHz"
    );
    let expected = rate * secs;
    assert!(
        (ticks - expected).abs() <= 0.5 * expected,
        "{ticks} ticks over {secs} s, expected about {expected}\n{text}"
    );
    assert!(v["frames_received"].as_u64().unwrap_or(0) > 0, "{text}");
    assert_eq!(v["cyclictest"]["status"], "disabled", "{text}");
}

/// `lop-bench organs` on one small organ of its own making: the surface built, meshed to about
/// the size asked, made into a scene whose poke the mock device plays, run live for 3 s (the
/// poke reaches the surface about 1.3 s after start, inside the window), the same poke pressed
/// offline by the simulated hand with the light grip, one JSON row with the touched body's
/// figures. The targets are the bench's to judge, not this test's.
#[test]
fn organs_meshes_a_built_surface_and_measures_it_live() {
    let lopd = lopd_beside_bench();
    assert!(
        lopd.is_file(),
        "{} does not exist: run `cargo test --workspace`",
        lopd.display()
    );
    let dir = std::env::temp_dir().join(format!("lopbench-organs-smoke-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let json = dir.join("organs.json");
    std::fs::create_dir_all(&dir).unwrap();
    let stdout = common::run_bench(
        &[
            "organs".as_ref(),
            "--no-shipped".as_ref(),
            "--surfaces".as_ref(),
            "ellipsoid".as_ref(),
            "--sizes".as_ref(),
            "800".as_ref(),
            "--threads".as_ref(),
            "1".as_ref(),
            "--seconds".as_ref(),
            "3".as_ref(),
            "--dir".as_ref(),
            dir.as_os_str(),
            "--json".as_ref(),
            json.as_os_str(),
            "--lopd".as_ref(),
            lopd.as_os_str(),
        ],
        Duration::from_secs(180),
    );
    assert!(stdout.contains("ellipsoid-800"), "{stdout}");
    assert!(dir.join("organs.svg").is_file(), "{stdout}");
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).expect("JSON written")).unwrap();
    let rows = v.as_array().expect("an array of rows");
    assert_eq!(rows.len(), 1, "{v:#}");
    let r = &rows[0];
    assert_eq!(r["name"], "ellipsoid-800", "{r:#}");
    assert_eq!(r["threads"], 1, "{r:#}");
    // The mesher's own target: within ±20 % of the count asked.
    let tets = r["tets"].as_u64().expect("tets");
    assert!(
        (640..=960).contains(&tets),
        "{tets} tetrahedra for 800 asked: {r:#}"
    );
    assert!(
        r["frames_in_contact"].as_u64().unwrap() > 0,
        "never pressed: {r:#}"
    );
    let period = r["period_ms"].as_f64().expect("a period in contact");
    assert!([1.0, 2.0, 4.0, 5.0, 10.0].contains(&period), "{r:#}");
    for key in [
        "frame_interval_p99_us",
        "frame_age_contact_p99_us",
        "step_p50_us",
    ] {
        let x = r[key].as_f64().unwrap_or(f64::NAN);
        assert!(x.is_finite() && x > 0.0, "{key}: {r:#}");
    }
    let held = r["held_force_1ms_n"]
        .as_f64()
        .expect("the offline held force");
    assert!(held > 0.0 && held < 5.0, "{r:#}");
    // No energy generated at the device port on a small organ that keeps up (0.000 µJ in
    // every 2k row of the bench). 1 µJ against the ~1 mJ the hand puts in: a late frame's
    // pop generates hundreds of µJ.
    let energy = r["device_port_energy_j"].as_f64().expect("the port energy");
    assert!((0.0..1e-6).contains(&energy), "{r:#}");
    // Live, the same hand through `lopd run` comes to rest on the same tissue: the held force
    // is a static equilibrium of the same mesh, whatever the frame age on the way (the
    // figures show 0.0–0.1 %; 10 % leaves room for a busy machine's late frames).
    let live = r["live_held_force_n"]
        .as_f64()
        .expect("the live held force");
    assert!((live / held - 1.0).abs() < 0.1, "{r:#}");
    let live_energy = r["live_device_port_energy_j"]
        .as_f64()
        .expect("the live port energy");
    assert!((0.0..1e-6).contains(&live_energy), "{r:#}");
    assert!(dir
        .join("ellipsoid-800-threads-1-light-grip-forces.csv")
        .is_file());
    let _ = std::fs::remove_dir_all(&dir);
}
