//! The device contract: what every driver (mock, replay, OpenHaptics) offers the haptic loop.
//!
//! A device's life is `start → (read, write_force)* → stop`, in the copper-rs task shape: `start`
//! may allocate and fail with a rich [`DeviceOpenError`]; `read` and `write_force` run on the
//! 1 kHz RT thread and must not allocate, lock, format or make syscalls other than the device's
//! own, so their error is the plain `Copy` enum [`DeviceError`]; `stop` writes zero force and
//! releases the device, on every exit path (OpenHaptics keeps rendering the last force it was
//! given).
//!
//! A device with its own servo clock ([`Pacing::DeviceClock`], OpenHaptics) is driven through
//! [`HapticDevice::run_clocked`] instead: the driver calls the loop's tick inside its servo
//! callback, on its scheduler thread, with the same RT rules from the second call on.
//!
//! Everything here is in the device's own frame and units (OpenHaptics convention): millimetres,
//! newtons, +x to the user's right, +y up, +z toward the user. The daemon maps device millimetres
//! into scene metres with the scene's workspace transform.

use crate::mock::ScriptError;
use crate::replay::RecordingError;

/// Device button 1 (OpenHaptics `HD_DEVICE_BUTTON_1`): grab / pick tissue.
pub const BUTTON_GRAB: u32 = 1 << 0;
/// Device button 2 (OpenHaptics `HD_DEVICE_BUTTON_2`): electrocautery (heat).
pub const BUTTON_HEAT: u32 = 1 << 1;
/// The cut button: a cautery's electrosurgical cut (the tissue its heat vaporises is cut
/// away). Not a physical button of its own on a two-button stylus: scripts press it as
/// `"cut"`.
pub const BUTTON_CUT: u32 = 1 << 2;

/// One reading of the device, in the device's own frame and units (OpenHaptics: mm, +x right,
/// +y up, +z toward the user).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DeviceSample {
    /// Tool-tip position, mm.
    pub position_mm: [f64; 3],
    /// Tool-tip velocity, mm/s.
    pub velocity_mm_s: [f64; 3],
    /// Pressed buttons, a bit set of [`BUTTON_GRAB`], [`BUTTON_HEAT`], [`BUTTON_CUT`].
    pub buttons: u32,
}

impl DeviceSample {
    /// Whether every button in `mask` is pressed.
    pub fn pressed(&self, mask: u32) -> bool {
        self.buttons & mask == mask
    }

    /// Whether position and velocity are all finite (the loop's first validation step).
    pub fn is_finite(&self) -> bool {
        self.position_mm
            .iter()
            .chain(&self.velocity_mm_s)
            .all(|v| v.is_finite())
    }
}

/// What a device can render and reach.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DeviceLimits {
    /// Peak force, N (OpenHaptics `HD_NOMINAL_MAX_FORCE`).
    pub max_force_n: f64,
    /// Force the device can hold indefinitely, N (`HD_NOMINAL_MAX_CONTINUOUS_FORCE`).
    pub max_continuous_force_n: f64,
    /// Stiffness beyond which the device buzzes, N/mm (`HD_NOMINAL_MAX_STIFFNESS`).
    pub max_stiffness_n_per_mm: f64,
    /// Lower corner of the usable workspace box, mm.
    pub workspace_min_mm: [f64; 3],
    /// Upper corner of the usable workspace box, mm.
    pub workspace_max_mm: [f64; 3],
}

impl DeviceLimits {
    /// Whether `position_mm` lies in the usable workspace box (bounds included). NaN is outside.
    pub fn in_workspace(&self, position_mm: [f64; 3]) -> bool {
        (0..3).all(|i| {
            position_mm[i] >= self.workspace_min_mm[i] && position_mm[i] <= self.workspace_max_mm[i]
        })
    }
}

/// Who paces the haptic loop.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Pacing {
    /// lop's own RT thread with absolute deadlines (mock, replay).
    SelfPaced,
    /// The device's servo callback is the clock (OpenHaptics' scheduler thread).
    DeviceClock,
}

/// An error on the RT path: plain and `Copy`, so reporting it never allocates.
///
/// The variants mirror the OpenHaptics error classes (as the HD API reference defines them).
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum DeviceError {
    /// The device reported a hardware fault (`HD_DEVICE_FAULT`, `HD_TIMER_ERROR`).
    #[error("device fault")]
    Fault,
    /// The link to the device failed (`HD_COMM_ERROR`, `HD_COMM_CONFIG_ERROR`).
    #[error("device communication error")]
    Communication,
    /// The commanded force exceeded the device's limit (`HD_EXCEEDED_MAX_FORCE`,
    /// `HD_EXCEEDED_MAX_FORCE_IMPULSE`); the device output zero instead.
    #[error("force limit exceeded")]
    ForceLimitExceeded,
    /// The handle moved faster than the device allows (`HD_EXCEEDED_MAX_VELOCITY`).
    #[error("velocity limit exceeded")]
    VelocityLimitExceeded,
    /// The motors are too warm to render force (`HD_WARM_MOTORS`).
    #[error("motors too warm")]
    MotorsWarm,
    /// A commanded force had a NaN or infinite component; the device output zero instead.
    #[error("non-finite force refused")]
    NonFiniteForce,
    /// `read` or `write_force` before `start`.
    #[error("device not started")]
    NotStarted,
    /// `read` or `write_force` after `stop`.
    #[error("device stopped")]
    Stopped,
}

impl DeviceError {
    /// Whether the loop may keep going: force errors are recoverable (zero the force and go on),
    /// device, communication and lifecycle errors are not.
    pub fn is_recoverable(&self) -> bool {
        match self {
            Self::ForceLimitExceeded
            | Self::VelocityLimitExceeded
            | Self::MotorsWarm
            | Self::NonFiniteForce => true,
            Self::Fault | Self::Communication | Self::NotStarted | Self::Stopped => false,
        }
    }
}

/// Why a device could not be opened or started. Off the RT path, so it may carry text.
#[derive(Debug, thiserror::Error)]
pub enum DeviceOpenError {
    /// The mock's script could not be read or is invalid.
    #[error(transparent)]
    Script(#[from] ScriptError),
    /// The recording to replay could not be read or is invalid.
    #[error(transparent)]
    Recording(#[from] RecordingError),
    /// The driver or its device is not available on this machine (library missing, driver not
    /// built, device not connected).
    #[error("device `{device}` is not available: {reason}")]
    Unavailable {
        /// The device as the user named it.
        device: String,
        /// What is missing and, where known, how to fix it.
        reason: String,
    },
    /// The device was found but refused to initialise or start streaming.
    #[error("device `{device}` failed to start: {reason}")]
    Start {
        /// The device as the user named it.
        device: String,
        /// The driver's or vendor library's explanation.
        reason: String,
    },
}

/// A haptic device as the haptic loop sees it.
///
/// `read` and `write_force` are called 1000×/s on the RT thread: implementations must not
/// allocate, lock, format strings or make syscalls other than the device I/O itself.
pub trait HapticDevice: Send {
    /// Human-readable name for logs (not called on the RT path).
    fn name(&self) -> &str;

    /// What the device can render and reach.
    fn limits(&self) -> DeviceLimits;

    /// Whether lop's RT thread or the device's servo callback paces the loop.
    fn pacing(&self) -> Pacing;

    /// Start streaming (may allocate; called before the RT loop).
    fn start(&mut self) -> Result<(), DeviceOpenError>;

    /// Read the current sample. `t` = seconds since the loop started (tick index × period for a
    /// self-paced loop): the mock plays its script at `t`, so runs are deterministic.
    fn read(&mut self, t: f64) -> Result<DeviceSample, DeviceError>;

    /// Command a force in newtons, device frame. The caller guarantees finite and clamped; the
    /// driver still refuses non-finite (returns `Err`, writes zero).
    fn write_force(&mut self, force_n: [f64; 3]) -> Result<(), DeviceError>;

    /// Write zero force and release the device. Idempotent. Called on every exit path.
    fn stop(&mut self);

    /// Runs `tick` inside the device's own servo callback, once per servo tick, on the device's
    /// scheduler thread, until `tick` returns [`ServoControl::Stop`], the device fails or its
    /// scheduler stalls; blocks the calling thread meanwhile. Only for
    /// [`Pacing::DeviceClock`] devices (the default refuses).
    ///
    /// Inside `tick`, the devices it is given (this one; a driver that runs several devices on
    /// one servo clock gives them all, in order) read and write within the servo frame; the RT
    /// rules hold there. The first call may be slow (the caller may set up there, e.g. build
    /// state that must live on the scheduler thread); every later call must not allocate, lock,
    /// format or block. When `tick` stops, and on every other way out (a fatal device error, a
    /// panic in `tick`), the driver writes zero force to every device in that same frame.
    fn run_clocked(&mut self, tick: &mut ServoTick<'_>) -> Result<ServoRun, DeviceOpenError> {
        let _ = tick;
        Err(DeviceOpenError::Unavailable {
            device: self.name().to_owned(),
            reason: "this device is paced by lop's own loop, not by a servo callback".into(),
        })
    }
}

/// What a servo tick asks of the device-clocked driver.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ServoControl {
    /// Call again next servo tick.
    Continue,
    /// Write zero force to every device and stop calling (OpenHaptics `HD_CALLBACK_DONE`).
    Stop,
}

/// When a servo tick runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ServoClock {
    /// Servo callbacks so far (0 for the first one).
    pub tick: u64,
    /// `CLOCK_MONOTONIC` at the start of the callback, ns.
    pub now_ns: u64,
}

/// The per-tick closure a device-clocked driver runs in its servo callback, given the devices
/// of that clock (one, or several sharing the vendor's scheduler) inside their frames. `Send`:
/// it runs on the device's scheduler thread.
pub type ServoTick<'a> =
    dyn FnMut(&mut [&mut dyn HapticDevice], ServoClock) -> ServoControl + Send + 'a;

/// Why a device-clocked run ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ServoEnd {
    /// The tick asked to stop.
    Requested,
    /// A device reported an unrecoverable error; zero force was written to every device in
    /// that frame.
    Device(DeviceError),
    /// The tick panicked; zero force was written to every device in that frame.
    Panicked,
    /// The scheduler stopped calling back (the device or its link died).
    Stalled,
}

/// How a device-clocked run went.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ServoRun {
    /// Servo callbacks that ran the tick.
    pub ticks: u64,
    /// Why it ended.
    pub end: ServoEnd,
}

/// `CLOCK_MONOTONIC` now, ns (a vDSO call: no syscall, no allocation).
pub(crate) fn monotonic_ns() -> u64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid, writable timespec; CLOCK_MONOTONIC always exists on Linux.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) };
    ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn force_errors_are_recoverable_device_errors_are_not() {
        assert!(DeviceError::ForceLimitExceeded.is_recoverable());
        assert!(DeviceError::NonFiniteForce.is_recoverable());
        assert!(!DeviceError::Fault.is_recoverable());
        assert!(!DeviceError::Communication.is_recoverable());
        assert!(!DeviceError::NotStarted.is_recoverable());
    }

    #[test]
    fn workspace_check_rejects_nan() {
        let limits = crate::mock::MockDevice::omni_limits();
        assert!(limits.in_workspace([0.0, 0.0, 0.0]));
        assert!(limits.in_workspace([80.0, -60.0, 35.0]));
        assert!(!limits.in_workspace([80.1, 0.0, 0.0]));
        assert!(!limits.in_workspace([f64::NAN, 0.0, 0.0]));
    }
}
