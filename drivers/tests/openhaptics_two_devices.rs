//! Two OpenHaptics devices by their configured names on the library's one scheduler, against
//! the stand-in libHD serving the named devices `Left` and `Right`
//! (`LOP_STANDIN_DEVICE_NAMES`), each playing its own trajectory.
//!
//! Invariants guarded:
//! - each device is initialised by its name and reads its own position; each renders the
//!   force written to it, not the other's (every state call applies to the current device, so
//!   a read or write that did not make its device current would land on the other);
//! - every servo tick begins and ends each device's frame exactly once, in pairs
//!   (no `HD_ILLEGAL_BEGIN`/`END`, no force set outside a frame);
//! - an error the library reports for one device is that device's: a force error on `Right`
//!   fails only `Right`'s read (the loop goes on), a communication error on `Right` ends the
//!   run with zero force on both devices in that last frame;
//! - a requested stop and `stop` leave zero force on every device, rendered at every release
//!   step (`hdUnschedule`, `hdStopScheduler`, `hdDisable`, `hdDisableDevice`);
//! - the servo path of two devices allocates nothing after warm-up;
//! - an unknown name is a start error naming it, and the device started before it is released;
//!   a name given twice is refused before the library is touched.

#[path = "../standin-hd/testing.rs"]
mod standin;

use std::path::Path;

use lop_drivers::openhaptics::{OpenHapticsDevice, OpenHapticsScheduler};
use lop_drivers::{DeviceError, DeviceOpenError, HapticDevice, ServoControl, ServoEnd};
use lop_test_support::alloc::{self, Counting};
use lop_test_support::fixtures::temp_dir;
use standin::{
    assert_frames_paired, assert_safe_exit, logs_in, logs_of, read_log, standin_library,
    StandinEvent,
};

#[global_allocator]
static A: Counting = Counting::armed_threads();

const NAMES: [&str; 2] = ["Left", "Right"];
/// Where each device's stylus rests, mm.
const POSITIONS: [[f64; 3]; 2] = [[-20.0, 5.0, 0.0], [20.0, -5.0, 0.0]];

/// The force the tick writes to device `k` at `position_mm`, N: from its own reading, and
/// different per device.
fn force_for(k: usize, position_mm: [f64; 3]) -> [f64; 3] {
    [-0.01 * position_mm[0], 0.3 + 0.3 * k as f64, 0.0]
}

fn setup(dir: &Path, errors: &str) {
    let logs = dir.join("logs");
    let _ = std::fs::remove_dir_all(&logs);
    std::fs::create_dir_all(&logs).unwrap();
    // SAFETY (env writes): this test is the only one in its process and sets the variables
    // before any thread reads them (the stand-in reads them at hdInitDevice).
    unsafe {
        std::env::set_var("LOP_HD_LIBRARY", standin_library());
        std::env::set_var("LOP_STANDIN_DEVICE_NAMES", NAMES.join(","));
        std::env::set_var("LOP_STANDIN_ERRORS", errors);
        std::env::set_var("LOP_STANDIN_LOG_DIR", &logs);
        std::env::remove_var("LOP_STANDIN_TRAJECTORY");
    }
    for (name, p) in NAMES.iter().zip(POSITIONS) {
        let path = dir.join(format!("{name}.csv"));
        std::fs::write(&path, format!("{},{},{}\n", p[0], p[1], p[2])).unwrap();
        // SAFETY: as above.
        unsafe { std::env::set_var(format!("LOP_STANDIN_TRAJECTORY_{name}"), &path) };
    }
}

/// Each device's log of the one session in `dir`.
fn session_logs(dir: &Path) -> [Vec<StandinEvent>; 2] {
    NAMES.map(|name| {
        let files = logs_of(&dir.join("logs"), name);
        assert_eq!(files.len(), 1, "{name}: one session: {files:?}");
        read_log(&files[0])
    })
}

#[test]
fn two_named_devices_on_one_scheduler() {
    let dir = temp_dir("lop-oh-two");

    // 1. A run with a force error and then a communication error on Right only.
    setup(&dir, "600:0x0201@Right,1500:0x0302@Right");
    let mut left = OpenHapticsDevice::open(Some("Left"), None).expect("the stand-in loads");
    let mut right = OpenHapticsDevice::open(Some("Right"), None).unwrap();
    let mut scheduler = OpenHapticsScheduler::new();
    scheduler
        .start(&mut [&mut left, &mut right])
        .expect("both devices up");
    assert!(scheduler.is_running());
    for d in [&left, &right] {
        assert_eq!(d.limits().max_force_n, 3.3, "{}", d.label());
        assert!(d.name().contains(d.label()), "{}", d.name());
    }

    let mut mismatches = [0u64; 2];
    let mut recoverable = Vec::with_capacity(8);
    let mut fatal = Vec::with_capacity(8);
    let run = scheduler
        .run_clocked(&mut [&mut left, &mut right], &mut |devices, clock| {
            assert_eq!(devices.len(), 2);
            if clock.tick == 100 {
                alloc::reset();
                alloc::arm();
            }
            // As the haptic loop does: every device read, then every device written.
            let mut forces = [[0.0; 3]; 2];
            for (k, device) in devices.iter_mut().enumerate() {
                match device.read(clock.tick as f64 * 1e-3) {
                    Ok(s) => {
                        if s.position_mm != POSITIONS[k] {
                            mismatches[k] += 1;
                        }
                        forces[k] = force_for(k, s.position_mm);
                    }
                    Err(e) if e.is_recoverable() => recoverable.push((k, clock.tick, e)),
                    Err(e) => {
                        // Keep going on purpose: the driver must stop the run itself.
                        fatal.push((k, clock.tick, e));
                    }
                }
            }
            for (device, force) in devices.iter_mut().zip(forces) {
                let _ = device.write_force(force);
            }
            ServoControl::Continue
        })
        .expect("servo run");
    alloc::disarm();
    let allocations = alloc::allocations();
    assert_eq!(
        run.end,
        ServoEnd::Device(DeviceError::Communication),
        "{run:?}"
    );
    assert_eq!(mismatches, [0, 0], "each device reads its own position");
    assert_eq!(recoverable.len(), 1, "{recoverable:?}");
    assert_eq!(
        (recoverable[0].0, recoverable[0].2),
        (1, DeviceError::ForceLimitExceeded),
        "the force error is Right's alone"
    );
    assert_eq!(fatal.len(), 1, "{fatal:?}");
    assert_eq!((fatal[0].0, fatal[0].2), (1, DeviceError::Communication));
    assert!((1490..=1502).contains(&fatal[0].1), "{fatal:?}");
    assert_eq!(
        allocations, 0,
        "allocations on the servo thread after warm-up"
    );
    assert_eq!(left.stats().recoverable_errors, 0);
    assert_eq!(right.stats().recoverable_errors, 1);
    scheduler.stop(&mut [&mut left, &mut right]);
    assert!(!scheduler.is_running());

    let logs = session_logs(&dir);
    for (k, (log, name)) in logs.iter().zip(NAMES).enumerate() {
        assert_frames_paired(log, name);
        assert_safe_exit(log, name);
        // While running, each device rendered its own force; Right's force error tick alone
        // rendered zero.
        let running: Vec<&StandinEvent> = log
            .iter()
            .filter(|e| e.event == "frame" && e.tick > 100 && e.tick < 1490)
            .collect();
        assert!(running.len() > 1200, "{name}: {} frames", running.len());
        let own = force_for(k, POSITIONS[k]);
        let zero = running.iter().filter(|e| e.force == [0.0; 3]).count();
        let others = running
            .iter()
            .filter(|e| e.force != own && e.force != [0.0; 3])
            .count();
        assert_eq!(others, 0, "{name}: frames with a force not its own");
        assert_eq!(zero, k, "{name}: frames with zero force while running");
    }
    // One frame of each device per servo tick.
    let frames = |log: &[StandinEvent]| log.iter().filter(|e| e.event == "frame").count();
    assert_eq!(frames(&logs[0]), frames(&logs[1]));

    // 2. A requested stop, then `stop`: zero force on both.
    setup(&dir, "");
    scheduler.start(&mut [&mut left, &mut right]).unwrap();
    let run = scheduler
        .run_clocked(&mut [&mut left, &mut right], &mut |devices, clock| {
            for (k, device) in devices.iter_mut().enumerate() {
                let _ = device.read(0.0);
                let _ = device.write_force(force_for(k, POSITIONS[k]));
            }
            if clock.tick >= 300 {
                ServoControl::Stop
            } else {
                ServoControl::Continue
            }
        })
        .unwrap();
    assert_eq!(run.end, ServoEnd::Requested);
    assert_eq!(run.ticks, 301);
    scheduler.stop(&mut [&mut left, &mut right]);
    for (k, (log, name)) in session_logs(&dir).iter().zip(NAMES).enumerate() {
        assert_frames_paired(log, name);
        assert_safe_exit(log, name);
        let own = force_for(k, POSITIONS[k]);
        assert!(
            log.iter().any(|e| e.event == "frame" && e.force == own),
            "{name}: its force was never rendered"
        );
    }
    assert_eq!(left.read(0.0), Err(DeviceError::NotStarted));

    // 3. An unknown name: a start error naming it; Left, started first, is released and the
    // scheduler never started.
    setup(&dir, "");
    let mut unknown = OpenHapticsDevice::open(Some("NoSuchOmni"), None).unwrap();
    let e = scheduler.start(&mut [&mut left, &mut unknown]).unwrap_err();
    let text = e.to_string();
    assert!(matches!(e, DeviceOpenError::Start { .. }), "{text}");
    assert!(
        text.contains("NoSuchOmni") && text.contains("HD_DEVICE_FAULT"),
        "{text}"
    );
    assert!(!scheduler.is_running());
    assert_eq!(left.read(0.0), Err(DeviceError::NotStarted));
    let files = logs_in(&dir.join("logs"));
    assert_eq!(files.len(), 1, "only Left was initialised: {files:?}");
    let log = read_log(&files[0]);
    assert!(log.iter().any(|e| e.event == "disable_device"));
    assert!(!log.iter().any(|e| e.event == "frame"));

    // 4. One name twice: refused before the library is touched.
    let mut again = OpenHapticsDevice::open(Some("Left"), None).unwrap();
    let text = scheduler
        .start(&mut [&mut left, &mut again])
        .unwrap_err()
        .to_string();
    assert!(
        text.contains("openhaptics:Left") && text.contains("named twice"),
        "{text}"
    );
    assert_eq!(logs_in(&dir.join("logs")).len(), 1);

    // 5. The devices still start alone (each on a scheduler of its own).
    right.start().unwrap();
    right.stop();

    let _ = std::fs::remove_dir_all(&dir);
}
