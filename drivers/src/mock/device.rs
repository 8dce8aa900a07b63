//! The mock device: plays a [`MockScript`] and records the forces it is sent.
//!
//! Deterministic by construction: `read(t)` is the script sampled at `t`, with no state carried
//! between reads, so a run paced by tick index reproduces bit for bit. `new` allocates everything
//! (the force ring); `read`, `write_force` and `stop` are pure memory operations.

use std::io;
use std::path::Path;

use super::record::{write_force_csv, ForceRecord, ForceRing, FORCE_RECORD_CAPACITY};
use super::script::MockScript;
use crate::device::{
    DeviceError, DeviceLimits, DeviceOpenError, DeviceSample, HapticDevice, Pacing,
};

/// A force is over the limit only if it exceeds it by more than this relative margin, so a force
/// the caller clamped to exactly the limit is not refused over a rounding error.
pub(crate) const FORCE_LIMIT_TOLERANCE: f64 = 1e-9;

/// Where the device is in its `new → start → stop` life.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Phase {
    Created,
    Running,
    Stopped,
}

/// A scripted device for tests, benchmarks and demos without hardware.
///
/// Like a real device it refuses what it cannot render: a non-finite force, or one above
/// `limits.max_force_n`, returns an error and renders (records) zero instead, and the refusal is
/// counted in [`rejected_forces`](Self::rejected_forces) so tests can assert the daemon never
/// sent one.
#[derive(Debug)]
pub struct MockDevice {
    script: MockScript,
    limits: DeviceLimits,
    /// `"mock (<script name>)"`, built once so `name()` never formats.
    name: String,
    phase: Phase,
    /// Run time of the latest `read`; stamps the forces written after it.
    last_read_t: f64,
    record: ForceRing,
    rejected_forces: u64,
}

impl MockDevice {
    /// A mock playing `script` with `limits`, recording the last
    /// [`FORCE_RECORD_CAPACITY`] forces (preallocated here).
    pub fn new(script: MockScript, limits: DeviceLimits) -> MockDevice {
        Self::with_record_capacity(script, limits, FORCE_RECORD_CAPACITY)
    }

    /// As [`new`](Self::new), keeping the last `capacity` forces (at least 1).
    pub fn with_record_capacity(
        script: MockScript,
        limits: DeviceLimits,
        capacity: usize,
    ) -> MockDevice {
        MockDevice {
            name: format!("mock ({})", script.name()),
            script,
            limits,
            phase: Phase::Created,
            last_read_t: 0.0,
            record: ForceRing::with_capacity(capacity),
            rejected_forces: 0,
        }
    }

    /// The Phantom Omni's figures (the vendor's published specifications): 3.3 N peak, 0.88 N
    /// continuous, 0.7 N/mm nominal max stiffness, usable workspace ±80 × ±60 × ±35 mm.
    pub fn omni_limits() -> DeviceLimits {
        DeviceLimits {
            max_force_n: 3.3,
            max_continuous_force_n: 0.88,
            max_stiffness_n_per_mm: 0.7,
            workspace_min_mm: [-80.0, -60.0, -35.0],
            workspace_max_mm: [80.0, 60.0, 35.0],
        }
    }

    /// The script being played.
    pub fn script(&self) -> &MockScript {
        &self.script
    }

    /// The forces rendered so far, oldest first: the last
    /// [`capacity`](ForceRecord::capacity) of them, each stamped with the run time of the read
    /// before it. Refused forces appear as zero; `stop` appends a final zero.
    pub fn force_record(&self) -> ForceRecord<'_> {
        self.record.view()
    }

    /// The force currently rendered: the newest record entry, zero before any write.
    pub fn last_force(&self) -> [f64; 3] {
        self.record
            .view()
            .last()
            .map_or([0.0; 3], |(_, force)| force)
    }

    /// Whether `stop` has been called (and `start` not since).
    pub fn stopped(&self) -> bool {
        self.phase == Phase::Stopped
    }

    /// Forces refused as non-finite or above the force limit: zero for a well-behaved caller.
    pub fn rejected_forces(&self) -> u64 {
        self.rejected_forces
    }

    /// Writes the force record as CSV: a `t,fx,fy,fz` header, then one row per entry, oldest
    /// first, in seconds and newtons.
    pub fn write_force_csv(&self, path: &Path) -> io::Result<()> {
        write_force_csv(self.force_record(), path)
    }

    /// Whether the device can render `force_n`: finite, and within the force limit.
    fn check_force(&self, force_n: [f64; 3]) -> Result<(), DeviceError> {
        if !force_n.iter().all(|f| f.is_finite()) {
            return Err(DeviceError::NonFiniteForce);
        }
        let magnitude = force_n.iter().map(|f| f * f).sum::<f64>().sqrt();
        if magnitude > self.limits.max_force_n * (1.0 + FORCE_LIMIT_TOLERANCE) {
            return Err(DeviceError::ForceLimitExceeded);
        }
        Ok(())
    }

    /// Fails unless running.
    fn check_running(&self) -> Result<(), DeviceError> {
        match self.phase {
            Phase::Running => Ok(()),
            Phase::Created => Err(DeviceError::NotStarted),
            Phase::Stopped => Err(DeviceError::Stopped),
        }
    }
}

impl HapticDevice for MockDevice {
    fn name(&self) -> &str {
        &self.name
    }

    fn limits(&self) -> DeviceLimits {
        self.limits
    }

    fn pacing(&self) -> Pacing {
        Pacing::SelfPaced
    }

    /// Starts (or restarts after `stop`); never fails.
    fn start(&mut self) -> Result<(), DeviceOpenError> {
        self.phase = Phase::Running;
        Ok(())
    }

    /// The script's sample at `t` (broken as a sample fault active at `t` says), or the injected
    /// device fault active at `t`.
    fn read(&mut self, t: f64) -> Result<DeviceSample, DeviceError> {
        self.check_running()?;
        self.last_read_t = t;
        let device_fault = self
            .script
            .faults()
            .iter()
            .find(|fault| fault.contains(t) && !fault.error.is_recoverable());
        match device_fault {
            Some(fault) => Err(fault.error),
            None => {
                let sample = self.script.sample(t);
                Ok(match self.script.sample_fault_at(t) {
                    Some(fault) => fault.apply(sample, &self.limits),
                    None => sample,
                })
            }
        }
    }

    /// Records `force_n`, or zero (with an error) if it is non-finite, above the force limit, or
    /// an injected fault is active at the time of the last read.
    fn write_force(&mut self, force_n: [f64; 3]) -> Result<(), DeviceError> {
        self.check_running()?;
        let t = self.last_read_t;
        let injected = self.script.faults().iter().find(|f| f.contains(t));
        let verdict = match injected {
            Some(fault) => Err(fault.error),
            None => self
                .check_force(force_n)
                .inspect_err(|_| self.rejected_forces += 1),
        };
        self.record
            .push(t, if verdict.is_ok() { force_n } else { [0.0; 3] });
        verdict
    }

    /// Records a final zero force if running, then marks the device stopped. Idempotent.
    fn stop(&mut self) {
        if self.phase == Phase::Running {
            self.record.push(self.last_read_t, [0.0; 3]);
        }
        self.phase = Phase::Stopped;
    }
}
