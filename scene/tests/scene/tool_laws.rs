//! Each tool of a scene presses with its own laws (`Rounds::with_tools`), under its own index:
//! a round with the first tool absent and the second pressing gives, bit for bit, the world of
//! a round with the second tool's laws alone, reports the press under index 1, and differs
//! from the same press with the first tool's laws.

use std::path::PathBuf;

use lop_config::parse_scene;
use lop_scene::{DeviceClamp, Rounds, TickTool, ToolLaws};
use lop_sim::world::{Coupling, World};

/// One mass-spring cylinder (radius 0.03 m, height 0.12 m, base fixed) and two tools of
/// different radii and springs; it "lives" in config/scenes.
fn two_tools() -> lop_config::Scene {
    let text = r#"
[scene]
gravity = [0.0, 0.0, 0.0]

[[tool]]
radius = 0.003
stiffness = 300.0

[[tool]]
radius = 0.005
stiffness = 800.0

[[body]]
name = "c"
mesh = "../../assets/meshes/cylinder"
model = "msd"

[body.msd]
stiffness = 100.0
density = 1000.0
damping = 0.1
dt = 0.01
integrator = "implicit-euler"
"#;
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../config/scenes/test-tools.toml");
    parse_scene(text, &path).unwrap_or_else(|e| panic!("{e}"))
}

/// 20 rounds of 10 ms with `tools`, from rest; the world afterwards.
fn press(mut rounds: Rounds, tools: &[Option<TickTool>]) -> World {
    let mut world = lop_scene::load(two_tools()).unwrap().world;
    for k in 1..=20 {
        rounds.advance_tools(&mut world, k as f64 * 0.01, tools, &[], false, || 0);
    }
    world
}

fn same_positions(a: &World, b: &World) -> bool {
    a.bodies[0]
        .model
        .positions()
        .iter()
        .zip(b.bodies[0].model.positions())
        .all(|(p, q)| (0..3).all(|k| p[k].to_bits() == q[k].to_bits()))
}

#[test]
fn each_tool_presses_with_its_own_laws_under_its_own_index() {
    let scene = two_tools();
    let laws: Vec<ToolLaws> = (0..2)
        .map(|t| ToolLaws::of_tool(&scene, t, DeviceClamp::NONE))
        .collect();
    assert_ne!(laws[0].bodies[0], laws[1].bodies[0]);
    // A tool 2 mm into the cylinder's side at half height.
    let tool = TickTool {
        center: [-0.03 - 0.005 + 0.002, 0.06, 0.0],
        coupling: Coupling::Nearest,
        heat: false,
        cut: false,
        stiffness: None,
    };

    let both = Rounds::offline(laws[0].clone()).with_tools(laws.clone());
    assert_eq!(both.laws(), &laws[0]);
    assert_eq!(both.tool_laws().len(), 2);
    let second = press(both, &[None, Some(tool)]);
    let c = &second.bodies[0].contacts;
    assert!(c[1].depth > 0.0, "{:?}", c[1]);
    assert_eq!(c[0].depth, 0.0, "{:?}", c[0]);

    let alone = press(Rounds::offline(laws[1].clone()), &[Some(tool)]);
    assert!(
        same_positions(&second, &alone),
        "tool 1 did not press with its laws"
    );
    let first_laws = press(Rounds::offline(laws[0].clone()), &[Some(tool)]);
    assert!(
        !same_positions(&second, &first_laws),
        "the two tools' laws press alike"
    );
}
