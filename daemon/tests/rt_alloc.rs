//! Real time is a contract: after start-up the haptic tick never touches the heap. This test
//! counts every allocation made on the tick's thread while `HapticLoop::tick` runs — device read,
//! frame and topology receive from iceoryx2, contact, safety, device write, blackboard update,
//! ring push, histograms and telemetry — over 10,000 ticks of the mock poke on the organs
//! scene, with fresh frames arriving all along, and requires zero.

mod common;

use common::DeformSide;
use lop_config::{load_scene, resolve_scene, resolve_script, DaemonConfig};
use lop_daemon::haptic::{rings, HapticLoop, HapticSettings, IndexSlot};
use lop_drivers::mock::{MockDevice, MockScript};
use lop_drivers::HapticDevice;
use lop_ipc::*;
use lop_scene as scene;
use lop_test_support::alloc::{self, allocations, counted, Counting};

#[global_allocator]
static A: Counting = Counting::armed_threads();

/// The allocation counters are the process's: the tests that read them run one at a time.
static SERIAL: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// Holds [`SERIAL`] for a test (a failed test's poison is no reason to fail the next).
fn serial() -> std::sync::MutexGuard<'static, ()> {
    SERIAL.lock().unwrap_or_else(|e| e.into_inner())
}

/// Longest wait for a published frame to reach the loop.
const WAIT: std::time::Duration = std::time::Duration::from_secs(5);

#[test]
fn haptic_tick_allocates_nothing_over_10k_ticks() {
    let _serial = serial();
    let prefix = format!("rtalloc-{}", std::process::id());
    let names = ServiceNames::new(&prefix).unwrap();
    let scene_file = load_scene(&resolve_scene("organs").unwrap()).unwrap();
    let script = MockScript::load(&resolve_script("organs-poke").unwrap()).unwrap();
    let mut device = MockDevice::new(script, MockDevice::omni_limits());
    device.start().unwrap();
    let settings = HapticSettings::new(&DaemonConfig::default(), &scene_file, device.limits());
    let hl_tool_stiffness = settings.pipeline().tool.stiffness;
    let loaded = scene::load(scene_file).unwrap();

    // The deformation side, played by this test: topology once, frames as the loop runs.
    let deform = DeformSide::new("rtalloc-deform", &names, &loaded);
    let ((tool_tx, mut tool_rx), (tel_tx, mut tel_rx)) = rings(&settings).unwrap();
    let mut hl = HapticLoop::new(&names, settings, tool_tx, tel_tx).unwrap();

    deform.publish_topology();
    let publish_frame = |seq: u64| deform.publish_frame(seq);

    // Warm-up: the first frames, topology and a few ticks may set things up; the contact index
    // is built on its own thread, so tick until it has arrived (in `lopd` that takes the first
    // few milliseconds after a topology; this loop runs far faster than real time).
    publish_frame(0);
    assert!(hl.await_frame(0, WAIT), "frame 0 never arrived");
    for _ in 0..100 {
        let now = clock::monotonic_ns();
        hl.tick(&mut [&mut device], now, now);
    }
    let mut waited = 0;
    while !hl.contact_ready() && waited < 10_000 {
        std::thread::sleep(std::time::Duration::from_millis(1));
        let now = clock::monotonic_ns();
        hl.tick(&mut [&mut device], now, now);
        waited += 1;
    }
    assert!(hl.contact_ready(), "no contact index after 10 s");
    alloc::reset();

    let mut contact_ticks = 0;
    let mut local_ticks = 0;
    let max_step = DaemonConfig::default().haptic.max_force_step_n;
    let mut last_force = [0.0f64; 3];
    let mut last_device: Option<[f64; 3]> = None;
    let mut largest_excess: f64 = 0.0;
    let mut last_state: Option<ToolState> = None;
    for i in 0..10_000u64 {
        if i % 10 == 0 {
            // Every other frame carries a local model of the press the last tick rendered
            // (the tissue as stiff as half the tool spring), so both paths run.
            let local = last_state
                .filter(|s| i % 20 == 0 && s.flags & TOOL_FLAG_CONTACT != 0 && s.contact_body >= 0)
                .map(|s| common::local_model_of(&s));
            deform.publish_frame_local(i / 10 + 1, local);
            // Frames reach the loop through its frame thread: wait for this one, so every
            // tick below renders the frame this loop meant it to (outside the count).
            assert!(
                hl.await_frame(i / 10 + 1, WAIT),
                "frame {} never arrived",
                i / 10 + 1
            );
        }
        let now = clock::monotonic_ns();
        let out = counted(|| hl.tick(&mut [&mut device], now, now));
        if out.state().flags & TOOL_FLAG_CONTACT != 0 {
            contact_ticks += 1;
        }
        if out.state().flags & TOOL_FLAG_LOCAL_MODEL != 0 {
            local_ticks += 1;
        }
        // Frames come at 100 Hz, the force is rendered at 1 kHz: it stays smooth — no step
        // larger than the per-tick limit beyond what the tool spring explains of the device's
        // move this tick, contact onset (from zero force) included.
        let f = out.state().force;
        let step = ((f[0] - last_force[0]).powi(2)
            + (f[1] - last_force[1]).powi(2)
            + (f[2] - last_force[2]).powi(2))
        .sqrt();
        let p = out.state().device_position;
        let moved = last_device.map_or(0.0, |q| {
            ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
        });
        let k = out.state().tool_stiffness.max(hl_tool_stiffness);
        largest_excess = largest_excess.max(step - k * moved);
        last_force = f;
        last_device = Some(p);
        last_state = Some(*out.state());
        while tool_rx.pop().is_ok() {}
        while tel_rx.pop().is_some() {}
    }
    let allocations = allocations();
    let frees = alloc::deallocations();
    assert!(
        contact_ticks > 500,
        "the poke must exercise the contact path ({contact_ticks})"
    );
    assert_eq!(allocations, 0, "heap allocations on the haptic tick");
    assert_eq!(frees, 0, "heap frees on the haptic tick");
    assert!(
        local_ticks > 100,
        "the frames' local model must be rendered ({local_ticks} ticks)"
    );
    assert!(
        largest_excess <= max_step + 1e-12,
        "force step {largest_excess} N beyond the device's motion, over the {max_step} N per-tick limit"
    );

    // The counter does see allocations (the test can fail).
    counted(|| std::hint::black_box(vec![1u8; 16]));
    assert!(alloc::allocations() > 0);
}

/// The contact index handover when the return ring is full (the helper thread that frees
/// retired indices has fallen behind): the tick keeps the retired index and retries, and
/// neither allocates nor frees.
#[test]
fn a_full_return_ring_neither_allocates_nor_frees_on_the_tick() {
    let _serial = serial();
    let (mut tx, mut rx) = rtrb::RingBuffer::<Box<Vec<u8>>>::new(4);
    let (mut back, mut freed) = rtrb::RingBuffer::<Box<Vec<u8>>>::new(1);
    let mut slot = IndexSlot::default();
    tx.push(Box::new(vec![1; 64])).unwrap();
    slot.take_newest(&mut rx, &mut back);
    back.push(Box::new(vec![0; 64])).unwrap();
    for k in 2..4u8 {
        tx.push(Box::new(vec![k; 64])).unwrap();
    }
    let before = (allocations(), alloc::deallocations());
    for _ in 0..100 {
        counted(|| slot.take_newest(&mut rx, &mut back));
    }
    assert_eq!(
        (allocations(), alloc::deallocations()),
        before,
        "the handover allocated or freed"
    );
    assert_eq!(slot.current().map(|v| v[0]), Some(2), "3 waits for room");
    // Room again: everything retired comes back to be freed, the newest is in use.
    let mut returned = Vec::new();
    for _ in 0..4 {
        while let Ok(v) = freed.pop() {
            returned.push(v[0]);
        }
        slot.take_newest(&mut rx, &mut back);
    }
    assert_eq!(returned, vec![0, 1, 2]);
    assert_eq!(slot.current().map(|v| v[0]), Some(3));
}

/// Two devices in one loop (a second tool 30 mm along the liver, the same poke): the tick of
/// both allocates nothing either, and both tools press.
#[test]
fn a_tick_of_two_devices_allocates_nothing() {
    let _serial = serial();
    let prefix = format!("rtalloc2-{}", std::process::id());
    let names = ServiceNames::new(&prefix).unwrap();
    let mut scene_file = load_scene(&resolve_scene("organs").unwrap()).unwrap();
    let mut right = scene_file.tool().clone();
    right.name = "right".into();
    right.workspace.offset[0] += 0.03;
    scene_file.tools.push(right);
    let script = || MockScript::load(&resolve_script("organs-poke").unwrap()).unwrap();
    let mut left = MockDevice::new(script(), MockDevice::omni_limits());
    let mut right = MockDevice::new(script(), MockDevice::omni_limits());
    left.start().unwrap();
    right.start().unwrap();
    let settings = HapticSettings::for_devices(
        &DaemonConfig::default(),
        &scene_file,
        &[left.limits(), right.limits()],
    );
    let loaded = scene::load(scene_file).unwrap();
    let deform = DeformSide::new("rtalloc2-deform", &names, &loaded);
    let ((tool_tx, mut tool_rx), (tel_tx, mut tel_rx)) = rings(&settings).unwrap();
    let mut hl = HapticLoop::new(&names, settings, tool_tx, tel_tx).unwrap();
    assert_eq!(hl.tool_count(), 2);
    deform.publish_topology();
    deform.publish_frame(0);
    assert!(hl.await_frame(0, WAIT), "frame 0 never arrived");
    let mut waited = 0;
    while !hl.contact_ready() && waited < 10_000 {
        std::thread::sleep(std::time::Duration::from_millis(1));
        let now = clock::monotonic_ns();
        hl.tick(&mut [&mut left, &mut right], now, now);
        waited += 1;
    }
    assert!(hl.contact_ready(), "no contact index after 10 s");
    alloc::reset();
    let mut contact_ticks = [0; 2];
    for i in 0..5_000u64 {
        if i % 10 == 0 {
            deform.publish_frame(i / 10 + 1);
            assert!(hl.await_frame(i / 10 + 1, WAIT));
        }
        let now = clock::monotonic_ns();
        let out = counted(|| hl.tick(&mut [&mut left, &mut right], now, now));
        assert_eq!(out.tools, 2);
        for (k, s) in out.states[..2].iter().enumerate() {
            assert_eq!(s.tool, k as u32);
            if s.flags & TOOL_FLAG_CONTACT != 0 {
                contact_ticks[k] += 1;
            }
        }
        while tool_rx.pop().is_ok() {}
        while tel_rx.pop().is_some() {}
    }
    assert_eq!(
        allocations(),
        0,
        "heap allocations on a tick of two devices"
    );
    assert_eq!(
        alloc::deallocations(),
        0,
        "heap frees on a tick of two devices"
    );
    assert!(
        contact_ticks.iter().all(|&n| n > 500),
        "both tools must press: {contact_ticks:?}"
    );
}
