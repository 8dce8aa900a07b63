//! A stand-in for the Force Dimension DHD library: a small `cdylib` that exports the DHD symbols
//! lop's `forcedimension` driver loads (C ABI, the names, return codes and error numbers of the
//! vendor's DHD API), so the driver's whole path runs in CI without a device.
//!
//! What it does, like the real library:
//! - serves N devices by enumeration index; `dhdOpenID(index)` hands out device IDs in opening
//!   order (lowest free ID first — so an ID is not its index unless devices open in order) and
//!   returns the same ID for a device already open;
//! - every device call takes the device ID, fails with -1 on a bad one and sets the calling
//!   thread's last error (`dhdErrorGetLast`, `dhdErrorGetLastStr`);
//! - positions in metres, velocities in m/s, forces in newtons, in DHD's frame;
//!   `dhdGetLinearVelocity` fails once with `DHD_ERROR_TIMEOUT` after each open (its estimator
//!   has no history yet); `dhdSetForce` scales a force above the device type's figure and
//!   returns `DHD_MOTOR_SATURATED`.
//!
//! Set up by environment variables, read when the state is first used and at
//! `lop_standin_dhd_reset`:
//! - `LOP_STANDIN_DHD_COUNT`: how many devices (default 1);
//! - `LOP_STANDIN_DHD_TYPES`: comma-separated `dhdGetSystemType` values by index (default 33,
//!   omega.3, for every device); serials are 1000 + index;
//! - `LOP_STANDIN_DHD_VERSION`: what `dhdGetSDKVersion` reports (default `3.17.6-0`);
//! - `LOP_STANDIN_DHD_LOG_DIR`: at each `dhdClose` write `standin-dhd-<pid>-<index>-<n>.csv`
//!   there: `event,fx,fy,fz`, the force commanded at that moment (DHD frame), for `open`,
//!   `enable_on`, `force` (every `dhdSetForce`), `enable_off` and `close`.
//!
//! Tests in the same process steer it through the `lop_standin_dhd_*` functions (positions,
//! buttons, injected errors) and read back what each device received.
//!
//! It is a test fixture, not a real-time component: it locks a mutex and allocates freely.

// The exported functions mirror the vendor's C API; their safety contract is the vendor's
// (valid pointers of the documented sizes), not repeated per function.
#![allow(clippy::missing_safety_doc)]

use std::cell::Cell;
use std::ffi::{c_char, c_int, c_uchar, c_uint, c_ushort, CStr};
use std::io::Write;
use std::sync::{Mutex, MutexGuard};

const DHD_MOTOR_SATURATED: c_int = 2;
const DHD_TIMEGUARD: c_int = 1;
const DHD_NO_ERROR: c_int = 0;
const DHD_ERROR: c_int = 1;
const DHD_ERROR_TIMEOUT: c_int = 7;
const DHD_ERROR_INVALID_INDEX: c_int = 15;
const DHD_ERROR_NOT_ENABLED: c_int = 19;

thread_local! {
    static LAST_ERROR: Cell<c_int> = const { Cell::new(DHD_NO_ERROR) };
}

fn fail(code: c_int) -> c_int {
    LAST_ERROR.with(|e| e.set(code));
    -1
}

#[derive(Default)]
struct Device {
    system_type: c_int,
    id: Option<c_int>,
    position: [f64; 3],
    velocity: [f64; 3],
    buttons: c_uint,
    force_enabled: bool,
    /// The force last commanded (after the stand-in's own saturation), DHD frame.
    force: [f64; 3],
    force_writes: u64,
    force_at_disable: Option<[f64; 3]>,
    force_at_close: Option<[f64; 3]>,
    closes: u64,
    /// `dhdGetLinearVelocity` calls left to fail with DHD_ERROR_TIMEOUT.
    velocity_warmup: u32,
    /// Injected: the next `calls` I/O calls fail with `code`.
    injected: Option<(c_int, u32)>,
    /// Position reads so far (every other one answers as TimeGuard would).
    reads: u64,
    log: Vec<(&'static str, [f64; 3])>,
}

#[derive(Default)]
struct State {
    devices: Vec<Device>,
    version: [c_int; 4],
    log_dir: Option<String>,
    sessions: u32,
}

static STATE: Mutex<Option<State>> = Mutex::new(None);

fn env_state() -> State {
    let count = std::env::var("LOP_STANDIN_DHD_COUNT")
        .ok()
        .and_then(|v| v.trim().parse().ok())
        .unwrap_or(1usize);
    let types: Vec<c_int> = std::env::var("LOP_STANDIN_DHD_TYPES")
        .unwrap_or_default()
        .split(',')
        .filter_map(|t| t.trim().parse().ok())
        .collect();
    let version = std::env::var("LOP_STANDIN_DHD_VERSION").unwrap_or_else(|_| "3.17.6-0".into());
    let mut v = [0; 4];
    for (k, part) in version.split(['.', '-']).take(4).enumerate() {
        v[k] = part.trim().parse().unwrap_or(0);
    }
    State {
        devices: (0..count)
            .map(|i| Device {
                system_type: types.get(i).copied().unwrap_or(33),
                ..Default::default()
            })
            .collect(),
        version: v,
        log_dir: std::env::var("LOP_STANDIN_DHD_LOG_DIR").ok(),
        sessions: 0,
    }
}

fn state() -> MutexGuard<'static, Option<State>> {
    let mut g = STATE.lock().unwrap_or_else(|p| p.into_inner());
    if g.is_none() {
        *g = Some(env_state());
    }
    g
}

/// Runs `f` on the device with ID `id`; -1 and `DHD_ERROR` for an ID nobody opened.
fn with_id(id: c_char, f: impl FnOnce(&mut Device, usize) -> c_int) -> c_int {
    let mut g = state();
    let s = g.as_mut().unwrap();
    match s.devices.iter().position(|d| d.id == Some(c_int::from(id))) {
        Some(i) => f(&mut s.devices[i], i),
        None => fail(DHD_ERROR),
    }
}

/// Runs `f` on the device at enumeration `index` (a test control).
fn with_index<T: Default>(index: c_int, f: impl FnOnce(&mut Device) -> T) -> T {
    let mut g = state();
    let s = g.as_mut().unwrap();
    match s.devices.get_mut(index as usize) {
        Some(d) if index >= 0 => f(d),
        _ => T::default(),
    }
}

impl Device {
    /// An injected error due on this call, if any.
    fn injected_error(&mut self) -> Option<c_int> {
        let (code, calls) = self.injected?;
        self.injected = (calls > 1).then(|| (code, calls - 1));
        Some(code)
    }
}

fn system_name(system_type: c_int) -> &'static CStr {
    match system_type {
        33 => c"omega.3 (lop stand-in)",
        34 | 36 => c"omega.6 (lop stand-in)",
        35 | 37 => c"omega.7 (lop stand-in)",
        104 | 105 => c"sigma.7 (lop stand-in)",
        63 => c"delta.3 (lop stand-in)",
        60 => c"Falcon (lop stand-in)",
        _ => c"custom (lop stand-in)",
    }
}

/// The force figure of a type, N (what the motors deliver before saturating).
fn max_force(system_type: c_int) -> f64 {
    match system_type {
        63 => 20.0,
        60 => 8.0,
        33..=37 | 104 | 105 => 12.0,
        _ => 4.0,
    }
}

#[no_mangle]
pub unsafe extern "C" fn dhdGetSDKVersion(
    major: *mut c_int,
    minor: *mut c_int,
    release: *mut c_int,
    revision: *mut c_int,
) {
    let v = state().as_ref().unwrap().version;
    unsafe {
        *major = v[0];
        *minor = v[1];
        *release = v[2];
        *revision = v[3];
    }
}

#[no_mangle]
pub extern "C" fn dhdGetDeviceCount() -> c_int {
    state().as_ref().unwrap().devices.len() as c_int
}

#[no_mangle]
pub extern "C" fn dhdOpenID(index: c_char) -> c_int {
    let mut g = state();
    let s = g.as_mut().unwrap();
    let index = c_int::from(index);
    if index < 0 || index as usize >= s.devices.len() {
        return fail(DHD_ERROR_INVALID_INDEX);
    }
    if let Some(id) = s.devices[index as usize].id {
        return id;
    }
    let id = (0..)
        .find(|id| !s.devices.iter().any(|d| d.id == Some(*id)))
        .unwrap();
    let d = &mut s.devices[index as usize];
    d.id = Some(id);
    d.force_enabled = false;
    d.force = [0.0; 3];
    d.velocity_warmup = 1;
    d.log.clear();
    d.log.push(("open", d.force));
    id
}

#[no_mangle]
pub extern "C" fn dhdClose(id: c_char) -> c_int {
    let mut g = state();
    let s = g.as_mut().unwrap();
    let Some(i) = s.devices.iter().position(|d| d.id == Some(c_int::from(id))) else {
        return fail(DHD_ERROR);
    };
    s.sessions += 1;
    let session = s.sessions;
    let d = &mut s.devices[i];
    d.log.push(("close", d.force));
    d.force_at_close = Some(d.force);
    d.closes += 1;
    d.id = None;
    d.force_enabled = false;
    if let Some(dir) = &s.log_dir {
        let mut text = String::from("event,fx,fy,fz\n");
        for (event, f) in &d.log {
            text.push_str(&format!("{event},{},{},{}\n", f[0], f[1], f[2]));
        }
        let path = format!("{dir}/standin-dhd-{}-{i}-{session}.csv", std::process::id());
        if let Ok(mut file) = std::fs::File::create(path) {
            let _ = file.write_all(text.as_bytes());
        }
    }
    d.log.clear();
    0
}

#[no_mangle]
pub extern "C" fn dhdGetSystemType(id: c_char) -> c_int {
    with_id(id, |d, _| d.system_type)
}

#[no_mangle]
pub extern "C" fn dhdGetSystemName(id: c_char) -> *const c_char {
    let mut t = -1;
    if with_id(id, |d, _| {
        t = d.system_type;
        0
    }) < 0
    {
        return std::ptr::null();
    }
    system_name(t).as_ptr()
}

#[no_mangle]
pub unsafe extern "C" fn dhdGetSerialNumber(serial: *mut c_ushort, id: c_char) -> c_int {
    with_id(id, |_, index| {
        unsafe { *serial = 1000 + index as c_ushort };
        0
    })
}

#[no_mangle]
pub unsafe extern "C" fn dhdGetPosition(
    x: *mut f64,
    y: *mut f64,
    z: *mut f64,
    id: c_char,
) -> c_int {
    with_id(id, |d, _| {
        if let Some(code) = d.injected_error() {
            return fail(code);
        }
        d.reads += 1;
        unsafe {
            *x = d.position[0];
            *y = d.position[1];
            *z = d.position[2];
        }
        if d.reads % 2 == 0 {
            DHD_TIMEGUARD
        } else {
            0
        }
    })
}

#[no_mangle]
pub unsafe extern "C" fn dhdGetLinearVelocity(
    x: *mut f64,
    y: *mut f64,
    z: *mut f64,
    id: c_char,
) -> c_int {
    with_id(id, |d, _| {
        if let Some(code) = d.injected_error() {
            return fail(code);
        }
        if d.velocity_warmup > 0 {
            d.velocity_warmup -= 1;
            return fail(DHD_ERROR_TIMEOUT);
        }
        unsafe {
            *x = d.velocity[0];
            *y = d.velocity[1];
            *z = d.velocity[2];
        }
        0
    })
}

#[no_mangle]
pub extern "C" fn dhdGetButtonMask(id: c_char) -> c_uint {
    let mut mask = 0;
    with_id(id, |d, _| {
        mask = d.buttons;
        0
    });
    mask
}

#[no_mangle]
pub extern "C" fn dhdSetForce(fx: f64, fy: f64, fz: f64, id: c_char) -> c_int {
    with_id(id, |d, _| {
        if let Some(code) = d.injected_error() {
            return fail(code);
        }
        let mut f = [fx, fy, fz];
        let magnitude = (fx * fx + fy * fy + fz * fz).sqrt();
        let max = max_force(d.system_type);
        let mut r = 0;
        if !magnitude.is_finite() {
            return fail(DHD_ERROR);
        }
        if magnitude > max {
            f = f.map(|c| c * max / magnitude);
            r = DHD_MOTOR_SATURATED;
        }
        d.force = f;
        d.force_writes += 1;
        d.log.push(("force", f));
        r
    })
}

#[no_mangle]
pub extern "C" fn dhdEnableForce(on: c_uchar, id: c_char) -> c_int {
    with_id(id, |d, _| {
        if let Some(code) = d.injected_error() {
            return fail(code);
        }
        d.force_enabled = on != 0;
        if on == 0 {
            d.force_at_disable = Some(d.force);
        }
        d.log
            .push((if on != 0 { "enable_on" } else { "enable_off" }, d.force));
        0
    })
}

#[no_mangle]
pub extern "C" fn dhdErrorGetLast() -> c_int {
    LAST_ERROR.with(|e| e.get())
}

#[no_mangle]
pub extern "C" fn dhdErrorGetLastStr() -> *const c_char {
    let text: &'static CStr = match dhdErrorGetLast() {
        DHD_NO_ERROR => c"no error",
        DHD_ERROR => c"undefined error (stand-in)",
        2 => c"communication error between the host and the device (stand-in)",
        DHD_ERROR_TIMEOUT => c"timeout (stand-in)",
        DHD_ERROR_INVALID_INDEX => c"invalid index (stand-in)",
        DHD_ERROR_NOT_ENABLED => c"feature not enabled (stand-in)",
        _ => c"error (stand-in)",
    };
    text.as_ptr()
}

// ---- test controls -------------------------------------------------------------------------

/// Forgets every device and re-reads the environment, with `count` devices (-1: from
/// `LOP_STANDIN_DHD_COUNT`).
#[no_mangle]
pub extern "C" fn lop_standin_dhd_reset(count: c_int) {
    let mut s = env_state();
    if count >= 0 {
        let t = s.devices.first().map_or(33, |d| d.system_type);
        s.devices.resize_with(count as usize, || Device {
            system_type: t,
            ..Default::default()
        });
    }
    *STATE.lock().unwrap_or_else(|p| p.into_inner()) = Some(s);
}

/// Makes `dhdGetSDKVersion` report `major.minor.release-revision`.
#[no_mangle]
pub extern "C" fn lop_standin_dhd_set_version(
    major: c_int,
    minor: c_int,
    release: c_int,
    revision: c_int,
) {
    state().as_mut().unwrap().version = [major, minor, release, revision];
}

/// Sets the device's position (m) and velocity (m/s), DHD frame.
#[no_mangle]
pub extern "C" fn lop_standin_dhd_set_motion(
    index: c_int,
    x: f64,
    y: f64,
    z: f64,
    vx: f64,
    vy: f64,
    vz: f64,
) {
    with_index(index, |d| {
        d.position = [x, y, z];
        d.velocity = [vx, vy, vz];
    })
}

/// Sets the device's pressed buttons (bit i: button i).
#[no_mangle]
pub extern "C" fn lop_standin_dhd_set_buttons(index: c_int, mask: c_uint) {
    with_index(index, |d| d.buttons = mask)
}

/// Makes the device's next `calls` I/O calls (position, velocity, force, enable) fail with DHD
/// error number `code`.
#[no_mangle]
pub extern "C" fn lop_standin_dhd_inject_error(index: c_int, code: c_int, calls: c_uint) {
    with_index(index, |d| d.injected = (calls > 0).then_some((code, calls)))
}

/// The device's last commanded force (DHD frame) into `out[3]`; returns how many forces it
/// received in all.
#[no_mangle]
pub unsafe extern "C" fn lop_standin_dhd_force(index: c_int, out: *mut f64) -> u64 {
    with_index(index, |d| {
        unsafe { std::ptr::copy_nonoverlapping(d.force.as_ptr(), out, 3) };
        d.force_writes
    })
}

/// The force commanded when forces were last disabled (`which` 0) or the device last closed
/// (`which` 1) into `out[3]`; returns 0 if that never happened, else 1.
#[no_mangle]
pub unsafe extern "C" fn lop_standin_dhd_force_at(
    index: c_int,
    which: c_int,
    out: *mut f64,
) -> c_int {
    with_index(index, |d| {
        let f = if which == 0 {
            d.force_at_disable
        } else {
            d.force_at_close
        };
        match f {
            Some(f) => {
                unsafe { std::ptr::copy_nonoverlapping(f.as_ptr(), out, 3) };
                1
            }
            None => 0,
        }
    })
}

/// Bit 0: the device is open; bit 1: its forces are enabled. Bits 8 and up: how many times it
/// was closed.
#[no_mangle]
pub extern "C" fn lop_standin_dhd_status(index: c_int) -> u64 {
    with_index(index, |d| {
        u64::from(d.id.is_some()) | u64::from(d.force_enabled) << 1 | d.closes << 8
    })
}
