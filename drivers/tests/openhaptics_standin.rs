//! The `openhaptics` driver end to end against the stand-in libHD (`drivers/standin-hd`): the
//! library is loaded at run time, the device comes up with the library's limits, the servo
//! callback runs the tick on the library's 1 kHz scheduler thread, errors are classified
//! (a force error keeps the loop going, a communication error stops it), and the force the
//! device renders last — at the end of the run and before every `hdUnschedule`,
//! `hdStopScheduler` and `hdDisableDevice` — is exactly zero.
//!
//! The servo path allocates nothing after the first tick: a counting allocator counts every
//! allocation our code makes on the scheduler thread from tick 100 on (the stand-in is a
//! separate shared library with its own allocator, standing for the vendor's code).
//!
//! The stand-in is one process-wide library, so the scenarios run in sequence in one test
//! (several named devices on one scheduler: `openhaptics_two_devices.rs`).

#[path = "../standin-hd/testing.rs"]
mod standin;

use std::path::Path;

use lop_drivers::openhaptics::OpenHapticsDevice;
use lop_drivers::{DeviceError, DeviceOpenError, HapticDevice, Pacing, ServoControl, ServoEnd};
use lop_test_support::alloc::{self, Counting};
use lop_test_support::fixtures::temp_dir;
use lop_test_support::vec3::norm;
use standin::{assert_safe_exit, logs_in, read_log, standin_library, StandinEvent};

#[global_allocator]
static A: Counting = Counting::armed_threads();

/// y of the trajectory at servo tick `k`: from 40 mm down to 0 mm over 2 s, then held.
fn traj_y(k: u64) -> f64 {
    40.0 - 40.0 * (k.min(2000) as f64 / 2000.0)
}

fn setup(dir: &Path, errors: &str) {
    let traj = dir.join("trajectory.csv");
    let mut text = String::from("# x,y,z,buttons\n");
    for k in 0..=3000 {
        text.push_str(&format!(
            "1.5,{},-2.0,{}\n",
            traj_y(k),
            if k >= 1000 { 1 } else { 0 }
        ));
    }
    std::fs::write(&traj, text).unwrap();
    let logs = dir.join("logs");
    let _ = std::fs::remove_dir_all(&logs);
    std::fs::create_dir_all(&logs).unwrap();
    // SAFETY (env writes): this test is the only one in its process and sets the variables
    // before any thread reads them (the stand-in reads them at hdInitDevice).
    unsafe {
        std::env::set_var("LOP_HD_LIBRARY", standin_library());
        std::env::set_var("LOP_STANDIN_TRAJECTORY", &traj);
        std::env::set_var("LOP_STANDIN_ERRORS", errors);
        std::env::set_var("LOP_STANDIN_LOG_DIR", &logs);
    }
}

fn session_log(dir: &Path) -> Vec<StandinEvent> {
    let files = logs_in(&dir.join("logs"));
    assert_eq!(files.len(), 1, "one device session: {files:?}");
    read_log(&files[0])
}

#[test]
fn openhaptics_driver_against_the_standin() {
    let dir = temp_dir("lop-oh-standin");

    // 1. A run with a force error at tick 500 and a communication error at tick 1500.
    setup(&dir, "500:0x0201,1500:0x0302");
    let mut device = OpenHapticsDevice::open(None, None).expect("the stand-in loads");
    assert_eq!(device.pacing(), Pacing::DeviceClock);
    assert_eq!(device.library_path(), standin_library());
    device.start().expect("device up");
    let limits = device.limits();
    assert_eq!(limits.max_force_n, 3.3);
    assert_eq!(limits.max_continuous_force_n, 0.88);
    assert_eq!(limits.max_stiffness_n_per_mm, 0.7);
    assert_eq!(limits.workspace_min_mm, [-80.0, -60.0, -35.0]);
    assert_eq!(limits.workspace_max_mm, [80.0, 60.0, 35.0]);
    assert!(device.model().unwrap().contains("stand-in"));
    // Outside the servo loop, a read goes through a synchronous scheduler call.
    let s = device.read(0.0).expect("synchronous read");
    assert_eq!(s.position_mm[0], 1.5);

    let mut reads = 0u64;
    let mut mismatches = 0u64;
    let mut recoverable = Vec::with_capacity(8);
    let mut fatal = Vec::with_capacity(8);
    let mut refused_nan = false;
    let mut rendered = 0u64;
    let run = device
        .run_clocked(&mut |devices, clock| {
            let dev = &mut *devices[0];
            if clock.tick == 100 {
                alloc::reset();
                alloc::arm();
            }
            let y = match dev.read(clock.tick as f64 * 1e-3) {
                Ok(s) => {
                    reads += 1;
                    // Contact below y = 20 mm: a spring of 0.1 N/mm pushing up (plus 0.2 N).
                    if s.position_mm[0] != 1.5 || s.position_mm[2] != -2.0 {
                        mismatches += 1;
                    }
                    s.position_mm[1]
                }
                Err(e) if e.is_recoverable() => {
                    recoverable.push((clock.tick, e));
                    40.0
                }
                Err(e) => {
                    fatal.push((clock.tick, e));
                    // Keep going on purpose: the driver must stop the run itself.
                    return ServoControl::Continue;
                }
            };
            let force = if clock.tick == 700 {
                [0.0, 9.0, 0.0] // above the device's 3.3 N: the driver clamps
            } else if clock.tick == 800 {
                [f64::NAN, 0.0, 0.0]
            } else {
                [0.0, 0.2 + (20.0 - y).max(0.0) * 0.1, 0.0]
            };
            match dev.write_force(force) {
                Ok(()) => rendered += 1,
                Err(DeviceError::NonFiniteForce) => refused_nan = true,
                Err(_) => {}
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
    assert_eq!(fatal.len(), 1, "the tick saw the communication error once");
    assert!((1490..=1502).contains(&fatal[0].0), "{fatal:?}");
    assert_eq!(recoverable.len(), 1, "{recoverable:?}");
    assert_eq!(recoverable[0].1, DeviceError::ForceLimitExceeded);
    assert!(
        reads > 1300 && run.ticks > 1400,
        "reads {reads}, ticks {}",
        run.ticks
    );
    assert_eq!(mismatches, 0);
    assert!(refused_nan);
    assert_eq!(
        allocations, 0,
        "allocations on the servo thread after warm-up"
    );
    let stats = device.stats();
    assert_eq!(stats.clamped_forces, 1);
    assert_eq!(stats.non_finite_forces, 1);
    assert_eq!(stats.recoverable_errors, 1);
    device.stop();
    let log = session_log(&dir);
    assert_safe_exit(&log, "session");
    let frames: Vec<&StandinEvent> = log.iter().filter(|e| e.event == "frame").collect();
    let max = frames.iter().map(|e| norm(e.force)).fold(0.0, f64::max);
    assert!(
        (max - 3.3).abs() < 1e-9,
        "the 9 N request rendered clamped to 3.3 N, max rendered {max}"
    );
    // Contact force felt after the recoverable error (the loop kept going).
    let after = frames
        .iter()
        .filter(|e| e.tick > 1100 && e.tick < 1490)
        .map(|e| e.force[1])
        .fold(0.0, f64::max);
    let expect = 0.2 + (20.0 - traj_y(1489)) * 0.1;
    assert!(
        (after - expect).abs() < 0.02,
        "force {after} N, expected about {expect} N"
    );
    // The NaN tick, and only it, rendered zero while running.
    let zero = frames
        .iter()
        .filter(|e| e.tick > 100 && e.tick < 1490 && e.force == [0.0; 3])
        .count();
    assert_eq!(zero, 1, "frames with zero force while running");

    // 2. A requested stop and a restart of the same device object.
    setup(&dir, "");
    device.start().expect("restart");
    let run = device
        .run_clocked(&mut |devices, clock| {
            let _ = devices[0].read(0.0);
            let _ = devices[0].write_force([0.5, 0.0, 0.0]);
            if clock.tick >= 300 {
                ServoControl::Stop
            } else {
                ServoControl::Continue
            }
        })
        .unwrap();
    assert_eq!(run.end, ServoEnd::Requested);
    assert_eq!(run.ticks, 301);
    drop(device); // drop stops the device
    let log = session_log(&dir);
    assert_safe_exit(&log, "session");
    assert!(log
        .iter()
        .any(|e| e.event == "frame" && e.force == [0.5, 0.0, 0.0]));

    // 3. A panic in the tick: zero force in that frame, the run ends, nothing unwinds into C.
    // (The panic is expected: keep its message out of the test output.)
    let default_hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    setup(&dir, "");
    let mut device = OpenHapticsDevice::open(None, None).unwrap();
    device.start().unwrap();
    let run = device
        .run_clocked(&mut |devices, clock| {
            let _ = devices[0].write_force([0.0, 1.0, 0.0]);
            if clock.tick == 50 {
                panic!("a bug in the tick");
            }
            ServoControl::Continue
        })
        .unwrap();
    std::panic::set_hook(default_hook);
    assert_eq!(run.end, ServoEnd::Panicked);
    device.stop();
    assert_safe_exit(&session_log(&dir), "session");

    // 4. An unknown device name is a clear start error, and nothing is left running.
    setup(&dir, "");
    let mut device = OpenHapticsDevice::open(Some("NoSuchOmni"), None).unwrap();
    let e = device.start().unwrap_err();
    let text = e.to_string();
    assert!(matches!(e, DeviceOpenError::Start { .. }), "{text}");
    assert!(
        text.contains("NoSuchOmni") && text.contains("HD_DEVICE_FAULT"),
        "{text}"
    );
    assert_eq!(device.read(0.0), Err(DeviceError::NotStarted));
    drop(device);

    // 5. A named device the library knows.
    let mut device = OpenHapticsDevice::open(Some("Omni"), None).unwrap();
    device.start().unwrap();
    device.stop();

    let _ = std::fs::remove_dir_all(&dir);
}
