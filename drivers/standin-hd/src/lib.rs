//! A stand-in for the OpenHaptics HD library: a small `cdylib` that exports the HD symbols lop's
//! `openhaptics` driver loads (C ABI, same names and constants as the vendor's HD API),
//! so the driver's whole path runs in CI without a Phantom Omni.
//!
//! What it does, like the real library:
//! - serves the devices named in its configuration, each by its own handle (`hdInitDevice(NAME)`;
//!   `NULL` or `"Default Device"` is the first name); each device has its own trajectory,
//!   frame state, force and event log; an unknown name fails with `HD_DEVICE_FAULT` and
//!   `HD_INVALID_HANDLE`, a name already initialised with `HD_DEVICE_ALREADY_INITIATED`;
//! - state calls (`hdGetDoublev`, `hdGetIntegerv`, `hdSetDoublev`, `hdEnable`, `hdDisable`)
//!   apply to the current device: the one last made current by `hdMakeCurrentDevice` (or just
//!   initialised). `hdBeginFrame(h)` and `hdEndFrame(h)` bracket device `h`'s frame and do not
//!   make it current; a begin inside an open frame is `HD_ILLEGAL_BEGIN`, an end outside one
//!   `HD_ILLEGAL_END`, a force set on a device outside its frame `HD_INVALID_OPERATION`; a
//!   handle that is not an initialised device is `HD_BAD_HANDLE`;
//! - `hdStartScheduler` starts its own 1 kHz scheduler thread (one for every device) that calls
//!   the registered callbacks in priority order; a callback returning `HD_CALLBACK_DONE` is
//!   dropped; `hdScheduleSynchronous` runs a callback on that thread and waits for it;
//! - a device plays its trajectory, one row per servo tick, and keeps rendering the last force
//!   it was given (committed at `hdEndFrame`); `hdGetError` pops one queue of errors for every
//!   device, each naming the device it concerns (`HDErrorInfo::hHD`).
//!
//! Controlled by environment variables, read when the first device of a session (no device
//! initialised) is initialised, the trajectories when each device is:
//! - `LOP_STANDIN_DEVICE_NAMES`: comma-separated names of the devices it serves, in handle
//!   order (default `Omni`).
//! - `LOP_STANDIN_TRAJECTORY`: CSV file, one row per servo tick: `x_mm,y_mm,z_mm[,buttons]`
//!   (lines starting with `#` and a header row are skipped); after the last row the device
//!   holds still. Without it the stylus rests at the origin. `LOP_STANDIN_TRAJECTORY_<NAME>`
//!   gives device `NAME` its own.
//! - `LOP_STANDIN_ERRORS`: `TICK:CODE[@NAME],...` — push HD error `CODE` (hex `0x0302` or
//!   decimal) at servo tick `TICK`, concerning device `NAME` (default: the first device).
//! - `LOP_STANDIN_LOG_DIR`: at `hdDisableDevice` write that device's log as
//!   `standin-<pid>-<n>-<NAME>.csv` there (`n` counts the disables of the process): one row per
//!   event `event,tick,code,fx,fy,fz` where the force is the one the device renders at that
//!   moment — `begin` and `frame` rows for every `hdBeginFrame` and `hdEndFrame`, and `init`,
//!   `error`, `exceeded`, `illegal_begin`, `illegal_end`, `set_outside_frame`,
//!   `force_output_on/off`, `unschedule`, `stop_scheduler`, `disable_device` rows
//!   (`unschedule` and `stop_scheduler` in the log of every initialised device).
//!
//! It is a test fixture, not a real-time component: it locks a mutex and allocates freely.

// The exported functions mirror the vendor's C API; their safety contract is the vendor's
// (valid pointers of the documented sizes), not repeated per function.
#![allow(clippy::missing_safety_doc)]

use std::collections::VecDeque;
use std::ffi::{c_char, c_int, c_uint, c_ulong, c_void, CStr};
use std::io::Write;
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

type Hhd = c_uint;
type HdCallback = unsafe extern "C" fn(*mut c_void) -> c_uint;

#[repr(C)]
pub struct HdErrorInfo {
    error_code: c_uint,
    internal_error_code: c_int,
    hhd: Hhd,
}

const HD_SUCCESS: c_uint = 0;
const HD_CALLBACK_DONE: c_uint = 0;
const HD_INVALID_HANDLE: Hhd = 0xFFFF_FFFF;
const HD_CURRENT_BUTTONS: c_uint = 0x2000;
const HD_CURRENT_POSITION: c_uint = 0x2050;
const HD_CURRENT_VELOCITY: c_uint = 0x2051;
const HD_CURRENT_TRANSFORM: c_uint = 0x2052;
const HD_CURRENT_FORCE: c_uint = 0x2700;
const HD_DEVICE_MODEL_TYPE: c_uint = 0x2501;
const HD_USABLE_WORKSPACE_DIMENSIONS: c_uint = 0x2551;
const HD_NOMINAL_MAX_STIFFNESS: c_uint = 0x2602;
const HD_NOMINAL_MAX_FORCE: c_uint = 0x2603;
const HD_NOMINAL_MAX_CONTINUOUS_FORCE: c_uint = 0x2604;
const HD_NOMINAL_MAX_DAMPING: c_uint = 0x2609;
const HD_FORCE_OUTPUT: c_uint = 0x4000;
const HD_EXCEEDED_MAX_FORCE: c_uint = 0x0201;
const HD_DEVICE_FAULT: c_uint = 0x0300;
const HD_DEVICE_ALREADY_INITIATED: c_uint = 0x0301;
const HD_INVALID_ENUM: c_uint = 0x0100;
const HD_INVALID_OPERATION: c_uint = 0x0102;
const HD_BAD_HANDLE: c_uint = 0x0104;
const HD_ILLEGAL_BEGIN: c_uint = 0x0400;
const HD_ILLEGAL_END: c_uint = 0x0401;

/// The Omni's nominal figures (the vendor's published specifications).
const MAX_FORCE: f64 = 3.3;
const MAX_CONTINUOUS_FORCE: f64 = 0.88;
const MAX_STIFFNESS: f64 = 0.7;
const WORKSPACE: [f64; 6] = [-80.0, -60.0, -35.0, 80.0, 60.0, 35.0];

struct Callback {
    handle: c_ulong,
    f: HdCallback,
    data: usize,
    priority: u16,
}

struct SyncJob {
    f: HdCallback,
    data: usize,
    done: Arc<(Mutex<bool>, Condvar)>,
}

/// One device the stand-in serves; its handle is its index.
#[derive(Default)]
struct Device {
    name: String,
    initialized: bool,
    force_output: bool,
    in_frame: bool,
    trajectory: Vec<[f64; 4]>,
    /// Force set in the current frame; committed at hdEndFrame.
    frame_force: [f64; 3],
    /// Force the motors render now.
    rendered: [f64; 3],
    log: Vec<(&'static str, u64, c_uint, [f64; 3])>,
}

impl Device {
    fn row(&self, tick: u64) -> [f64; 4] {
        match self.trajectory.len() {
            0 => [0.0; 4],
            n => self.trajectory[(tick as usize).min(n - 1)],
        }
    }
}

#[derive(Default)]
struct State {
    /// The devices, by handle.
    devices: Vec<Device>,
    /// The handle state calls apply to.
    current: Option<usize>,
    /// Servo ticks so far (the scheduler's clock).
    tick: u64,
    /// (tick, code, device).
    scripted_errors: Vec<(u64, c_uint, usize)>,
    /// (code, the device it concerns).
    errors: VecDeque<(c_uint, Hhd)>,
    log_dir: Option<String>,
    sessions: u32,
    callbacks: Vec<Callback>,
    next_handle: c_ulong,
    sync_jobs: Vec<SyncJob>,
    running: bool,
}

static STATE: Mutex<Option<State>> = Mutex::new(None);
static SCHEDULER: Mutex<Option<JoinHandle<()>>> = Mutex::new(None);

fn state() -> MutexGuard<'static, Option<State>> {
    let mut g = STATE.lock().unwrap_or_else(|p| p.into_inner());
    if g.is_none() {
        *g = Some(State {
            next_handle: 1,
            ..Default::default()
        });
    }
    g
}

macro_rules! with_state {
    (|$s:ident| $body:expr) => {{
        let mut guard = state();
        let $s = guard.as_mut().unwrap();
        $body
    }};
}

impl State {
    /// An event in device `d`'s log, with the force it renders now.
    fn event(&mut self, d: usize, kind: &'static str, code: c_uint) {
        let tick = self.tick;
        if let Some(dev) = self.devices.get_mut(d) {
            let f = dev.rendered;
            dev.log.push((kind, tick, code, f));
        }
    }

    /// An event in the log of every initialised device.
    fn event_all(&mut self, kind: &'static str) {
        for d in 0..self.devices.len() {
            if self.devices[d].initialized {
                self.event(d, kind, 0);
            }
        }
    }

    fn error(&mut self, code: c_uint, d: Option<usize>) {
        let hhd = d.map_or(HD_INVALID_HANDLE, |d| d as Hhd);
        self.errors.push_back((code, hhd));
    }

    /// The initialised device of handle `hhd`; else queues `HD_BAD_HANDLE`.
    fn device(&mut self, hhd: Hhd) -> Option<usize> {
        let d = hhd as usize;
        if self.devices.get(d).is_some_and(|dev| dev.initialized) {
            Some(d)
        } else {
            self.error(HD_BAD_HANDLE, None);
            None
        }
    }

    /// The current device, if it is initialised; else queues `HD_BAD_HANDLE`.
    fn current(&mut self) -> Option<usize> {
        match self.current {
            Some(d) => self.device(d as Hhd),
            None => {
                self.error(HD_BAD_HANDLE, None);
                None
            }
        }
    }

    fn write_log(&mut self, d: usize) {
        let Some(dir) = &self.log_dir else {
            return;
        };
        self.sessions += 1;
        let dev = &mut self.devices[d];
        let path = format!(
            "{dir}/standin-{}-{}-{}.csv",
            std::process::id(),
            self.sessions,
            dev.name
        );
        let mut text = String::from("event,tick,code,fx,fy,fz\n");
        for (kind, tick, code, f) in &dev.log {
            text.push_str(&format!(
                "{kind},{tick},{code},{},{},{}\n",
                f[0], f[1], f[2]
            ));
        }
        if let Ok(mut file) = std::fs::File::create(&path) {
            let _ = file.write_all(text.as_bytes());
        }
        dev.log.clear();
    }
}

fn parse_code(s: &str) -> Option<c_uint> {
    let s = s.trim();
    match s.strip_prefix("0x") {
        Some(h) => c_uint::from_str_radix(h, 16).ok(),
        None => s.parse().ok(),
    }
}

fn load_trajectory(name: &str) -> Vec<[f64; 4]> {
    let Ok(path) = std::env::var(format!("LOP_STANDIN_TRAJECTORY_{name}"))
        .or_else(|_| std::env::var("LOP_STANDIN_TRAJECTORY"))
    else {
        return Vec::new();
    };
    let text =
        std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("stand-in libHD: {path}: {e}"));
    let mut rows = Vec::new();
    for line in text.lines() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let v: Vec<f64> = line
            .split(',')
            .filter_map(|x| x.trim().parse().ok())
            .collect();
        if v.len() >= 3 {
            rows.push([v[0], v[1], v[2], v.get(3).copied().unwrap_or(0.0)]);
        }
    }
    rows
}

/// A new session: the devices, the scripted errors and the log directory from the environment.
fn load_session(s: &mut State) {
    s.devices = std::env::var("LOP_STANDIN_DEVICE_NAMES")
        .unwrap_or_else(|_| "Omni".into())
        .split(',')
        .map(|n| Device {
            name: n.trim().to_string(),
            ..Default::default()
        })
        .collect();
    s.current = None;
    s.tick = 0;
    let names: Vec<String> = s.devices.iter().map(|d| d.name.clone()).collect();
    s.scripted_errors = std::env::var("LOP_STANDIN_ERRORS")
        .unwrap_or_default()
        .split(',')
        .filter_map(|item| {
            let (tick, rest) = item.split_once(':')?;
            let (code, device) = match rest.split_once('@') {
                Some((code, name)) => {
                    let d = names.iter().position(|n| n == name.trim());
                    let d = d.unwrap_or_else(|| {
                        panic!("stand-in libHD: LOP_STANDIN_ERRORS names no device: {item}")
                    });
                    (code, d)
                }
                None => (rest, 0),
            };
            Some((tick.trim().parse().ok()?, parse_code(code)?, device))
        })
        .collect();
    s.log_dir = std::env::var("LOP_STANDIN_LOG_DIR").ok();
}

#[no_mangle]
pub unsafe extern "C" fn hdInitDevice(name: *const c_char) -> Hhd {
    let name = if name.is_null() {
        None
    } else {
        Some(
            unsafe { CStr::from_ptr(name) }
                .to_string_lossy()
                .into_owned(),
        )
    };
    with_state!(|s| {
        if !s.devices.iter().any(|d| d.initialized) {
            load_session(s);
        }
        let d = match name.as_deref() {
            None | Some("Default Device") => Some(0),
            Some(n) => s.devices.iter().position(|d| d.name == n),
        };
        let Some(d) = d.filter(|&d| d < s.devices.len()) else {
            s.error(HD_DEVICE_FAULT, None);
            return HD_INVALID_HANDLE;
        };
        if s.devices[d].initialized {
            s.error(HD_DEVICE_ALREADY_INITIATED, Some(d));
            return HD_INVALID_HANDLE;
        }
        let trajectory = load_trajectory(&s.devices[d].name);
        let dev = &mut s.devices[d];
        dev.initialized = true;
        dev.force_output = false;
        dev.in_frame = false;
        dev.trajectory = trajectory;
        dev.rendered = [0.0; 3];
        dev.frame_force = [0.0; 3];
        dev.log.clear();
        s.current = Some(d);
        s.event(d, "init", 0);
        d as Hhd
    })
}

#[no_mangle]
pub extern "C" fn hdDisableDevice(hhd: Hhd) {
    with_state!(|s| {
        let Some(d) = s.device(hhd) else {
            return;
        };
        s.event(d, "disable_device", 0);
        let dev = &mut s.devices[d];
        dev.initialized = false;
        dev.force_output = false;
        dev.in_frame = false;
        dev.rendered = [0.0; 3];
        if s.current == Some(d) {
            s.current = None;
        }
        s.write_log(d);
    })
}

#[no_mangle]
pub extern "C" fn hdMakeCurrentDevice(hhd: Hhd) {
    with_state!(|s| {
        if let Some(d) = s.device(hhd) {
            s.current = Some(d);
        }
    })
}

#[no_mangle]
pub extern "C" fn hdGetCurrentDevice() -> Hhd {
    with_state!(|s| s.current.map_or(HD_INVALID_HANDLE, |d| d as Hhd))
}

#[no_mangle]
pub extern "C" fn hdEnable(cap: c_uint) {
    with_state!(|s| {
        let Some(d) = s.current() else {
            return;
        };
        if cap == HD_FORCE_OUTPUT {
            s.devices[d].force_output = true;
            s.event(d, "force_output_on", 0);
        }
    })
}

#[no_mangle]
pub extern "C" fn hdDisable(cap: c_uint) {
    with_state!(|s| {
        let Some(d) = s.current() else {
            return;
        };
        if cap == HD_FORCE_OUTPUT {
            s.event(d, "force_output_off", 0);
            s.devices[d].force_output = false;
            s.devices[d].rendered = [0.0; 3];
        }
    })
}

#[no_mangle]
pub extern "C" fn hdSetSchedulerRate(_hz: c_ulong) {}

fn scheduler_loop() {
    let period = Duration::from_millis(1);
    let mut next = Instant::now();
    loop {
        next += period;
        let now = Instant::now();
        if next > now {
            std::thread::sleep(next - now);
        } else {
            next = now; // late: no burst of catch-up ticks
        }
        let (jobs, mut callbacks) = with_state!(|s| {
            if !s.running {
                // Release anyone waiting on a synchronous call.
                for job in s.sync_jobs.drain(..) {
                    let (m, c) = &*job.done;
                    *m.lock().unwrap() = true;
                    c.notify_all();
                }
                return;
            }
            s.tick += 1;
            let tick = s.tick;
            let due: Vec<(c_uint, usize)> = s
                .scripted_errors
                .iter()
                .filter(|(t, _, _)| *t == tick)
                .map(|(_, c, d)| (*c, *d))
                .collect();
            for (code, d) in due {
                s.error(code, Some(d));
                s.event(d, "error", code);
            }
            let cbs: Vec<(c_ulong, usize, usize, u16)> = s
                .callbacks
                .iter()
                .map(|c| (c.handle, c.f as usize, c.data, c.priority))
                .collect();
            (std::mem::take(&mut s.sync_jobs), cbs)
        });
        for job in jobs {
            unsafe { (job.f)(job.data as *mut c_void) };
            let (m, c) = &*job.done;
            *m.lock().unwrap() = true;
            c.notify_all();
        }
        callbacks.sort_by_key(|c| std::cmp::Reverse(c.3));
        for (handle, f, data, _) in callbacks {
            let still = with_state!(|s| s.callbacks.iter().any(|c| c.handle == handle));
            if !still {
                continue;
            }
            // SAFETY: registered by hdScheduleAsynchronous with this signature.
            let f: HdCallback = unsafe { std::mem::transmute::<usize, HdCallback>(f) };
            let code = unsafe { f(data as *mut c_void) };
            if code == HD_CALLBACK_DONE {
                with_state!(|s| s.callbacks.retain(|c| c.handle != handle));
            }
        }
    }
}

#[no_mangle]
pub extern "C" fn hdStartScheduler() {
    let mut sched = SCHEDULER.lock().unwrap_or_else(|p| p.into_inner());
    if sched.is_some() {
        return;
    }
    with_state!(|s| s.running = true);
    *sched = Some(
        std::thread::Builder::new()
            .name("standin-hd-servo".into())
            .spawn(scheduler_loop)
            .expect("stand-in scheduler thread"),
    );
}

#[no_mangle]
pub extern "C" fn hdStopScheduler() {
    with_state!(|s| {
        s.event_all("stop_scheduler");
        s.running = false;
    });
    let handle = SCHEDULER.lock().unwrap_or_else(|p| p.into_inner()).take();
    if let Some(h) = handle {
        let _ = h.join();
    }
}

#[no_mangle]
pub extern "C" fn hdScheduleAsynchronous(
    f: HdCallback,
    data: *mut c_void,
    priority: u16,
) -> c_ulong {
    with_state!(|s| {
        let handle = s.next_handle;
        s.next_handle += 1;
        s.callbacks.push(Callback {
            handle,
            f,
            data: data as usize,
            priority,
        });
        handle
    })
}

#[no_mangle]
pub unsafe extern "C" fn hdScheduleSynchronous(f: HdCallback, data: *mut c_void, _priority: u16) {
    let done = Arc::new((Mutex::new(false), Condvar::new()));
    let queued = with_state!(|s| {
        if s.running {
            s.sync_jobs.push(SyncJob {
                f,
                data: data as usize,
                done: done.clone(),
            });
            true
        } else {
            false
        }
    });
    if !queued {
        unsafe { f(data) };
        return;
    }
    let (m, c) = &*done;
    let mut finished = m.lock().unwrap();
    while !*finished {
        finished = c.wait(finished).unwrap();
    }
}

#[no_mangle]
pub extern "C" fn hdUnschedule(handle: c_ulong) {
    with_state!(|s| {
        s.event_all("unschedule");
        s.callbacks.retain(|c| c.handle != handle);
    })
}

#[no_mangle]
pub extern "C" fn hdBeginFrame(hhd: Hhd) {
    with_state!(|s| {
        let Some(d) = s.device(hhd) else {
            return;
        };
        if s.devices[d].in_frame {
            s.error(HD_ILLEGAL_BEGIN, Some(d));
            s.event(d, "illegal_begin", HD_ILLEGAL_BEGIN);
        }
        let dev = &mut s.devices[d];
        dev.in_frame = true;
        dev.frame_force = dev.rendered;
        s.event(d, "begin", 0);
    })
}

#[no_mangle]
pub extern "C" fn hdEndFrame(hhd: Hhd) {
    with_state!(|s| {
        let Some(d) = s.device(hhd) else {
            return;
        };
        if !s.devices[d].in_frame {
            s.error(HD_ILLEGAL_END, Some(d));
            s.event(d, "illegal_end", HD_ILLEGAL_END);
            return;
        }
        let dev = &mut s.devices[d];
        dev.in_frame = false;
        dev.rendered = if dev.force_output {
            dev.frame_force
        } else {
            [0.0; 3]
        };
        s.event(d, "frame", 0);
    })
}

#[no_mangle]
pub unsafe extern "C" fn hdGetDoublev(what: c_uint, out: *mut f64) {
    let values: Vec<f64> = with_state!(|s| {
        let Some(d) = s.current() else {
            return;
        };
        let dev = &s.devices[d];
        let row = dev.row(s.tick);
        let prev = dev.row(s.tick.saturating_sub(1));
        match what {
            HD_CURRENT_POSITION => row[..3].to_vec(),
            HD_CURRENT_VELOCITY => (0..3).map(|k| (row[k] - prev[k]) * 1000.0).collect(),
            HD_CURRENT_TRANSFORM => {
                let mut m = vec![0.0; 16];
                m[0] = 1.0;
                m[5] = 1.0;
                m[10] = 1.0;
                m[15] = 1.0;
                m[12..15].copy_from_slice(&row[..3]);
                m
            }
            HD_CURRENT_FORCE => dev.rendered.to_vec(),
            HD_NOMINAL_MAX_FORCE => vec![MAX_FORCE],
            HD_NOMINAL_MAX_CONTINUOUS_FORCE => vec![MAX_CONTINUOUS_FORCE],
            HD_NOMINAL_MAX_STIFFNESS => vec![MAX_STIFFNESS],
            HD_NOMINAL_MAX_DAMPING => vec![0.003],
            HD_USABLE_WORKSPACE_DIMENSIONS => WORKSPACE.to_vec(),
            _ => {
                s.error(HD_INVALID_ENUM, Some(d));
                Vec::new()
            }
        }
    });
    for (i, v) in values.iter().enumerate() {
        unsafe { *out.add(i) = *v };
    }
}

#[no_mangle]
pub unsafe extern "C" fn hdGetIntegerv(what: c_uint, out: *mut c_int) {
    with_state!(|s| {
        let Some(d) = s.current() else {
            return;
        };
        match what {
            HD_CURRENT_BUTTONS => unsafe { *out = s.devices[d].row(s.tick)[3] as c_int },
            _ => s.error(HD_INVALID_ENUM, Some(d)),
        }
    })
}

#[no_mangle]
pub unsafe extern "C" fn hdSetDoublev(what: c_uint, values: *const f64) {
    let v = unsafe { [*values, *values.add(1), *values.add(2)] };
    with_state!(|s| {
        let Some(d) = s.current() else {
            return;
        };
        if what != HD_CURRENT_FORCE {
            s.error(HD_INVALID_ENUM, Some(d));
            return;
        }
        if !s.devices[d].in_frame {
            s.error(HD_INVALID_OPERATION, Some(d));
            s.event(d, "set_outside_frame", HD_INVALID_OPERATION);
            return;
        }
        let magnitude = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        if !magnitude.is_finite() || magnitude > MAX_FORCE * (1.0 + 1e-9) {
            // Like the device: refuse and render nothing.
            s.error(HD_EXCEEDED_MAX_FORCE, Some(d));
            s.event(d, "exceeded", HD_EXCEEDED_MAX_FORCE);
            s.devices[d].frame_force = [0.0; 3];
            return;
        }
        s.devices[d].frame_force = v;
    })
}

#[no_mangle]
pub extern "C" fn hdGetError() -> HdErrorInfo {
    with_state!(|s| {
        let (error_code, hhd) = s.errors.pop_front().unwrap_or((HD_SUCCESS, 0));
        HdErrorInfo {
            error_code,
            internal_error_code: 0,
            hhd,
        }
    })
}

#[no_mangle]
pub extern "C" fn hdGetString(what: c_uint) -> *const c_char {
    if what == HD_DEVICE_MODEL_TYPE {
        c"lop stand-in (PHANToM Omni)".as_ptr()
    } else {
        std::ptr::null()
    }
}
