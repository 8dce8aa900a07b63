//! Session record and replay: the device stream of a session (poses, velocities, buttons, tick
//! indices and timestamps) in a small versioned binary file, and a [`ReplayDevice`] that plays it
//! back by tick index.
//!
//! Replay is deterministic like the mock: `read(t)` returns the sample recorded at tick
//! `round(t × rate)` and carries no state between reads, so replaying one recording twice on the
//! same tick sequence gives bit-identical samples. The file format is documented in
//! [`format`](self#file-format) below and in [`RECORDING_VERSION`].
//!
//! # File format
//! Little-endian throughout.
//!
//! | bytes | field |
//! |---|---|
//! | 8 | magic `LOP-REC\0` |
//! | 4 | format version (`u32`, currently 1) |
//! | 8 | tick rate, Hz (`f64`) |
//! | 72 | device limits: max force, continuous force, stiffness, workspace min xyz, max xyz (9 × `f64`) |
//! | 4 | length `n` of the metadata text (`u32`) |
//! | n | metadata, UTF-8 `key=value` lines (`scene`, `scene_path`, `device`, `started_unix_s`) |
//! | 72 × k | records: tick (`u64`), time since the first record in ns (`u64`), position mm (3 × `f64`), velocity mm/s (3 × `f64`), buttons (`u32`), status (`u32`: 0 = sample, else the device error of that tick) |

mod device;
mod format;

pub use device::ReplayDevice;
pub use format::{
    RecordedSample, Recording, RecordingError, RecordingHeader, RecordingWriter, RECORDING_MAGIC,
    RECORDING_VERSION, RECORD_BYTES,
};
