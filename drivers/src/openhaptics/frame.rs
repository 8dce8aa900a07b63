//! [`ServoFrame`]: one device as the tick sees it inside a servo frame — its reads and writes,
//! each made while it is the library's current device, and the errors the library reports.
//!
//! libHD's state calls (`hdGetDoublev`, `hdSetDoublev`, `hdEnable`, …) apply to the current
//! device, so every read and write makes its device current first: with several devices on one
//! scheduler the tick may read one, then another, then write the first. The library keeps one
//! error stack for every device, each error naming its device: an error one device's check pops
//! for another device of the same scheduler is parked ([`ParkedErrors`]) and reported by that
//! device's next read or write, never by the device that happened to look.

use std::ffi::c_uint;
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::Arc;

use super::ffi::{self, HdApi, HdEnum, Hhd};
use crate::device::{
    DeviceError, DeviceLimits, DeviceOpenError, DeviceSample, HapticDevice, Pacing,
};

/// How many queued errors one `hdGetError` drain reads at most (the stack is short; a bound
/// keeps a misbehaving library from spinning the servo thread).
pub(super) const MAX_ERRORS_PER_DRAIN: usize = 16;

/// Maps an HD error code to the driver's error class; `None` for `HD_SUCCESS`.
///
/// Force errors are recoverable; device, communication, timer errors and everything unknown or
/// unexpected (invalid enum, frame errors, …) are not — an unknown state is not a safe one.
pub fn classify_error(code: c_uint) -> Option<DeviceError> {
    Some(match code {
        ffi::HD_SUCCESS => return None,
        ffi::HD_WARM_MOTORS => DeviceError::MotorsWarm,
        ffi::HD_EXCEEDED_MAX_FORCE | ffi::HD_EXCEEDED_MAX_FORCE_IMPULSE | ffi::HD_FORCE_ERROR => {
            DeviceError::ForceLimitExceeded
        }
        ffi::HD_EXCEEDED_MAX_VELOCITY => DeviceError::VelocityLimitExceeded,
        ffi::HD_COMM_ERROR | ffi::HD_COMM_CONFIG_ERROR => DeviceError::Communication,
        _ => DeviceError::Fault,
    })
}

/// The worse of two errors: an unrecoverable one stays; otherwise the later one.
fn worse(earlier: Option<DeviceError>, later: Option<DeviceError>) -> Option<DeviceError> {
    match (earlier, later) {
        (Some(a), _) if !a.is_recoverable() => Some(a),
        (a, None) => a,
        (_, b) => b,
    }
}

/// Counters of one device's servo traffic.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct OpenHapticsStats {
    /// Forces scaled down to the device's peak force.
    pub clamped_forces: u64,
    /// Forces refused as non-finite (zero written instead).
    pub non_finite_forces: u64,
    /// Recoverable (force) errors the device reported.
    pub recoverable_errors: u64,
    /// The last HD error code seen (0 if none).
    pub last_error_code: u32,
}

/// Errors popped from the library's one error stack on behalf of another device of the same
/// scheduler: one slot per device handle, holding the worst code not yet reported (0: none).
///
/// Every access is on the scheduler thread (or on the thread that runs a frame while the
/// scheduler does not); the slots are atomics so the frames that share them stay `Send`.
pub(super) struct ParkedErrors {
    slots: Vec<(Hhd, AtomicU32)>,
}

impl ParkedErrors {
    /// One empty slot per handle of the scheduler's devices.
    pub(super) fn new(handles: &[Hhd]) -> ParkedErrors {
        ParkedErrors {
            slots: handles.iter().map(|&h| (h, AtomicU32::new(0))).collect(),
        }
    }

    /// Parks `code`, which the library reported for device `hhd`, if that is another device
    /// of this scheduler than `own`; whether it did. An unrecoverable code already parked stays.
    fn park(&self, own: Hhd, hhd: Hhd, code: c_uint) -> bool {
        if hhd == own {
            return false;
        }
        let Some((_, slot)) = self.slots.iter().find(|(h, _)| *h == hhd) else {
            return false;
        };
        let _ = slot.fetch_update(Ordering::Relaxed, Ordering::Relaxed, |old| {
            let replace =
                old == ffi::HD_SUCCESS || classify_error(old).is_some_and(|e| e.is_recoverable());
            replace.then_some(code)
        });
        true
    }

    /// The code parked for device `own`, if any, and empties its slot.
    fn take(&self, own: Hhd) -> Option<c_uint> {
        let (_, slot) = self.slots.iter().find(|(h, _)| *h == own)?;
        match slot.swap(ffi::HD_SUCCESS, Ordering::Relaxed) {
            ffi::HD_SUCCESS => None,
            code => Some(code),
        }
    }
}

/// The device as seen inside a servo frame: what the tick closure reads and writes.
pub(super) struct ServoFrame {
    pub(super) api: &'static HdApi,
    /// The device's handle (`HD_INVALID_HANDLE` before it is started).
    pub(super) hhd: Hhd,
    /// For logs: the device as the user named it and the library it came from.
    pub(super) name: String,
    pub(super) limits: DeviceLimits,
    /// Inside `hdBeginFrame`/`hdEndFrame`.
    pub(super) open: bool,
    /// An error seen at the end of the previous frame, reported by the next `read`.
    pub(super) pending: Option<DeviceError>,
    /// An unrecoverable error was handed to the tick (it must stop).
    pub(super) fatal_reported: Option<DeviceError>,
    pub(super) stats: OpenHapticsStats,
    /// The other devices' errors, shared by the frames of one scheduler (set while started).
    pub(super) parked: Option<Arc<ParkedErrors>>,
}

// SAFETY: ServoFrame holds only the immutable API table, plain data, counters and atomics.
unsafe impl Send for ServoFrame {}

impl ServoFrame {
    fn make_current(&self) {
        // SAFETY: valid handle of a started device; the library's state calls apply to it next.
        unsafe { (self.api.make_current_device)(self.hhd) };
    }

    /// Makes the device current and begins its frame.
    pub(super) fn begin(&mut self) {
        self.make_current();
        // SAFETY: valid handle of a started device; called on the scheduler thread.
        unsafe { (self.api.begin_frame)(self.hhd) };
        self.open = true;
    }

    /// Ends the device's frame (its force is committed there), if it is open.
    pub(super) fn end(&mut self) {
        if self.open {
            self.make_current();
            // SAFETY: as `begin`.
            unsafe { (self.api.end_frame)(self.hhd) };
            self.open = false;
        }
    }

    /// Counts an error code reported for this device; its class.
    fn note(&mut self, code: c_uint) -> Option<DeviceError> {
        let e = classify_error(code)?;
        self.stats.last_error_code = code;
        if e.is_recoverable() {
            self.stats.recoverable_errors += 1;
        }
        Some(e)
    }

    /// This device's errors: the ones parked for it, then the error stack until `HD_SUCCESS`
    /// (another device's errors are parked for it). The worst (unrecoverable over
    /// recoverable). Allocation-free.
    pub(super) fn drain(&mut self) -> Option<DeviceError> {
        let mut worst = None;
        if let Some(code) = self.parked.as_ref().and_then(|p| p.take(self.hhd)) {
            let e = self.note(code);
            worst = worse(worst, e);
        }
        for _ in 0..MAX_ERRORS_PER_DRAIN {
            // SAFETY: plain HD call returning a 12-byte struct by value.
            let info = unsafe { (self.api.get_error)() };
            if info.error_code == ffi::HD_SUCCESS {
                break;
            }
            let parked = self
                .parked
                .as_ref()
                .is_some_and(|p| p.park(self.hhd, info.hhd, info.error_code));
            if !parked {
                let e = self.note(info.error_code);
                worst = worse(worst, e);
            }
        }
        worst
    }

    /// Errors raised by `hdEndFrame` (the force is committed there): kept for the next read.
    pub(super) fn collect_end_of_frame_errors(&mut self) {
        let now = self.drain();
        self.pending = worse(self.pending, now);
    }

    /// Sets the force of this device (made current first) in its open frame.
    pub(super) fn set_force_raw(&mut self, f: [f64; 3]) {
        self.make_current();
        // SAFETY: three doubles, as HD_CURRENT_FORCE expects.
        unsafe { (self.api.set_doublev)(ffi::HD_CURRENT_FORCE, f.as_ptr()) };
    }

    fn report(&mut self, e: DeviceError) -> DeviceError {
        if !e.is_recoverable() {
            self.fatal_reported = Some(e);
        }
        e
    }

    fn get3(&self, what: HdEnum) -> [f64; 3] {
        let mut v = [0.0; 3];
        // SAFETY: three doubles for position / velocity.
        unsafe { (self.api.get_doublev)(what, v.as_mut_ptr()) };
        v
    }
}

impl HapticDevice for ServoFrame {
    fn name(&self) -> &str {
        &self.name
    }

    fn limits(&self) -> DeviceLimits {
        self.limits
    }

    fn pacing(&self) -> Pacing {
        Pacing::DeviceClock
    }

    fn start(&mut self) -> Result<(), DeviceOpenError> {
        Ok(())
    }

    /// Position, velocity and buttons of this servo frame (the device made current first);
    /// any error the device reported since the last check (including at the end of the
    /// previous frame, or popped by another device's check) fails the read.
    fn read(&mut self, _t: f64) -> Result<DeviceSample, DeviceError> {
        self.make_current();
        let position_mm = self.get3(ffi::HD_CURRENT_POSITION);
        let velocity_mm_s = self.get3(ffi::HD_CURRENT_VELOCITY);
        let mut buttons: std::ffi::c_int = 0;
        // SAFETY: one int for HD_CURRENT_BUTTONS.
        unsafe { (self.api.get_integerv)(ffi::HD_CURRENT_BUTTONS, &mut buttons) };
        let now = self.drain();
        let earlier = self.pending.take();
        if let Some(e) = worse(earlier, now) {
            return Err(self.report(e));
        }
        Ok(DeviceSample {
            position_mm,
            velocity_mm_s,
            buttons: buttons as u32,
        })
    }

    /// Writes the force (the device made current first), scaled down to the device's peak
    /// force if above it; a non-finite force or a force error from the device writes zero
    /// instead and returns the error.
    fn write_force(&mut self, force_n: [f64; 3]) -> Result<(), DeviceError> {
        let magnitude = force_n.iter().map(|f| f * f).sum::<f64>().sqrt();
        if !magnitude.is_finite() {
            self.stats.non_finite_forces += 1;
            self.set_force_raw([0.0; 3]);
            return Err(DeviceError::NonFiniteForce);
        }
        let max = self.limits.max_force_n;
        let force = if magnitude > max {
            self.stats.clamped_forces += 1;
            let k = max / magnitude;
            [force_n[0] * k, force_n[1] * k, force_n[2] * k]
        } else {
            force_n
        };
        self.set_force_raw(force);
        if let Some(e) = self.drain() {
            self.set_force_raw([0.0; 3]);
            return Err(self.report(e));
        }
        Ok(())
    }

    /// Zero force in the current frame (the tick's own stop; the driver's `stop` releases).
    fn stop(&mut self) {
        self.set_force_raw([0.0; 3]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn force_errors_are_recoverable_device_errors_stop() {
        assert_eq!(classify_error(ffi::HD_SUCCESS), None);
        for code in [0x0200, 0x0201, 0x0202, 0x0203, 0x0204] {
            assert!(classify_error(code).unwrap().is_recoverable(), "{code:#x}");
        }
        for code in [
            0x0300, 0x0301, 0x0302, 0x0303, 0x0304, 0x0100, 0x0402, 0x9999,
        ] {
            assert!(!classify_error(code).unwrap().is_recoverable(), "{code:#x}");
        }
        assert_eq!(classify_error(0x0302), Some(DeviceError::Communication));
    }

    #[test]
    fn another_devices_error_is_parked_for_it_and_the_worst_stays() {
        let parked = ParkedErrors::new(&[0, 1]);
        assert!(
            !parked.park(0, 0, ffi::HD_EXCEEDED_MAX_FORCE),
            "own errors are not parked"
        );
        assert!(
            !parked.park(0, 7, ffi::HD_COMM_ERROR),
            "a handle of no device of the scheduler is the looking device's"
        );
        assert!(parked.park(0, 1, ffi::HD_COMM_ERROR));
        assert!(parked.park(0, 1, ffi::HD_EXCEEDED_MAX_FORCE));
        assert_eq!(parked.take(0), None);
        assert_eq!(parked.take(1), Some(ffi::HD_COMM_ERROR));
        assert_eq!(parked.take(1), None);
        assert!(parked.park(1, 0, ffi::HD_EXCEEDED_MAX_FORCE));
        assert!(parked.park(1, 0, ffi::HD_DEVICE_FAULT));
        assert_eq!(parked.take(0), Some(ffi::HD_DEVICE_FAULT));
    }
}
