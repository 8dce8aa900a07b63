//! Daemon config, workspace map, name resolution and path handling.

use crate::common;

use std::path::{Path, PathBuf};

use common::{fixture_dir, good_with, scene_path, GOOD};
use lop_config::{
    list_scenes_in, load_daemon_config, load_scene, parse_daemon_config, parse_scene,
    resolve_scene_in, ConfigError, DaemonConfig, FemMode, ForceLaw, HeatParams, HeatSpec,
    Importance, ModelPin, Rates, ToolSpec, WorkspaceMap,
};

fn daemon_err(text: &str, needles: &[&str]) {
    let err = parse_daemon_config(text, Path::new("/etc/lop/lopd.toml")).unwrap_err();
    let msg = err.to_string();
    assert!(msg.contains("/etc/lop/lopd.toml"), "no file in: {msg}");
    for needle in needles {
        assert!(msg.contains(needle), "message lacks {needle:?}: {msg}");
    }
}

#[test]
fn empty_daemon_config_is_the_default() {
    let cfg = parse_daemon_config("", Path::new("lopd.toml")).unwrap();
    assert_eq!(cfg, DaemonConfig::default());
    assert_eq!(cfg.status_interval_ms, 500);
    assert_eq!(cfg.haptic.core, None);
    assert_eq!(cfg.haptic.rt_priority, 80);
    assert!(cfg.haptic.lock_memory);
    assert_eq!(cfg.haptic.stale_frame_ms, 100.0);
    assert_eq!(cfg.haptic.ramp_ms, 5.0);
    assert_eq!(cfg.haptic.max_force_n, 3.0);
    assert_eq!(cfg.haptic.spin_us, 50.0);
    assert_eq!(cfg.haptic.max_force_step_n, 0.05);
    assert_eq!(cfg.deform.core, None);
    assert_eq!(cfg.deform.threads, lop_config::default_deform_threads());
    assert_eq!(cfg.deform.max_period_ms, 10);
    assert_eq!(cfg.deform.rt_priority, 40);
}

/// `[deform] rt_priority`: 0 (the normal scheduler) or a `SCHED_FIFO` priority below the
/// haptic loop's frame thread (`[haptic] rt_priority` − 1); the default 40 is lowered under a
/// low haptic priority, never refused.
#[test]
fn the_deformation_priority_stays_below_the_haptic_loop() {
    let parse = |text: &str| parse_daemon_config(text, Path::new("lopd.toml"));
    assert_eq!(
        parse("[deform]\nrt_priority = 0\n")
            .unwrap()
            .deform
            .rt_priority,
        0
    );
    assert_eq!(
        parse("[deform]\nrt_priority = 78\n")
            .unwrap()
            .deform
            .rt_priority,
        78
    );
    let low = parse("[haptic]\nrt_priority = 10\n").unwrap();
    assert_eq!(low.deform.rt_priority, 8);
    assert_eq!(
        parse("[haptic]\nrt_priority = 2\n")
            .unwrap()
            .deform
            .rt_priority,
        0
    );
    for (text, bad) in [
        ("[deform]\nrt_priority = 79\n", "79"),
        ("[deform]\nrt_priority = 300\n", "300"),
        (
            "[haptic]\nrt_priority = 30\n[deform]\nrt_priority = 40\n",
            "40",
        ),
    ] {
        daemon_err(
            text,
            &["deform.rt_priority", bad, "below the haptic", "rt_priority"],
        );
    }
    assert!(parse("[deform]\nrt_priority = -1\n").is_err());
}

/// `[deform] max_period_ms`: 1 to 100 ms; outside, refused with the key and the value.
#[test]
fn the_longest_period_is_checked() {
    let parse = |ms: i64| {
        parse_daemon_config(
            &format!("[deform]\nmax_period_ms = {ms}\n"),
            Path::new("lopd.toml"),
        )
    };
    assert_eq!(parse(1).unwrap().deform.max_period_ms, 1);
    assert_eq!(parse(100).unwrap().deform.max_period_ms, 100);
    for bad in [0, 101] {
        daemon_err(
            &format!("[deform]\nmax_period_ms = {bad}\n"),
            &[
                "deform.max_period_ms",
                &bad.to_string(),
                "between 1 and 100 ms",
            ],
        );
    }
    assert!(parse(-5).is_err());
}

/// `[deform] threads`: 0 or missing is the documented default (every core but one, at least
/// one); up to the machine's cores is taken as is; more is refused with both numbers.
#[test]
fn deform_threads_are_checked_against_the_machine() {
    let cores = lop_config::machine_cores();
    let parse = |t: usize| {
        parse_daemon_config(
            &format!("[deform]\nthreads = {t}\n"),
            Path::new("lopd.toml"),
        )
    };
    assert_eq!(
        parse(0).unwrap().deform.threads,
        cores.saturating_sub(1).max(1)
    );
    assert_eq!(parse(1).unwrap().deform.threads, 1);
    assert_eq!(parse(cores).unwrap().deform.threads, cores);
    let asked = cores + 3;
    daemon_err(
        &format!("[deform]\nthreads = {asked}\n"),
        &[
            "deform.threads",
            &format!("{asked} threads asked"),
            &format!("has {cores} cores"),
        ],
    );
}

#[test]
fn daemon_config_from_file() {
    let path = fixture_dir().join("lopd.toml");
    std::fs::write(
        &path,
        "status_interval_ms = 250\n[haptic]\ncore = 1\nrt_priority = 99\nlock_memory = false\n\
         max_force_n = 2.5\n[deform]\ncore = 0\n",
    )
    .unwrap();
    let cfg = load_daemon_config(&path).unwrap();
    assert_eq!(cfg.status_interval_ms, 250);
    assert_eq!(cfg.haptic.core, Some(1));
    assert_eq!(cfg.haptic.rt_priority, 99);
    assert!(!cfg.haptic.lock_memory);
    assert_eq!(cfg.haptic.max_force_n, 2.5);
    assert_eq!(cfg.haptic.ramp_ms, 5.0);
    assert_eq!(cfg.deform.core, Some(0));
}

#[test]
fn daemon_config_bad_priority() {
    daemon_err(
        "[haptic]\nrt_priority = 0\n",
        &["haptic.rt_priority = 0", "1 and 99", ":2:"],
    );
    daemon_err(
        "[haptic]\nrt_priority = 100\n",
        &["haptic.rt_priority = 100", "1 and 99"],
    );
    daemon_err(
        "[haptic]\nrt_priority = 300\n",
        &["haptic.rt_priority", "300"],
    );
}

#[test]
fn daemon_config_other_errors() {
    daemon_err(
        "[haptic]\nmax_force = 2.0\n",
        &["haptic", "max_force", "unknown field"],
    );
    daemon_err(
        "[haptic]\nmax_force_n = nan\n",
        &["haptic.max_force_n = nan"],
    );
    daemon_err("[haptic]\nramp_ms = 500.0\n", &["haptic.ramp_ms = 500.0"]);
    daemon_err("[haptic]\ncore = -1\n", &["haptic.core", "-1"]);
    daemon_err("status_interval_ms = 0\n", &["status_interval_ms = 0"]);
    daemon_err("[haptic\n", &["line 1"]);
}

/// `[device] dhd_library`: a relative path is the config file's neighbour, an absolute one is
/// kept, and an empty or non-path value names the key.
#[test]
fn the_dhd_library_key() {
    let cfg = parse_daemon_config(
        "[device]\ndhd_library = \"sdk/lib/libdhd.so\"\n",
        Path::new("/etc/lop/lopd.toml"),
    )
    .unwrap();
    assert_eq!(
        cfg.device.dhd_library,
        Some(PathBuf::from("/etc/lop/sdk/lib/libdhd.so"))
    );
    assert_eq!(cfg.device.hd_library, None);
    let cfg = parse_daemon_config(
        "[device]\ndhd_library = \"/opt/fd/libdhd.so\"\n",
        Path::new("lopd.toml"),
    )
    .unwrap();
    assert_eq!(
        cfg.device.dhd_library,
        Some(PathBuf::from("/opt/fd/libdhd.so"))
    );
    assert_eq!(DaemonConfig::default().device.dhd_library, None);
    daemon_err(
        "[device]\ndhd_library = \"\"\n",
        &["device.dhd_library", "libdhd.so"],
    );
    daemon_err(
        "[device]\ndhd_library = 3\n",
        &["lopd.toml:2", "device.dhd_library", "3"],
    );
    daemon_err(
        "[device]\ndhd_libary = \"x\"\n",
        &["dhd_libary", "unknown field"],
    );
}

#[test]
fn missing_files_name_the_path() {
    let err = load_daemon_config(Path::new("/nonexistent/lopd.toml")).unwrap_err();
    assert!(matches!(err, ConfigError::Read { .. }));
    assert!(err.to_string().contains("/nonexistent/lopd.toml"));
    let err = load_scene(Path::new("/nonexistent/scene.toml")).unwrap_err();
    assert!(err.to_string().contains("/nonexistent/scene.toml"));
}

#[test]
fn workspace_round_trip_with_rotation() {
    let w = WorkspaceMap {
        scale: 2.0,
        rotate_deg: [30.0, -45.0, 100.0],
        offset: [0.2, 0.1, -0.3],
    };
    let t = w.transform();
    let points = [
        [0.0, 0.0, 0.0],
        [80.0, -60.0, 35.0],
        [-120.5, 7.25, -88.0],
        [1e-3, 250.0, -1e-6],
    ];
    for p in points {
        let scene = w.device_to_scene(p);
        let back = w.scene_to_device(scene);
        for i in 0..3 {
            assert!(
                (back[i] - p[i]).abs() < 1e-12,
                "{p:?} -> {scene:?} -> {back:?}"
            );
        }
        assert_eq!(t.device_to_scene(p), scene);
        // Lengths scale by 1e-3 * scale; directions only rotate.
        let d = [scene[0] - 0.2, scene[1] - 0.1, scene[2] + 0.3];
        let norm = |v: [f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        assert!((norm(d) - norm(p) * 2e-3).abs() < 1e-15);
        let dir = w.device_dir_to_scene(p);
        let dir_back = w.scene_dir_to_device(dir);
        for i in 0..3 {
            assert!((dir_back[i] - p[i]).abs() < 1e-12);
        }
    }
    // The device origin lands on the offset.
    assert_eq!(w.device_to_scene([0.0; 3]), [0.2, 0.1, -0.3]);
}

#[test]
fn defaults_apply_when_tables_are_absent() {
    let scene = parse_scene(GOOD, &scene_path()).unwrap();
    assert_eq!(scene.tool(), &ToolSpec::default());
    assert_eq!(scene.tool().force_law, ForceLaw::Linear);
    assert_eq!(scene.tool().heat_power, 20.0);
    assert_eq!(scene.rates, Rates::default());
    assert_eq!(scene.tool().workspace, WorkspaceMap::default());
    assert_eq!(scene.device.mock_script, None);
    let a = &scene.bodies[0];
    assert_eq!(a.importance, Importance::Important);
    assert_eq!(a.model, ModelPin::Auto);
    assert_eq!(a.scale, 1.0);
    assert_eq!(a.translate, [0.0; 3]);
    assert!(a.fixed_nodes.is_empty());
    assert_eq!(a.fem.as_ref().unwrap().mode, FemMode::Corotational);
    assert_eq!(scene.bodies[1].importance, Importance::Normal);
    assert_ne!(scene.bodies[0].color, scene.bodies[1].color);
    assert!(scene.bodies.iter().all(|b| b.gc.is_none()));
    // Heat: liver-like tissue at 37 °C in 22 °C air, no own heat step.
    assert_eq!(
        scene.heat,
        HeatSpec {
            air_temperature: 22.0,
            air_coefficient: 10.0,
            contact_conductance: 500.0,
            dt: None,
        }
    );
    for b in &scene.bodies {
        assert_eq!(
            b.heat,
            HeatParams {
                conductivity: 0.52,
                specific_heat: 3540.0,
                density: 1060.0,
                initial: 37.0,
                coagulation: 60.0,
                burn_stiffening: 1.0,
            }
        );
    }
}

#[test]
fn heat_tables_are_read() {
    let text = format!(
        "[heat]\nair_temperature = 25.0\nair_coefficient = 0.0\ncontact_conductance = 100.0\n\
         dt = 0.05\n{}",
        good_with(
            "integrator = \"rk4\"\n",
            "integrator = \"rk4\"\n\n[body.heat]\nconductivity = 0.5\nspecific_heat = 3600.0\n\
             density = 1050.0\ninitial = 36.5\ncoagulation = 65.0\nburn_stiffening = 2.5\n",
        )
    );
    let scene = parse_scene(&text, &scene_path()).unwrap();
    assert_eq!(scene.heat.air_temperature, 25.0);
    assert_eq!(scene.heat.air_coefficient, 0.0);
    assert_eq!(scene.heat.contact_conductance, 100.0);
    assert_eq!(scene.heat.dt, Some(0.05));
    assert_eq!(scene.bodies[0].heat, HeatParams::default());
    let b = &scene.bodies[1].heat;
    assert_eq!(
        (b.conductivity, b.specific_heat, b.density),
        (0.5, 3600.0, 1050.0)
    );
    assert_eq!(
        (b.initial, b.coagulation, b.burn_stiffening),
        (36.5, 65.0, 2.5)
    );
}

#[test]
fn scene_name_defaults_to_file_stem() {
    let text = good_with("name = \"t\"\n", "");
    let scene = parse_scene(&text, &scene_path()).unwrap();
    assert_eq!(scene.name, "test-scene");
}

#[test]
fn relative_paths_resolve_against_the_scene_file() {
    let text = format!("[device]\nmock_script = \"scripts/poke.toml\"\n{GOOD}");
    let scene = parse_scene(&text, &scene_path()).unwrap();
    let dir = fixture_dir();
    assert_eq!(scene.bodies[0].mesh, dir.join("m"));
    assert_eq!(
        scene.device.mock_script.as_deref(),
        Some(dir.join("scripts/poke.toml").as_path())
    );
    assert!(scene.path.is_absolute());
    // A mesh given as a file that exists is taken as is.
    let scene = parse_scene(
        &good_with("mesh = \"m\"", "mesh = \"m.node\""),
        &scene_path(),
    )
    .unwrap();
    assert_eq!(scene.bodies[0].mesh, dir.join("m.node"));
}

#[test]
fn body_transform_scales_rotates_then_translates() {
    let text = good_with(
        "mesh = \"m\"\n\n[body.msd]",
        "mesh = \"m\"\nscale = 2.0\nrotate_deg = [0.0, 0.0, 90.0]\ntranslate = [1.0, 0.0, 0.0]\n\
         fixed_nodes = [3, 1]\n\n[body.msd]",
    );
    let scene = parse_scene(&text, &scene_path()).unwrap();
    let b = &scene.bodies[1];
    assert_eq!(b.fixed_nodes, vec![3, 1]);
    // (1,0,0) -> scale (2,0,0) -> 90° about z (0,2,0) -> translate (1,2,0).
    assert_eq!(b.transform_point([1.0, 0.0, 0.0]), [1.0, 2.0, 0.0]);
}

fn temp_dirs() -> (PathBuf, PathBuf) {
    let root = fixture_dir().join("resolve");
    let first = root.join("first");
    let second = root.join("second");
    for d in [&first, &second] {
        std::fs::create_dir_all(d).unwrap();
    }
    std::fs::write(first.join("alpha.toml"), "").unwrap();
    std::fs::write(second.join("alpha.toml"), "").unwrap();
    std::fs::write(second.join("beta.toml"), "").unwrap();
    std::fs::write(second.join("notes.txt"), "").unwrap();
    (first, second)
}

#[test]
fn scene_names_resolve_in_directory_order() {
    let (first, second) = temp_dirs();
    let dirs = vec![first.clone(), second.clone(), PathBuf::from("/nonexistent")];
    assert_eq!(
        resolve_scene_in("alpha", &dirs).unwrap(),
        first.join("alpha.toml")
    );
    assert_eq!(
        resolve_scene_in("beta", &dirs).unwrap(),
        second.join("beta.toml")
    );
    let names: Vec<String> = list_scenes_in(&dirs).into_iter().map(|(n, _)| n).collect();
    assert_eq!(names, ["alpha", "beta"]);

    let err = resolve_scene_in("gamma", &dirs).unwrap_err();
    let msg = err.to_string();
    for needle in [
        "\"gamma\"",
        "alpha, beta",
        "/nonexistent",
        first.to_str().unwrap(),
    ] {
        assert!(msg.contains(needle), "message lacks {needle:?}: {msg}");
    }
    assert!(resolve_scene_in("", &dirs).is_err());
}

#[test]
fn paths_are_taken_as_paths() {
    let (_, second) = temp_dirs();
    let beta = second.join("beta.toml");
    assert_eq!(resolve_scene_in(beta.to_str().unwrap(), &[]).unwrap(), beta);
    let err = resolve_scene_in("no/such/scene.toml", std::slice::from_ref(&second)).unwrap_err();
    assert!(matches!(err, ConfigError::NoSuchFile { .. }));
    assert!(err.to_string().contains("no/such/scene.toml"));
    // A ".toml" suffix makes it a path even without a slash.
    assert!(resolve_scene_in("beta.toml", &[second]).is_err());
}

#[test]
fn unknown_script_name_lists_directories() {
    let err = lop_config::resolve_script("no-such-script-name").unwrap_err();
    let msg = err.to_string();
    assert!(
        msg.starts_with("mock script \"no-such-script-name\" not found"),
        "{msg}"
    );
    assert!(msg.contains("config/scripts"), "{msg}");
}

#[test]
fn remote_section_names_the_bad_key_and_value() {
    let cfg = parse_daemon_config(
        "[remote]\nenabled = true\nlisten = [\"tcp/127.0.0.1:17447\"]\nconnect = [\"tcp/10.0.0.2:7447\"]\n",
        Path::new("lopd.toml"),
    )
    .unwrap();
    assert!(cfg.remote.enabled);
    assert_eq!(cfg.remote.listen, ["tcp/127.0.0.1:17447"]);
    assert_eq!(cfg.remote.connect, ["tcp/10.0.0.2:7447"]);
    assert_eq!(
        cfg.remote.tunnel,
        std::path::PathBuf::from(lop_config::DEFAULT_TUNNEL)
    );
    daemon_err(
        "[remote]\nlisten = [\"tcp/127.0.0.1:7447\", \"tcp/127.0.0.1\"]\n",
        &["remote.listen[1]", "\"tcp/127.0.0.1\"", "has no port"],
    );
    daemon_err(
        "[remote]\nconnect = [\"http/rig:80\"]\n",
        &["remote.connect[0]", "unknown transport \"http\""],
    );
    daemon_err(
        "[remote]\nmode = \"router\"\n",
        &["remote.mode", "\"router\"", "\"peer\" or \"client\""],
    );
    daemon_err(
        "[remote]\nmode = \"client\"\n",
        &["remote.connect", "router's endpoint in connect"],
    );
    daemon_err(
        "[remote]\nzenoh_config = \"nowhere.json5\"\n",
        &[
            "remote.zenoh_config",
            "nowhere.json5",
            "no such Zenoh configuration file",
        ],
    );
    daemon_err(
        "[remote]\nframe_rate_hz = 5000\n",
        &["remote.frame_rate_hz", "5000", "at most 1000"],
    );
    daemon_err(
        "[remote]\nservices = [\"scene\", \"control\"]\n",
        &["remote.services[1]", "\"control\"", "never cross"],
    );
    daemon_err(
        "[remote]\nservices = [\"tool\"]\n",
        &["remote.services", "add \"scene\""],
    );
    daemon_err("[remote]\ncontrol = true\n", &["control"]);
}
