//! The `forcedimension` driver end to end against the stand-in DHD library
//! (`drivers/standin-dhd`), loaded at run time through the daemon config's path argument.
//!
//! Invariants guarded:
//! - devices are opened by the SDK's index, whatever ID the SDK hands out: with two devices each
//!   driver reads its own device and each device receives only its own driver's forces;
//! - DHD's frame and metres map to lop's (mm, +x right, +y up, +z toward the user) and forces
//!   map back, so pushing up in lop pushes up on the device;
//! - the last force a device received is exactly zero once the driver stops or is dropped,
//!   and it was zero when the motors were disabled; `stop` is idempotent;
//! - a DHD error maps to the right `DeviceError` (communication vs fault); a non-finite force
//!   is refused with zero sent; a force above the device's figure is scaled to it;
//! - a missing library, one of another SDK major version, a device index the SDK does not
//!   have, a device opened twice: each a clear error naming what was tried and found;
//! - `read` and `write_force` allocate nothing (a counting allocator counts this thread; the
//!   stand-in is a separate shared library with its own allocator, standing for the vendor's).
//!
//! The stand-in is process-wide state: the tests take one lock and reset it first.

#[path = "../standin-dhd/testing.rs"]
mod standin_dhd;

use std::path::PathBuf;
use std::sync::{Mutex, MutexGuard};

use lop_drivers::forcedimension::{ForceDimensionDevice, LIBRARY_ENV};
use lop_drivers::{DeviceError, DeviceOpenError, HapticDevice, Pacing, BUTTON_GRAB, BUTTON_HEAT};
use lop_test_support::alloc::{self, Counting, Counts};
use standin_dhd::{standin_library, Controls};

#[global_allocator]
static A: Counting = Counting::armed_threads();

/// The stand-in, reset to `count` devices, held for the test's length.
fn standin(count: usize) -> (MutexGuard<'static, ()>, Controls, PathBuf) {
    static LOCK: Mutex<()> = Mutex::new(());
    let guard = LOCK.lock().unwrap_or_else(|p| p.into_inner());
    assert!(
        std::env::var_os(LIBRARY_ENV).is_none(),
        "unset {LIBRARY_ENV}: it would replace the stand-in these tests load"
    );
    let lib = standin_library();
    let controls = Controls::open(&lib);
    controls.reset(count);
    (guard, controls, lib)
}

fn started(index: u8, lib: &std::path::Path) -> ForceDimensionDevice {
    let mut d = ForceDimensionDevice::open(Some(index), Some(lib)).expect("the stand-in loads");
    d.start().expect("device up");
    d
}

#[test]
fn two_devices_each_read_their_own_and_receive_only_their_own_force() {
    let (_g, ctl, lib) = standin(2);
    ctl.set_motion(0, [0.010, 0.020, 0.030], [0.1, 0.0, 0.0]);
    ctl.set_motion(1, [-0.010, 0.0, 0.005], [0.0, -0.2, 0.0]);
    ctl.set_buttons(0, 0b101);
    ctl.set_buttons(1, 0b010);
    // Index 1 opens first, so the SDK hands it ID 0: IDs are not indices.
    let mut right = started(1, &lib);
    let mut left = started(0, &lib);
    assert_eq!(left.pacing(), Pacing::SelfPaced);
    assert_eq!(right.serial(), Some(1001));
    assert!(left.name().contains("dhd:0") && left.name().contains("omega.3"));
    let limits = left.limits();
    assert_eq!(limits.max_force_n, 12.0);
    assert_eq!(limits.workspace_max_mm, [75.0; 3]);

    // DHD (x toward the user, y right, z up) in m → lop (x right, y up, z toward the user) in mm.
    let l = left.read(0.0).unwrap();
    let r = right.read(0.0).unwrap();
    assert_eq!(l.position_mm, [20.0, 30.0, 10.0]);
    assert_eq!(r.position_mm, [0.0, 5.0, -10.0]);
    assert_eq!(l.buttons, BUTTON_GRAB, "button 2 is not one of lop's");
    assert_eq!(r.buttons, BUTTON_HEAT);
    // The SDK's velocity estimator needs history: the first velocity is zero, then mapped.
    assert_eq!(l.velocity_mm_s, [0.0; 3]);
    assert_eq!(left.stats().velocity_unavailable, 1);
    assert_eq!(left.read(0.001).unwrap().velocity_mm_s, [0.0, 0.0, 100.0]);
    assert_eq!(right.read(0.001).unwrap().velocity_mm_s, [-200.0, 0.0, 0.0]);

    let before = ctl.device(1).force_writes;
    left.write_force([1.0, 0.0, 0.0]).unwrap(); // lop right = DHD +y
    assert_eq!(ctl.device(0).force, [0.0, 1.0, 0.0]);
    assert_eq!(
        ctl.device(1).force_writes,
        before,
        "device 1 got device 0's force"
    );
    right.write_force([0.0, 0.0, 2.0]).unwrap(); // lop toward the user = DHD +x
    right.write_force([0.0, 3.0, 0.0]).unwrap(); // lop up = DHD +z
    assert_eq!(ctl.device(1).force, [0.0, 0.0, 3.0]);
    assert_eq!(
        ctl.device(0).force,
        [0.0, 1.0, 0.0],
        "device 0 got device 1's force"
    );
    assert_eq!(ctl.device(1).force_writes, before + 2);

    // One driver per device in a process.
    let mut twice = ForceDimensionDevice::open(Some(0), Some(&lib)).unwrap();
    let e = twice.start().unwrap_err().to_string();
    assert!(e.contains("already driven") && e.contains("dhd:0"), "{e}");
    drop(twice);
    assert!(
        ctl.device(0).open,
        "the refused second driver closed the first's device"
    );

    left.stop();
    assert!(!ctl.device(0).open);
    assert!(ctl.device(1).open, "stopping device 0 closed device 1");
    right.write_force([0.0, 1.0, 0.0]).unwrap();
    assert_eq!(ctl.device(1).force, [0.0, 0.0, 1.0]);
}

#[test]
fn stop_and_drop_leave_zero_force_and_the_motors_off() {
    let (_g, ctl, lib) = standin(1);
    let mut d = started(0, &lib);
    assert!(ctl.device(0).force_enabled);
    d.write_force([0.5, 2.0, -1.0]).unwrap();
    assert_eq!(ctl.device(0).force, [-1.0, 0.5, 2.0]);
    d.stop();
    let s = ctl.device(0);
    assert!(!s.open && !s.force_enabled, "{s:?}");
    assert_eq!(s.force, [0.0; 3]);
    assert_eq!(
        s.force_at_disable,
        Some([0.0; 3]),
        "motors disabled with a force set"
    );
    assert_eq!(s.force_at_close, Some([0.0; 3]));
    assert_eq!(s.closes, 1);
    d.stop();
    assert_eq!(ctl.device(0).closes, 1, "stop is idempotent");
    assert_eq!(d.read(0.0), Err(DeviceError::Stopped));
    assert_eq!(d.write_force([0.0; 3]), Err(DeviceError::Stopped));

    // The same driver starts again, and dropping it stops it.
    d.start().unwrap();
    d.write_force([0.0, 1.5, 0.0]).unwrap();
    assert_eq!(ctl.device(0).force, [0.0, 0.0, 1.5]);
    drop(d);
    let s = ctl.device(0);
    assert!(!s.open, "{s:?}");
    assert_eq!(s.force_at_disable, Some([0.0; 3]));
    assert_eq!(s.force_at_close, Some([0.0; 3]));
    assert_eq!(s.closes, 2);

    // Never started: nothing to read, and nothing opened.
    let mut idle = ForceDimensionDevice::open(None, Some(&lib)).unwrap();
    assert_eq!(idle.read(0.0), Err(DeviceError::NotStarted));
    idle.stop();
    assert_eq!(ctl.device(0).closes, 2);
}

#[test]
fn errors_map_to_device_errors_and_bad_forces_never_reach_the_device() {
    let (_g, ctl, lib) = standin(1);
    let mut d = started(0, &lib);
    ctl.inject_error(0, 2, 1); // DHD_ERROR_COM
    assert_eq!(d.read(0.0), Err(DeviceError::Communication));
    assert_eq!(d.stats().last_error_code, 2);
    assert!(d.read(0.0).is_ok(), "the link came back");
    ctl.inject_error(0, 19, 1); // DHD_ERROR_NOT_ENABLED: forces off by the device's safety
    assert_eq!(d.write_force([0.0, 1.0, 0.0]), Err(DeviceError::Fault));
    assert_eq!(d.stats().last_error_code, 19);

    d.write_force([0.0, 1.0, 0.0]).unwrap();
    assert_eq!(
        d.write_force([f64::NAN, 1.0, 0.0]),
        Err(DeviceError::NonFiniteForce)
    );
    assert_eq!(ctl.device(0).force, [0.0; 3], "zero sent instead of NaN");
    d.write_force([0.0, 30.0, 40.0]).unwrap(); // 50 N against the omega.3's 12 N
    let f = ctl.device(0).force;
    assert!(
        (f[0] - 12.0 * 0.8).abs() < 1e-12 && (f[2] - 12.0 * 0.6).abs() < 1e-12,
        "{f:?}"
    );
    let stats = d.stats();
    assert_eq!((stats.clamped_forces, stats.non_finite_forces), (1, 1));
    assert_eq!(
        stats.saturated_forces, 0,
        "lop clamps before the SDK has to"
    );
}

#[test]
fn start_errors_name_what_was_found() {
    let (_g, ctl, lib) = standin(2);
    let mut d = ForceDimensionDevice::open(Some(5), Some(&lib)).unwrap();
    let e = d.start().unwrap_err();
    let text = e.to_string();
    assert!(matches!(e, DeviceOpenError::Start { .. }), "{text}");
    assert!(
        text.contains("dhd:5") && text.contains("index 5") && text.contains("indices 0 to 1"),
        "{text}"
    );
    ctl.reset(0);
    let text = ForceDimensionDevice::open(None, Some(&lib))
        .unwrap()
        .start()
        .unwrap_err()
        .to_string();
    assert!(
        text.contains("sees 0") && text.contains("lopd doctor"),
        "{text}"
    );

    // The motors refuse to come on: a clear error, and the device is closed again.
    ctl.reset(1);
    let mut d = ForceDimensionDevice::open(Some(0), Some(&lib)).unwrap();
    ctl.inject_error(0, 20, 2); // DHD_ERROR_DEVICE_IN_USE on the zero force and the enable
    let text = d.start().unwrap_err().to_string();
    assert!(
        text.contains("dhdEnableForce") && text.contains("DHD_ERROR_DEVICE_IN_USE"),
        "{text}"
    );
    assert!(!ctl.device(0).open);
    assert_eq!(d.read(0.0), Err(DeviceError::NotStarted));
    d.start()
        .expect("the index is free again after the failed start");
}

#[test]
fn a_missing_or_wrong_library_is_a_clear_error() {
    let (_g, _ctl, lib) = standin(1);
    let missing = PathBuf::from("/nonexistent/lop-test/libdhd.so");
    let e = ForceDimensionDevice::open(Some(1), Some(&missing)).unwrap_err();
    let text = e.to_string();
    assert!(matches!(e, DeviceOpenError::Unavailable { .. }), "{text}");
    assert!(
        text.contains("/nonexistent/lop-test/libdhd.so") && text.contains("LOP_DHD_LIBRARY"),
        "{text}"
    );
    let e = ForceDimensionDevice::discover(Some(&missing)).unwrap_err();
    assert!(e.to_string().contains("dhd_library"), "{e}");

    // A library of another SDK major version (a copy of the stand-in: its own state).
    let copy = lib.with_file_name("libdhd-v4.so");
    std::fs::copy(&lib, &copy).unwrap();
    Controls::open(&copy).set_version([4, 0, 1, 7]);
    let text = ForceDimensionDevice::open(None, Some(&copy))
        .unwrap_err()
        .to_string();
    assert!(
        text.contains("SDK 4.0.1-7") && text.contains("3.x") && text.contains("libdhd-v4.so"),
        "{text}"
    );
    // Not a DHD library at all.
    let text = ForceDimensionDevice::open(None, Some(std::path::Path::new("libc.so.6")))
        .unwrap_err()
        .to_string();
    assert!(text.contains("libc.so.6"), "{text}");
}

#[test]
fn discovery_lists_every_device() {
    let (_g, ctl, lib) = standin(3);
    let found = ForceDimensionDevice::discover(Some(&lib)).unwrap();
    assert_eq!(found.library, lib);
    assert_eq!(found.sdk_version, "3.17.6-0");
    assert_eq!(found.devices.len(), 3);
    for (i, d) in found.devices.iter().enumerate() {
        assert_eq!(d.index as usize, i);
        assert_eq!(d.system_type, Ok(33));
        assert_eq!(d.serial, Some(1000 + i as u16));
        assert_eq!(d.model, Some("omega.3"));
        assert!(d.system_name.as_deref().unwrap().contains("omega.3"));
        let s = ctl.device(i);
        assert!(!s.open && !s.force_enabled && s.force_writes == 0, "{s:?}");
    }
}

/// The loop's RT path as the haptic loop drives it: `read`, `write_force`, refused forces, an
/// injected error, then `stop`: no allocation on this thread.
#[test]
fn reads_and_writes_allocate_nothing() {
    let (_g, ctl, lib) = standin(1);
    let mut d = started(0, &lib);
    let run = |d: &mut ForceDimensionDevice, ticks: u64| {
        let mut errors = 0u64;
        for tick in 0..ticks {
            if tick == ticks / 2 + 1 {
                ctl.inject_error(0, 2, 1);
            }
            let force = match d.read(tick as f64 * 1e-3) {
                Ok(s) if tick % 1000 == 999 => [f64::NAN, s.position_mm[1], 0.0],
                Ok(s) if tick % 1000 == 500 => [0.0, 50.0, s.position_mm[2]],
                Ok(s) => [0.0, (30.0 - s.position_mm[1]).max(0.0) * 0.1, 0.0],
                Err(_) => {
                    errors += 1;
                    [0.0; 3]
                }
            };
            if d.write_force(force).is_err() {
                errors += 1;
            }
        }
        errors
    };
    run(&mut d, 100); // warm-up
    let mut errors = 0;
    let Counts { allocations, bytes } = alloc::this_thread(|| errors = run(&mut d, 10_000));
    assert_eq!((allocations, bytes), (0, 0), "the RT path allocated");
    assert_eq!(
        errors,
        1 + 10,
        "one injected error and ten refused NaN forces"
    );
    assert_eq!(d.stats().clamped_forces, 10);
    let Counts { allocations, .. } = alloc::this_thread(|| d.stop());
    assert_eq!(allocations, 0, "stop allocated");
    assert_eq!(ctl.device(0).force_at_close, Some([0.0; 3]));
    // The counter does count.
    let c = alloc::this_thread(|| drop(std::hint::black_box(vec![0u8; 64])));
    assert_eq!((c.allocations, c.bytes), (1, 64));
}
