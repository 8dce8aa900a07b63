//! The shipped scenes load and validate (which also proves their mesh paths resolve), and carry
//! the thesis' numbers.

use lop_config::{
    list_scenes, load_scene, parse_daemon_config, parse_scene, resolve_scene, FemMode, ForceLaw,
    HeatParams, HeatSpec, Importance, ModelPin, NodeMass, Scene, ToolKind,
};
use lop_sim::lop::{CageDynamics, CageSprings};

/// Length and FNV-1a hash of config/scenes/organs.toml (see `organs_scene_file_is_unchanged`).
const ORGANS_LEN: usize = 6349;
const ORGANS_FNV1A: u64 = 0xdb6979cc21aa5c5b;

fn shipped(name: &str) -> Scene {
    let path = resolve_scene(name).unwrap_or_else(|e| panic!("{e}"));
    load_scene(&path).unwrap_or_else(|e| panic!("{e}"))
}

fn assert_omni_safe_tool(scene: &Scene) {
    let t = scene.tool();
    assert_eq!(t.radius, 0.003);
    assert_eq!(t.force_law, ForceLaw::Linear);
    assert_eq!(t.stiffness, 300.0);
    assert_eq!(t.damping, 0.0);
    assert_eq!(t.max_force, 3.0);
    assert_eq!(t.heat_power, 20.0);
    // Stiffness felt at the stylus stays under the Omni's ~0.7 N/mm.
    assert!(t.stiffness * scene.tool().workspace.scale <= 700.0);
}

fn assert_common(scene: &Scene, script: &str) {
    assert_omni_safe_tool(scene);
    assert_eq!(scene.rates.haptic_hz, 1000.0);
    assert_eq!(scene.rates.deform_max_hz, 1000.0);
    assert_eq!(scene.rates.publish_hz, 250.0);
    let mock = scene.device.mock_script.as_ref().expect("mock script");
    assert!(mock.ends_with(format!("scripts/{script}")), "{mock:?}");
    assert!(!scene.description.is_empty());
    for b in &scene.bodies {
        assert!(
            b.mesh.parent().unwrap().ends_with("assets/meshes"),
            "{:?}",
            b.mesh
        );
        assert!(b.msd.is_some() && b.model == ModelPin::Auto);
        // Every shipped body spells out the heat defaults.
        assert_eq!(b.heat, HeatParams::default(), "{}", b.name);
    }
    assert_eq!(scene.heat, HeatSpec::default());
}

#[test]
fn all_shipped_scenes_are_listed() {
    let names: Vec<String> = list_scenes().into_iter().map(|(n, _)| n).collect();
    for want in [
        "abdomen",
        "abdomen-two-hands",
        "beam",
        "cylinders",
        "organs",
    ] {
        assert!(names.iter().any(|n| n == want), "{want} not in {names:?}");
    }
}

#[test]
fn beam() {
    let s = shipped("beam");
    assert_eq!(s.name, "beam");
    assert_common(&s, "beam-poke.toml");
    assert_eq!(s.gravity, [0.0, -9.81, 0.0]);
    assert_eq!(s.tool().workspace.scale, 2.0);
    assert_eq!(s.tool().workspace.offset, [0.2, 0.0, 0.0]);
    assert_eq!(s.bodies.len(), 1);
    let b = &s.bodies[0];
    assert!(b.mesh.ends_with("beam"));
    assert_eq!(b.importance, Importance::Important);
    let msd = b.msd.as_ref().unwrap();
    assert_eq!(msd.stiffness, 250.0);
    assert_eq!(msd.mass, NodeMass::PerNode(0.1));
    assert_eq!(msd.damping, 0.01);
    assert_eq!(msd.dt, 0.005);
    let fem = b.fem.as_ref().unwrap();
    assert_eq!(fem.mode, FemMode::Corotational);
}

#[test]
fn cylinders_match_table_6_1() {
    let s = shipped("cylinders");
    assert_eq!(s.name, "cylinders");
    assert_common(&s, "cylinders-poke.toml");
    assert_eq!(s.gravity, [0.0, -9.81, 0.0]);
    assert_eq!(s.tool().workspace.scale, 1.0);
    assert_eq!(s.tool().workspace.offset, [0.0, 0.06, 0.0]);
    let names: Vec<&str> = s.bodies.iter().map(|b| b.name.as_str()).collect();
    assert_eq!(names, ["cylinder_a", "cylinder_b"]);
    assert_eq!(s.bodies[0].importance, Importance::Important);
    assert_eq!(s.bodies[1].importance, Importance::Normal);
    assert_eq!(s.bodies[0].translate, [-0.031, 0.0, 0.0]);
    assert_eq!(s.bodies[1].translate, [0.031, 0.0, 0.0]);
    for b in &s.bodies {
        assert!(b.mesh.ends_with("cylinder"));
        let fem = b.fem.as_ref().unwrap();
        assert_eq!(
            (fem.young, fem.poisson, fem.density, fem.damping, fem.dt),
            (600.0, 0.0023, 30.0, 1.0, 0.02)
        );
        let msd = b.msd.as_ref().unwrap();
        assert_eq!(
            (msd.stiffness, msd.mass, msd.damping, msd.dt),
            (700.0, NodeMass::Density(120.0), 0.4, 0.02)
        );
        let gc = b.gc.as_ref().unwrap();
        assert_eq!((gc.springs, gc.dt), (Some(CageSprings::THESIS), Some(0.02)));
    }
}

#[test]
fn organs_match_table_6_2() {
    let s = shipped("organs");
    assert_eq!(s.name, "organs");
    assert_common(&s, "organs-poke.toml");
    assert_eq!(s.gravity, [0.0, 0.0, 0.0]);
    assert_eq!(s.tool().workspace.scale, 2.0);
    let names: Vec<&str> = s.bodies.iter().map(|b| b.name.as_str()).collect();
    assert_eq!(names, ["liver", "spleen", "stomach", "pancreas"]);
    for b in &s.bodies {
        assert!(b.mesh.ends_with(&b.name));
        let want = if b.name == "liver" || b.name == "stomach" {
            Importance::Important
        } else {
            Importance::Normal
        };
        assert_eq!(b.importance, want, "{}", b.name);
        let fem = b.fem.as_ref().unwrap();
        assert_eq!(
            (fem.young, fem.poisson, fem.density, fem.damping, fem.dt),
            (140.0, 0.023, 10.0, 10.0, 0.01)
        );
        let gc = b.gc.as_ref().unwrap();
        assert_eq!((gc.springs, gc.dt), (Some(CageSprings::THESIS), Some(0.02)));
        assert_eq!(b.msd.as_ref().unwrap().mass, NodeMass::Density(10.0));
    }
}

/// The default scene: the organs' meshes with the literature's soft-tissue values cited in its
/// comments (config/scenes/abdomen.toml).
#[test]
fn abdomen_has_real_tissue_values() {
    let s = shipped("abdomen");
    assert_eq!(s.name, "abdomen");
    assert_common(&s, "abdomen-poke.toml");
    // Gravity off: the organs' supports are not modelled (see the scene's comments).
    assert_eq!(s.gravity, [0.0, 0.0, 0.0]);
    // The same device mapping and bodies as the thesis' organs scene.
    let organs = shipped("organs");
    assert_eq!(s.tool().workspace, organs.tool().workspace);
    assert_eq!(s.lop, organs.lop);
    let names: Vec<&str> = s.bodies.iter().map(|b| b.name.as_str()).collect();
    assert_eq!(names, ["liver", "spleen", "stomach", "pancreas"]);
    // Young's modulus per organ, Pa, as cited in the scene.
    let young = [
        ("liver", 4100.0),
        ("spleen", 18000.0),
        ("stomach", 10000.0),
        ("pancreas", 1400.0),
    ];
    for (b, o) in s.bodies.iter().zip(&organs.bodies) {
        assert_eq!(b.mesh, o.mesh, "{}", b.name);
        assert_eq!(b.fixed_nodes, o.fixed_nodes, "{}", b.name);
        assert_eq!(b.importance, o.importance, "{}", b.name);
        let fem = b
            .fem
            .as_ref()
            .expect("every abdomen body has FEM parameters");
        let (_, e) = young.iter().find(|(n, _)| *n == b.name).unwrap();
        assert_eq!(fem.young, *e, "{}", b.name);
        // Soft tissue, kPa range.
        assert!(
            (1e3..1e5).contains(&fem.young),
            "{}: E {}",
            b.name,
            fem.young
        );
        // Near incompressible, below where linear tetrahedra lock.
        assert!(
            (0.4..0.5).contains(&fem.poisson),
            "{}: nu {}",
            b.name,
            fem.poisson
        );
        assert_eq!(fem.poisson, 0.45, "{}", b.name);
        assert!((1000.0..=1100.0).contains(&fem.density), "{}", b.name);
        assert_eq!(fem.mode, FemMode::Corotational);
        let msd = b.msd.as_ref().unwrap();
        assert_eq!(msd.mass, NodeMass::Density(fem.density), "{}", b.name);
        assert!(msd.stiffness > 0.0 && msd.damping > 0.0);
        let gc = b.gc.as_ref().unwrap();
        assert_eq!(gc.dynamics, CageDynamics::Projected, "{}", b.name);
    }
}

/// `organs` is the thesis' reproduction: its file stays byte for byte as it was when `abdomen`
/// became the default (FNV-1a of the file). Change the thesis' numbers in a new scene instead.
#[test]
fn abdomen_two_hands_is_the_abdomen_with_a_grasper_and_a_hook() {
    let s = shipped("abdomen-two-hands");
    let abdomen = shipped("abdomen");
    assert_eq!(s.name, "abdomen-two-hands");
    assert!(!s.description.is_empty());
    // The abdomen's organs and sections, its device mapping.
    assert_eq!(s.bodies, abdomen.bodies);
    assert_eq!(
        (&s.lop, &s.heat, &s.collision),
        (&abdomen.lop, &abdomen.heat, &abdomen.collision)
    );
    assert_eq!(s.rates, abdomen.rates);
    // Two tools, each with a script of its own, both Omni-safe and mapped as the abdomen's.
    let kinds: Vec<ToolKind> = s.tools.iter().map(|t| t.kind).collect();
    assert_eq!(
        kinds,
        [ToolKind::Grasper { jaw_radius: 0.004 }, ToolKind::Hook]
    );
    for (t, tool) in s.tools.iter().enumerate() {
        assert_eq!(tool.workspace, abdomen.tool().workspace);
        assert!(tool.stiffness * tool.workspace.scale <= 700.0);
        let script = s.tool_script(t).expect("a script per tool");
        assert!(script.exists(), "{script:?}");
        assert!(script.ends_with(format!("abdomen-two-hands-{}.toml", tool.name)));
    }
}

#[test]
fn organs_scene_file_is_unchanged() {
    let path = resolve_scene("organs").unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let hash = bytes.iter().fold(0xcbf2_9ce4_8422_2325_u64, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    });
    assert_eq!(
        (bytes.len(), hash),
        (ORGANS_LEN, ORGANS_FNV1A),
        "{} changed: it reproduces the thesis' Table 6.2",
        path.display()
    );
}

/// The ```toml blocks of the crate documentation (the user documentation of the file formats).
fn doc_toml_blocks() -> Vec<String> {
    let lib = include_str!("../../src/lib.rs");
    let mut blocks = Vec::new();
    let mut current: Option<String> = None;
    for line in lib.lines().filter_map(|l| l.strip_prefix("//!")) {
        let line = line.strip_prefix(' ').unwrap_or(line);
        match (&mut current, line.trim()) {
            (None, "```toml") => current = Some(String::new()),
            (Some(_), "```") => blocks.extend(current.take()),
            (Some(block), _) => {
                block.push_str(line);
                block.push('\n');
            }
            (None, _) => {}
        }
    }
    blocks
}

#[test]
fn documentation_examples_are_valid() {
    let blocks = doc_toml_blocks();
    assert_eq!(blocks.len(), 3, "{blocks:#?}");
    // The scene example, as if it were a file beside the shipped scenes.
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/doc-example.toml");
    let scene = parse_scene(&blocks[0], &path).unwrap_or_else(|e| panic!("{e}"));
    let organs = shipped("organs");
    assert_eq!(scene.tool(), organs.tool());
    assert_eq!(scene.tool().workspace, organs.tool().workspace);
    assert_eq!(scene.rates, organs.rates);
    assert_eq!(scene.device, organs.device);
    let (doc_liver, liver) = (&scene.bodies[0], &organs.bodies[0]);
    assert_eq!(
        (&doc_liver.fem, &doc_liver.msd, &doc_liver.gc),
        (&liver.fem, &liver.msd, &liver.gc)
    );
    // The `[[body.fix]]` example, appended to the scene example's (last) body.
    let with_fix = format!("{}\n{}", blocks[0], blocks[1]);
    let scene = parse_scene(&with_fix, &path).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(scene.bodies[0].fix.len(), 2, "{:?}", scene.bodies[0].fix);
    // The daemon example.
    let cfg = parse_daemon_config(&blocks[2], std::path::Path::new("lopd.toml"))
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(cfg.haptic.core, Some(1));
}
