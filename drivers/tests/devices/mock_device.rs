//! The mock device's contract: it plays its script deterministically, refuses non-finite and
//! over-limit forces by rendering zero, always ends its record with the zero written by `stop`,
//! and its force ring keeps the newest entries in order after wrap-around.

use std::path::Path;

use lop_drivers::mock::{MockDevice, MockScript, FORCE_RECORD_CAPACITY, OUT_OF_WORKSPACE_MM};
use lop_drivers::{DeviceError, HapticDevice, Pacing};

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
t = 2.0
position = [0.0, 40.0, 10.0]
"#;

fn script() -> MockScript {
    MockScript::parse(SCRIPT, Path::new("device-test.toml")).unwrap()
}

fn started(capacity: usize) -> MockDevice {
    let mut device =
        MockDevice::with_record_capacity(script(), MockDevice::omni_limits(), capacity);
    device.start().unwrap();
    device
}

#[test]
fn reads_play_the_script_at_the_given_time() {
    let mut device = started(16);
    assert_eq!(device.pacing(), Pacing::SelfPaced);
    assert_eq!(device.name(), "mock (device-test)");
    for t in [0.0, 0.25, 1.0, 1.7, 2.0, 5.3] {
        assert_eq!(device.read(t).unwrap(), script().sample(t));
    }
}

#[test]
fn read_and_write_before_start_and_after_stop_fail() {
    let mut device = MockDevice::new(script(), MockDevice::omni_limits());
    assert_eq!(device.read(0.0), Err(DeviceError::NotStarted));
    assert_eq!(device.write_force([0.0; 3]), Err(DeviceError::NotStarted));
    device.start().unwrap();
    device.stop();
    assert_eq!(device.read(0.0), Err(DeviceError::Stopped));
    assert_eq!(device.write_force([0.0; 3]), Err(DeviceError::Stopped));
}

#[test]
fn non_finite_force_is_refused_and_zero_recorded() {
    let mut device = started(16);
    device.read(0.5).unwrap();
    device.write_force([0.1, 0.2, 0.3]).unwrap();
    for bad in [
        [f64::NAN, 0.0, 0.0],
        [0.0, f64::INFINITY, 0.0],
        [0.0, 0.0, f64::NEG_INFINITY],
    ] {
        assert_eq!(device.write_force(bad), Err(DeviceError::NonFiniteForce));
        assert_eq!(device.last_force(), [0.0; 3]);
    }
    assert_eq!(device.rejected_forces(), 3);
    let forces: Vec<_> = device.force_record().iter().map(|(_, f)| f).collect();
    assert_eq!(forces, [[0.1, 0.2, 0.3], [0.0; 3], [0.0; 3], [0.0; 3]]);
}

#[test]
fn force_above_the_device_limit_is_refused_but_the_limit_itself_is_not() {
    let mut device = started(16);
    device.read(0.0).unwrap();
    let max = MockDevice::omni_limits().max_force_n;
    let at_limit = [max / 3f64.sqrt(); 3];
    assert_eq!(device.write_force(at_limit), Ok(()));
    assert_eq!(device.last_force(), at_limit);
    assert_eq!(
        device.write_force([0.0, -(max + 0.01), 0.0]),
        Err(DeviceError::ForceLimitExceeded)
    );
    assert_eq!(device.last_force(), [0.0; 3]);
    assert_eq!(device.rejected_forces(), 1);
}

#[test]
fn stop_records_zero_last_and_is_idempotent() {
    let mut device = started(16);
    device.read(1.5).unwrap();
    device.write_force([0.5, 0.0, -0.5]).unwrap();
    assert!(!device.stopped());
    device.stop();
    assert!(device.stopped());
    assert_eq!(device.last_force(), [0.0; 3]);
    assert_eq!(device.force_record().last(), Some((1.5, [0.0; 3])));
    assert_eq!(device.force_record().total_writes(), 2);
    device.stop();
    device.stop();
    assert_eq!(device.force_record().total_writes(), 2);
    assert!(device.stopped());
}

#[test]
fn stop_before_start_records_nothing() {
    let mut device = MockDevice::new(script(), MockDevice::omni_limits());
    device.stop();
    assert!(device.stopped());
    assert!(device.force_record().is_empty());
}

#[test]
fn force_ring_keeps_the_last_n_in_order_after_wrap_around() {
    const N: usize = 7;
    let mut device = started(N);
    let writes = 3 * N + 4;
    for i in 0..writes {
        device.read(i as f64 * 1e-3).unwrap();
        device.write_force([i as f64 * 1e-3, 0.0, 0.0]).unwrap();
    }
    let record = device.force_record();
    assert_eq!(record.capacity(), N);
    assert_eq!(record.len(), N);
    assert_eq!(record.total_writes(), writes as u64);
    let kept: Vec<f64> = record.iter().map(|(_, f)| f[0] / 1e-3).collect();
    let expected: Vec<f64> = (writes - N..writes).map(|i| i as f64).collect();
    for (k, e) in kept.iter().zip(&expected) {
        assert!((k - e).abs() < 1e-9, "{kept:?} vs {expected:?}");
    }
    let times: Vec<f64> = record.iter().map(|(t, _)| t).collect();
    assert!(times.windows(2).all(|w| w[0] < w[1]), "{times:?}");
    assert_eq!(record.last(), record.iter().next_back());

    // Before wrap-around the ring is simply the writes so far.
    let mut device = started(N);
    device.write_force([1.0, 0.0, 0.0]).unwrap();
    device.write_force([2.0, 0.0, 0.0]).unwrap();
    let forces: Vec<f64> = device
        .force_record()
        .into_iter()
        .map(|(_, f)| f[0])
        .collect();
    assert_eq!(forces, [1.0, 2.0]);
}

#[test]
fn default_ring_holds_two_minutes_at_one_kilohertz() {
    let device = MockDevice::new(script(), MockDevice::omni_limits());
    assert_eq!(device.force_record().capacity(), FORCE_RECORD_CAPACITY);
    assert_eq!(FORCE_RECORD_CAPACITY, 120_000);
}

#[test]
fn identical_runs_give_identical_records() {
    let run = || {
        let mut device = started(4096);
        for tick in 0..3000 {
            let sample = device.read(tick as f64 * 1e-3).unwrap();
            // A spring toward y = 30 mm, like a floor.
            let force = [0.0, (30.0 - sample.position_mm[1]).max(0.0) * 0.1, 0.0];
            device.write_force(force).unwrap();
        }
        device.stop();
        device.force_record().iter().collect::<Vec<_>>()
    };
    assert_eq!(run(), run());
}

#[test]
fn injected_faults_fail_reads_and_writes_in_their_window() {
    let text = format!(
        "{SCRIPT}\n[[fault]]\nfrom = 0.5\nuntil = 0.6\nerror = \"communication\"\n\
         [[fault]]\nfrom = 1.0\nuntil = 1.1\nerror = \"force_limit\"\n"
    );
    let script = MockScript::parse(&text, Path::new("faults.toml")).unwrap();
    let mut device = MockDevice::new(script, MockDevice::omni_limits());
    device.start().unwrap();
    assert!(device.read(0.45).is_ok());
    device.write_force([0.1, 0.0, 0.0]).unwrap();
    assert_eq!(device.read(0.55), Err(DeviceError::Communication));
    assert_eq!(
        device.write_force([0.1, 0.0, 0.0]),
        Err(DeviceError::Communication)
    );
    assert_eq!(device.last_force(), [0.0; 3]);
    // A force fault lets reads through but renders zero.
    assert!(device.read(1.05).is_ok());
    assert_eq!(
        device.write_force([0.1, 0.0, 0.0]),
        Err(DeviceError::ForceLimitExceeded)
    );
    assert_eq!(device.last_force(), [0.0; 3]);
    // Faults are not the caller's doing.
    assert_eq!(device.rejected_forces(), 0);
    assert!(device.read(1.2).is_ok());
    device.write_force([0.1, 0.0, 0.0]).unwrap();
}

#[test]
fn injected_sample_faults_report_broken_samples_in_their_window() {
    let text = format!(
        "{SCRIPT}\n[[fault]]\nfrom = 0.5\nuntil = 0.6\nsample = \"nan\"\n\
         [[fault]]\nfrom = 1.0\nuntil = 1.1\nsample = \"out_of_workspace\"\n"
    );
    let script = MockScript::parse(&text, Path::new("sample-faults.toml")).unwrap();
    assert_eq!(script.faults(), []);
    assert_eq!(script.sample_faults().len(), 2);
    let limits = MockDevice::omni_limits();
    let mut device = MockDevice::new(script.clone(), limits);
    device.start().unwrap();
    // Outside the windows: the script, untouched.
    for t in [0.45, 0.6, 0.95, 1.1] {
        assert_eq!(device.read(t).unwrap(), script.sample(t), "t = {t}");
    }
    // NaN: the read succeeds, the sample is not finite, the buttons are the script's.
    let nan = device.read(0.55).unwrap();
    assert!(!nan.is_finite(), "{nan:?}");
    assert!(nan.position_mm.iter().all(|c| c.is_nan()));
    assert_eq!(nan.buttons, script.sample(0.55).buttons);
    // Out of the workspace: finite, far beyond its upper corner on every axis.
    let out = device.read(1.05).unwrap();
    assert!(out.is_finite());
    assert!(!limits.in_workspace(out.position_mm));
    for k in 0..3 {
        assert_eq!(
            out.position_mm[k],
            limits.workspace_max_mm[k] + OUT_OF_WORKSPACE_MM
        );
    }
    assert_eq!(out.velocity_mm_s, script.sample(1.05).velocity_mm_s);
    // A broken sample is not a device error: forces are still rendered.
    device.write_force([0.1, 0.0, 0.0]).unwrap();
    assert_eq!(device.last_force(), [0.1, 0.0, 0.0]);
}

#[test]
fn force_csv_lists_the_record_oldest_first() {
    let mut device = started(2);
    for (i, fx) in [1.0, 2.0, 3.0].into_iter().enumerate() {
        device.read(i as f64 * 0.5).unwrap();
        device.write_force([fx, -0.5, 0.25]).unwrap();
    }
    device.stop();
    let path = std::env::temp_dir().join(format!("lop-drivers-csv-{}.csv", std::process::id()));
    device.write_force_csv(&path).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    std::fs::remove_file(&path).unwrap();
    assert_eq!(text, "t,fx,fy,fz\n1,3,-0.5,0.25\n1,0,0,0\n");
}

#[test]
fn stationary_script_holds_still() {
    let mut device = MockDevice::new(
        MockScript::stationary([1.0, 2.0, 3.0]),
        MockDevice::omni_limits(),
    );
    device.start().unwrap();
    let sample = device.read(42.0).unwrap();
    assert_eq!(sample.position_mm, [1.0, 2.0, 3.0]);
    assert_eq!(sample.velocity_mm_s, [0.0; 3]);
    assert_eq!(sample.buttons, 0);
}
