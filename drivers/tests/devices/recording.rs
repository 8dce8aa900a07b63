//! Session recordings: what is written is read back bit for bit, the replay device plays it by
//! tick index deterministically, and every kind of damage is a clear error naming the file and
//! the byte.

use std::path::Path;

use lop_drivers::replay::{
    RecordedSample, Recording, RecordingError, RecordingHeader, RecordingWriter, ReplayDevice,
    RECORD_BYTES,
};
use lop_drivers::{DeviceError, DeviceLimits, DeviceSample, HapticDevice};
use lop_test_support::fixtures::temp_dir;

fn limits() -> DeviceLimits {
    lop_drivers::mock::MockDevice::omni_limits()
}

fn sample(k: u64) -> DeviceSample {
    let x = k as f64;
    DeviceSample {
        position_mm: [0.1 * x, (x * 0.37).sin() * 20.0, -1.0 / (x + 3.0)],
        velocity_mm_s: [100.0, (x * 0.37).cos() * 7.4e3, 1e-300],
        buttons: (k % 4) as u32,
    }
}

fn write(path: &Path, ticks: impl Iterator<Item = u64>) -> Vec<RecordedSample> {
    let _ = std::fs::remove_file(path);
    let header = RecordingHeader {
        rate_hz: 1000.0,
        limits: limits(),
        metadata: vec![
            ("scene".into(), "organs".into()),
            ("device".into(), "mock".into()),
        ],
    };
    let mut w = RecordingWriter::create(path, &header).unwrap();
    let mut written = Vec::new();
    for k in ticks {
        let r = RecordedSample {
            tick: k,
            time_ns: k * 1_000_000 + 17,
            sample: if k == 7 {
                DeviceSample::default()
            } else {
                sample(k)
            },
            error: (k == 7).then_some(DeviceError::ForceLimitExceeded),
        };
        w.write(&r).unwrap();
        written.push(r);
    }
    w.finish().unwrap();
    written
}

#[test]
fn round_trip_is_bit_exact_and_replay_is_deterministic() {
    let dir = temp_dir("lop-recording");
    let path = dir.join("a.lrec");
    // Ticks 0..2000 with 100..110 lost (a full ring while recording).
    let written = write(&path, (0..2000).filter(|k| !(100..110).contains(k)));
    let rec = Recording::load(&path).unwrap();
    assert_eq!(rec.records(), written.as_slice());
    assert_eq!(rec.header().rate_hz, 1000.0);
    assert_eq!(rec.header().limits, limits());
    assert_eq!(rec.header().get("scene"), Some("organs"));
    assert_eq!(rec.duration(), 1.999);
    // A recording is never overwritten.
    let header = rec.header().clone();
    assert!(RecordingWriter::create(&path, &header).is_err());

    // Replay by tick index: twice, bit-identical, and equal to what was recorded.
    let play = || {
        let mut d = ReplayDevice::open(&path).unwrap();
        d.start().unwrap();
        (0..2500u64)
            .map(|k| d.read(k as f64 / 1000.0))
            .collect::<Vec<_>>()
    };
    let (a, b) = (play(), play());
    assert_eq!(a, b);
    assert_eq!(a[5], Ok(sample(5)));
    assert_eq!(a[7], Err(DeviceError::ForceLimitExceeded));
    assert_eq!(
        a[105],
        Ok(sample(99)),
        "a lost tick holds the previous record"
    );
    assert_eq!(a[1999], Ok(sample(1999)));
    assert_eq!(
        a[2400],
        Ok(sample(1999)),
        "the last pose holds after the end"
    );
    // Offline sampling holds the pose through an error tick.
    assert_eq!(rec.sample(0.007), sample(6));

    // The replay device refuses what the recorded device could not render.
    let mut d = ReplayDevice::open(&path).unwrap();
    d.start().unwrap();
    assert_eq!(
        d.write_force([0.0, 4.0, 0.0]),
        Err(DeviceError::ForceLimitExceeded)
    );
    assert_eq!(
        d.write_force([f64::NAN, 0.0, 0.0]),
        Err(DeviceError::NonFiniteForce)
    );
    assert_eq!(d.write_force([0.0, 1.0, 0.0]), Ok(()));
    d.stop();
    assert_eq!(d.last_force(), [0.0; 3]);
    assert_eq!(d.limits(), limits());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn damaged_recordings_are_located_errors() {
    let dir = temp_dir("lop-recording-bad");
    let good = dir.join("good.lrec");
    write(&good, 0..10);
    let bytes = std::fs::read(&good).unwrap();
    let header_len = bytes.len() - 10 * RECORD_BYTES;
    let load = |name: &str, b: &[u8]| {
        let p = dir.join(name);
        std::fs::write(&p, b).unwrap();
        let e = Recording::load(&p).unwrap_err();
        let text = e.to_string();
        assert!(text.contains(name), "{text}");
        (e, text)
    };

    // A record cut short: the offset of the broken record is named.
    let (e, text) = load("cut.lrec", &bytes[..bytes.len() - 30]);
    assert!(matches!(e, RecordingError::Truncated { .. }), "{text}");
    let offset = header_len + 9 * RECORD_BYTES;
    assert!(text.contains(&format!("byte {offset}")), "{text}");
    assert!(text.contains("record 9 has 42 of 72 bytes"), "{text}");

    // A header cut short.
    let (e, text) = load("head.lrec", &bytes[..30]);
    assert!(matches!(e, RecordingError::Truncated { .. }), "{text}");
    assert!(
        text.contains("byte 20") && text.contains("device limits"),
        "{text}"
    );

    // Not a recording at all; a future version.
    let (e, _) = load("text.lrec", b"t,fx,fy,fz\n0,0,0,0\n");
    assert!(matches!(e, RecordingError::NotARecording { .. }));
    let mut v2 = bytes.clone();
    v2[8] = 2;
    let (_, text) = load("v2.lrec", &v2);
    assert!(text.contains("version 2"), "{text}");

    // A NaN position in record 3.
    let mut nan = bytes.clone();
    let at = header_len + 3 * RECORD_BYTES + 16;
    nan[at..at + 8].copy_from_slice(&f64::NAN.to_le_bytes());
    let (e, text) = load("nan.lrec", &nan);
    assert!(matches!(e, RecordingError::Invalid { .. }), "{text}");
    assert!(
        text.contains(&format!("byte {at}")) && text.contains("record 3"),
        "{text}"
    );

    // Ticks going backwards.
    let mut back = bytes.clone();
    let at = header_len + 5 * RECORD_BYTES;
    back[at..at + 8].copy_from_slice(&2u64.to_le_bytes());
    let (_, text) = load("back.lrec", &back);
    assert!(text.contains("tick 2 does not follow tick 4"), "{text}");

    // Missing file.
    let e = Recording::load(&dir.join("missing.lrec")).unwrap_err();
    assert!(e.to_string().contains("missing.lrec"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A broken sample the device reported (NaN, as `[[fault]] sample = "nan"` plays it) is
/// recorded with its own status and zeros, so the file stays readable; the replay device
/// reports it broken again (the loop refuses it as it did live) and the offline trajectory
/// holds the last good position through it.
#[test]
fn broken_samples_are_recorded_and_replayed_as_broken() {
    let dir = temp_dir("lop-recording-broken");
    let path = dir.join("nan.lrec");
    let header = RecordingHeader {
        rate_hz: 1000.0,
        limits: limits(),
        metadata: vec![],
    };
    let mut w = RecordingWriter::create(&path, &header).unwrap();
    for k in 0..10u64 {
        let mut s = sample(k);
        if k == 4 {
            s.position_mm = [f64::NAN; 3];
        }
        w.write(&RecordedSample {
            tick: k,
            time_ns: k * 1_000_000,
            sample: s,
            error: None,
        })
        .unwrap();
    }
    w.finish().unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let rec = Recording::load(&path).expect("a recording with a broken sample reads");
    assert!(!rec.records()[4].sample.is_finite());
    assert!(rec.records()[3].sample.is_finite() && rec.records()[5].sample.is_finite());
    assert_eq!(
        rec.sample(0.004),
        sample(3),
        "the offline trajectory holds the last good one"
    );
    let mut dev = ReplayDevice::new(rec);
    dev.start().unwrap();
    let s = dev.read(0.004).unwrap();
    assert!(!s.is_finite(), "replayed broken: {s:?}");
    assert!(dev.read(0.005).unwrap().is_finite());
    // Only the status says broken: NaN bytes under a sample status are damage.
    let n = bytes.len();
    let mut damaged = bytes.clone();
    let record4 = n - 6 * RECORD_BYTES;
    damaged[record4 + 68..record4 + 72].copy_from_slice(&0u32.to_le_bytes());
    damaged[record4 + 16..record4 + 24].copy_from_slice(&f64::NAN.to_le_bytes());
    std::fs::write(&path, &damaged).unwrap();
    assert!(Recording::load(&path).is_err());
    let _ = std::fs::remove_dir_all(&dir);
}
