//! Smoke test of `lop-bench lop --quick`: every efficiency run has every body with positive
//! timings, the poked body of every with-GC interaction run switched level, the collision trial
//! detected collisions every round (and only it) and its push moved the other cylinder, every
//! speed-up and effectiveness row is there with positive finite numbers, and every CSV/SVG file
//! it lists exists. No wall-clock bound on any figure (speed goes in `docs/benchmarks.md`, not
//! in tests).

use crate::common;

use std::path::PathBuf;
use std::time::Duration;

use serde_json::Value;

/// The eight configurations of the cylinders' trials.
const CYLINDER_CONFIGS: &[&str] = &[
    "fem-fem-nogc",
    "fem-fem-gc",
    "fem-msd-nogc",
    "fem-msd-gc",
    "msd-fem-nogc",
    "msd-fem-gc",
    "msd-msd-nogc",
    "msd-msd-gc",
];

/// Part 1's runs: (scene, trial, configuration keys, bodies).
const EFFICIENCY: [(&str, &str, &[&str], &[&str]); 4] = [
    (
        "cylinders",
        "gravity",
        CYLINDER_CONFIGS,
        &["cylinder_a", "cylinder_b"],
    ),
    (
        "cylinders",
        "interaction",
        CYLINDER_CONFIGS,
        &["cylinder_a", "cylinder_b"],
    ),
    (
        "cylinders",
        "interaction-collision",
        CYLINDER_CONFIGS,
        &["cylinder_a", "cylinder_b"],
    ),
    (
        "organs",
        "interaction",
        &["all-fem-nogc", "all-fem-gc"],
        &["liver", "spleen", "stomach", "pancreas"],
    ),
];

/// Part 2's bodies and rows.
const SPEED_BODIES: [&str; 6] = [
    "liver",
    "spleen",
    "stomach",
    "pancreas",
    "cylinder_a",
    "cylinder_b",
];
const SPEED_VARIANTS: [&str; 8] = [
    "fem-corotational",
    "msd-implicit-euler",
    "gc-box",
    "gc-fitted",
    "gc-subdivided-box-2",
    "gc-box-no-load",
    "gc-fitted-no-load",
    "gc-subdivided-box-2-no-load",
];

/// Part 3's cases and approximations.
const CASES: [&str; 2] = ["cylinder", "liver"];
const APPROXIMATIONS: [&str; 8] = [
    "gc-box-projected",
    "gc-box-mass-spring",
    "gc-box-mass-spring-tuned",
    "gc-fitted-projected",
    "gc-fitted-mass-spring",
    "gc-subdivided-box-2-projected",
    "gc-subdivided-box-2-mass-spring",
    "rest",
];

fn positive(v: &Value, what: &str) -> f64 {
    let x = v
        .as_f64()
        .unwrap_or_else(|| panic!("{what}: not a number: {v}"));
    assert!(x.is_finite() && x > 0.0, "{what}: {x}");
    x
}

#[test]
fn lop_quick_reports_every_run_and_writes_its_files() {
    let dir = std::env::temp_dir().join(format!("lopbench-lop-smoke-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("temp dir");
    let json = dir.join("lop.json");
    let stdout = common::run_bench(
        &[
            "lop".as_ref(),
            "--quick".as_ref(),
            "--out".as_ref(),
            dir.as_os_str(),
            "--json".as_ref(),
            json.as_os_str(),
        ],
        Duration::from_secs(900),
    );

    let text = std::fs::read_to_string(&json).expect("JSON written");
    let v: Value = serde_json::from_str(&text).expect("valid JSON");
    assert_eq!(v["quick"], true);

    // Part 1: every run, every body, timed; the poked body of a with-GC interaction run
    // switched from its cage; a pinned body never switches.
    let runs = v["efficiency"].as_array().expect("efficiency");
    let mut expected_runs = 0;
    for (scene, trial, configs, bodies) in EFFICIENCY {
        for config in configs {
            expected_runs += 1;
            let key = format!("{scene}-{trial}-{config}");
            let run = runs
                .iter()
                .find(|r| r["key"] == key.as_str())
                .unwrap_or_else(|| panic!("no run {key}:\n{stdout}"));
            assert_eq!(run["scene"], scene);
            assert_eq!(run["trial"], trial);
            let with_gc = run["with_gc"].as_bool().unwrap();
            assert_eq!(with_gc, config.ends_with("-gc"), "{key}");
            let rows = run["bodies"].as_array().unwrap();
            assert_eq!(rows.len(), bodies.len(), "{key}");
            for body in bodies {
                let b = rows
                    .iter()
                    .find(|b| b["body"] == *body)
                    .unwrap_or_else(|| panic!("{key}: no body {body}"));
                let what = format!("{key}/{body}");
                let steps = b["steps"].as_u64().unwrap();
                assert!(steps >= 5, "{what}: {steps} steps");
                assert_eq!(
                    b["gc_steps"].as_u64().unwrap() + b["precise_steps"].as_u64().unwrap(),
                    steps,
                    "{what}"
                );
                positive(&b["mean_us"], &format!("{what} mean"));
                positive(&b["p99_us"], &format!("{what} p99"));
                assert!(
                    !b["median_gc_us"].is_null() || !b["median_precise_us"].is_null(),
                    "{what}: no median"
                );
                for m in ["median_gc_us", "median_precise_us"] {
                    if !b[m].is_null() {
                        positive(&b[m], &format!("{what} {m}"));
                    }
                }
                assert_eq!(b["resets"], 0, "{what}: blew up");
                if !with_gc {
                    assert_eq!(b["switches"], 0, "{what}");
                    assert_eq!(b["gc_steps"], 0, "{what}");
                }
            }
            if with_gc && trial.starts_with("interaction") {
                let poked = if scene == "organs" {
                    "liver"
                } else {
                    "cylinder_a"
                };
                let b = rows.iter().find(|b| b["body"] == poked).unwrap();
                assert!(
                    b["switches"].as_u64().unwrap() >= 1,
                    "{key}: {poked} never switched: {b}"
                );
                assert!(b["precise_steps"].as_u64().unwrap() >= 1, "{key}: {b}");
            }
        }
    }
    assert_eq!(runs.len(), expected_runs);
    assert!(v.get("pending").is_none(), "no trial is left pending");
    // Collision is detected in the collision trial only, once per round; the push reaches the
    // other cylinder and moves it along +x.
    for run in runs {
        let key = run["key"].as_str().unwrap();
        let c = &run["collision"];
        if run["trial"] != "interaction-collision" {
            assert!(c.is_null(), "{key}: collision on: {c}");
            continue;
        }
        let rounds = run["bodies"][0]["steps"].as_u64().unwrap();
        assert_eq!(c["detections"].as_u64().unwrap(), rounds, "{key}: {c}");
        positive(&c["median_us"], &format!("{key} detection median"));
        positive(&c["mean_us"], &format!("{key} detection mean"));
        assert!(c["contact_detections"].as_u64().unwrap() >= 1, "{key}: {c}");
        assert!(c["max_penetrations"].as_u64().unwrap() >= 1, "{key}: {c}");
        assert_eq!(c["pushed"], "cylinder_b", "{key}");
        let b = run["bodies"]
            .as_array()
            .unwrap()
            .iter()
            .find(|b| b["body"] == "cylinder_b")
            .unwrap();
        let control = c["control_pushed_max_dx_mm"].as_f64().unwrap();
        assert!(
            b["max_dx_mm"].as_f64().unwrap() >= control + 0.1 && c["propagated"] == true,
            "{key}: the push did not move cylinder_b: {b}\n{c}"
        );
        positive(
            &b["max_contact_force_x_mn"],
            &format!("{key} force on cylinder_b"),
        );
        // Without collision the pusher goes into the other cylinder: the script pushes it there.
        positive(
            &c["control_max_interpenetration_mm"],
            &format!("{key} control interpenetration"),
        );
        let csv = dir.join(c["csv"].as_str().unwrap());
        let body = std::fs::read_to_string(&csv).unwrap_or_else(|_| panic!("{csv:?}"));
        assert!(
            body.starts_with("round,time_s,detect_us,penetrations,max_depth_mm,tree_builds\n"),
            "{csv:?}"
        );
        assert_eq!(body.lines().count() as u64, rounds + 1, "{csv:?}");
    }

    // Part 2: every variant on every body, with a positive speed-up figure.
    let speed = v["speedup"].as_array().expect("speedup");
    for body in SPEED_BODIES {
        for variant in SPEED_VARIANTS {
            let r = speed
                .iter()
                .find(|r| r["body"] == body && r["variant"] == variant)
                .unwrap_or_else(|| panic!("no speed-up row {variant} on {body}"));
            let what = format!("{body}/{variant}");
            let median = positive(&r["median_us"], &what);
            assert!(r["p99_us"].as_f64().unwrap() >= median, "{what}: {r}");
            positive(&r["speedup_vs_fem"], &what);
            assert!(r["steps"].as_u64().unwrap() >= 10, "{what}: {r}");
            assert_eq!(r["blow_ups"], 0, "{what}: {r}");
            if variant.starts_with("gc-") {
                positive(&r["cage_vertices"], &what);
            }
        }
    }
    assert_eq!(speed.len(), SPEED_BODIES.len() * SPEED_VARIANTS.len());

    // Part 3: both references and every approximation on both bodies.
    let cases = v["effectiveness"].as_array().expect("effectiveness");
    assert_eq!(cases.len(), CASES.len());
    for case in CASES {
        let c = cases
            .iter()
            .find(|c| c["case"] == case)
            .unwrap_or_else(|| panic!("no case {case}"));
        positive(&c["smallest_extent_m"], case);
        assert!(c["loaded_nodes"].as_u64().unwrap() > 0, "{case}");
        for reference in ["fem", "msd"] {
            let r = c["references"]
                .as_array()
                .unwrap()
                .iter()
                .find(|r| r["reference"] == reference)
                .unwrap_or_else(|| panic!("{case}: no reference {reference}"));
            positive(&r["max_displacement_mm"], &format!("{case}/{reference}"));
            assert_eq!(r["blow_ups"], 0, "{case}/{reference}");
            let csv = dir.join(r["csv"].as_str().unwrap());
            let body = std::fs::read_to_string(&csv).unwrap_or_else(|_| panic!("{csv:?}"));
            let mut lines = body.lines();
            let header = lines.next().unwrap();
            assert!(
                header.starts_with("iteration,time_s,")
                    && header.contains("gc_box_mass_spring_max_pct"),
                "{header}"
            );
            assert!(lines.count() > 10, "{csv:?} too short");
            for a in APPROXIMATIONS {
                let row = c["variants"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .find(|x| x["reference"] == reference && x["variant"] == a)
                    .unwrap_or_else(|| panic!("{case}: no {a} vs {reference}"));
                let what = format!("{case}/{reference}/{a}");
                let max = positive(&row["max_error_pct"], &what);
                let mean = positive(&row["mean_error_pct"], &what);
                assert!(mean <= max, "{what}: {row}");
                assert_eq!(row["blow_ups"], 0, "{what}: {row}");
                // The tuned cage reports what its search found, and the search never ends
                // worse than where it started (the table values).
                let tuned = &row["tuned"];
                if a.ends_with("-tuned") {
                    for key in ["stiffness", "density", "damping", "calibration_start_pct"] {
                        positive(&tuned[key], &format!("{what}/{key}"));
                    }
                    let start = tuned["calibration_start_pct"].as_f64().unwrap();
                    let found = tuned["calibration_pct"].as_f64().unwrap();
                    assert!(found <= start, "{what}: {tuned}");
                } else {
                    assert!(tuned.is_null(), "{what}: {tuned}");
                }
            }
        }
    }

    // The targets table is filled.
    let targets = v["targets"].as_array().expect("targets");
    assert!(targets.len() >= 3, "{targets:?}");
    for t in targets {
        assert!(t["value"].as_f64().unwrap().is_finite(), "{t}");
        assert!(t["met"].is_boolean(), "{t}");
    }

    // Every listed file exists; the plots have lines.
    let files = v["files"].as_array().unwrap();
    assert!(files.len() >= 26 + 8 + 4 + 4 + 2, "{files:?}");
    for f in files {
        let path = PathBuf::from(f.as_str().unwrap());
        assert!(path.is_file(), "listed file {f} missing");
        if path.extension().is_some_and(|e| e == "svg") {
            let body = std::fs::read_to_string(&path).unwrap();
            assert!(
                body.starts_with("<svg") && body.contains("<polyline"),
                "{path:?}"
            );
        }
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        if path.extension().is_some_and(|e| e == "csv")
            && name.starts_with("part1-")
            && !name.ends_with("-collision.csv")
        {
            let body = std::fs::read_to_string(&path).unwrap();
            assert!(
                body.starts_with("iteration,body,time_s,model,step_us\n"),
                "{path:?}"
            );
            assert!(body.lines().count() > 10, "{path:?} too short");
        }
    }
    for svg in [
        "part1-cylinders-gravity.svg",
        "part1-cylinders-interaction.svg",
        "part1-cylinders-interaction-collision.svg",
        "part1-organs-interaction.svg",
        "part3-cylinder.svg",
        "part3-liver.svg",
    ] {
        assert!(dir.join(svg).is_file(), "{svg} missing");
    }
    let _ = std::fs::remove_dir_all(&dir);
}
