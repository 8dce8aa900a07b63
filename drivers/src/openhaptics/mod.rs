//! The Phantom Omni / Geomagic Touch through the OpenHaptics HD library (`libHD.so`).
//!
//! The library is proprietary: it is loaded at run time ([`ffi`]), never linked, and only the
//! symbols lop calls are declared. Which file: `LOP_HD_LIBRARY` if set, else the daemon config's
//! `[device] hd_library`, else the loader's search for `libHD.so` and the usual install
//! directories ([`DEFAULT_LIBRARY_CANDIDATES`]). A missing library is a
//! [`DeviceOpenError::Unavailable`](crate::DeviceOpenError::Unavailable) that lists every path
//! tried and the fix — never a silent failure.
//!
//! Life of the device:
//! - `open`: load the library (nothing touches the device yet).
//! - `start`: `hdInitDevice` (default or named device), read the device's limits (max and
//!   continuous force, stiffness, usable workspace: the loop clamps to them), enable force
//!   output, start the vendor's servo scheduler.
//! - `run_clocked`: the device is the clock. A callback scheduled with `hdScheduleAsynchronous`
//!   runs the caller's tick once per servo tick inside `hdBeginFrame`/`hdEndFrame` and checks
//!   `hdGetError` every tick: force errors (`HD_EXCEEDED_MAX_FORCE`, …) zero the force and the
//!   loop goes on; device and communication errors end the run with zero force in that frame.
//! - `stop`: zero force (in a scheduler frame) before `hdUnschedule`, `hdStopScheduler`,
//!   `hdDisable(HD_FORCE_OUTPUT)` and `hdDisableDevice`. Also on drop.

mod device;
pub mod ffi;

pub use device::{classify_error, OpenHapticsDevice, OpenHapticsStats, SERVO_STALL_LIMIT};
pub use ffi::{library_candidates, DEFAULT_LIBRARY_CANDIDATES, LIBRARY_ENV};
