//! The Phantom Omni / Geomagic Touch through the OpenHaptics HD library (`libHD.so`).
//!
//! The library is proprietary: it is loaded at run time ([`ffi`]), never linked, and only the
//! symbols lop calls are declared. Which file: `LOP_HD_LIBRARY` if set, else the daemon config's
//! `[device] hd_library`, else the loader's search for `libHD.so` and the usual install
//! directories ([`DEFAULT_LIBRARY_CANDIDATES`]). A missing library is a
//! [`DeviceOpenError::Unavailable`](crate::DeviceOpenError::Unavailable) that lists every path
//! tried and the fix — never a silent failure.
//!
//! Life of a device:
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
//!
//! Several devices (two hands) share the library's one scheduler: [`OpenHapticsScheduler`]
//! initialises each by its configured name, starts the scheduler once and runs one servo
//! callback that begins every device's frame, ticks once with all of them and ends every frame;
//! each read and write makes its device current first, since the library's state calls apply
//! to the current device. The modules follow those seams: `frame` (one device inside a servo
//! frame, its errors), `scheduler` (start, the one callback, stop), `device` (the library, the
//! handle, the limits).

mod device;
pub mod ffi;
mod frame;
mod scheduler;

pub use device::OpenHapticsDevice;
pub use ffi::{library_candidates, DEFAULT_LIBRARY_CANDIDATES, LIBRARY_ENV};
pub use frame::{classify_error, OpenHapticsStats};
pub use scheduler::{OpenHapticsScheduler, SERVO_STALL_LIMIT};
