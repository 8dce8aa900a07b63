//! The tool as a contact patch: a sphere pressed into a clamped block through the god-object
//! and the world's step, as the daemon runs it.

use lop_sim::contact::{ForceLaw, ToolSphere};
use lop_sim::fem::{box_mesh, Fem, FemMode, FemParameters};
use lop_sim::haptic::WorldProbe;
use lop_sim::model::Model;
use lop_sim::world::World;

const R: f64 = 0.003;
const K_TOOL: f64 = 600.0;

struct Sample {
    depth: f64,
    hand: [f64; 3],
    tissue: [f64; 3],
}

/// Presses a sphere vertically into the middle of a `size` block clamped at the bottom, meshed
/// with `cells`, at 1 mm/s to `max_depth` device travel below the surface, then holds.
fn press(size: [f64; 3], cells: [usize; 3], max_depth: f64, hold_steps: usize) -> Vec<Sample> {
    let mesh = box_mesh(size, cells, |p| p[2] < 1e-9);
    let params = FemParameters {
        young: 30e3,
        poisson: 0.3,
        density: 1050.0,
        damping: 20.0,
        dt: 1e-3,
        mode: FemMode::Linear,
    };
    let fem = Fem::new(&mesh, params).unwrap();
    let mut world = World::new([0.0; 3]);
    world.add_model("block", mesh, Model::Fem(fem));
    let mut probe = WorldProbe::new(&world, R);
    let top = size[2];
    let (cx, cy) = (size[0] / 2.0 + 1e-5, size[1] / 2.0 + 2e-5);
    let start = top + R + 2e-4;
    let speed = 1e-3;
    let mut out = Vec::new();
    let travel_steps = ((start - (top + R - max_depth)) / (speed * 1e-3)).ceil() as usize;
    for step in 0..travel_steps + hold_steps {
        let z = (start - speed * 1e-3 * step as f64).max(top + R - max_depth);
        let device = [cx, cy, z];
        let god = probe.tick(&world, device, false);
        let tool = ToolSphere {
            center: device,
            radius: R,
            stiffness: K_TOOL,
            law: ForceLaw::Linear,
        };
        world
            .step_body_coupled(0, Some(&tool), probe.coupling())
            .unwrap();
        if std::env::var("PATCH_DEBUG").is_ok() && step % 20 == 0 && step > 200 && step < 700 {
            let lc = world.bodies[0].last_contact;
            println!("step {step} dev {:?} god {:?} anchor {} patch {:?} f {:?} m {}", device.map(|c| (c*1e6).round()/1e3), god.proxy.map(|c| (c*1e6).round()/1e3), god.anchor.is_some(), lc.proxy.map(|p| p.map(|c| (c*1e6).round()/1e3)), lc.force_on_tissue.map(|c| (c*1e5).round()/1e2), 0);
        }
        let hand = lop_sim::haptic::hand_force(&god, ForceLaw::Linear, K_TOOL, 0.0, [0.0; 3]);
        out.push(Sample {
            depth: top + R - god.proxy[2],
            hand,
            tissue: world.bodies[0].last_contact.force_on_tissue,
        });
    }
    out
}

#[test]
fn experiment() {
    let ns: Vec<usize> = std::env::var("PATCH_N").unwrap_or("10".into()).split(',').map(|x| x.parse().unwrap()).collect();
    for n in ns {
        let t0 = std::time::Instant::now();
        let s = press([0.01, 0.01, 0.005], [n, n, n / 2], 0.45e-3, 200);
        let mut printed = 0.0;
        for x in &s {
            if x.depth >= printed + 0.05e-3 {
                printed = x.depth;
                println!(
                    "n {n} depth {:.3} mm hand {:?} tissue {:?}",
                    x.depth * 1e3,
                    x.hand.map(|f| (f * 1e5).round() / 1e2),
                    x.tissue.map(|f| (f * 1e5).round() / 1e2)
                );
            }
        }
        let last = s.last().unwrap();
        println!("n {n} took {:?}", t0.elapsed());
        println!("n {n} end depth {:.4} hand {:?} tissue {:?}", last.depth * 1e3, last.hand, last.tissue);
    }
}
