//! Real time is a contract: after start-up the haptic tick never touches the heap. This test
//! counts every allocation made on the tick's thread while `HapticLoop::tick` runs — device read,
//! frame and topology receive from iceoryx2, contact, safety, device write, blackboard update,
//! ring push, histograms and telemetry — over 10,000 ticks of the mock poke on the organs
//! scene, with fresh frames arriving all along, and requires zero.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicU64, Ordering};

use lop_config::{load_scene, resolve_scene, resolve_script, DaemonConfig};
use lop_daemon::haptic::{rings, HapticLoop, HapticSettings};
use lop_daemon::scene;
use lop_drivers::mock::{MockDevice, MockScript};
use lop_drivers::HapticDevice;
use lop_ipc::services::{self, Role};
use lop_ipc::*;

struct Counting;

static ALLOCATIONS: AtomicU64 = AtomicU64::new(0);
thread_local! {
    static COUNTING: Cell<bool> = const { Cell::new(false) };
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if COUNTING.with(|c| c.get()) {
            ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        }
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if COUNTING.with(|c| c.get()) {
            ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        }
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn counted<R>(f: impl FnOnce() -> R) -> R {
    COUNTING.with(|c| c.set(true));
    let r = f();
    COUNTING.with(|c| c.set(false));
    r
}

#[test]
fn haptic_tick_allocates_nothing_over_10k_ticks() {
    let prefix = format!("rtalloc-{}", std::process::id());
    let names = ServiceNames::new(&prefix).unwrap();
    let scene_file = load_scene(&resolve_scene("organs").unwrap()).unwrap();
    let script = MockScript::load(&resolve_script("organs-poke").unwrap()).unwrap();
    let mut device = MockDevice::new(script, MockDevice::omni_limits());
    device.start().unwrap();
    let settings = HapticSettings::new(&DaemonConfig::default(), &scene_file, device.limits());
    let loaded = scene::load(scene_file).unwrap();

    // The deformation side, played by this test: topology once, frames as the loop runs.
    let node = services::node("rtalloc-deform").unwrap();
    let topo_pub = services::topology_service(&node, &names, Role::Owner)
        .unwrap()
        .publisher_builder()
        .initial_max_slice_len(loaded.topology_indices.len())
        .create()
        .unwrap();
    let frame_pub = services::frame_service(&node, &names, Role::Owner)
        .unwrap()
        .publisher_builder()
        .initial_max_slice_len(loaded.topology.node_count as usize)
        .create()
        .unwrap();

    let ((tool_tx, mut tool_rx), (tel_tx, mut tel_rx)) = rings();
    let mut hl = HapticLoop::new(&names, settings, tool_tx, tel_tx).unwrap();

    let mut topology = loaded.topology;
    topology.topology_id = 42;
    let mut s = topo_pub
        .loan_slice_uninit(loaded.topology_indices.len())
        .unwrap();
    *s.user_header_mut() = topology;
    s.write_from_slice(&loaded.topology_indices).send().unwrap();

    let publish_frame = |seq: u64| {
        let n = topology.node_count as usize;
        let mut s = frame_pub.loan_slice_uninit(n).unwrap();
        let h = s.user_header_mut();
        h.contract_version = CONTRACT_VERSION;
        h.topology_id = 42;
        h.sequence = seq;
        h.body_count = topology.body_count;
        h.node_count = n as u32;
        h.publish_ns = clock::monotonic_ns();
        for (i, b) in loaded.world.bodies.iter().enumerate() {
            let bf = &mut h.bodies[i];
            let (lo, hi) = lop_sim::mesh::bounds(&b.mesh.nodes);
            bf.aabb_min = lo.map(|c| c as f32);
            bf.aabb_max = hi.map(|c| c as f32);
        }
        let mut k = 0;
        let s = s.write_from_fn(|_| NodeSample::default());
        let mut s = s;
        for b in &loaded.world.bodies {
            for p in &b.mesh.nodes {
                s.payload_mut()[k] = NodeSample {
                    position: [p[0] as f32, p[1] as f32, p[2] as f32],
                    temperature: 37.0,
                    flags: 0,
                };
                k += 1;
            }
        }
        s.send().unwrap();
    };

    // Warm-up: the first frames, topology and a few ticks may set things up.
    publish_frame(0);
    for _ in 0..100 {
        let now = clock::monotonic_ns();
        hl.tick(&mut device, now, now);
    }
    ALLOCATIONS.store(0, Ordering::Relaxed);

    let mut contact_ticks = 0;
    let max_step = DaemonConfig::default().haptic.max_force_step_n;
    let mut last_force = [0.0f64; 3];
    let mut largest_step: f64 = 0.0;
    for i in 0..10_000u64 {
        if i % 10 == 0 {
            publish_frame(i / 10 + 1);
        }
        let now = clock::monotonic_ns();
        let out = counted(|| hl.tick(&mut device, now, now));
        if out.state.flags & TOOL_FLAG_CONTACT != 0 {
            contact_ticks += 1;
        }
        // Frames come at 100 Hz, the force is rendered at 1 kHz: it stays smooth — no step
        // larger than the per-tick limit, except at contact onset (from zero force).
        let f = out.state.force;
        let step = ((f[0] - last_force[0]).powi(2)
            + (f[1] - last_force[1]).powi(2)
            + (f[2] - last_force[2]).powi(2))
        .sqrt();
        if last_force != [0.0; 3] {
            largest_step = largest_step.max(step);
        }
        last_force = f;
        while tool_rx.pop().is_ok() {}
        while tel_rx.pop().is_ok() {}
    }
    let allocations = ALLOCATIONS.load(Ordering::Relaxed);
    assert!(
        contact_ticks > 500,
        "the poke must exercise the contact path ({contact_ticks})"
    );
    assert_eq!(allocations, 0, "heap allocations on the haptic tick");
    assert!(
        largest_step <= max_step + 1e-12,
        "force step {largest_step} N over the {max_step} N per-tick limit"
    );

    // The counter does see allocations (the test can fail).
    counted(|| std::hint::black_box(vec![1u8; 16]));
    assert!(ALLOCATIONS.load(Ordering::Relaxed) > 0);
}
