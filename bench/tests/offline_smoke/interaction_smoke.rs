//! Smoke test of `lop-bench interaction --quick`: every row is there with positive finite
//! figures (ticks, collision detections and heat steps all counted), the poke, grab and block
//! runs really touched tissue (the walk ran), and the CSV and SVG exist. No wall-clock bound on any
//! figure (speed goes in `docs/benchmarks.md`, not in tests).

use crate::common;

use std::time::Duration;

use serde_json::Value;

#[test]
fn interaction_quick_reports_every_row() {
    let dir = std::env::temp_dir().join(format!("lop-bench-interaction-{}", std::process::id()));
    let json = dir.join("report.json");
    let stdout = common::run_bench(
        &[
            "interaction".as_ref(),
            "--quick".as_ref(),
            "--out".as_ref(),
            dir.as_os_str(),
            "--json".as_ref(),
            json.as_os_str(),
        ],
        Duration::from_secs(600),
    );
    assert!(stdout.contains("tick organs poke"), "{stdout}");
    let report: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let rows = report["rows"].as_array().unwrap();
    let keys: Vec<&str> = rows.iter().map(|r| r["key"].as_str().unwrap()).collect();
    for key in [
        "tick_organs_poke",
        "tick_organs_grab",
        "collide_organs",
        "heat_organs_liver",
        "heat_organs_spleen",
        "heat_organs_stomach",
        "heat_organs_pancreas",
        "heat_organs_all",
        "tick_cylinders_poke",
        "tick_cylinders_grab",
        "collide_cylinders",
        "heat_cylinders_cylinder_a",
        "heat_cylinders_all",
        "tick_block_0.8mm",
        "tick_block_0.8mm_frame",
    ] {
        assert!(keys.contains(&key), "missing row {key}: {keys:?}");
    }
    for r in rows {
        let count = r["count"].as_u64().unwrap();
        assert!(count >= 50, "{r}");
        for q in ["p50_us", "p99_us", "max_us"] {
            let v = r[q].as_f64().unwrap();
            assert!(v.is_finite() && v > 0.0, "{r}");
        }
        // Quick mode: 2 s at 1 kHz; the block's ticks split into those taking a frame (every
        // tenth) and the others.
        let key = r["key"].as_str().unwrap();
        if key.starts_with("tick_") {
            let expected = match key {
                k if k.starts_with("tick_block") && k.ends_with("_frame") => 200,
                k if k.starts_with("tick_block") => 1800,
                _ => 2000,
            };
            assert_eq!(count, expected, "{r}");
            let label = r["label"].as_str().unwrap();
            let walks: u64 = label
                .split('/')
                .nth(1)
                .and_then(|s| s.split_whitespace().next())
                .and_then(|s| s.parse().ok())
                .unwrap_or(0);
            assert!(walks > 0, "the tool never came near a surface: {label}");
        }
    }
    assert!(dir.join("interaction.csv").exists());
    assert!(dir.join("interaction_p99.svg").exists());
    let _ = std::fs::remove_dir_all(&dir);
}
