//! One world round for every caller: the same inputs driven through the deformation process's
//! path (`Rounds::live`, which `DeformLoop::tick` runs with the tool state it reads) and
//! through `lopd simulate` (the real command's function, writing its files) give bit-identical
//! positions.

use std::path::PathBuf;

use lop_daemon::simulate::{self, SimulateOptions};
use lop_drivers::mock::{MockDevice, MockScript};
use lop_drivers::{BUTTON_CUT, BUTTON_GRAB, BUTTON_HEAT};
use lop_scene::{DeviceClamp, ToolLaws};
use lop_scene::{Rounds, TickTool};
use lop_sim::haptic::WorldProbe;
use lop_sim::world::Coupling;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// `scene` poked by `script` for `steps` steps of every body, both ways.
fn both_paths_agree(scene: &str, script_name: &str, steps: u64) {
    let scene_path = root().join(format!("config/scenes/{scene}.toml"));
    let script_path = root().join(format!("config/scripts/{script_name}.toml"));
    let out = std::env::temp_dir().join(format!("lop-one-round-{scene}-{}", std::process::id()));

    // lopd simulate.
    let simulated = simulate::run(SimulateOptions {
        scene: lop_config::load_scene(&scene_path).unwrap(),
        steps,
        until_converged: false,
        static_solve: false,
        scripts: vec![script_path.clone()],
        replay: None,
        out: out.clone(),
    })
    .unwrap()
    .world;
    std::fs::remove_dir_all(&out).ok();

    // The deformation process's path: the scene as `DeformLoop::new` loads it (its laws
    // without a device clamp), the haptic side's god-object and device-clamped stiffness as
    // the tool state carries them, the same round times.
    let scene_file = lop_config::load_scene(&scene_path).unwrap();
    let hand_laws = ToolLaws::new(
        &scene_file,
        DeviceClamp {
            max_stiffness_n_per_mm: MockDevice::omni_limits().max_stiffness_n_per_mm,
        },
    );
    let mut rounds = Rounds::live(ToolLaws::new(&scene_file, DeviceClamp::NONE), 1_000_000);
    let workspace = scene_file.tool().workspace.transform();
    let mut world = lop_scene::load(scene_file).unwrap().world;
    let script = MockScript::load(&script_path).unwrap();
    let mut probe = WorldProbe::new(&world, hand_laws.tool.radius);
    let n = world.bodies.len();
    let mut taken = vec![0u64; n];
    let mut skip = vec![false; n];
    let mut touched = 0;
    loop {
        for (s, &k) in skip.iter_mut().zip(&taken) {
            *s = k >= steps;
        }
        let running = (0..n).filter(|&i| !skip[i]);
        let Some(next) = running
            .clone()
            .map(|i| world.bodies[i].time + world.bodies[i].model.dt())
            .min_by(f64::total_cmp)
        else {
            break;
        };
        let now = running
            .map(|i| world.bodies[i].time)
            .fold(f64::INFINITY, f64::min);
        let sample = script.sample(now);
        let at = workspace.device_to_scene(sample.position_mm);
        probe.tick(&world, at, sample.pressed(BUTTON_GRAB));
        let coupling = probe.coupling();
        let stiffness = match coupling {
            Coupling::GodObject(Some((b, _))) => {
                touched += 1;
                Some(hand_laws.stiffness(b))
            }
            _ => None,
        };
        let tool = TickTool {
            center: at,
            coupling,
            heat: sample.pressed(BUTTON_HEAT),
            cut: sample.pressed(BUTTON_CUT),
            stiffness,
        };
        rounds.advance(
            &mut world,
            next,
            std::slice::from_ref(&tool),
            &skip,
            false,
            || 0,
        );
        for (k, r) in taken.iter_mut().zip(&world.last_round().bodies) {
            *k += r.steps as u64;
        }
    }
    assert!(
        touched > 10,
        "{scene}/{script_name}: the tool touched in {touched} rounds only"
    );
    for (a, b) in simulated.bodies.iter().zip(&world.bodies) {
        assert_eq!(a.time, b.time, "{}: clocks", a.name);
        let same = a
            .model
            .positions()
            .iter()
            .zip(b.model.positions())
            .all(|(p, q)| (0..3).all(|k| p[k].to_bits() == q[k].to_bits()));
        assert!(same, "{scene}/{script_name}: body {} differs", a.name);
        let moved = a
            .model
            .positions()
            .iter()
            .zip(&a.mesh.nodes)
            .any(|(p, r)| p != r);
        assert!(moved, "{}: never moved", a.name);
    }
}

#[test]
fn deform_path_and_simulate_agree_bit_for_bit() {
    both_paths_agree("cylinders", "cylinders-grab", 150);
}
