//! The live rounds' clock (`Rounds::live`): a body that cannot catch up drops the time still
//! due as lag, but the hand-over from the cage (20 ms) to the FEM (1 ms) on a touch is the
//! cage's hold, not lag: the FEM starts from the cage's last state, up to one cage period
//! behind the wall clock, and joins the clock in that round.

use std::path::PathBuf;

use lop_scene::{DeviceClamp, Rounds, TickTool, ToolLaws};
use lop_sim::model::ModelKind;
use lop_sim::world::Coupling;

fn abdomen() -> lop_config::Scene {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../config/scenes/abdomen.toml");
    lop_config::load_scene(&path).unwrap()
}

#[test]
fn a_hand_over_joins_the_wall_clock_and_real_lag_is_dropped() {
    let scene = abdomen();
    let mut rounds = Rounds::live(ToolLaws::new(&scene, DeviceClamp::NONE));
    let mut world = lop_scene::load(scene).unwrap().world;
    let liver = world
        .bodies
        .iter()
        .position(|b| b.name == "liver")
        .expect("the abdomen has a liver");
    assert_eq!(world.bodies[liver].model.kind(), ModelKind::Gc);
    // A tool on the liver's surface: the first surface triangle's first corner.
    let corner = world.bodies[liver].mesh.surface[0][0] as usize;
    let on_liver = world.bodies[liver].model.positions()[corner];
    let tool = TickTool {
        center: on_liver,
        coupling: Coupling::Nearest,
        heat: false,
        stiffness: None,
    };

    // The wall clock in 1 ms rounds, 0.25 s untouched (the cage steps every 20 ms), then the
    // tool on the liver.
    let start = world.bodies[liver].time;
    let (mut advanced, mut handed_over, mut k) = (0.0, false, 0);
    while k < 400 {
        k += 1;
        let until = start + k as f64 * 1e-3;
        let before = (world.bodies[liver].time, world.bodies[liver].model.kind());
        let touching = (k > 250).then_some(&tool);
        rounds.advance(&mut world, until, touching, &[], false, || 0);
        let r = world.last_round().bodies[liver];
        advanced += r.advanced;
        assert!(!r.lagged, "round {k} ({until} s) dropped lag: {r:?}");
        if before.1 == ModelKind::Gc && world.bodies[liver].model.kind() != ModelKind::Gc {
            handed_over = true;
            // The cage's step was due: it had stood for a cage period; the FEM took its
            // steps from there, then joined the clock.
            assert!(until - before.0 > 10e-3, "{until} - {}", before.0);
            assert!((world.bodies[liver].time - until).abs() < 1e-12);
            assert!((r.advanced - (until - before.0)).abs() < 1e-12, "{r:?}");
        }
    }
    assert!(handed_over, "the tool never made the liver switch");
    // What a real-time meter sees: the whole wall time stepped (the cage's last partial
    // period at the start aside).
    let wall = world.bodies[liver].time - start;
    assert!((advanced - wall).abs() < 1e-9, "{advanced} of {wall} s");

    // Now a stall of 10 ms with the FEM running: at most four 1 ms steps, the rest dropped as
    // lag, and only the steps count as advanced.
    let dt = world.bodies[liver].model.dt();
    assert!(dt <= 1e-3 + 1e-12, "{dt}");
    let before = world.bodies[liver].time;
    let until = before + 10e-3;
    rounds.advance(&mut world, until, Some(&tool), &[], false, || 0);
    let r = world.last_round().bodies[liver];
    assert!(r.lagged, "{r:?}");
    assert_eq!(r.steps, lop_scene::MAX_CATCH_UP);
    assert!(
        (r.advanced - f64::from(r.steps) * dt).abs() < 1e-12,
        "{r:?}"
    );
    assert!((world.bodies[liver].time - until).abs() < 1e-12);
}
