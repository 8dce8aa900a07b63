//! The deformation process couples every tool of the scene: the real `DeformLoop`, over shared
//! memory, with two tools' states written to their blackboard entries as a haptic process
//! writes them, each pressing one cylinder from its own side with its own spring.
//!
//! - While both press, every frame's `contacts[0]` and `contacts[1]` each carry a contact
//!   patch on the cylinder, balanced on that tool's side, with a local model whose force on
//!   the tissue points along that tool's press: opposite signs along x.
//! - Once the first tool's state goes stale, its entry carries no contact and the second
//!   tool's stays under index 1 (a stale tool does not shift the others), on the cylinder in
//!   every frame: the first tool's state growing older than the blackboard's drop limit does
//!   not close the board while the second tool's is fresh.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use lop_config::DaemonConfig;
use lop_daemon::deform::{DeformLoop, DeformOptions};
use lop_ipc::services::{self, Role};
use lop_ipc::*;
use lop_sim::contact::closest_on_surface;

/// One cylinder (radius 0.03 m, height 0.12 m, upright along +y, base fixed), pinned to FEM;
/// two tools of different radii and springs.
const SCENE: &str = r#"
[scene]
name = "two-tools"
gravity = [0.0, 0.0, 0.0]

[[tool]]
name = "left"
radius = 0.003
stiffness = 300.0

[[tool]]
name = "right"
radius = 0.004
stiffness = 500.0

[rates]
deform_max_hz = 1000.0

[[body]]
name = "cylinder"
mesh = "MESH"
model = "fem"

[body.fem]
young = 3000.0
poisson = 0.3
density = 1000.0
damping = 1.0
dt = 0.005
"#;

/// How far each tool's device is past its god-object, into the tissue, m.
const PRESS: f64 = 0.002;

/// Longest a phase may take if the loop falls behind (a loaded machine).
const WATCHDOG: Duration = Duration::from_secs(20);

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The state of tool `tool` pressing at rest from outside point `from`: the god-object resting
/// on the closest surface point (`radius` off it), the device `PRESS` further in along the
/// surface's normal, the tool's spring `stiffness`; stamped later.
fn press(
    world: &lop_sim::world::World,
    tool: u32,
    from: [f64; 3],
    radius: f64,
    stiffness: f64,
) -> ToolState {
    let body = &world.bodies[0];
    let hit = closest_on_surface(body.model.positions(), &body.mesh.surface, from)
        .expect("the cylinder has a surface");
    let proxy: [f64; 3] = std::array::from_fn(|k| hit.point[k] + hit.normal[k] * radius);
    ToolState {
        contract_version: CONTRACT_VERSION,
        flags: TOOL_FLAG_CONTACT,
        tool,
        device_position: std::array::from_fn(|k| proxy[k] - hit.normal[k] * PRESS),
        proxy_position: proxy,
        tool_radius: radius,
        contact_body: 0,
        contact_triangle: hit.triangle as u32,
        contact_barycentric: hit.barycentric,
        tool_stiffness: stiffness,
        ..ToolState::default()
    }
}

/// Rests each tool's god-object where the frame `h` balanced its contact patch, as the haptic
/// loop does (it renders against the tissue as the deformation left it).
fn rest_on(h: &FrameHeader, states: [&mut ToolState; 2]) {
    for (c, s) in h.contacts.iter().zip(states) {
        if c.body == 0 {
            s.proxy_position = c.proxy;
        }
    }
}

#[test]
fn two_tools_press_one_body_from_opposite_sides_each_under_its_own_index() {
    let dir = std::env::temp_dir().join(format!("lop-two-tools-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mesh = root().join("assets/meshes/cylinder");
    let scene_path = dir.join("two-tools.toml");
    std::fs::write(
        &scene_path,
        SCENE.replace("MESH", mesh.to_str().expect("a UTF-8 path")),
    )
    .unwrap();
    let scene = lop_config::load_scene(&scene_path).unwrap();
    assert_eq!(scene.tools.len(), 2);
    let prefix = format!("twotools-{}", std::process::id());
    let names = ServiceNames::new(&prefix).unwrap();

    // The haptic side's blackboard, made before the loop so that it reads it from the start.
    let node = services::node("twotools-haptic").unwrap();
    let board = services::tool_board_owner(&node, &names).unwrap();
    let writer = board.writer_builder().create().unwrap();
    let entries: Vec<_> = (0..2)
        .map(|t| {
            writer
                .entry::<ToolState>(&services::tool_latest_key(t))
                .unwrap()
        })
        .collect();

    let mut deform = DeformLoop::new(&DeformOptions {
        scene: scene.clone(),
        names: names.clone(),
        config: DaemonConfig::default(),
        duration: None,
    })
    .unwrap();
    let frames = services::frame_service(&node, &names, Role::Client)
        .unwrap()
        .subscriber_builder()
        .create()
        .unwrap();

    // The presses, on the rest shape: tool 0 from −x, tool 1 from +x, at half height.
    let world = lop_scene::load(scene).unwrap().world;
    let mut left = press(&world, 0, [-0.05, 0.06, 0.0], 0.003, 300.0);
    let mut right = press(&world, 1, [0.05, 0.06, 0.0], 0.004, 500.0);
    assert!(left.proxy_position[0] < -0.03 && right.proxy_position[0] > 0.03);

    // Frames carry the topology id the tool states must name.
    let start = Instant::now();
    let topology_id = loop {
        deform.tick();
        if let Some(s) = frames.receive().unwrap() {
            break s.user_header().topology_id;
        }
        assert!(start.elapsed() < WATCHDOG, "no frame");
    };
    left.topology_id = topology_id;
    right.topology_id = topology_id;

    // Both tools press for 0.3 s, their states stamped every tick.
    let mut last = None;
    let start = Instant::now();
    while start.elapsed() < Duration::from_millis(300) || last.is_none() {
        let now = clock::monotonic_ns();
        for (entry, state) in entries.iter().zip([&mut left, &mut right]) {
            state.stamp_ns = now;
            state.sequence += 1;
            entry.update_with_copy(*state);
        }
        deform.tick();
        while let Some(s) = frames.receive().unwrap() {
            let h = *s.user_header();
            rest_on(&h, [&mut left, &mut right]);
            last = Some(h);
        }
        assert!(start.elapsed() < WATCHDOG, "no frame while pressing");
    }
    let h = last.unwrap();
    assert_eq!(h.tool_count, 2);
    let (c0, c1) = (h.contacts[0], h.contacts[1]);
    assert_eq!((c0.body, c1.body), (0, 0), "{c0:?}\n{c1:?}");
    assert!(c0.proxy[0] < 0.0 && c1.proxy[0] > 0.0, "{c0:?}\n{c1:?}");
    assert_eq!((c0.local, c1.local), (1, 1), "{c0:?}\n{c1:?}");
    // The tissue pushed along each press: +x by the left tool, −x by the right one.
    assert!(c0.force[0] > 0.05, "{c0:?}");
    assert!(c1.force[0] < -0.05, "{c1:?}");

    // The left tool's state stops; the right one presses on for 0.35 s: past the stale limit
    // (0.1 s) and the blackboard's drop limit (0.15 s) of the left tool's state.
    let stopped = Instant::now();
    let mut seen = 0;
    let mut left_gone = 0;
    let mut local = 0;
    while stopped.elapsed() < Duration::from_millis(350) {
        right.stamp_ns = clock::monotonic_ns();
        right.sequence += 1;
        entries[1].update_with_copy(right);
        deform.tick();
        while let Some(s) = frames.receive().unwrap() {
            let h = *s.user_header();
            rest_on(&h, [&mut left, &mut right]);
            let c1 = h.contacts[1];
            assert_eq!(
                (h.tool_count, c1.body),
                (2, 0),
                "the right tool lost its contact {} ms after the left stopped: {c1:?}",
                stopped.elapsed().as_millis()
            );
            if c1.local == 1 {
                // Never pulling: a step where the tissue moved off the tool's sphere (it
                // springs back once the left tool lets go) gives the patch no force at all.
                assert!(c1.force[0] <= 0.0, "{c1:?}");
                local += 1;
            }
            seen += 1;
            if stopped.elapsed() > Duration::from_millis(200) {
                assert_eq!(h.contacts[0].body, NO_CONTACT, "{:?}", h.contacts[0]);
                left_gone += 1;
            }
        }
        assert!(stopped.elapsed() < WATCHDOG);
    }
    assert!(
        seen > 20 && left_gone > 5 && local > seen / 2,
        "{seen} frames, {left_gone} late, {local} with a local model"
    );
    std::fs::remove_dir_all(&dir).ok();
}
