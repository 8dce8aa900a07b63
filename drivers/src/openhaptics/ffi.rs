//! The few OpenHaptics HD declarations lop uses, written from the vendor's published HD API
//! reference, and the run-time loading of `libHD.so`.
//!
//! The library and its headers are proprietary and cannot be shipped, so nothing links against
//! it: [`HdApi::load`] `dlopen`s the library and resolves each symbol by name. The library stays
//! loaded for the life of the process (its scheduler thread may outlive any one device).

use std::ffi::{c_char, c_int, c_uint, c_ulong, c_void};
use std::path::{Path, PathBuf};

use crate::vendor_lib::Library;

/// `HHD`: a device handle.
pub type Hhd = c_uint;
/// `HDenum`.
pub type HdEnum = c_uint;
/// `HDCallbackCode`.
pub type HdCallbackCode = c_uint;
/// `HDSchedulerHandle`.
pub type HdSchedulerHandle = c_ulong;
/// A scheduler callback: `HDCallbackCode (*)(void *user_data)`.
pub type HdCallback = unsafe extern "C" fn(*mut c_void) -> HdCallbackCode;

/// `HDErrorInfo` (12 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct HdErrorInfo {
    /// `HDerror`: `HD_SUCCESS` or an error code.
    pub error_code: c_uint,
    /// Vendor-internal detail.
    pub internal_error_code: c_int,
    /// The device it concerns.
    pub hhd: Hhd,
}

pub const HD_SUCCESS: c_uint = 0x0000;
pub const HD_CALLBACK_DONE: HdCallbackCode = 0;
pub const HD_CALLBACK_CONTINUE: HdCallbackCode = 1;
pub const HD_INVALID_HANDLE: Hhd = 0xFFFF_FFFF;
pub const HD_MAX_SCHEDULER_PRIORITY: u16 = 65535;

pub const HD_CURRENT_BUTTONS: HdEnum = 0x2000;
pub const HD_CURRENT_POSITION: HdEnum = 0x2050;
pub const HD_CURRENT_VELOCITY: HdEnum = 0x2051;
pub const HD_CURRENT_FORCE: HdEnum = 0x2700;
pub const HD_DEVICE_MODEL_TYPE: HdEnum = 0x2501;
pub const HD_USABLE_WORKSPACE_DIMENSIONS: HdEnum = 0x2551;
pub const HD_NOMINAL_MAX_STIFFNESS: HdEnum = 0x2602;
pub const HD_NOMINAL_MAX_FORCE: HdEnum = 0x2603;
pub const HD_NOMINAL_MAX_CONTINUOUS_FORCE: HdEnum = 0x2604;
pub const HD_FORCE_OUTPUT: HdEnum = 0x4000;
pub const HD_MAX_FORCE_CLAMPING: HdEnum = 0x4001;

pub const HD_WARM_MOTORS: c_uint = 0x0200;
pub const HD_EXCEEDED_MAX_FORCE: c_uint = 0x0201;
pub const HD_EXCEEDED_MAX_FORCE_IMPULSE: c_uint = 0x0202;
pub const HD_EXCEEDED_MAX_VELOCITY: c_uint = 0x0203;
pub const HD_FORCE_ERROR: c_uint = 0x0204;
pub const HD_DEVICE_FAULT: c_uint = 0x0300;
pub const HD_DEVICE_ALREADY_INITIATED: c_uint = 0x0301;
pub const HD_COMM_ERROR: c_uint = 0x0302;
pub const HD_COMM_CONFIG_ERROR: c_uint = 0x0303;
pub const HD_TIMER_ERROR: c_uint = 0x0304;

/// The vendor's name for an error code, for messages.
pub fn error_name(code: c_uint) -> &'static str {
    match code {
        HD_SUCCESS => "HD_SUCCESS",
        0x0100 => "HD_INVALID_ENUM",
        0x0101 => "HD_INVALID_VALUE",
        0x0102 => "HD_INVALID_OPERATION",
        0x0104 => "HD_BAD_HANDLE",
        HD_WARM_MOTORS => "HD_WARM_MOTORS",
        HD_EXCEEDED_MAX_FORCE => "HD_EXCEEDED_MAX_FORCE",
        HD_EXCEEDED_MAX_FORCE_IMPULSE => "HD_EXCEEDED_MAX_FORCE_IMPULSE",
        HD_EXCEEDED_MAX_VELOCITY => "HD_EXCEEDED_MAX_VELOCITY",
        HD_FORCE_ERROR => "HD_FORCE_ERROR",
        HD_DEVICE_FAULT => "HD_DEVICE_FAULT",
        HD_DEVICE_ALREADY_INITIATED => "HD_DEVICE_ALREADY_INITIATED",
        HD_COMM_ERROR => "HD_COMM_ERROR",
        HD_COMM_CONFIG_ERROR => "HD_COMM_CONFIG_ERROR",
        HD_TIMER_ERROR => "HD_TIMER_ERROR",
        0x0400 => "HD_ILLEGAL_BEGIN",
        0x0401 => "HD_ILLEGAL_END",
        0x0402 => "HD_FRAME_ERROR",
        0x0500 => "HD_INVALID_PRIORITY",
        _ => "an unknown HD error",
    }
}

/// The HD functions lop calls, resolved from the loaded library.
pub struct HdApi {
    pub init_device: unsafe extern "C" fn(*const c_char) -> Hhd,
    pub disable_device: unsafe extern "C" fn(Hhd),
    pub make_current_device: unsafe extern "C" fn(Hhd),
    pub enable: unsafe extern "C" fn(HdEnum),
    pub disable: unsafe extern "C" fn(HdEnum),
    pub start_scheduler: unsafe extern "C" fn(),
    pub stop_scheduler: unsafe extern "C" fn(),
    pub schedule_asynchronous:
        unsafe extern "C" fn(HdCallback, *mut c_void, u16) -> HdSchedulerHandle,
    pub schedule_synchronous: unsafe extern "C" fn(HdCallback, *mut c_void, u16),
    pub unschedule: unsafe extern "C" fn(HdSchedulerHandle),
    pub begin_frame: unsafe extern "C" fn(Hhd),
    pub end_frame: unsafe extern "C" fn(Hhd),
    pub get_doublev: unsafe extern "C" fn(HdEnum, *mut f64),
    pub set_doublev: unsafe extern "C" fn(HdEnum, *const f64),
    pub get_integerv: unsafe extern "C" fn(HdEnum, *mut c_int),
    pub get_error: unsafe extern "C" fn() -> HdErrorInfo,
    /// `hdGetString` (optional: only for the device model in messages).
    pub get_string: Option<unsafe extern "C" fn(HdEnum) -> *const c_char>,
    /// The file that was loaded.
    pub path: PathBuf,
}

/// Default places to look for the library when neither `LOP_HD_LIBRARY` nor the daemon config
/// names one: the loader's own search (`LD_LIBRARY_PATH`, `ld.so.cache`), then the usual install
/// directories of the OpenHaptics packages.
pub const DEFAULT_LIBRARY_CANDIDATES: [&str; 6] = [
    "libHD.so",
    "libHD.so.3",
    "/usr/lib/libHD.so",
    "/usr/lib64/libHD.so",
    "/usr/local/lib/libHD.so",
    "/usr/lib/x86_64-linux-gnu/libHD.so",
];

/// The environment variable that names the library to load (it wins over the daemon config).
pub const LIBRARY_ENV: &str = "LOP_HD_LIBRARY";

/// The libraries to try, in order: `LOP_HD_LIBRARY` if set, else `configured` if given, else
/// [`DEFAULT_LIBRARY_CANDIDATES`].
pub fn library_candidates(configured: Option<&Path>) -> Vec<PathBuf> {
    crate::vendor_lib::candidates(LIBRARY_ENV, configured, &DEFAULT_LIBRARY_CANDIDATES)
}

impl HdApi {
    /// Loads the first library of `candidates` that opens. Err: one line per candidate tried,
    /// with the loader's reason, or the symbol that a loaded library lacks.
    pub fn load(candidates: &[PathBuf]) -> Result<&'static HdApi, String> {
        crate::vendor_lib::load(candidates, Self::resolve)
    }

    // Each transmute's target is the type of the struct field it initialises.
    #[allow(clippy::missing_transmute_annotations)]
    fn resolve(library: &Library) -> Result<HdApi, String> {
        let path = &library.path;
        let sym = |name: &str| -> Result<*mut c_void, String> {
            library.symbol(name).ok_or_else(|| {
                format!(
                    "{} lacks the symbol `{name}`: is it the OpenHaptics HD library (libHD.so)?",
                    path.display()
                )
            })
        };
        // SAFETY (every transmute below): the symbol has this C signature in the HD API
        // (the vendor's HD API reference); a function pointer and a data pointer have the same size
        // on Linux.
        macro_rules! f {
            ($name:literal) => {
                unsafe { std::mem::transmute::<*mut c_void, _>(sym($name)?) }
            };
        }
        let get_string = sym("hdGetString").ok().map(|p| unsafe {
            std::mem::transmute::<*mut c_void, unsafe extern "C" fn(HdEnum) -> *const c_char>(p)
        });
        Ok(HdApi {
            init_device: f!("hdInitDevice"),
            disable_device: f!("hdDisableDevice"),
            make_current_device: f!("hdMakeCurrentDevice"),
            enable: f!("hdEnable"),
            disable: f!("hdDisable"),
            start_scheduler: f!("hdStartScheduler"),
            stop_scheduler: f!("hdStopScheduler"),
            schedule_asynchronous: f!("hdScheduleAsynchronous"),
            schedule_synchronous: f!("hdScheduleSynchronous"),
            unschedule: f!("hdUnschedule"),
            begin_frame: f!("hdBeginFrame"),
            end_frame: f!("hdEndFrame"),
            get_doublev: f!("hdGetDoublev"),
            set_doublev: f!("hdSetDoublev"),
            get_integerv: f!("hdGetIntegerv"),
            get_error: f!("hdGetError"),
            get_string,
            path: path.clone(),
        })
    }
}
