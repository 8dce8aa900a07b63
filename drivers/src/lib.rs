//! Haptic device drivers for lop.
//!
//! The haptic loop talks to every device through the [`HapticDevice`] trait: `start` (may
//! allocate, may fail with [`DeviceOpenError`]), then `read` and `write_force` 1000×/s on the RT
//! thread (no allocation, no locks, no formatting; errors are the `Copy` enum [`DeviceError`]),
//! and `stop`, which writes zero force on every exit path.
//!
//! Drivers:
//! - [`mock`]: plays a TOML script of waypoints and records the forces it receives; deterministic,
//!   for tests, benchmarks and demos.
//! - [`hand`]: a stylus held by a simulated hand (two masses, springs and dampers) that follows
//!   a mock script as its intent and yields to the rendered forces; integrated at 10 kHz inside
//!   the device; the stand-in for a person.
//! - [`replay`]: plays a session recording by tick index (deterministic); also the recording
//!   file format and its writer.
//! - [`openhaptics`]: a Phantom Omni / Touch through the proprietary OpenHaptics HD library,
//!   loaded at run time; the device's servo callback is the clock ([`Pacing::DeviceClock`],
//!   [`HapticDevice::run_clocked`]); several devices share the library's one scheduler and one
//!   servo callback ([`openhaptics::OpenHapticsScheduler`]).
//! - [`forcedimension`]: Force Dimension omega / sigma / delta devices through the proprietary
//!   DHD SDK, loaded at run time; paced by lop's own loop, device chosen by the SDK's index.
//!
//! Units and frame are the device's own (OpenHaptics): millimetres, newtons, +x right, +y up,
//! +z toward the user.

mod device;
pub mod forcedimension;
pub mod hand;
pub mod mock;
pub mod openhaptics;
pub mod replay;
mod spec;
mod vendor_lib;

pub use device::{
    DeviceError, DeviceLimits, DeviceOpenError, DeviceSample, HapticDevice, Pacing, ServoClock,
    ServoControl, ServoEnd, ServoRun, ServoTick, BUTTON_CUT, BUTTON_GRAB, BUTTON_HEAT,
};
pub use spec::{DeviceSpec, DeviceSpecError, DEVICE_SPEC_FORMS};
