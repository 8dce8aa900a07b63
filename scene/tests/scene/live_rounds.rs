//! The live rounds' clock (`Rounds::live`): a body behind takes up to `MAX_CATCH_UP` steps
//! within the round's budget and catches up over the rounds that follow, up to
//! `MAX_CATCH_UP − 1` periods behind; beyond, it drops the time still due as lag. The
//! hand-over from the cage (20 ms) to the FEM (1 ms) on a touch is the cage's hold, not lag:
//! the FEM starts from the cage's last state, up to one cage period behind the wall clock, and
//! joins the clock in that round.

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
    let mut rounds = Rounds::live(ToolLaws::new(&scene, DeviceClamp::NONE), 1_000_000);
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
        cut: false,
        stiffness: None,
    };

    // The wall clock in 1 ms rounds, each woken 20-90 µs late as a real loop is, 0.25 s
    // untouched (the cage steps every 20 ms), then the tool on the liver.
    let start = world.bodies[liver].time;
    assert_eq!(start, 0.0);
    let (mut dropped, mut handed_over, mut fem_rounds) = (0.0, None, 0);
    for k in 1..=400 {
        let until = k as f64 * 1e-3 + [20e-6, 90e-6, 50e-6][k % 3];
        let before = (world.bodies[liver].time, world.bodies[liver].model.kind());
        let touching = (k > 250).then_some(&tool);
        rounds.advance(
            &mut world,
            until,
            touching.map_or(&[][..], std::slice::from_ref),
            &[],
            false,
            || 0,
        );
        let r = world.last_round().bodies[liver];
        let time = world.bodies[liver].time;
        dropped += r.dropped;
        assert!(!r.lagged(), "round {k} ({until} s) dropped lag: {r:?}");
        if before.1 == ModelKind::Gc && world.bodies[liver].model.kind() != ModelKind::Gc {
            handed_over = Some(k);
            // The cage's step was due: it had stood for a cage period; the FEM took its
            // steps from there, then joined the clock on the grid of its period.
            let dt = world.bodies[liver].model.dt();
            assert!(until - before.0 > 10e-3, "{until} - {}", before.0);
            assert!(time <= until && until - time < dt, "{time} for {until}");
            let on_grid = time / dt;
            assert!((on_grid - on_grid.round()).abs() < 1e-6, "{time} for {dt}");
        } else if handed_over.is_some() {
            // On the grid, one step each round whatever the wake-up latency.
            assert_eq!(r.steps, 1, "round {k} ({until} s): {r:?}");
            fem_rounds += 1;
        }
    }
    assert!(
        handed_over.is_some(),
        "the tool never made the liver switch"
    );
    assert!(fem_rounds > 100, "{fem_rounds}");
    // What a real-time meter sees: nothing dropped, and the clock within a period of the
    // wall's.
    assert_eq!(dropped, 0.0);
    assert!(400e-3 - world.bodies[liver].time < 1e-3 + 1e-12);

    // Now a stall of 10 ms with the FEM running, steps that cost nothing on the round's clock:
    // four 1 ms steps, up to three more periods kept behind, the rest dropped as lag; the body
    // is due at once, and the next round (run back to back, at the same wall time here)
    // catches up.
    let dt = world.bodies[liver].model.dt();
    assert!(dt <= 1e-3 + 1e-12, "{dt}");
    let before = world.bodies[liver].time;
    let until = before + 10e-3;
    rounds.advance(
        &mut world,
        until,
        std::slice::from_ref(&tool),
        &[],
        false,
        || 0,
    );
    let r = world.last_round().bodies[liver];
    assert!(r.lagged() && r.due, "{r:?}");
    assert_eq!(r.steps, lop_scene::MAX_CATCH_UP);
    let time = world.bodies[liver].time;
    let kept = f64::from(lop_scene::MAX_CATCH_UP - 1) * dt;
    assert!(
        until - time >= kept - 1e-12 && until - time < kept + dt,
        "{time} for {until}"
    );
    let stepped_to = before + f64::from(r.steps) * dt;
    assert!((r.dropped - (time - stepped_to)).abs() < 1e-12, "{r:?}");
    assert!(r.dropped > 2e-3, "{r:?}");
    rounds.advance(
        &mut world,
        until,
        std::slice::from_ref(&tool),
        &[],
        false,
        || 0,
    );
    let r = world.last_round().bodies[liver];
    assert_eq!((r.steps, r.dropped, r.due), (3, 0.0, false), "{r:?}");
    let time = world.bodies[liver].time;
    assert!(
        time <= until + 1e-12 && until - time < dt,
        "{time} for {until}"
    );

    // The same stall with steps that take 0.4 ms of the round's clock each (and its every
    // reading): the round's 1 ms budget allows one step, then the round ends with its frame;
    // the rounds that follow take one step each until the body has caught up.
    let before = world.bodies[liver].time;
    let until = before + 10e-3;
    let mut t = 0u64;
    let mut slow = || {
        t += 400_000;
        t
    };
    rounds.advance(
        &mut world,
        until,
        std::slice::from_ref(&tool),
        &[],
        false,
        &mut slow,
    );
    let r = world.last_round().bodies[liver];
    assert!(r.lagged() && r.due && r.steps == 1, "{r:?}");
    let mut rounds_after = 0;
    loop {
        rounds.advance(
            &mut world,
            until,
            std::slice::from_ref(&tool),
            &[],
            false,
            &mut slow,
        );
        let r = world.last_round().bodies[liver];
        assert_eq!((r.steps, r.dropped), (1, 0.0), "{r:?}");
        rounds_after += 1;
        if !r.due {
            break;
        }
        assert!(rounds_after < 10, "never caught up");
    }
    assert_eq!(rounds_after, lop_scene::MAX_CATCH_UP - 1);
}
