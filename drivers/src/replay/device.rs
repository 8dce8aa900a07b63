//! The replay device: a [`Recording`] played back by tick index, paced by lop's own loop.

use std::path::Path;

use super::format::Recording;
use crate::device::{
    DeviceError, DeviceLimits, DeviceOpenError, DeviceSample, HapticDevice, Pacing,
};

/// Plays a recorded device stream. Deterministic: `read(t)` is the record at tick
/// `round(t × rate)`, so a run paced by tick index replays bit for bit. After the last record
/// the device holds its last pose. Ticks that recorded a device error replay that error.
#[derive(Debug)]
pub struct ReplayDevice {
    recording: Recording,
    /// `"replay (<file>)"`, built once so `name()` never formats.
    name: String,
    running: bool,
    last_force: [f64; 3],
    rejected_forces: u64,
}

impl ReplayDevice {
    /// Reads and validates the recording at `path`.
    pub fn open(path: &Path) -> Result<ReplayDevice, DeviceOpenError> {
        Ok(Self::new(Recording::load(path)?))
    }

    /// Plays `recording`.
    pub fn new(recording: Recording) -> ReplayDevice {
        ReplayDevice {
            name: format!("replay ({})", recording.path().display()),
            recording,
            running: false,
            last_force: [0.0; 3],
            rejected_forces: 0,
        }
    }

    /// The recording being played.
    pub fn recording(&self) -> &Recording {
        &self.recording
    }

    /// The force last written (zero after `stop`).
    pub fn last_force(&self) -> [f64; 3] {
        self.last_force
    }

    /// Forces refused as non-finite or above the recorded device's limit.
    pub fn rejected_forces(&self) -> u64 {
        self.rejected_forces
    }
}

impl HapticDevice for ReplayDevice {
    fn name(&self) -> &str {
        &self.name
    }

    /// The recorded device's limits, so the loop clamps as it did when recording.
    fn limits(&self) -> DeviceLimits {
        self.recording.header().limits
    }

    fn pacing(&self) -> Pacing {
        Pacing::SelfPaced
    }

    fn start(&mut self) -> Result<(), DeviceOpenError> {
        if self.recording.records().is_empty() {
            return Err(DeviceOpenError::Start {
                device: self.name.clone(),
                reason: "the recording holds no samples".into(),
            });
        }
        self.running = true;
        Ok(())
    }

    fn read(&mut self, t: f64) -> Result<DeviceSample, DeviceError> {
        if !self.running {
            return Err(DeviceError::NotStarted);
        }
        match self.recording.at(t) {
            Some(r) => match r.error {
                Some(e) => Err(e),
                None => Ok(r.sample),
            },
            None => Err(DeviceError::NotStarted),
        }
    }

    fn write_force(&mut self, force_n: [f64; 3]) -> Result<(), DeviceError> {
        if !self.running {
            return Err(DeviceError::NotStarted);
        }
        let magnitude = force_n.iter().map(|f| f * f).sum::<f64>().sqrt();
        if !magnitude.is_finite() {
            self.rejected_forces += 1;
            self.last_force = [0.0; 3];
            return Err(DeviceError::NonFiniteForce);
        }
        if magnitude > self.limits().max_force_n * (1.0 + 1e-9) {
            self.rejected_forces += 1;
            self.last_force = [0.0; 3];
            return Err(DeviceError::ForceLimitExceeded);
        }
        self.last_force = force_n;
        Ok(())
    }

    fn stop(&mut self) {
        self.last_force = [0.0; 3];
        self.running = false;
    }
}
