//! Real time on the device's clock: the OpenHaptics path (driver servo callback → `ServoTask`
//! → `HapticLoop::tick`, with `--record`'s tap) allocates nothing after its first callback.
//!
//! The device is the stand-in libHD (`drivers/standin-hd`) playing the organs poke at 1 kHz on
//! its own scheduler thread; this test plays the deformation side (topology once, a frame every
//! 10 ms). Every allocation our code makes on the scheduler thread from servo tick 200 to 5200
//! is counted — the driver's callback wrapper, the error checks, the tick, the ring pushes —
//! and must be zero. (The stand-in's own allocations go through its own allocator: they stand
//! for the vendor's code.)

#[path = "../../drivers/standin-hd/testing.rs"]
mod standin;

mod common;

use std::sync::atomic::{AtomicBool, Ordering};

use common::DeformSide;
use lop_config::{load_scene, resolve_scene, resolve_script, DaemonConfig};
use lop_daemon::haptic::{rings, HapticSettings};
use lop_daemon::servo::ServoTask;
use lop_drivers::mock::MockScript;
use lop_drivers::openhaptics::OpenHapticsDevice;
use lop_drivers::{HapticDevice, ServoControl, ServoEnd};
use lop_ipc::*;
use lop_scene as scene;
use lop_test_support::alloc::{self, Counting};

#[global_allocator]
static A: Counting = Counting::armed_threads();

const COUNT_FROM: u64 = 200;
const COUNT_UNTIL: u64 = 5200;
static STOP: AtomicBool = AtomicBool::new(false);

/// The task crosses to the scheduler thread; its loop is built and dropped there (as in
/// `lop_daemon::servo::run`).
struct SendTask<'a>(ServoTask<'a>);
// SAFETY: see above; the spawning thread does not touch the task while the device runs it.
unsafe impl Send for SendTask<'_> {}
impl SendTask<'_> {
    fn call(&mut self, d: &mut dyn HapticDevice, c: lop_drivers::ServoClock) -> ServoControl {
        if c.tick == COUNT_FROM {
            alloc::reset();
            alloc::arm();
        }
        if c.tick == COUNT_UNTIL {
            alloc::disarm();
            STOP.store(true, Ordering::Relaxed);
        }
        self.0.on_tick(d, c)
    }
}

#[test]
fn servo_path_allocates_nothing_after_the_first_callback() {
    let dir = std::env::temp_dir().join(format!("lop-rtalloc-servo-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let script = MockScript::load(&resolve_script("organs-poke").unwrap()).unwrap();
    let mut text = String::new();
    for k in 0..8000 {
        let s = script.sample(k as f64 / 1000.0);
        let p = s.position_mm;
        text.push_str(&format!("{},{},{},{}\n", p[0], p[1], p[2], s.buttons));
    }
    let trajectory = dir.join("trajectory.csv");
    std::fs::write(&trajectory, text).unwrap();
    // SAFETY: the only test in this binary; set before any other thread runs.
    unsafe {
        std::env::set_var("LOP_HD_LIBRARY", standin::standin_library());
        std::env::set_var("LOP_STANDIN_TRAJECTORY", &trajectory);
        std::env::remove_var("LOP_STANDIN_ERRORS");
        std::env::remove_var("LOP_STANDIN_LOG_DIR");
    }

    let prefix = format!("rtalloc-servo-{}", std::process::id());
    let names = ServiceNames::new(&prefix).unwrap();
    let scene_file = load_scene(&resolve_scene("organs").unwrap()).unwrap();
    let mut device = OpenHapticsDevice::open(None, None).unwrap();
    device.start().unwrap();
    let settings = HapticSettings::new(&DaemonConfig::default(), &scene_file, device.limits());
    let loaded = scene::load(scene_file.clone()).unwrap();

    // The deformation side.
    let deform = DeformSide::new("rtalloc-servo-deform", &names, &loaded);
    let publish_topology = || deform.publish_topology();
    let publish_frame = |seq: u64| deform.publish_frame(seq);

    let ((tool_tx, mut tool_rx), (tel_tx, mut tel_rx)) = rings(&settings).unwrap();
    let header = lop_daemon::record::header(
        1000.0,
        device.limits(),
        "organs",
        &scene_file.path,
        "openhaptics",
    );
    let (mut tap, writer) = lop_daemon::record::start(&dir.join("rt.lrec"), &header).unwrap();
    let running = AtomicBool::new(true);
    let mut contact_ticks = 0u64;
    let run = std::thread::scope(|scope| {
        let servo = scope.spawn(|| {
            let task = ServoTask::new(
                &names,
                settings,
                None,
                &STOP,
                None,
                tool_tx,
                tel_tx,
                Some(&mut tap),
            );
            let mut cell = SendTask(task);
            let cell_ref = &mut cell;
            let run = device.run_clocked(&mut |d, c| cell_ref.call(d, c)).unwrap();
            running.store(false, Ordering::Release);
            let summary = cell.0.summary(run).unwrap();
            (run, summary)
        });
        let mut seq = 0;
        while running.load(Ordering::Acquire) {
            // The loop subscribes in its first servo callback: repeat the topology for a while
            // so it cannot miss it.
            if seq < 100 {
                publish_topology();
            }
            seq += 1;
            publish_frame(seq);
            while let Ok(t) = tool_rx.pop() {
                if t.flags & TOOL_FLAG_CONTACT != 0 {
                    contact_ticks += 1;
                }
            }
            while tel_rx.pop().is_some() {}
            std::thread::sleep(std::time::Duration::from_millis(10));
        }
        servo.join().unwrap()
    });
    device.stop();
    let records = writer.finish().unwrap();
    let (run, summary) = run;
    let allocations = alloc::allocations();
    assert_eq!(run.end, ServoEnd::Requested);
    assert!(summary.ticks >= COUNT_UNTIL - 1, "{summary:?}");
    assert!(records >= COUNT_UNTIL - 1, "{records} records");
    assert!(
        contact_ticks > 500,
        "the poke must exercise the contact path ({contact_ticks})"
    );
    assert_eq!(
        allocations, 0,
        "heap allocations on the servo thread after the first callback"
    );
    // The counter does see allocations (the test can fail).
    alloc::counted(|| std::hint::black_box(vec![1u8; 16]));
    assert!(alloc::allocations() > 0);
    let _ = std::fs::remove_dir_all(&dir);
}
