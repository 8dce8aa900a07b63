//! `--record PATH`: the device stream of a session (tick, time, position, velocity, buttons, and
//! the device error of a tick, if any) written to a recording that `--device replay:PATH` plays
//! back (format: `lop_drivers::replay`).
//!
//! The RT thread never does file I/O: [`Recorded`] wraps the device for one tick and pushes each
//! read into a preallocated lock-free ring ([`RecordTap`], 8 s at 1 kHz); a normal thread
//! ([`RecordWriter`]) drains it into the file. A full ring drops the sample (counted) rather
//! than block. An existing recording is never overwritten: the new one takes the first free
//! `NAME-N.EXT`, so a restarted haptic process keeps the crashed session's recording.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

use anyhow::{Context, Result};
use lop_drivers::replay::{RecordedSample, RecordingHeader, RecordingWriter};
use lop_drivers::{
    DeviceError, DeviceLimits, DeviceOpenError, DeviceSample, HapticDevice, Pacing, ServoRun,
    ServoTick,
};

use crate::rt;

/// Samples the ring holds: 8 s at 1 kHz.
pub const RECORD_RING: usize = 8192;

/// The RT side of a recording: a ring producer and the tick counter.
pub struct RecordTap {
    ring: rtrb::Producer<RecordedSample>,
    reads: u64,
    first_ns: Option<u64>,
    dropped: u64,
}

impl RecordTap {
    /// Queues the outcome of one device read. Allocation-free, lock-free, never blocks.
    #[inline]
    pub fn push(&mut self, read: &Result<DeviceSample, DeviceError>) {
        let now = rt::now_ns();
        let first = *self.first_ns.get_or_insert(now);
        let (sample, error) = match read {
            Ok(s) => (*s, None),
            Err(e) => (DeviceSample::default(), Some(*e)),
        };
        let r = RecordedSample {
            tick: self.reads,
            time_ns: now - first,
            sample,
            error,
        };
        self.reads += 1;
        if self.ring.push(r).is_err() {
            self.dropped += 1;
        }
    }

    /// Samples lost because the writer fell behind.
    pub fn dropped(&self) -> u64 {
        self.dropped
    }
}

/// A device whose reads are also recorded. Wraps the device for the loop (self-paced) or for
/// one servo tick (device clock).
pub struct Recorded<'a> {
    /// The real device.
    pub device: &'a mut dyn HapticDevice,
    /// Where the reads go.
    pub tap: &'a mut RecordTap,
}

impl HapticDevice for Recorded<'_> {
    fn name(&self) -> &str {
        self.device.name()
    }
    fn limits(&self) -> DeviceLimits {
        self.device.limits()
    }
    fn pacing(&self) -> Pacing {
        self.device.pacing()
    }
    fn start(&mut self) -> Result<(), DeviceOpenError> {
        self.device.start()
    }
    #[inline]
    fn read(&mut self, t: f64) -> Result<DeviceSample, DeviceError> {
        let r = self.device.read(t);
        self.tap.push(&r);
        r
    }
    #[inline]
    fn write_force(&mut self, force_n: [f64; 3]) -> Result<(), DeviceError> {
        self.device.write_force(force_n)
    }
    fn stop(&mut self) {
        self.device.stop()
    }
    fn run_clocked(&mut self, tick: &mut ServoTick<'_>) -> Result<ServoRun, DeviceOpenError> {
        self.device.run_clocked(tick)
    }
}

/// The writer thread of a recording.
pub struct RecordWriter {
    path: PathBuf,
    done: Arc<AtomicBool>,
    thread: JoinHandle<Result<u64>>,
}

/// `path` if it does not exist, else the first free `STEM-N.EXT`.
pub fn free_path(path: &Path) -> PathBuf {
    if !path.exists() {
        return path.to_path_buf();
    }
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let ext = path.extension().map(|e| e.to_string_lossy().into_owned());
    (1..)
        .map(|n| {
            let name = match &ext {
                Some(e) => format!("{stem}-{n}.{e}"),
                None => format!("{stem}-{n}"),
            };
            path.with_file_name(name)
        })
        .find(|p| !p.exists())
        .expect("some suffix is free")
}

/// Creates the recording (at [`free_path`]) and starts its writer thread.
pub fn start(path: &Path, header: &RecordingHeader) -> Result<(RecordTap, RecordWriter)> {
    let path = free_path(path);
    let mut writer = RecordingWriter::create(&path, header)
        .with_context(|| format!("creating the recording {}", path.display()))?;
    let (producer, mut consumer) = rtrb::RingBuffer::new(RECORD_RING);
    let done = Arc::new(AtomicBool::new(false));
    let thread = {
        let done = done.clone();
        let shown = path.display().to_string();
        std::thread::Builder::new()
            .name("lop-record".into())
            .spawn(move || -> Result<u64> {
                loop {
                    let finished = done.load(Ordering::Acquire);
                    while let Ok(r) = consumer.pop() {
                        writer
                            .write(&r)
                            .with_context(|| format!("writing the recording {shown}"))?;
                    }
                    if finished {
                        let n = writer.records();
                        writer
                            .finish()
                            .with_context(|| format!("writing the recording {shown}"))?;
                        return Ok(n);
                    }
                    std::thread::sleep(Duration::from_millis(5));
                }
            })?
    };
    Ok((
        RecordTap {
            ring: producer,
            reads: 0,
            first_ns: None,
            dropped: 0,
        },
        RecordWriter { path, done, thread },
    ))
}

impl RecordWriter {
    /// The file being written.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Writes what is left in the ring, closes the file; the number of records written.
    pub fn finish(self) -> Result<u64> {
        self.done.store(true, Ordering::Release);
        match self.thread.join() {
            Ok(r) => r,
            Err(_) => anyhow::bail!("the recording writer panicked ({})", self.path.display()),
        }
    }
}

/// The header of a recording made now.
pub fn header(
    rate_hz: f64,
    limits: DeviceLimits,
    scene_name: &str,
    scene_path: &Path,
    device: &str,
) -> RecordingHeader {
    let started = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    RecordingHeader {
        rate_hz,
        limits,
        metadata: vec![
            ("scene".into(), scene_name.into()),
            ("scene_path".into(), scene_path.display().to_string()),
            ("device".into(), device.into()),
            ("started_unix_s".into(), started.to_string()),
            ("lopd".into(), env!("CARGO_PKG_VERSION").into()),
        ],
    }
}
