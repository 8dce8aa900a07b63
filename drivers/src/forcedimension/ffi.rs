//! The few Force Dimension DHD declarations lop uses, written from the vendor's published DHD
//! API reference, and the run-time loading of `libdhd.so`.
//!
//! The SDK is proprietary and cannot be shipped, so nothing links against it: [`DhdApi::load`]
//! `dlopen`s the library and resolves each symbol by name. The library stays loaded for the
//! life of the process.
//!
//! Facts relied on (DHD API reference, SDK 3.x):
//! - every device call takes the device ID as its last argument, a C `char`; `dhdOpenID(char
//!   index)` opens the device at enumeration index `0..dhdGetDeviceCount()` and returns its ID
//!   (a different number space from the index), or -1;
//! - calls return 0 on success and -1 on error, except `dhdGetPosition`, which may also return
//!   [`DHD_TIMEGUARD`] (the SDK's throttling answered from its cache: still a success), and
//!   `dhdSetForce`, which may also return [`DHD_MOTOR_SATURATED`] (a motor could not deliver
//!   its share; the SDK scaled the force, keeping its direction: still a success);
//! - on error the thread's last error is set: `dhdErrorGetLast()` is its number,
//!   `dhdErrorGetLastStr()` a static description;
//! - positions are metres, velocities metres per second, forces newtons, all in the device's
//!   own frame (see [`super`] for the axes); `dhdGetButtonMask` has bit `i` set while button
//!   `i` is pressed;
//! - `dhdEnableForce(DHD_OFF, id)` disables the motors and puts the device in BRAKE mode.

use std::ffi::{c_char, c_int, c_uchar, c_uint, c_ushort, c_void, CStr};
use std::path::{Path, PathBuf};

use crate::vendor_lib::Library;

/// `DHD_ON` / `DHD_OFF` for `dhdEnableForce`.
pub const DHD_ON: c_uchar = 1;
pub const DHD_OFF: c_uchar = 0;
/// `dhdGetPosition`'s success code when TimeGuard answered from the SDK's cache.
pub const DHD_TIMEGUARD: c_int = 1;
/// `dhdSetForce`'s success code when the force was scaled to what the motors deliver.
pub const DHD_MOTOR_SATURATED: c_int = 2;

// `dhdErrorGetLast()` values (the DHD error enumeration).
pub const DHD_NO_ERROR: c_int = 0;
pub const DHD_ERROR: c_int = 1;
pub const DHD_ERROR_COM: c_int = 2;
pub const DHD_ERROR_DHC_BUSY: c_int = 3;
pub const DHD_ERROR_NO_DRIVER_FOUND: c_int = 4;
pub const DHD_ERROR_NO_DEVICE_FOUND: c_int = 5;
pub const DHD_ERROR_NOT_AVAILABLE: c_int = 6;
pub const DHD_ERROR_TIMEOUT: c_int = 7;
pub const DHD_ERROR_DEVICE_NOT_READY: c_int = 12;
pub const DHD_ERROR_INVALID_INDEX: c_int = 15;
pub const DHD_ERROR_NOT_ENABLED: c_int = 19;
pub const DHD_ERROR_DEVICE_IN_USE: c_int = 20;

/// The vendor's name for an error number, for messages.
pub fn error_name(code: c_int) -> &'static str {
    match code {
        DHD_NO_ERROR => "DHD_NO_ERROR",
        DHD_ERROR => "DHD_ERROR",
        DHD_ERROR_COM => "DHD_ERROR_COM",
        DHD_ERROR_DHC_BUSY => "DHD_ERROR_DHC_BUSY",
        DHD_ERROR_NO_DRIVER_FOUND => "DHD_ERROR_NO_DRIVER_FOUND",
        DHD_ERROR_NO_DEVICE_FOUND => "DHD_ERROR_NO_DEVICE_FOUND",
        DHD_ERROR_NOT_AVAILABLE => "DHD_ERROR_NOT_AVAILABLE",
        DHD_ERROR_TIMEOUT => "DHD_ERROR_TIMEOUT",
        8 => "DHD_ERROR_GEOMETRY",
        9 => "DHD_ERROR_EXPERT_MODE_DISABLED",
        10 => "DHD_ERROR_NOT_IMPLEMENTED",
        11 => "DHD_ERROR_OUT_OF_MEMORY",
        DHD_ERROR_DEVICE_NOT_READY => "DHD_ERROR_DEVICE_NOT_READY",
        13 => "DHD_ERROR_FILE_NOT_FOUND",
        14 => "DHD_ERROR_CONFIGURATION",
        DHD_ERROR_INVALID_INDEX => "DHD_ERROR_INVALID_INDEX",
        16 => "DHD_ERROR_DEPRECATED",
        17 => "DHD_ERROR_NULL_ARGUMENT",
        18 => "DHD_ERROR_REDUNDANT_FAIL",
        DHD_ERROR_NOT_ENABLED => "DHD_ERROR_NOT_ENABLED",
        DHD_ERROR_DEVICE_IN_USE => "DHD_ERROR_DEVICE_IN_USE",
        21 => "DHD_ERROR_INVALID",
        22 => "DHD_ERROR_NO_REGULATION",
        _ => "an unknown DHD error",
    }
}

/// The DHD API generation these declarations are written against; a library of another major
/// version is refused at load (its ABI may differ).
pub const SUPPORTED_MAJOR_VERSION: c_int = 3;

/// The DHD functions lop calls, resolved from the loaded library.
pub struct DhdApi {
    pub get_device_count: unsafe extern "C" fn() -> c_int,
    pub open_id: unsafe extern "C" fn(c_char) -> c_int,
    pub close: unsafe extern "C" fn(c_char) -> c_int,
    pub get_system_type: unsafe extern "C" fn(c_char) -> c_int,
    pub get_system_name: unsafe extern "C" fn(c_char) -> *const c_char,
    pub get_serial_number: unsafe extern "C" fn(*mut c_ushort, c_char) -> c_int,
    pub get_position: unsafe extern "C" fn(*mut f64, *mut f64, *mut f64, c_char) -> c_int,
    pub get_linear_velocity: unsafe extern "C" fn(*mut f64, *mut f64, *mut f64, c_char) -> c_int,
    pub get_button_mask: unsafe extern "C" fn(c_char) -> c_uint,
    pub set_force: unsafe extern "C" fn(f64, f64, f64, c_char) -> c_int,
    pub enable_force: unsafe extern "C" fn(c_uchar, c_char) -> c_int,
    pub error_get_last: unsafe extern "C" fn() -> c_int,
    pub error_get_last_str: unsafe extern "C" fn() -> *const c_char,
    /// The SDK version the library reports, `major.minor.release-revision`.
    pub version: [c_int; 4],
    /// The file that was loaded.
    pub path: PathBuf,
}

/// Default places to look for the library when neither `LOP_DHD_LIBRARY` nor the daemon config
/// names one: the loader's own search (`LD_LIBRARY_PATH`, `ld.so.cache`), then where the SDK's
/// `make install` and distribution packages put it.
pub const DEFAULT_LIBRARY_CANDIDATES: [&str; 5] = [
    "libdhd.so",
    "/usr/local/lib/libdhd.so",
    "/usr/lib/libdhd.so",
    "/usr/lib64/libdhd.so",
    "/usr/lib/x86_64-linux-gnu/libdhd.so",
];

/// The environment variable that names the library to load (it wins over the daemon config).
pub const LIBRARY_ENV: &str = "LOP_DHD_LIBRARY";

/// The libraries to try, in order: `LOP_DHD_LIBRARY` if set, else `configured` if given, else
/// [`DEFAULT_LIBRARY_CANDIDATES`].
pub fn library_candidates(configured: Option<&Path>) -> Vec<PathBuf> {
    crate::vendor_lib::candidates(LIBRARY_ENV, configured, &DEFAULT_LIBRARY_CANDIDATES)
}

/// A NUL-terminated static string from the library, or `None` for NULL.
///
/// # Safety
/// `p` is NULL or points at a NUL-terminated string that stays valid while it is read.
pub unsafe fn c_text(p: *const c_char) -> Option<String> {
    (!p.is_null()).then(|| unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned())
}

impl DhdApi {
    /// Loads the first library of `candidates` that opens. Err: one line per candidate tried,
    /// with the loader's reason, or the symbol a loaded library lacks, or its unsupported
    /// version.
    pub fn load(candidates: &[PathBuf]) -> Result<&'static DhdApi, String> {
        crate::vendor_lib::load(candidates, Self::resolve)
    }

    /// The SDK version as the vendor prints it.
    pub fn version_text(&self) -> String {
        let [a, b, c, d] = self.version;
        format!("{a}.{b}.{c}-{d}")
    }

    // Each transmute's target is the type of the struct field it initialises.
    #[allow(clippy::missing_transmute_annotations)]
    fn resolve(library: &Library) -> Result<DhdApi, String> {
        let path = &library.path;
        let sym = |name: &str| library.symbol(name);
        // The version first, so a missing symbol can be reported with it.
        let mut version = [-1; 4];
        if let Some(p) = sym("dhdGetSDKVersion") {
            // SAFETY: `void dhdGetSDKVersion(int *major, int *minor, int *release, int
            // *revision)` in the DHD API; four valid int pointers.
            unsafe {
                let f = std::mem::transmute::<
                    *mut c_void,
                    unsafe extern "C" fn(*mut c_int, *mut c_int, *mut c_int, *mut c_int),
                >(p);
                let [a, b, c, d] = &mut version;
                f(a, b, c, d);
            }
        }
        let found = if version[0] < 0 {
            "no dhdGetSDKVersion".to_string()
        } else {
            format!(
                "SDK {}.{}.{}-{}",
                version[0], version[1], version[2], version[3]
            )
        };
        let missing = |name: &str| {
            format!(
                "{} ({found}) lacks the symbol `{name}`: is it the Force Dimension DHD library \
                 (libdhd.so, SDK {SUPPORTED_MAJOR_VERSION}.x)?",
                path.display()
            )
        };
        if version[0] != SUPPORTED_MAJOR_VERSION {
            return Err(format!(
                "{}: {found}, but lop is written against the DHD API of SDK \
                 {SUPPORTED_MAJOR_VERSION}.x; install a {SUPPORTED_MAJOR_VERSION}.x SDK",
                path.display()
            ));
        }
        // SAFETY (every transmute below): the symbol has this C signature in the DHD API
        // reference; a function pointer and a data pointer have the same size on Linux.
        macro_rules! f {
            ($name:literal) => {
                unsafe {
                    std::mem::transmute::<*mut c_void, _>(sym($name).ok_or_else(|| missing($name))?)
                }
            };
        }
        Ok(DhdApi {
            get_device_count: f!("dhdGetDeviceCount"),
            open_id: f!("dhdOpenID"),
            close: f!("dhdClose"),
            get_system_type: f!("dhdGetSystemType"),
            get_system_name: f!("dhdGetSystemName"),
            get_serial_number: f!("dhdGetSerialNumber"),
            get_position: f!("dhdGetPosition"),
            get_linear_velocity: f!("dhdGetLinearVelocity"),
            get_button_mask: f!("dhdGetButtonMask"),
            set_force: f!("dhdSetForce"),
            enable_force: f!("dhdEnableForce"),
            error_get_last: f!("dhdErrorGetLast"),
            error_get_last_str: f!("dhdErrorGetLastStr"),
            version,
            path: path.clone(),
        })
    }

    /// The thread's last DHD error as (number, the library's description). Not for the RT
    /// path (it allocates the text).
    pub fn last_error(&self) -> (c_int, String) {
        // SAFETY: plain DHD calls; the string is static in the library.
        let code = unsafe { (self.error_get_last)() };
        let text = unsafe { c_text((self.error_get_last_str)()) }.unwrap_or_default();
        (code, text)
    }
}
