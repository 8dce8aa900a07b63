//! `lopd`'s command line on good and bad input: shipped meshes give sane figures; malformed
//! meshes, bad scenes and unsupported devices give exit code 2 and a message naming the file,
//! key or value — never a panic; devices that cannot run together are refused naming them.

use crate::lopd_cli;

use std::path::{Path, PathBuf};

use lopd_cli::{lopd, run};

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn field(text: &str, key: &str) -> f64 {
    let line = text
        .lines()
        .find(|l| l.trim_start().starts_with(key))
        .unwrap_or_else(|| panic!("no {key:?} in\n{text}"));
    line.split(':')
        .nth(1)
        .unwrap()
        .split_whitespace()
        .next()
        .unwrap()
        .trim_end_matches(',')
        .parse()
        .unwrap_or_else(|e| panic!("{key}: {e} in {line:?}"))
}

#[test]
fn mesh_info_on_every_shipped_mesh() {
    // (name, nodes, tets, volume m³) with the expected volume from the analytic shape where
    // there is one: the bar 0.4 × 0.1 × 0.1 exactly; the cylinder's polygonal section is a
    // little under π r² h.
    let expect = [
        ("beam", 568.0, 1770.0, Some((0.004, 1e-12))),
        (
            "cylinder",
            260.0,
            991.0,
            Some((std::f64::consts::PI * 0.03 * 0.03 * 0.12, 0.03)),
        ),
        ("liver", 555.0, 1706.0, None),
        ("spleen", 238.0, 705.0, None),
        ("stomach", 311.0, 920.0, None),
        ("pancreas", 231.0, 655.0, None),
    ];
    for (name, nodes, tets, volume) in expect {
        let path = repo().join("assets/meshes").join(name);
        let (code, out, err) = run(lopd().args(["mesh", "info"]).arg(&path));
        assert_eq!(code, 0, "{name}: {err}");
        assert_eq!(field(&out, "nodes"), nodes, "{name}\n{out}");
        assert_eq!(field(&out, "tetrahedra"), tets, "{name}\n{out}");
        let q_line = out
            .lines()
            .find(|l| l.starts_with("quality:"))
            .expect("quality line");
        let q_min: f64 = q_line
            .split_whitespace()
            .nth(2)
            .unwrap()
            .trim_end_matches(',')
            .parse()
            .unwrap();
        assert!(q_min > 0.05 && q_min <= 1.0, "{name}: quality {q_min}");
        let v = field(&out, "volume");
        if let Some((exact, rel)) = volume {
            let rel: f64 = rel;
            assert!(
                ((v - exact) / exact).abs() <= rel.max(1e-9),
                "{name}: volume {v} vs {exact}"
            );
        } else {
            assert!(v > 1e-5 && v < 1e-2, "{name}: volume {v}");
        }
    }
}

#[test]
fn malformed_mesh_is_a_located_error_not_a_panic() {
    let dir = std::env::temp_dir().join(format!("lopd-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let base = dir.join("bad");
    std::fs::write(
        base.with_extension("node"),
        "4 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n",
    )
    .unwrap();
    std::fs::write(base.with_extension("ele"), "1 4 0\n1 1 2 3 9\n").unwrap();
    let (code, _, err) = run(lopd().args(["mesh", "info"]).arg(&base));
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("bad.ele:2"), "{err}");
    assert!(err.contains('9'), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    std::fs::remove_dir_all(&dir).unwrap();
}

fn write_scene(dir: &Path, text: &str) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let p = dir.join("scene.toml");
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn bad_scene_key_and_value_are_named() {
    let dir = std::env::temp_dir().join(format!("lopd-cli-scene-{}", std::process::id()));
    let organs = std::fs::read_to_string(repo().join("config/scenes/organs.toml")).unwrap();
    let mesh_dir = repo().join("assets/meshes");
    let fixed = organs.replace("../../assets/meshes", mesh_dir.to_str().unwrap());
    // A NaN Young's modulus.
    let p = write_scene(&dir, &fixed.replacen("young = 140.0", "young = nan", 1));
    let (code, _, err) = run(lopd().args(["run", "--duration", "1", "--scene"]).arg(&p));
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("young") && (err.contains("NaN") || err.contains("nan")),
        "{err}"
    );
    // An unknown key.
    let p = write_scene(
        &dir,
        &fixed.replacen("[tool]\n", "[tool]\nstifness = 3.0\n", 1),
    );
    let (code, _, err) = run(lopd().args(["run", "--duration", "1", "--scene"]).arg(&p));
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("stifness"), "{err}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn unknown_scene_lists_the_shipped_ones() {
    let (code, _, err) = run(lopd().args(["run", "--duration", "1", "--scene", "kidney"]));
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("kidney") && err.contains("organs"), "{err}");
}

#[test]
fn unsupported_devices_are_refused_clearly() {
    for (dev, needle) in [
        ("openhaptics", "OpenHaptics"),
        ("replay:/tmp/x.rec", "replay"),
        ("phantom", "phantom"),
        ("mock:no-such-script", "no-such-script"),
    ] {
        let (code, _, err) = run(lopd().args(["run", "--duration", "1", "--device", dev]));
        assert_eq!(code, 2, "{dev}: {err}");
        assert!(err.contains(needle), "{dev}: {err}");
    }
}

/// One run has one clock: an OpenHaptics device beside a device of lop's own loop is refused
/// naming both, whichever comes first, and `--record` takes one device — before any device is
/// started (`lopd haptic`, the process `lopd run` supervises; the stand-in libHD serves the
/// names).
#[test]
fn openhaptics_beside_another_clock_is_refused() {
    let dir = std::env::temp_dir().join(format!("lopd-cli-clocks-{}", std::process::id()));
    let organs = std::fs::read_to_string(repo().join("config/scenes/organs.toml")).unwrap();
    let mesh_dir = repo().join("assets/meshes");
    let scripts_dir = repo().join("config/scripts");
    let two_tools = organs
        .replace("../../assets/meshes", mesh_dir.to_str().unwrap())
        .replace("\"../scripts", &format!("\"{}", scripts_dir.display()))
        .replacen("[tool]\n", "[[tool]]\nname = \"left\"\n", 1)
        + "\n[[tool]]\nname = \"right\"\nradius = 0.003\nstiffness = 300.0\n";
    let scene = write_scene(&dir, &two_tools);
    let haptic_or_run = |command: &str, devices: [&str; 2], record: bool| {
        let mut c = lopd();
        c.args([command, "--duration", "1", "--prefix"])
            .arg(format!("cli-clocks-{}", std::process::id()))
            .arg("--scene")
            .arg(&scene)
            .env("LOP_HD_LIBRARY", crate::standin::standin_library())
            .env("LOP_STANDIN_DEVICE_NAMES", "Left,Right");
        for d in devices {
            c.args(["--device", d]);
        }
        if record {
            c.arg("--record").arg(dir.join("two.lrec"));
        }
        run(&mut c)
    };
    let haptic = |devices: [&str; 2], record: bool| haptic_or_run("haptic", devices, record);
    for devices in [["openhaptics:Left", "mock"], ["mock", "openhaptics:Left"]] {
        let (code, _, err) = haptic(devices, false);
        assert_ne!(code, 0, "{devices:?}: {err}");
        assert!(
            err.contains("--device openhaptics:Left beside --device mock")
                && err.contains("one clock"),
            "{devices:?}: {err}"
        );
    }
    // `lopd run` refuses it before starting anything (exit 2, bad input), rather than leave
    // the supervisor restarting a haptic process that fails the same way.
    let (code, _, err) = haptic_or_run("run", ["openhaptics:Left", "mock"], false);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("one clock"), "{err}");
    let (code, _, err) = haptic(["openhaptics:Left", "openhaptics:Right"], true);
    assert_ne!(code, 0, "{err}");
    assert!(err.contains("--record takes one device"), "{err}");
    assert!(!dir.join("two.lrec").exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `lopd remote attach` and `lopd run --remote`: a missing rig endpoint, a malformed endpoint
/// and a missing tunnel program are each named (exit 2 for bad input, 1 for the tunnel).
#[test]
fn remote_bad_input_is_named() {
    let (code, _, err) = run(lopd().args(["remote", "attach"]));
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("--connect tcp/RIG:7447"), "{err}");
    let (code, _, err) = run(lopd().args(["remote", "attach", "--connect", "tcp/rig"]));
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("--connect \"tcp/rig\"") && err.contains("has no port"),
        "{err}"
    );
    let (code, _, err) = run(lopd().args(["remote", "attach", "--mode", "router"]));
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("--mode \"router\""), "{err}");
    let (code, _, err) = run(lopd().args([
        "remote",
        "attach",
        "--connect",
        "tcp/127.0.0.1:7447",
        "--tunnel",
        "/nonexistent/iox2-link-tunnel-zenoh",
    ]));
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("\"/nonexistent/iox2-link-tunnel-zenoh\" was not found")
            && err.contains("cargo build --release -p lop-tunnel"),
        "{err}"
    );
    let (code, _, err) = run(lopd().args(["run", "--remote", "--remote-listen", "udp/:1"]));
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("has no host"), "{err}");
}
