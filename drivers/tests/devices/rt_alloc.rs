//! The mock's RT path allocates nothing: after construction and `start`, 10,000 `read` +
//! `write_force` calls (including refused forces, a loop wrap and ring wrap-around) allocate
//! zero bytes, proven by a counting global allocator.
//!
//! Only allocations made by the measuring thread while it measures are counted, so the test
//! harness's own threads cannot disturb the count.

use std::path::Path;

use lop_drivers::mock::{MockDevice, MockScript};
use lop_drivers::HapticDevice;
use lop_test_support::alloc::{self, Counts};

// The counting allocator (`Counting::armed_threads`) is installed once for this
// test binary, in `main.rs`.

/// Runs `f` with this thread's allocations counted; returns (allocations, bytes).
fn measure(f: impl FnOnce()) -> (u64, u64) {
    let Counts { allocations, bytes } = alloc::this_thread(f);
    (allocations, bytes)
}

const SCRIPT: &str = r#"
end = "loop"
[[waypoint]]
t = 0.0
position = [0.0, 40.0, 10.0]
[[waypoint]]
t = 1.0
position = [0.0, 20.0, 10.0]
buttons = ["grab"]
[[waypoint]]
t = 3.0
position = [10.0, 20.0, 10.0]
buttons = ["heat"]
[[waypoint]]
t = 4.0
position = [0.0, 40.0, 10.0]

[[fault]]
from = 6.0
until = 6.1
error = "communication"
"#;

/// One self-paced run of `ticks` ticks, as the haptic loop would drive the device.
fn run(device: &mut MockDevice, ticks: u64) {
    let mut errors = 0u64;
    for tick in 0..ticks {
        let t = tick as f64 * 1e-3;
        let force = match device.read(t) {
            Ok(sample) if tick % 1000 == 999 => [f64::NAN, sample.position_mm[1], 0.0],
            Ok(sample) => [0.0, (30.0 - sample.position_mm[1]).max(0.0) * 0.1, 0.0],
            Err(_) => {
                errors += 1;
                [0.0; 3]
            }
        };
        if device.write_force(force).is_err() {
            errors += 1;
        }
    }
    std::hint::black_box(errors);
}

#[test]
fn ten_thousand_reads_and_writes_allocate_nothing() {
    let script = MockScript::parse(SCRIPT, Path::new("rt-alloc.toml")).unwrap();
    for capacity in [lop_drivers::mock::FORCE_RECORD_CAPACITY, 1000] {
        let mut device =
            MockDevice::with_record_capacity(script.clone(), MockDevice::omni_limits(), capacity);
        device.start().unwrap();
        run(&mut device, 100); // warm-up

        let (allocations, bytes) = measure(|| run(&mut device, 10_000));
        assert_eq!(
            (allocations, bytes),
            (0, 0),
            "RT path allocated (ring capacity {capacity})"
        );
        let (allocations, _) = measure(|| device.stop());
        assert_eq!(allocations, 0, "stop allocated");
        assert!(
            device.rejected_forces() > 0,
            "refused forces were exercised"
        );
        assert_eq!(device.force_record().total_writes(), 10_100 + 1);
    }
    // The counter does count: a deliberate allocation is seen.
    let (allocations, bytes) = measure(|| drop(std::hint::black_box(vec![0u8; 64])));
    assert_eq!((allocations, bytes), (1, 64));
}

/// The simulated hand's RT path allocates nothing either: 10,000 reads (each 10 Runge–Kutta
/// steps sampling the script) and writes, refused forces, an injected fault and a loop wrap
/// included.
#[test]
fn the_hand_reads_and_writes_allocate_nothing() {
    use lop_drivers::hand::HandDevice;
    let script = MockScript::parse(SCRIPT, Path::new("rt-alloc.toml")).unwrap();
    let mut device = HandDevice::new(script, MockDevice::omni_limits());
    device.start().unwrap();
    let run = |device: &mut HandDevice, from: u64, ticks: u64| {
        let mut errors = 0u64;
        for tick in from..from + ticks {
            let t = tick as f64 * 1e-3;
            let force = match device.read(t) {
                Ok(sample) if tick % 1000 == 999 => [f64::NAN, sample.position_mm[1], 0.0],
                Ok(_) if tick % 1000 == 500 => [0.0, 5.0, 0.0],
                Ok(sample) => [0.0, (30.0 - sample.position_mm[1]).max(0.0) * 0.1, 0.0],
                Err(_) => {
                    errors += 1;
                    [0.0; 3]
                }
            };
            if device.write_force(force).is_err() {
                errors += 1;
            }
        }
        std::hint::black_box(errors);
    };
    run(&mut device, 0, 100); // warm-up
    let (allocations, bytes) = measure(|| run(&mut device, 100, 10_000));
    assert_eq!((allocations, bytes), (0, 0), "hand RT path allocated");
    let (allocations, _) = measure(|| device.stop());
    assert_eq!(allocations, 0, "stop allocated");
    assert_eq!(
        device.rejected_forces(),
        20,
        "refused forces were exercised"
    );
}
