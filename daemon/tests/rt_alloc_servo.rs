//! Real time on the devices' clock: the OpenHaptics path (driver servo callback → `ServoTask`
//! → `HapticLoop::tick`) allocates nothing after its first callback — with one device and
//! `--record`'s tap, and with two named devices on the library's one scheduler driving the two
//! tools of a scene.
//!
//! The devices are the stand-in libHD's (`drivers/standin-hd`) playing the organs poke at
//! 1 kHz on its own scheduler thread; this test plays the deformation side (topology once, a
//! frame every 10 ms). Every allocation our code makes on the scheduler thread from servo tick
//! 200 to 5200 is counted — the driver's callback wrapper, the frames of every device, the
//! error checks, the tick, the ring pushes — and must be zero. (The stand-in's own allocations
//! go through its own allocator: they stand for the vendor's code.) The stand-in is one
//! process-wide library, so both runs are one test, in sequence.

#[path = "../../drivers/standin-hd/testing.rs"]
mod standin;

mod common;

use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};

use common::DeformSide;
use lop_config::{load_scene, resolve_scene, resolve_script, DaemonConfig, Scene};
use lop_daemon::haptic::{rings, HapticSettings, HapticSummary};
use lop_daemon::record::RecordTap;
use lop_daemon::servo::ServoTask;
use lop_drivers::mock::MockScript;
use lop_drivers::openhaptics::{OpenHapticsDevice, OpenHapticsScheduler};
use lop_drivers::{HapticDevice, ServoControl, ServoEnd, ServoRun};
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
// SAFETY: see above; the spawning thread does not touch the task while the devices run it.
unsafe impl Send for SendTask<'_> {}
impl SendTask<'_> {
    fn call(
        &mut self,
        d: &mut [&mut dyn HapticDevice],
        c: lop_drivers::ServoClock,
    ) -> ServoControl {
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

/// What one run gave.
struct Outcome {
    run: ServoRun,
    summary: HapticSummary,
    /// Ticks each tool pressed.
    contact_ticks: Vec<u64>,
    allocations: u64,
}

/// Runs the haptic loop of `scene_file` on `devices` (started on `scheduler`) until servo tick
/// `COUNT_UNTIL`, with the deformation side publishing, then stops the devices.
fn run(
    tag: &str,
    scene_file: &Scene,
    scheduler: &mut OpenHapticsScheduler,
    devices: &mut [&mut OpenHapticsDevice],
    record: Option<&mut RecordTap>,
) -> Outcome {
    STOP.store(false, Ordering::Relaxed);
    let prefix = format!("rtalloc-servo-{tag}-{}", std::process::id());
    let names = ServiceNames::new(&prefix).unwrap();
    let limits: Vec<_> = devices.iter().map(|d| d.limits()).collect();
    let settings = HapticSettings::for_devices(&DaemonConfig::default(), scene_file, &limits);
    let loaded = scene::load(scene_file.clone()).unwrap();
    let deform = DeformSide::new(&format!("{prefix}-deform"), &names, &loaded);
    let ((tool_tx, mut tool_rx), (tel_tx, mut tel_rx)) = rings(&settings).unwrap();
    let running = AtomicBool::new(true);
    let mut contact_ticks = vec![0u64; scene_file.tools.len()];
    let (run, summary) = std::thread::scope(|scope| {
        let servo = scope.spawn(|| {
            let task = ServoTask::new(&names, settings, None, &STOP, None, tool_tx, tel_tx, record);
            let mut cell = SendTask(task);
            let cell_ref = &mut cell;
            let run = scheduler
                .run_clocked(devices, &mut |d, c| cell_ref.call(d, c))
                .unwrap();
            running.store(false, Ordering::Release);
            let summary = cell.0.summary(run).unwrap();
            (run, summary)
        });
        let mut seq = 0;
        while running.load(Ordering::Acquire) {
            // The loop subscribes in its first servo callback: repeat the topology for a while
            // so it cannot miss it.
            if seq < 100 {
                deform.publish_topology();
            }
            seq += 1;
            deform.publish_frame(seq);
            while let Ok(t) = tool_rx.pop() {
                if t.flags & TOOL_FLAG_CONTACT != 0 {
                    contact_ticks[t.tool as usize] += 1;
                }
            }
            while tel_rx.pop().is_some() {}
            std::thread::sleep(std::time::Duration::from_millis(10));
        }
        servo.join().unwrap()
    });
    let allocations = alloc::allocations();
    scheduler.stop(devices);
    Outcome {
        run,
        summary,
        contact_ticks,
        allocations,
    }
}

fn assert_quiet(outcome: &Outcome, what: &str) {
    assert_eq!(outcome.run.end, ServoEnd::Requested, "{what}");
    assert!(
        outcome.summary.ticks >= COUNT_UNTIL - 1,
        "{what}: {:?}",
        outcome.summary
    );
    assert!(
        outcome.contact_ticks.iter().all(|&n| n > 500),
        "{what}: every tool must press, exercising the contact path: {:?}",
        outcome.contact_ticks
    );
    assert_eq!(
        outcome.allocations, 0,
        "{what}: heap allocations on the servo thread after the first callback"
    );
}

fn write_trajectory(path: &Path) {
    let script = MockScript::load(&resolve_script("organs-poke").unwrap()).unwrap();
    let mut text = String::new();
    for k in 0..8000 {
        let s = script.sample(k as f64 / 1000.0);
        let p = s.position_mm;
        text.push_str(&format!("{},{},{},{}\n", p[0], p[1], p[2], s.buttons));
    }
    std::fs::write(path, text).unwrap();
}

#[test]
fn servo_path_allocates_nothing_after_the_first_callback() {
    let dir = std::env::temp_dir().join(format!("lop-rtalloc-servo-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let trajectory = dir.join("trajectory.csv");
    write_trajectory(&trajectory);
    // SAFETY: the only test in this binary; set before any other thread runs.
    unsafe {
        std::env::set_var("LOP_HD_LIBRARY", standin::standin_library());
        std::env::set_var("LOP_STANDIN_TRAJECTORY", &trajectory);
        std::env::remove_var("LOP_STANDIN_ERRORS");
        std::env::remove_var("LOP_STANDIN_LOG_DIR");
        std::env::remove_var("LOP_STANDIN_DEVICE_NAMES");
    }
    let organs = load_scene(&resolve_scene("organs").unwrap()).unwrap();

    // 1. One device, its reads recorded.
    let mut device = OpenHapticsDevice::open(None, None).unwrap();
    let mut scheduler = OpenHapticsScheduler::new();
    scheduler.start(&mut [&mut device]).unwrap();
    let header = lop_daemon::record::header(
        1000.0,
        device.limits(),
        "organs",
        &organs.path,
        "openhaptics",
    );
    let (mut tap, writer) = lop_daemon::record::start(&dir.join("rt.lrec"), &header).unwrap();
    let one = run(
        "one",
        &organs,
        &mut scheduler,
        &mut [&mut device],
        Some(&mut tap),
    );
    let records = writer.finish().unwrap();
    assert_quiet(&one, "one device, recorded");
    assert!(records >= COUNT_UNTIL - 1, "{records} records");
    drop(device);

    // 2. Two named devices on one scheduler, the second tool 30 mm along the liver.
    // SAFETY: as above; no device of the stand-in is initialised now.
    unsafe { std::env::set_var("LOP_STANDIN_DEVICE_NAMES", "Left,Right") };
    let mut two_tools = organs.clone();
    let mut right_tool = two_tools.tool().clone();
    right_tool.name = "right".into();
    right_tool.workspace.offset[0] += 0.03;
    two_tools.tools.push(right_tool);
    let mut left = OpenHapticsDevice::open(Some("Left"), None).unwrap();
    let mut right = OpenHapticsDevice::open(Some("Right"), None).unwrap();
    let mut scheduler = OpenHapticsScheduler::new();
    scheduler.start(&mut [&mut left, &mut right]).unwrap();
    let two = run(
        "two",
        &two_tools,
        &mut scheduler,
        &mut [&mut left, &mut right],
        None,
    );
    assert_quiet(&two, "two named devices");
    assert_eq!(two.contact_ticks.len(), 2);

    // The counter does see allocations (the test can fail).
    alloc::counted(|| std::hint::black_box(vec![1u8; 16]));
    assert!(alloc::allocations() > 0);
    let _ = std::fs::remove_dir_all(&dir);
}
