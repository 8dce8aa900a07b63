//! Faults around the frames' local model of the contact patch, on the real haptic loop (the
//! deformation side played by the test, as in `rt_alloc.rs`): a frame whose local model holds a
//! NaN, a frame without one, the deformation process stopping mid-contact and coming back. The
//! force stays finite and within the clamp throughout, falls back to the force law when the
//! model cannot be used, ramps to exactly zero within the ramp when the frames stop, and ramps
//! back in when they return.

use crate::common;

use common::{local_model_of as model_of, DeformSide};
use lop_config::{load_scene, resolve_scene, resolve_script, DaemonConfig};
use lop_daemon::haptic::{rings, HapticLoop, HapticSettings};
use lop_drivers::mock::{MockDevice, MockScript};
use lop_drivers::HapticDevice;
use lop_ipc::*;
use lop_scene as scene;

/// Longest wait for a published frame to reach the loop (through its frame thread).
const WAIT: std::time::Duration = std::time::Duration::from_secs(5);

fn norm(f: [f64; 3]) -> f64 {
    (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt()
}

#[test]
fn a_broken_or_missing_local_model_and_a_stopped_deformation_give_a_finite_ramped_force() {
    let prefix = format!("lmfault-{}", std::process::id());
    let names = ServiceNames::new(&prefix).unwrap();
    let scene_file = load_scene(&resolve_scene("organs").unwrap()).unwrap();
    let script = MockScript::load(&resolve_script("organs-poke").unwrap()).unwrap();
    let mut device = MockDevice::new(script, MockDevice::omni_limits());
    device.start().unwrap();
    let config = DaemonConfig::default();
    let settings = HapticSettings::new(&config, &scene_file, device.limits());
    let (clamp, stale_ns, ramp) = (
        settings.pipeline().max_force,
        settings.stale_ns,
        settings.pipeline().ramp_ticks,
    );
    let loaded = scene::load(scene_file).unwrap();
    let deform = DeformSide::new("lmfault-deform", &names, &loaded);
    let ((tool_tx, mut tool_rx), (tel_tx, mut tel_rx)) = rings(&settings).unwrap();
    let mut hl = HapticLoop::new(&names, settings, tool_tx, tel_tx).unwrap();
    deform.publish_topology();
    let mut seq = 0;
    let mut tick = |hl: &mut HapticLoop, device: &mut MockDevice, late_ns: u64| {
        let now = clock::monotonic_ns() + late_ns;
        let out = hl.tick(&mut [device], now, now);
        while tool_rx.pop().is_ok() {}
        while tel_rx.pop().is_some() {}
        let f = out.state().force;
        assert!(f.iter().all(|c| c.is_finite()), "force {f:?}");
        assert!(
            norm(f) <= clamp + 1e-12,
            "force {f:?} over the clamp {clamp}"
        );
        *out.state()
    };
    deform.publish_frame(seq);
    assert!(hl.await_frame(seq, WAIT));
    let mut waited = 0;
    while !hl.contact_ready() && waited < 10_000 {
        std::thread::sleep(std::time::Duration::from_millis(1));
        tick(&mut hl, &mut device, 0);
        waited += 1;
    }
    assert!(hl.contact_ready(), "no contact index");
    // Poke until pressing.
    let mut last = tick(&mut hl, &mut device, 0);
    let mut ticks = 0;
    while !(last.flags & TOOL_FLAG_CONTACT != 0 && norm(last.force) > 0.05) {
        if ticks % 10 == 0 {
            seq += 1;
            deform.publish_frame(seq);
            assert!(hl.await_frame(seq, WAIT));
        }
        last = tick(&mut hl, &mut device, 0);
        ticks += 1;
        assert!(ticks < 20_000, "the poke never pressed");
    }

    // A NaN in the local model: not used; the force law renders.
    let (body, proxy, mut broken) = model_of(&last);
    broken.stiffness[1][1] = f64::NAN;
    seq += 1;
    deform.publish_frame_local(seq, Some((body, proxy, broken)));
    assert!(hl.await_frame(seq, WAIT));
    for _ in 0..5 {
        last = tick(&mut hl, &mut device, 0);
        assert_eq!(
            last.flags & TOOL_FLAG_LOCAL_MODEL,
            0,
            "a NaN model was used"
        );
    }
    assert!(norm(last.force) > 0.0, "still pressing: {:?}", last.force);

    // A good one: used.
    seq += 1;
    deform.publish_frame_local(seq, Some(model_of(&last)));
    assert!(hl.await_frame(seq, WAIT));
    last = tick(&mut hl, &mut device, 0);
    assert_ne!(
        last.flags & TOOL_FLAG_LOCAL_MODEL,
        0,
        "the model was not used"
    );
    let pressing = norm(last.force);
    assert!(pressing > 0.0);

    // A frame without one: the force law again.
    seq += 1;
    deform.publish_frame(seq);
    assert!(hl.await_frame(seq, WAIT));
    last = tick(&mut hl, &mut device, 0);
    assert_eq!(last.flags & TOOL_FLAG_LOCAL_MODEL, 0);
    assert!(norm(last.force) > 0.0);

    // The deformation process stops mid-contact: its last frame goes stale, and the force
    // ramps down to exactly zero within the ramp, never growing.
    let mut previous = norm(last.force);
    let late = stale_ns + 1_000_000;
    for i in 0..=ramp {
        last = tick(&mut hl, &mut device, late);
        assert_ne!(last.flags & TOOL_FLAG_STALE_FRAME, 0);
        let f = norm(last.force);
        assert!(
            f <= previous + 1e-12,
            "tick {i} of the ramp: {f} after {previous}"
        );
        previous = f;
    }
    assert_eq!(last.force, [0.0; 3], "zero at the end of the ramp");

    // It comes back (a restarted process counts its frames from 0): the force ramps back in,
    // finite, from zero.
    deform.publish_frame(0);
    assert!(hl.await_frame(0, WAIT));
    let mut forces = Vec::new();
    for i in 0..(3 * ramp) {
        if i % 2 == 0 {
            deform.publish_frame(1 + i as u64);
            assert!(hl.await_frame(1 + i as u64, WAIT));
        }
        last = tick(&mut hl, &mut device, 0);
        forces.push(norm(last.force));
    }
    assert!(
        forces[0] <= pressing / ramp as f64 + 0.1,
        "the first tick back renders a ramped force: {forces:?}"
    );
    assert!(
        forces.last().copied().unwrap_or(0.0) > 0.0,
        "pressing again: {forces:?}"
    );
}
