//! Smoke test of `lop-bench models --quick`: every model × mesh row is there with a positive
//! median, the scaling series and the chapter-3 study ran, and every CSV/SVG file it lists
//! exists. No wall-clock bound on any figure (speed goes in `docs/benchmarks.md`, not in tests).

use crate::common;

use std::path::PathBuf;
use std::time::Duration;

const MESHES: [&str; 3] = ["beam", "cylinder", "liver"];
const MODELS: [&str; 7] = [
    "msd-explicit-euler",
    "msd-symplectic-euler",
    "msd-verlet",
    "msd-rk4",
    "msd-implicit-euler",
    "fem-linear",
    "fem-corotational",
];

#[test]
fn models_quick_reports_every_row_and_writes_the_study() {
    let dir = std::env::temp_dir().join(format!("lopbench-models-smoke-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("temp dir");
    let json = dir.join("m.json");
    let stdout = common::run_bench(
        &[
            "models".as_ref(),
            "--quick".as_ref(),
            "--out".as_ref(),
            dir.as_os_str(),
            "--json".as_ref(),
            json.as_os_str(),
        ],
        Duration::from_secs(600),
    );

    let text = std::fs::read_to_string(&json).expect("JSON written");
    let v: serde_json::Value = serde_json::from_str(&text).expect("valid JSON");
    assert_eq!(v["quick"], true);

    // Part 1: every model on every mesh, timed.
    let rows = v["step_times"].as_array().expect("step_times");
    for mesh in MESHES {
        for model in MODELS {
            let row = rows
                .iter()
                .find(|r| r["mesh"] == mesh && r["model"] == model)
                .unwrap_or_else(|| panic!("no row {model} on {mesh}:\n{stdout}"));
            let median = row["median_us"].as_f64().unwrap();
            let p99 = row["p99_us"].as_f64().unwrap();
            assert!(median > 0.0 && p99 >= median, "{model} on {mesh}: {row}");
            assert!(row["steps"].as_u64().unwrap() >= 5, "{row}");
        }
    }
    assert_eq!(rows.len(), MESHES.len() * MODELS.len());
    // The liver rows were timed with the tool in contact.
    for r in rows.iter().filter(|r| r["mesh"] == "liver") {
        assert!(
            r["contact_force_n"].as_f64().unwrap() > 0.0,
            "no contact: {r}"
        );
    }

    // Part 2: three models on at least three sizes, with a fitted exponent each.
    let scaling = v["scaling"].as_array().expect("scaling");
    assert!(scaling.len() >= 9, "{scaling:?}");
    assert!(scaling
        .iter()
        .all(|r| r["median_us"].as_f64().unwrap() > 0.0));
    let fits = v["scaling_fits"].as_array().expect("fits");
    assert_eq!(fits.len(), 3, "{fits:?}");
    assert!(fits
        .iter()
        .all(|f| f["exponent"].as_f64().unwrap().is_finite()));

    // Part 3: the study ran every figure and wrote its files.
    let runs = v["study"]["runs"].as_array().expect("runs");
    for fig in ["fig3_7", "fig3_8", "fig3_9", "fig3_10"] {
        assert!(runs.iter().any(|r| r["figure"] == fig), "no runs of {fig}");
        let svg = dir.join(format!("{fig}.svg"));
        let body = std::fs::read_to_string(&svg).unwrap_or_else(|_| panic!("{svg:?} missing"));
        assert!(
            body.starts_with("<svg") && body.contains("<polyline"),
            "{svg:?}"
        );
        let csvs: Vec<PathBuf> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| {
                let name = p.file_name().unwrap().to_string_lossy().to_string();
                name.starts_with(&format!("{fig}-")) && name.ends_with(".csv")
            })
            .collect();
        assert!(csvs.len() >= 2, "{fig}: CSV files {csvs:?}");
        for csv in csvs {
            let body = std::fs::read_to_string(&csv).unwrap();
            let mut lines = body.lines();
            let header = lines.next().unwrap();
            assert!(
                header.starts_with("time_s,") && header.contains("rk4_first_mm"),
                "{header}"
            );
            assert!(lines.count() > 10, "{csv:?} too short");
        }
    }
    // Explicit Euler at the thesis' steps is the textbook unstable case: it must be reported.
    assert!(
        runs.iter()
            .any(|r| r["integrator"] == "explicit-euler" && !r["blow_up_at_s"].is_null()),
        "no explicit Euler blow-up reported"
    );
    for name in ["fig3_11.csv", "fig3_11.svg"] {
        assert!(dir.join(name).is_file(), "{name} missing");
    }
    for f in v["files"].as_array().unwrap() {
        assert!(
            PathBuf::from(f.as_str().unwrap()).is_file(),
            "listed file {f} missing"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}
