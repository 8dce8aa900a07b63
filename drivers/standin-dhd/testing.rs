//! For tests: builds the stand-in DHD library (`drivers/standin-dhd`), returns the path of the
//! shared library, and steers it. Include it with
//! `#[path = "<relative>/drivers/standin-dhd/testing.rs"] mod standin_dhd;`.
//!
//! Built once per test process by `lop_test_support::standin::build_standin`.
//!
//! [`Controls`] opens the same library file the driver loads (`dlopen` of one path twice gives
//! one copy, so one state) and calls its `lop_standin_dhd_*` functions.

// Each test crate uses a different part of this file.
#![allow(dead_code)]

use std::ffi::{c_int, c_uint, c_void, CString};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// Path of a freshly built stand-in library (built once per process).
pub fn standin_library() -> PathBuf {
    static LIB: OnceLock<PathBuf> = OnceLock::new();
    LIB.get_or_init(|| {
        lop_test_support::standin::build_standin(
            env!("CARGO_MANIFEST_DIR"),
            env!("CARGO_TARGET_TMPDIR"),
            "dhd",
        )
    })
    .clone()
}

/// The stand-in's test controls, resolved from the library the driver loads.
pub struct Controls {
    reset: extern "C" fn(c_int),
    set_version: extern "C" fn(c_int, c_int, c_int, c_int),
    set_motion: extern "C" fn(c_int, f64, f64, f64, f64, f64, f64),
    set_buttons: extern "C" fn(c_int, c_uint),
    inject_error: extern "C" fn(c_int, c_int, c_uint),
    force: unsafe extern "C" fn(c_int, *mut f64) -> u64,
    force_at: unsafe extern "C" fn(c_int, c_int, *mut f64) -> c_int,
    status: extern "C" fn(c_int) -> u64,
}

/// What one simulated device received and is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DeviceState {
    /// The last force commanded, DHD frame, N.
    pub force: [f64; 3],
    /// Forces received in all.
    pub force_writes: u64,
    /// Open now.
    pub open: bool,
    /// Forces enabled now.
    pub force_enabled: bool,
    /// Times closed.
    pub closes: u64,
    /// The force commanded when forces were last disabled.
    pub force_at_disable: Option<[f64; 3]>,
    /// The force commanded when the device was last closed.
    pub force_at_close: Option<[f64; 3]>,
}

impl Controls {
    /// Opens `library` (the stand-in) and resolves its controls.
    pub fn open(library: &Path) -> Controls {
        let c_path = CString::new(library.as_os_str().as_encoded_bytes()).unwrap();
        // SAFETY: a valid C string; the stand-in has no constructors.
        let handle = unsafe { libc::dlopen(c_path.as_ptr(), libc::RTLD_NOW | libc::RTLD_LOCAL) };
        assert!(!handle.is_null(), "dlopen {}", library.display());
        let sym = |name: &str| -> *mut c_void {
            let c = CString::new(name).unwrap();
            // SAFETY: valid handle and C string.
            let p = unsafe { libc::dlsym(handle, c.as_ptr()) };
            assert!(!p.is_null(), "the stand-in lacks {name}");
            p
        };
        // SAFETY (each transmute): the stand-in exports the function with this signature.
        unsafe {
            Controls {
                reset: std::mem::transmute::<*mut c_void, extern "C" fn(c_int)>(sym(
                    "lop_standin_dhd_reset",
                )),
                set_version: std::mem::transmute::<
                    *mut c_void,
                    extern "C" fn(c_int, c_int, c_int, c_int),
                >(sym("lop_standin_dhd_set_version")),
                set_motion: std::mem::transmute::<
                    *mut c_void,
                    extern "C" fn(c_int, f64, f64, f64, f64, f64, f64),
                >(sym("lop_standin_dhd_set_motion")),
                set_buttons: std::mem::transmute::<*mut c_void, extern "C" fn(c_int, c_uint)>(sym(
                    "lop_standin_dhd_set_buttons",
                )),
                inject_error: std::mem::transmute::<*mut c_void, extern "C" fn(c_int, c_int, c_uint)>(
                    sym("lop_standin_dhd_inject_error"),
                ),
                force: std::mem::transmute::<
                    *mut c_void,
                    unsafe extern "C" fn(c_int, *mut f64) -> u64,
                >(sym("lop_standin_dhd_force")),
                force_at: std::mem::transmute::<
                    *mut c_void,
                    unsafe extern "C" fn(c_int, c_int, *mut f64) -> c_int,
                >(sym("lop_standin_dhd_force_at")),
                status: std::mem::transmute::<*mut c_void, extern "C" fn(c_int) -> u64>(sym(
                    "lop_standin_dhd_status",
                )),
            }
        }
    }

    /// Forgets every device; `count` devices from now on.
    pub fn reset(&self, count: usize) {
        (self.reset)(count as c_int)
    }

    /// Makes the library report SDK version `v` (major, minor, release, revision).
    pub fn set_version(&self, v: [i32; 4]) {
        (self.set_version)(v[0], v[1], v[2], v[3])
    }

    /// Places device `index` at `position_m` moving at `velocity_m_s` (DHD frame, SI).
    pub fn set_motion(&self, index: usize, position_m: [f64; 3], velocity_m_s: [f64; 3]) {
        let [x, y, z] = position_m;
        let [vx, vy, vz] = velocity_m_s;
        (self.set_motion)(index as c_int, x, y, z, vx, vy, vz)
    }

    /// Presses the buttons of `mask` on device `index` (bit i: button i).
    pub fn set_buttons(&self, index: usize, mask: u32) {
        (self.set_buttons)(index as c_int, mask)
    }

    /// Device `index`'s next `calls` I/O calls fail with DHD error number `code`.
    pub fn inject_error(&self, index: usize, code: i32, calls: u32) {
        (self.inject_error)(index as c_int, code, calls)
    }

    /// What device `index` received and is.
    pub fn device(&self, index: usize) -> DeviceState {
        let i = index as c_int;
        let mut force = [f64::NAN; 3];
        let mut at_disable = [f64::NAN; 3];
        let mut at_close = [f64::NAN; 3];
        // SAFETY: three-double buffers.
        let (force_writes, disabled, closed) = unsafe {
            (
                (self.force)(i, force.as_mut_ptr()),
                (self.force_at)(i, 0, at_disable.as_mut_ptr()),
                (self.force_at)(i, 1, at_close.as_mut_ptr()),
            )
        };
        let status = (self.status)(i);
        DeviceState {
            force,
            force_writes,
            open: status & 1 != 0,
            force_enabled: status & 2 != 0,
            closes: status >> 8,
            force_at_disable: (disabled == 1).then_some(at_disable),
            force_at_close: (closed == 1).then_some(at_close),
        }
    }
}

/// One row of a stand-in log (`LOP_STANDIN_DHD_LOG_DIR`): the event and the force commanded
/// at that moment (DHD frame).
#[derive(Clone, Debug, PartialEq)]
pub struct LogRow {
    pub event: String,
    pub force: [f64; 3],
}

/// Reads one stand-in log file.
pub fn read_log(path: &Path) -> Vec<LogRow> {
    let text = std::fs::read_to_string(path).expect("stand-in log");
    text.lines()
        .skip(1)
        .map(|l| {
            let v: Vec<&str> = l.split(',').collect();
            LogRow {
                event: v[0].to_string(),
                force: [
                    v[1].parse().unwrap(),
                    v[2].parse().unwrap(),
                    v[3].parse().unwrap(),
                ],
            }
        })
        .collect()
}

/// The stand-in log files in `dir` for device `index`, in session order.
pub fn logs_of(dir: &Path, index: usize) -> Vec<PathBuf> {
    let mut files: Vec<(u32, PathBuf)> = std::fs::read_dir(dir)
        .map(|d| {
            d.flatten()
                .filter_map(|e| {
                    let name = e.file_name().to_string_lossy().into_owned();
                    let rest = name.strip_prefix("standin-dhd-")?.strip_suffix(".csv")?;
                    let mut parts = rest.split('-');
                    let (_pid, i, session) = (parts.next()?, parts.next()?, parts.next()?);
                    (i.parse::<usize>().ok()? == index)
                        .then(|| (session.parse().unwrap_or(0), e.path()))
                })
                .collect()
        })
        .unwrap_or_default();
    files.sort();
    files.into_iter().map(|(_, p)| p).collect()
}
