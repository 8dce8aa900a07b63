//! The recording of the device stream (`lopd run --record`): what the haptic process logged
//! about it, read back with the replay reader, and the check that it is complete. A recording
//! holds one device's stream (it replays as `--device replay:PATH` on one tool), so `lopd run`
//! takes `--record` with one device only: a soak with two devices records nothing, and its
//! report says so (N/A) instead of passing a check it did not make.

use std::path::{Path, PathBuf};

use serde::Serialize;

use super::report::{check, not_applicable, Check, Evidence};
use super::supervisor::{log_line, number_after};

/// The recording's part of the report.
#[derive(Debug, Clone, Default, Serialize)]
pub(super) struct RecordingReport {
    pub(super) path: Option<String>,
    /// Records the haptic process said it wrote.
    pub(super) logged_records: Option<u64>,
    /// Samples it said it lost (writer behind).
    pub(super) logged_lost: u64,
    /// Records the reader read back.
    pub(super) read_records: Option<u64>,
    /// The reader's refusal.
    pub(super) error: Option<String>,
}

/// The recording named in the log, read back with the replay reader.
pub(super) fn read_recording(log: &str, planned: &Path) -> RecordingReport {
    let mut r = RecordingReport::default();
    let line = log_line(log, &["recorded", "device samples to"]);
    let path = line
        .as_deref()
        .and_then(|l| l.split("device samples to ").nth(1))
        .map(|rest| {
            let p = rest.split(" (").next().unwrap_or(rest).trim();
            PathBuf::from(p)
        })
        .unwrap_or_else(|| planned.to_path_buf());
    r.path = Some(path.display().to_string());
    r.logged_records = line.as_deref().and_then(|l| number_after(l, "recorded"));
    r.logged_lost = line
        .as_deref()
        .and_then(|l| l.rsplit(" (").next())
        .and_then(|tail| number_after(&format!(" {tail}"), " "))
        .filter(|_| line.as_deref().is_some_and(|l| l.contains(" lost")))
        .unwrap_or(0);
    match lop_drivers::replay::Recording::load(&path) {
        Ok(rec) => r.read_records = Some(rec.records().len() as u64),
        Err(e) => r.error = Some(e.to_string()),
    }
    r
}

// ---------------------------------------------------------------------------------------------
// The checks on this evidence.

/// The recording written, nothing lost, and every record read back.
pub(super) fn check_complete(e: &Evidence<'_>) -> Check {
    const NAME: &str = "recording written, complete and readable";
    if e.settings.devices > 1 {
        return not_applicable(
            NAME,
            format!(
                "nothing recorded: `lopd run --record` takes one device (a recording is one \
                 device's stream, replayed on one tool) and this run has {}",
                e.settings.devices
            ),
        );
    }
    let recording = e.recording;
    let rec_ok = recording.error.is_none()
        && recording.logged_lost == 0
        && recording.read_records.is_some()
        && recording.read_records == recording.logged_records;
    check(
        NAME,
        rec_ok,
        format!(
            "{}: {:?} records written, {} lost, {:?} read back{}",
            recording.path.as_deref().unwrap_or("?"),
            recording.logged_records,
            recording.logged_lost,
            recording.read_records,
            match &recording.error {
                Some(e) => format!("; the reader refused it: {e}"),
                None => String::new(),
            }
        ),
    )
}
