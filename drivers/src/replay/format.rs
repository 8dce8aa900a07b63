//! The recording file: header, records, a streaming writer and a validating reader.
//!
//! The reader refuses anything it cannot trust and says where: a wrong magic, an unknown
//! version, a truncated header or record (with its byte offset), a non-finite position, ticks
//! that do not increase, an unknown status code.
//!
//! A device that reported a broken sample (a NaN or infinite position or velocity: the haptic
//! loop refused it live) is recorded with its own status, [`BROKEN_SAMPLE`], and zeros in place
//! of the numbers, so the file holds only finite values; the replay device reports such a record
//! as a non-finite sample again, and the loop refuses it as it did live.

use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

use crate::device::{DeviceError, DeviceLimits, DeviceSample};

/// First eight bytes of every recording.
pub const RECORDING_MAGIC: [u8; 8] = *b"LOP-REC\0";
/// The format version this build writes and reads.
pub const RECORDING_VERSION: u32 = 1;
/// Bytes per record.
pub const RECORD_BYTES: usize = 72;
/// Bytes of the fixed part of the header (magic, version, rate, limits, metadata length).
const FIXED_HEADER_BYTES: usize = 8 + 4 + 8 + 9 * 8 + 4;
/// Metadata longer than this is refused as corrupt.
const MAX_METADATA_BYTES: usize = 64 * 1024;

/// What a recording says about itself.
#[derive(Clone, Debug, PartialEq)]
pub struct RecordingHeader {
    /// Tick rate of the recorded loop, Hz.
    pub rate_hz: f64,
    /// Limits of the recorded device (the replay device reports them, so clamps match).
    pub limits: DeviceLimits,
    /// `key=value` metadata in file order (`scene`, `scene_path`, `device`, `started_unix_s`).
    pub metadata: Vec<(String, String)>,
}

impl RecordingHeader {
    /// The value of metadata `key`, if present.
    pub fn get(&self, key: &str) -> Option<&str> {
        self.metadata
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| v.as_str())
    }
}

/// One recorded tick of the device stream.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RecordedSample {
    /// Tick index of the loop that read it.
    pub tick: u64,
    /// `CLOCK_MONOTONIC` time of the read relative to the first record, ns (for review; replay
    /// goes by `tick`).
    pub time_ns: u64,
    /// The sample read (zero when `error` is set).
    pub sample: DeviceSample,
    /// The device error the read returned instead of a sample.
    pub error: Option<DeviceError>,
}

/// A recording that cannot be read. Names the file and, where it applies, the byte offset.
#[derive(Debug, thiserror::Error)]
pub enum RecordingError {
    /// The file could not be opened or read.
    #[error("{}: cannot read the recording: {source}", path.display())]
    Io {
        /// The recording.
        path: PathBuf,
        /// The I/O error.
        source: io::Error,
    },
    /// The file does not start with [`RECORDING_MAGIC`].
    #[error("{}: not a lop session recording (bytes 0..8 are {found:?}, expected {:?})", path.display(), RECORDING_MAGIC)]
    NotARecording {
        /// The file.
        path: PathBuf,
        /// Its first bytes.
        found: Vec<u8>,
    },
    /// A format version this build does not read.
    #[error("{}: recording format version {found} at byte 8; this lopd reads version {RECORDING_VERSION}", path.display())]
    Version {
        /// The file.
        path: PathBuf,
        /// The version in the file.
        found: u32,
    },
    /// The file ends inside the header or a record.
    #[error("{}: truncated at byte {offset}: {what}", path.display())]
    Truncated {
        /// The file.
        path: PathBuf,
        /// Where the missing data starts.
        offset: u64,
        /// What is cut off.
        what: String,
    },
    /// A value in the file is invalid.
    #[error("{}: byte {offset}: {what}", path.display())]
    Invalid {
        /// The file.
        path: PathBuf,
        /// Where the bad value starts.
        offset: u64,
        /// What is wrong, with the value.
        what: String,
    },
}

/// Status code of a record whose sample the device reported broken (not finite).
pub const BROKEN_SAMPLE: u32 = 9;

/// Status code of a record: 0 = a sample, otherwise the device error.
fn status_code(error: Option<DeviceError>) -> u32 {
    match error {
        None => 0,
        Some(DeviceError::Fault) => 1,
        Some(DeviceError::Communication) => 2,
        Some(DeviceError::ForceLimitExceeded) => 3,
        Some(DeviceError::VelocityLimitExceeded) => 4,
        Some(DeviceError::MotorsWarm) => 5,
        Some(DeviceError::NonFiniteForce) => 6,
        Some(DeviceError::NotStarted) => 7,
        Some(DeviceError::Stopped) => 8,
    }
}

fn error_from_code(code: u32) -> Result<Option<DeviceError>, ()> {
    Ok(match code {
        0 => None,
        1 => Some(DeviceError::Fault),
        2 => Some(DeviceError::Communication),
        3 => Some(DeviceError::ForceLimitExceeded),
        4 => Some(DeviceError::VelocityLimitExceeded),
        5 => Some(DeviceError::MotorsWarm),
        6 => Some(DeviceError::NonFiniteForce),
        7 => Some(DeviceError::NotStarted),
        8 => Some(DeviceError::Stopped),
        _ => return Err(()),
    })
}

/// Encodes one record into its fixed-size bytes (no allocation: usable on any thread).
pub fn encode_record(r: &RecordedSample) -> [u8; RECORD_BYTES] {
    let mut b = [0u8; RECORD_BYTES];
    b[0..8].copy_from_slice(&r.tick.to_le_bytes());
    b[8..16].copy_from_slice(&r.time_ns.to_le_bytes());
    if r.error.is_none() && !r.sample.is_finite() {
        // Zeros and the broken-sample status (see the module docs).
        b[64..68].copy_from_slice(&r.sample.buttons.to_le_bytes());
        b[68..72].copy_from_slice(&BROKEN_SAMPLE.to_le_bytes());
        return b;
    }
    for k in 0..3 {
        let o = 16 + 8 * k;
        b[o..o + 8].copy_from_slice(&r.sample.position_mm[k].to_le_bytes());
        let o = 40 + 8 * k;
        b[o..o + 8].copy_from_slice(&r.sample.velocity_mm_s[k].to_le_bytes());
    }
    b[64..68].copy_from_slice(&r.sample.buttons.to_le_bytes());
    b[68..72].copy_from_slice(&status_code(r.error).to_le_bytes());
    b
}

/// Writes a recording: the header at creation, then records as they come.
pub struct RecordingWriter {
    out: BufWriter<File>,
    path: PathBuf,
    records: u64,
}

impl RecordingWriter {
    /// Creates `path` (which must not exist: a recording is never overwritten) and writes the
    /// header.
    pub fn create(path: &Path, header: &RecordingHeader) -> io::Result<RecordingWriter> {
        let file = File::options().write(true).create_new(true).open(path)?;
        let mut out = BufWriter::new(file);
        let mut meta = String::new();
        for (k, v) in &header.metadata {
            // One line per key: newlines in values would break the format.
            meta.push_str(&k.replace(['\n', '='], " "));
            meta.push('=');
            meta.push_str(&v.replace('\n', " "));
            meta.push('\n');
        }
        out.write_all(&RECORDING_MAGIC)?;
        out.write_all(&RECORDING_VERSION.to_le_bytes())?;
        out.write_all(&header.rate_hz.to_le_bytes())?;
        let l = &header.limits;
        let limits = [
            l.max_force_n,
            l.max_continuous_force_n,
            l.max_stiffness_n_per_mm,
            l.workspace_min_mm[0],
            l.workspace_min_mm[1],
            l.workspace_min_mm[2],
            l.workspace_max_mm[0],
            l.workspace_max_mm[1],
            l.workspace_max_mm[2],
        ];
        for v in limits {
            out.write_all(&v.to_le_bytes())?;
        }
        out.write_all(&(meta.len() as u32).to_le_bytes())?;
        out.write_all(meta.as_bytes())?;
        Ok(RecordingWriter {
            out,
            path: path.to_path_buf(),
            records: 0,
        })
    }

    /// Appends one record.
    pub fn write(&mut self, r: &RecordedSample) -> io::Result<()> {
        self.records += 1;
        self.out.write_all(&encode_record(r))
    }

    /// Records written so far.
    pub fn records(&self) -> u64 {
        self.records
    }

    /// The file being written.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Flushes everything to the file.
    pub fn finish(mut self) -> io::Result<()> {
        self.out.flush()?;
        self.out.get_ref().sync_data()
    }
}

/// A recording read into memory and validated.
#[derive(Clone, Debug, PartialEq)]
pub struct Recording {
    path: PathBuf,
    header: RecordingHeader,
    records: Vec<RecordedSample>,
}

/// Reads fixed-size little-endian fields with offsets for messages.
struct Cursor<'a> {
    bytes: &'a [u8],
    at: usize,
    path: &'a Path,
}

impl<'a> Cursor<'a> {
    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8], RecordingError> {
        if self.bytes.len() - self.at < n {
            return Err(RecordingError::Truncated {
                path: self.path.to_path_buf(),
                offset: self.at as u64,
                what: format!(
                    "{what}: {n} bytes expected, {} left",
                    self.bytes.len() - self.at
                ),
            });
        }
        let s = &self.bytes[self.at..self.at + n];
        self.at += n;
        Ok(s)
    }
    fn u32(&mut self, what: &str) -> Result<u32, RecordingError> {
        Ok(u32::from_le_bytes(self.take(4, what)?.try_into().unwrap()))
    }
    fn f64(&mut self, what: &str) -> Result<f64, RecordingError> {
        Ok(f64::from_le_bytes(self.take(8, what)?.try_into().unwrap()))
    }
    fn invalid(&self, offset: usize, what: String) -> RecordingError {
        RecordingError::Invalid {
            path: self.path.to_path_buf(),
            offset: offset as u64,
            what,
        }
    }
}

fn le_u64(b: &[u8]) -> u64 {
    u64::from_le_bytes(b.try_into().unwrap())
}
fn le_f64(b: &[u8]) -> f64 {
    f64::from_le_bytes(b.try_into().unwrap())
}

impl Recording {
    /// Reads and validates a recording.
    pub fn load(path: &Path) -> Result<Recording, RecordingError> {
        let bytes = std::fs::read(path).map_err(|source| RecordingError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::parse(&bytes, path)
    }

    /// Parses recording bytes; `path` is used only in messages.
    pub fn parse(bytes: &[u8], path: &Path) -> Result<Recording, RecordingError> {
        let mut c = Cursor { bytes, at: 0, path };
        if bytes.len() < 8 || bytes[..8] != RECORDING_MAGIC {
            return Err(RecordingError::NotARecording {
                path: path.to_path_buf(),
                found: bytes[..bytes.len().min(8)].to_vec(),
            });
        }
        c.at = 8;
        let version = c.u32("the format version")?;
        if version != RECORDING_VERSION {
            return Err(RecordingError::Version {
                path: path.to_path_buf(),
                found: version,
            });
        }
        let rate_at = c.at;
        let rate_hz = c.f64("the tick rate")?;
        if !(rate_hz.is_finite() && rate_hz > 0.0 && rate_hz <= 100_000.0) {
            return Err(c.invalid(
                rate_at,
                format!("tick rate {rate_hz} Hz is not in (0, 100000]"),
            ));
        }
        let limits_at = c.at;
        let raw = c.take(72, "the device limits")?;
        let l: [f64; 9] = std::array::from_fn(|i| le_f64(&raw[8 * i..8 * i + 8]));
        let limits = DeviceLimits {
            max_force_n: l[0],
            max_continuous_force_n: l[1],
            max_stiffness_n_per_mm: l[2],
            workspace_min_mm: [l[3], l[4], l[5]],
            workspace_max_mm: [l[6], l[7], l[8]],
        };
        let limits_ok = l.iter().all(|v| v.is_finite())
            && l[0] > 0.0
            && (0..3).all(|k| limits.workspace_min_mm[k] < limits.workspace_max_mm[k]);
        if !limits_ok {
            return Err(c.invalid(limits_at, format!("device limits {limits:?} are not valid")));
        }
        let meta_at = c.at;
        let meta_len = c.u32("the metadata length")? as usize;
        if meta_len > MAX_METADATA_BYTES {
            return Err(c.invalid(
                meta_at,
                format!("metadata length {meta_len} is implausible"),
            ));
        }
        let text_at = c.at;
        let text = std::str::from_utf8(c.take(meta_len, "the metadata")?)
            .map_err(|e| c.invalid(text_at, format!("metadata is not UTF-8 ({e})")))?;
        let metadata = text
            .lines()
            .filter(|l| !l.is_empty())
            .map(|l| match l.split_once('=') {
                Some((k, v)) => (k.to_string(), v.to_string()),
                None => (l.to_string(), String::new()),
            })
            .collect();
        debug_assert_eq!(c.at, FIXED_HEADER_BYTES + meta_len);

        let body = &bytes[c.at..];
        let whole = body.len() / RECORD_BYTES;
        if !body.len().is_multiple_of(RECORD_BYTES) {
            let offset = c.at + whole * RECORD_BYTES;
            return Err(RecordingError::Truncated {
                path: path.to_path_buf(),
                offset: offset as u64,
                what: format!(
                    "record {whole} has {} of {RECORD_BYTES} bytes",
                    body.len() % RECORD_BYTES
                ),
            });
        }
        let mut records = Vec::with_capacity(whole);
        for (i, b) in body.chunks_exact(RECORD_BYTES).enumerate() {
            let offset = c.at + i * RECORD_BYTES;
            let status = u32::from_le_bytes(b[68..72].try_into().unwrap());
            let broken = status == BROKEN_SAMPLE;
            let error = if broken {
                None
            } else {
                error_from_code(status).map_err(|()| {
                    c.invalid(offset + 68, format!("record {i}: unknown status {status}"))
                })?
            };
            let mut r = RecordedSample {
                tick: le_u64(&b[0..8]),
                time_ns: le_u64(&b[8..16]),
                sample: DeviceSample {
                    position_mm: [0, 1, 2].map(|k| le_f64(&b[16 + 8 * k..24 + 8 * k])),
                    velocity_mm_s: [0, 1, 2].map(|k| le_f64(&b[40 + 8 * k..48 + 8 * k])),
                    buttons: u32::from_le_bytes(b[64..68].try_into().unwrap()),
                },
                error,
            };
            if !r.sample.is_finite() {
                return Err(c.invalid(
                    offset + 16,
                    format!(
                        "record {i} (tick {}): non-finite position {:?} or velocity {:?}",
                        r.tick, r.sample.position_mm, r.sample.velocity_mm_s
                    ),
                ));
            }
            if broken {
                r.sample.position_mm = [f64::NAN; 3];
                r.sample.velocity_mm_s = [f64::NAN; 3];
            }
            if let Some(prev) = records.last().map(|p: &RecordedSample| p.tick) {
                if r.tick <= prev {
                    return Err(c.invalid(
                        offset,
                        format!("record {i}: tick {} does not follow tick {prev}", r.tick),
                    ));
                }
            }
            records.push(r);
        }
        Ok(Recording {
            path: path.to_path_buf(),
            header: RecordingHeader {
                rate_hz,
                limits,
                metadata,
            },
            records,
        })
    }

    /// The file it was read from.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Rate, limits and metadata.
    pub fn header(&self) -> &RecordingHeader {
        &self.header
    }

    /// Every record, in tick order.
    pub fn records(&self) -> &[RecordedSample] {
        &self.records
    }

    /// Seconds from the first to the last recorded tick.
    pub fn duration(&self) -> f64 {
        match (self.records.first(), self.records.last()) {
            (Some(a), Some(b)) => (b.tick - a.tick) as f64 / self.header.rate_hz,
            _ => 0.0,
        }
    }

    /// The record in force at run time `t` s: the last one whose tick is at most
    /// `round(t × rate)` (ticks lost while recording hold the previous record; before the first
    /// and after the last, the first and last hold). `None` only for an empty recording.
    /// Allocation-free.
    pub fn at(&self, t: f64) -> Option<&RecordedSample> {
        let first = self.records.first()?;
        let tick = if t.is_finite() && t > 0.0 {
            (t * self.header.rate_hz).round() as u64
        } else {
            0
        };
        let tick = tick + first.tick;
        let i = self.records.partition_point(|r| r.tick <= tick);
        Some(&self.records[i.saturating_sub(1)])
    }

    /// The tool's device sample at run time `t` (the recorded position is held through ticks
    /// that recorded a device error or a broken sample). For offline runs (`lopd simulate --device replay:PATH`).
    pub fn sample(&self, t: f64) -> DeviceSample {
        let Some(r) = self.at(t) else {
            return DeviceSample::default();
        };
        if r.error.is_none() && r.sample.is_finite() {
            return r.sample;
        }
        let i = self.records.partition_point(|x| x.tick < r.tick);
        self.records[..i]
            .iter()
            .rev()
            .find(|x| x.error.is_none() && x.sample.is_finite())
            .map_or(DeviceSample::default(), |x| x.sample)
    }
}
