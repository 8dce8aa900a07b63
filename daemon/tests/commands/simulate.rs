//! `lopd simulate` runs a scene offline and writes its outputs; with a mock script on simulated
//! time the run is deterministic: two runs give byte-identical final positions.

use std::path::Path;
use std::process::Command;

fn simulate(out: &Path, extra: &[&str]) -> String {
    let o = Command::new(env!("CARGO_BIN_EXE_lopd"))
        .args(["simulate", "--scene", "cylinders", "--out"])
        .arg(out)
        .args(extra)
        .env("RUST_BACKTRACE", "0")
        .env("LOP_LOG", "warn")
        .output()
        .expect("run lopd simulate");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8_lossy(&o.stdout).into_owned()
}

#[test]
fn offline_run_writes_outputs_and_is_deterministic() {
    let base = std::env::temp_dir().join(format!("lopd-simulate-{}", std::process::id()));
    let (a, b) = (base.join("a"), base.join("b"));
    let args = ["--steps", "90", "--script", "cylinders-poke"];
    let table = simulate(&a, &args);
    simulate(&b, &args);
    // Levels of precision: the poked cylinder_a (important) switched from its cage to FEM;
    // cylinder_b, never touched, still runs as its cage.
    let row = |name: &str| {
        table
            .lines()
            .find(|l| l.starts_with(name))
            .unwrap_or_else(|| panic!("no {name} row: {table}"))
            .to_string()
    };
    assert!(row("cylinder_a").contains(" FEM "), "{table}");
    assert!(row("cylinder_b").contains(" GC "), "{table}");
    let fa = std::fs::read(a.join("final_positions.csv")).unwrap();
    let fb = std::fs::read(b.join("final_positions.csv")).unwrap();
    assert_eq!(fa, fb, "two identical runs differ");
    let steps = std::fs::read_to_string(a.join("steps.csv")).unwrap();
    assert_eq!(steps.lines().count(), 1 + 2 * 90);
    // The FEM steps say what they cost: CG iterations (the corotational cylinder under
    // gravity needs some) and the factorisations so far (at least the first one).
    let header: Vec<&str> = steps.lines().next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (model, cg, factors) = (col("model"), col("cg_iterations"), col("factorizations"));
    let fem: Vec<Vec<&str>> = steps
        .lines()
        .skip(1)
        .map(|l| l.split(',').collect::<Vec<_>>())
        .filter(|r| r[model] == "Fem")
        .collect();
    assert!(!fem.is_empty(), "{steps}");
    assert!(fem.iter().any(|r| r[cg] != "0"), "{steps}");
    assert!(fem.iter().all(|r| r[factors] != "0"), "{steps}");
    for f in [
        "final_cylinder_a.vtk",
        "final_cylinder_b.vtk",
        "summary.json",
    ] {
        assert!(a.join(f).exists(), "{f}");
    }
    let summary = std::fs::read_to_string(a.join("summary.json")).unwrap();
    assert!(summary.contains("\"steps\": 90"), "{summary}");
    assert!(summary.contains("\"switches\": 1"), "{summary}");
    // The FEM body's system and factor sizes (null for a body without an FEM model).
    let v: serde_json::Value = serde_json::from_str(&summary).unwrap();
    let a_body = &v["bodies"][0];
    assert_eq!(a_body["name"], "cylinder_a", "{summary}");
    assert!(
        a_body["factor_entries"].as_u64().unwrap() > a_body["matrix_entries"].as_u64().unwrap(),
        "{summary}"
    );
    // Gravity sags the free cylinders' tops: some node moved.
    assert!(
        !summary.contains("\"max_displacement_m\": 0.0,"),
        "{summary}"
    );
    // Before the tip comes within the switch margin (2 mm, about 1.33 s into the script) both
    // bodies still run as their cages: the script's rest point is clear of cylinder_a.
    let early = simulate(
        &base.join("early"),
        &["--steps", "60", "--script", "cylinders-poke"],
    );
    assert!(
        early
            .lines()
            .any(|l| l.starts_with("cylinder_a") && l.contains(" GC ")),
        "{early}"
    );
    let summary = std::fs::read_to_string(base.join("early/summary.json")).unwrap();
    assert!(summary.contains("\"switches\": 0"), "{summary}");
    std::fs::remove_dir_all(&base).unwrap();
}

#[test]
fn static_solve_of_fem_bodies() {
    let out = std::env::temp_dir().join(format!("lopd-simulate-static-{}", std::process::id()));
    let table = simulate(&out, &["--static"]);
    let summary = std::fs::read_to_string(out.join("summary.json")).unwrap();
    assert!(summary.contains("skipped: not an FEM body"), "{summary}");
    assert!(table.contains("cylinder_a"), "{table}");
    std::fs::remove_dir_all(&out).unwrap();
}

/// `--device hand[:SCRIPT]`: the simulated hand closes the loop offline for one pass of the
/// script; every tick is written, the press goes through the local model, the coupling stays
/// passive at the device port, and two runs are byte-identical. A missing script is bad input.
#[test]
fn the_simulated_hand_closes_the_loop_offline() {
    let base = std::env::temp_dir().join(format!("lopd-simulate-hand-{}", std::process::id()));
    let run = |out: &Path| {
        let o = Command::new(env!("CARGO_BIN_EXE_lopd"))
            .args([
                "simulate",
                "--scene",
                "abdomen",
                "--device",
                "hand:abdomen-poke",
            ])
            .arg("--out")
            .arg(out)
            .env("LOP_LOG", "warn")
            .output()
            .expect("run lopd simulate");
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8_lossy(&o.stdout).into_owned()
    };
    let (a, b) = (base.join("a"), base.join("b"));
    let printed = run(&a);
    run(&b);
    assert!(printed.contains("simulated hand"), "{printed}");
    let csv = std::fs::read_to_string(a.join("hand.csv")).unwrap();
    assert_eq!(
        csv.lines().count(),
        1 + 4400,
        "one row per tick of the 4.4 s script"
    );
    assert_eq!(csv, std::fs::read_to_string(b.join("hand.csv")).unwrap());
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(a.join("hand_summary.json")).unwrap())
            .unwrap();
    let contact = s["contact_ticks"].as_u64().unwrap();
    assert!(contact > 1000, "{s}");
    assert!(
        s["local_model_ticks"].as_u64().unwrap() + 5 >= contact,
        "{s}"
    );
    let f = s["max_force_n"].as_f64().unwrap();
    assert!(f > 0.3 && f < 1.0, "{s}");
    assert!(s["device_port_min_j"].as_f64().unwrap() > -1e-9, "{s}");

    let o = Command::new(env!("CARGO_BIN_EXE_lopd"))
        .args(["simulate", "--device", "hand:no-such-script", "--out"])
        .arg(base.join("c"))
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("no-such-script"),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let _ = std::fs::remove_dir_all(&base);
}

/// A scene of two tools runs offline with both hands: `--device mock` once per tool plays
/// each tool's own script from the scene, the same run as naming the scripts with `--script`;
/// a third trajectory for two tools is bad input.
#[test]
fn every_tool_of_a_two_handed_scene_plays_its_script_offline() {
    let base = std::env::temp_dir().join(format!("lopd-simulate-two-{}", std::process::id()));
    let run = |out: &Path, extra: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_lopd"))
            .args([
                "simulate",
                "--scene",
                "abdomen-two-hands",
                "--steps",
                "1800",
            ])
            .arg("--out")
            .arg(out)
            .args(extra)
            .env("RUST_BACKTRACE", "0")
            .env("LOP_LOG", "warn")
            .output()
            .expect("run lopd simulate")
    };
    let (a, b) = (base.join("a"), base.join("b"));
    let o = run(&a, &["--device", "mock", "--device", "mock"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = run(
        &b,
        &[
            "--script",
            "abdomen-two-hands-grasper",
            "--script",
            "abdomen-two-hands-hook",
        ],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(
        std::fs::read(a.join("final_positions.csv")).unwrap(),
        std::fs::read(b.join("final_positions.csv")).unwrap(),
        "the scene's scripts and the same scripts named differ"
    );
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(a.join("summary.json")).unwrap()).unwrap();
    let scripts = s["scripts"].as_array().unwrap();
    assert_eq!(scripts.len(), 2, "{s}");
    assert!(scripts[0]
        .as_str()
        .unwrap()
        .ends_with("abdomen-two-hands-grasper.toml"));
    assert!(scripts[1]
        .as_str()
        .unwrap()
        .ends_with("abdomen-two-hands-hook.toml"));
    // By 1.8 s the grasper has closed its jaws on the liver's edge (1.5 s) and started to
    // retract it: the liver runs FEM and carries the grasper's pull.
    let steps = std::fs::read_to_string(a.join("steps.csv")).unwrap();
    let last = steps
        .lines()
        .rfind(|l| l.starts_with("liver,"))
        .unwrap()
        .split(',')
        .map(str::to_string)
        .collect::<Vec<_>>();
    assert_eq!(last[3], "Fem", "{last:?}");
    let force: f64 = last[7].parse().unwrap();
    assert!(
        force > 0.05,
        "the liver's contact force at 1.8 s: {force} N"
    );

    let o = run(
        &base.join("c"),
        &["--device", "mock", "--device", "mock", "--device", "mock"],
    );
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("3 tool trajectories") && err.contains("2 tool(s)"),
        "{err}"
    );
    let _ = std::fs::remove_dir_all(&base);
}

/// The shipped cut script cuts the shipped liver offline: holding the cut button on it, the
/// cautery vaporises the tissue under its tip and the cut lands (`cuts.csv`), and the final
/// mesh has lost those tetrahedra.
#[test]
fn the_shipped_cut_script_cuts_the_liver() {
    let out = std::env::temp_dir().join(format!("lopd-simulate-cut-{}", std::process::id()));
    let o = Command::new(env!("CARGO_BIN_EXE_lopd"))
        .args(["simulate", "--scene", "abdomen", "--script", "abdomen-cut"])
        .args(["--steps", "6500", "--out"])
        .arg(&out)
        .env("LOP_LOG", "warn")
        .output()
        .expect("run lopd simulate");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let cuts = std::fs::read_to_string(out.join("cuts.csv")).unwrap();
    let landed: Vec<Vec<&str>> = cuts
        .lines()
        .map(|l| l.split(',').collect::<Vec<_>>())
        .filter(|f| f.get(2) == Some(&"landed"))
        .collect();
    assert!(!landed.is_empty(), "no cut landed:\n{cuts}");
    // sim_time_s,body,event,tets,epoch,removed_tets,piece_tets,pieces_removed,tets_left,…
    let first = &landed[0];
    assert_eq!((first[1], first[4]), ("liver", "1"), "{cuts}");
    let left: usize = landed.last().unwrap()[8].parse().unwrap();
    assert!(left < 1706, "{cuts}");
    let vtk = std::fs::read_to_string(out.join("final_liver.vtk")).unwrap();
    let cells = vtk
        .lines()
        .find_map(|l| l.strip_prefix("CELLS "))
        .and_then(|l| l.split_whitespace().next())
        .and_then(|n| n.parse::<usize>().ok());
    assert_eq!(cells, Some(left), "the final mesh is the cut one");
    let _ = std::fs::remove_dir_all(&out);
}
