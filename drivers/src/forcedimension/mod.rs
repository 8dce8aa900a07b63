//! Force Dimension devices (omega.x, sigma.x, delta.x, Novint Falcon) through the DHD SDK
//! (`libdhd.so`).
//!
//! The SDK is proprietary: it is loaded at run time ([`ffi`]), never linked, and only the
//! functions lop calls are declared. Which file: `LOP_DHD_LIBRARY` if set, else the daemon
//! config's `[device] dhd_library`, else the loader's search for `libdhd.so` and the usual
//! install directories ([`DEFAULT_LIBRARY_CANDIDATES`]; the SDK's `make install` puts it in
//! `/usr/local/lib`). A missing library, or one of another SDK major version, is a
//! [`DeviceOpenError::Unavailable`](crate::DeviceOpenError::Unavailable) naming every path
//! tried and the fix.
//!
//! `--device dhd:INDEX` names the device by the SDK's enumeration index (`0..N-1`, the order
//! `dhdGetDeviceCount` counts them; `lopd doctor --device dhd` lists them); `--device dhd` is
//! index 0. The ID `dhdOpenID` returns is another number, kept inside the driver.
//!
//! Life of the device:
//! - `open`: load the library (nothing touches the device yet).
//! - `start`: `dhdOpenID`, the device's type, name and serial, its limits from the table in
//!   [`models`] (DHD does not report them), zero force, `dhdEnableForce(DHD_ON)`.
//! - `read` / `write_force`: called by lop's own 1 kHz loop ([`Pacing::SelfPaced`](crate::Pacing)):
//!   `dhdGetPosition`, `dhdGetLinearVelocity`, `dhdGetButtonMask`, `dhdSetForce`, mapped
//!   between DHD's frame in metres and lop's in millimetres ([`frame`]). No allocation: errors
//!   are the thread's DHD error number mapped to a `Copy` [`DeviceError`](crate::DeviceError).
//! - `stop`: zero force, `dhdEnableForce(DHD_OFF)` (BRAKE mode), `dhdClose`. Also on drop.
//!
//! The SDK applies gravity compensation inside `dhdSetForce` (its default), so the force lop
//! writes is the force the hand feels.

mod device;
pub mod ffi;
pub mod frame;
pub mod models;

pub use device::{
    classify_error, DeviceListing, Discovery, ForceDimensionDevice, ForceDimensionStats,
    MAX_DEVICE_INDEX,
};
pub use ffi::{library_candidates, DEFAULT_LIBRARY_CANDIDATES, LIBRARY_ENV};
pub use models::{model_for, DeviceModel};
