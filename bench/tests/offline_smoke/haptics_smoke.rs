//! Smoke test of `lop-bench haptics --quick`: both quick meshes are generated (gmsh), the
//! reference and the presses give positive finite forces, the reference sits within a band of
//! Hertz, the targets are all evaluated, and the CSV and SVG exist. It also asserts what the
//! contact patch promises, on the quick meshes: lop within 10 % of the static contact solution
//! on the same mesh (block and liver), and a felt force that converges with the mesh as that
//! solution does; and that the simulated hand's press on the default scene settles and
//! generates no energy at the device's stiffness limit; and that two simulated hands pinching a
//! free cube hold equal and opposite forces without generating energy at a firm hand's port.
//! No wall-clock bound.

use crate::common;

use std::time::Duration;

use serde_json::Value;

#[test]
fn haptics_quick_reports_every_mesh_and_target() {
    let dir = std::env::temp_dir().join(format!("lop-bench-haptics-{}", std::process::id()));
    let json = dir.join("report.json");
    let stdout = common::run_bench(
        &[
            "haptics".as_ref(),
            "--quick".as_ref(),
            "--out".as_ref(),
            dir.as_os_str(),
            "--json".as_ref(),
            json.as_os_str(),
        ],
        Duration::from_secs(900),
    );
    assert!(stdout.contains("Targets"), "{stdout}");
    let report: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let meshes = report["meshes"].as_array().unwrap();
    let keys: Vec<&str> = meshes.iter().map(|m| m["key"].as_str().unwrap()).collect();
    assert_eq!(keys, ["block_0.8mm", "block_0.4mm"]);
    for m in meshes {
        assert!(m["tets"].as_u64().unwrap() > 1000, "{m}");
        let edge = m["edge_mm"].as_f64().unwrap();
        let size = m["size_mm"].as_f64().unwrap();
        assert!(edge > 0.5 * size && edge < 2.0 * size, "{m}");
        assert!(m["reference_equilibrium"].as_f64().unwrap() < 1e-8, "{m}");
        let lop = m["lop_mn"].as_f64().unwrap();
        assert!(lop.is_finite() && lop > 0.0, "{m}");
        assert!(m["reached"].as_bool().unwrap(), "{m}");
    }
    // Mesh convergence of the felt force: on each mesh lop renders what the static contact
    // solution on that mesh gives (within the 10 % target), so refining the mesh changes what
    // the hand feels only as the finite-element solution itself converges: the two meshes'
    // forces differ by as much as their references do (within 3 points), and by at most the
    // 15 % target. (A one-point press gave 3.9 and 0.5 mN here: a factor of 8.)
    let lop = |m: &Value| m["lop_mn"].as_f64().unwrap();
    let reference = |m: &Value| m["reference_mn"].as_f64().unwrap();
    for m in meshes {
        let error = lop(m) / reference(m) - 1.0;
        assert!(
            error.abs() < 0.10,
            "lop against the same-mesh reference: {m}"
        );
    }
    let (coarse, fine) = (&meshes[0], &meshes[1]);
    let felt = lop(coarse) / lop(fine);
    let solved = reference(coarse) / reference(fine);
    assert!(
        (felt - solved).abs() < 0.03,
        "felt ratio {felt}, reference ratio {solved}"
    );
    assert!(felt < 1.15 && felt > 1.0 / 1.15, "felt ratio {felt}");
    for r in report["reference"].as_array().unwrap() {
        let ratio = r["force_mn"].as_f64().unwrap() / r["hertz_layer_mn"].as_f64().unwrap();
        assert!(ratio > 0.95 && ratio < 1.6, "{r}");
    }
    // Per mesh: same-mesh, and hold variation and sideways on two paths; across: spread and
    // Hertz on the finest.
    let targets = report["targets"].as_array().unwrap();
    assert_eq!(targets.len(), 2 + 1 + 1 + 2 * 4, "{targets:?}");
    // Part 2, the abdomen scene's liver: a light press (two holds), every figure present.
    let liver = &report["liver"];
    assert_eq!(liver["fem_mode"].as_str(), Some("linear"), "{liver}");
    assert!(
        liver["target_distance_mm"].as_f64().unwrap() < 1.0,
        "{liver}"
    );
    let rows = liver["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 2, "{liver}");
    for r in rows {
        for key in ["lop_mn", "reference_mn"] {
            let f = r[key].as_f64().unwrap();
            assert!(f.is_finite() && f > 0.0, "{key}: {r}");
        }
    }
    assert!(liver["pass"].is_boolean(), "{liver}");
    // Action against the tissue's own static solution, on a mesh coarser than the tool.
    for r in rows {
        let error = r["lop_mn"].as_f64().unwrap() / r["reference_mn"].as_f64().unwrap() - 1.0;
        assert!(
            error.abs() < 0.10,
            "liver: lop against the same-mesh reference: {r}"
        );
    }
    // Part 3, stability (quick: the default hand on the nominal and the stiffest tissue, at the
    // device's maximum and four times it, the passivity controller off and on): every run
    // present with finite figures, and the three targets pass — the default scene's press
    // settles and generates no energy at the device's stiffness limit, nor at any frame period.
    let stability = &report["stability"];
    let runs = stability["runs"].as_array().unwrap();
    assert_eq!(runs.len(), 8, "{stability}");
    for r in runs {
        assert!(r["held_n"].as_f64().unwrap() > 0.05, "{r}");
        assert!(r["hand_min_j"].as_f64().unwrap().is_finite(), "{r}");
        assert!(r["contact_ticks"].as_u64().unwrap() > 100, "{r}");
    }
    // Part 3b: the liver stepping every 1 and 10 ms, controller off and on: the held force
    // the same (the tissue's static answer to the press) and nothing generated.
    let periods = stability["periods"].as_array().unwrap();
    assert_eq!(periods.len(), 4, "{stability}");
    let held_1ms = periods[0]["held_n"].as_f64().unwrap();
    for r in periods {
        let held = r["held_n"].as_f64().unwrap();
        assert!((held - held_1ms).abs() < 0.05 * held_1ms, "{r}");
        assert!(r["contact_changes"].as_u64().unwrap() >= 2, "{r}");
    }
    let targets = stability["targets"].as_array().unwrap();
    assert_eq!(targets.len(), 4, "{stability}");
    for t in targets {
        assert_eq!(t["pass"].as_bool(), Some(true), "{t}");
    }
    // Part 4, the pinch (quick: two firm hands, and a light with a firm one): both hands of
    // each pinch hold through the measured hold, the two forces balance, and the targets pass.
    let pinch = &report["pinch"];
    let runs = pinch["runs"].as_array().unwrap();
    assert_eq!(runs.len(), 2, "{pinch}");
    for r in runs {
        let hands = r["hands"].as_array().unwrap();
        assert_eq!(hands.len(), 2, "{r}");
        for h in hands {
            assert!(h["held_n"].as_f64().unwrap() > 0.1, "{h}");
            assert_eq!(h["hold_contact_ticks"].as_u64(), Some(300), "{h}");
            // Each hand feels what its tool gave the tissue.
            let (held, tissue) = (
                h["held_n"].as_f64().unwrap(),
                h["tissue_n"].as_f64().unwrap(),
            );
            assert!((held - tissue).abs() < 0.01 * tissue, "{h}");
        }
        assert!(r["balance_max"].as_f64().unwrap() < 0.01, "{r}");
    }
    let targets = pinch["targets"].as_array().unwrap();
    assert_eq!(targets.len(), 4, "{pinch}");
    for t in targets {
        assert_eq!(t["pass"].as_bool(), Some(true), "{t}");
    }
    for f in [
        "pinch.csv",
        "pinch.svg",
        "pinch.toml",
        "stability.csv",
        "stability.svg",
        "liver.csv",
        "liver_press.csv",
        "liver_force_vs_depth.svg",
        "reference.csv",
        "press_0.8mm_vertical.csv",
        "press_0.4mm_tilted.csv",
        "force_vs_depth.svg",
        "error_vs_mesh.svg",
    ] {
        assert!(dir.join(f).exists(), "{f}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}
