//! A stand-in for the OpenHaptics HD library: a small `cdylib` that exports the HD symbols lop's
//! `openhaptics` driver loads (C ABI, same names and constants as the vendor's HD API),
//! so the driver's whole path runs in CI without a Phantom Omni.
//!
//! What it does, like the real library:
//! - `hdStartScheduler` starts its own 1 kHz scheduler thread that calls the registered
//!   callbacks in priority order; a callback returning `HD_CALLBACK_DONE` is dropped;
//!   `hdScheduleSynchronous` runs a callback on that thread and waits for it.
//! - The device plays a trajectory, one row per servo tick, and keeps rendering the last force
//!   it was given (committed at `hdEndFrame`); `hdGetError` pops a queue of errors.
//!
//! Controlled by environment variables, read at `hdInitDevice`:
//! - `LOP_STANDIN_TRAJECTORY`: CSV file, one row per servo tick: `x_mm,y_mm,z_mm[,buttons]`
//!   (lines starting with `#` and a header row are skipped); after the last row the device
//!   holds still. Without it the stylus rests at the origin.
//! - `LOP_STANDIN_ERRORS`: `TICK:CODE,...` — push HD error `CODE` (hex `0x0302` or decimal)
//!   at servo tick `TICK`.
//! - `LOP_STANDIN_LOG_DIR`: at `hdDisableDevice` write `standin-<pid>-<n>.csv` there: one row
//!   per event `event,tick,code,fx,fy,fz` where the force is the one being rendered at that
//!   moment — `frame` rows for every `hdEndFrame`, and `init`, `error`, `force_output_on/off`,
//!   `unschedule`, `stop_scheduler`, `disable_device` rows.
//! - `LOP_STANDIN_DEVICE_NAMES`: comma-separated names `hdInitDevice` accepts besides NULL and
//!   `"Default Device"` (default `Omni`); any other name fails with `HD_DEVICE_FAULT`.
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

#[derive(Default)]
struct State {
    initialized: bool,
    force_output: bool,
    in_frame: bool,
    /// Servo ticks so far (the scheduler's clock).
    tick: u64,
    trajectory: Vec<[f64; 4]>,
    scripted_errors: Vec<(u64, c_uint)>,
    errors: VecDeque<c_uint>,
    /// Force set in the current frame; committed at hdEndFrame.
    frame_force: [f64; 3],
    /// Force the motors render now.
    rendered: [f64; 3],
    log: Vec<(&'static str, u64, c_uint, [f64; 3])>,
    log_dir: Option<String>,
    sessions: u32,
    names: Vec<String>,
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
    fn event(&mut self, kind: &'static str, code: c_uint) {
        let (tick, f) = (self.tick, self.rendered);
        self.log.push((kind, tick, code, f));
    }

    fn row(&self, tick: u64) -> [f64; 4] {
        match self.trajectory.len() {
            0 => [0.0; 4],
            n => self.trajectory[(tick as usize).min(n - 1)],
        }
    }

    fn write_log(&mut self) {
        let Some(dir) = &self.log_dir else {
            return;
        };
        self.sessions += 1;
        let path = format!("{dir}/standin-{}-{}.csv", std::process::id(), self.sessions);
        let mut text = String::from("event,tick,code,fx,fy,fz\n");
        for (kind, tick, code, f) in &self.log {
            text.push_str(&format!(
                "{kind},{tick},{code},{},{},{}\n",
                f[0], f[1], f[2]
            ));
        }
        if let Ok(mut file) = std::fs::File::create(&path) {
            let _ = file.write_all(text.as_bytes());
        }
        self.log.clear();
    }
}

fn parse_code(s: &str) -> Option<c_uint> {
    let s = s.trim();
    match s.strip_prefix("0x") {
        Some(h) => c_uint::from_str_radix(h, 16).ok(),
        None => s.parse().ok(),
    }
}

fn load_env(s: &mut State) {
    s.trajectory.clear();
    if let Ok(path) = std::env::var("LOP_STANDIN_TRAJECTORY") {
        let text = std::fs::read_to_string(&path)
            .unwrap_or_else(|e| panic!("stand-in libHD: {path}: {e}"));
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
                s.trajectory
                    .push([v[0], v[1], v[2], v.get(3).copied().unwrap_or(0.0)]);
            }
        }
    }
    s.scripted_errors = std::env::var("LOP_STANDIN_ERRORS")
        .unwrap_or_default()
        .split(',')
        .filter_map(|item| {
            let (tick, code) = item.split_once(':')?;
            Some((tick.trim().parse().ok()?, parse_code(code)?))
        })
        .collect();
    s.log_dir = std::env::var("LOP_STANDIN_LOG_DIR").ok();
    s.names = std::env::var("LOP_STANDIN_DEVICE_NAMES")
        .unwrap_or_else(|_| "Omni".into())
        .split(',')
        .map(|n| n.trim().to_string())
        .collect();
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
        if s.initialized {
            s.errors.push_back(HD_DEVICE_ALREADY_INITIATED);
            return HD_INVALID_HANDLE;
        }
        load_env(s);
        let known = match &name {
            None => true,
            Some(n) => n == "Default Device" || s.names.iter().any(|k| k == n),
        };
        if !known {
            s.errors.push_back(HD_DEVICE_FAULT);
            return HD_INVALID_HANDLE;
        }
        s.initialized = true;
        s.tick = 0;
        s.rendered = [0.0; 3];
        s.frame_force = [0.0; 3];
        s.log.clear();
        s.event("init", 0);
        0
    })
}

#[no_mangle]
pub extern "C" fn hdDisableDevice(_hhd: Hhd) {
    with_state!(|s| {
        s.event("disable_device", 0);
        s.initialized = false;
        s.force_output = false;
        s.rendered = [0.0; 3];
        s.write_log();
    })
}

#[no_mangle]
pub extern "C" fn hdMakeCurrentDevice(_hhd: Hhd) {}

#[no_mangle]
pub extern "C" fn hdGetCurrentDevice() -> Hhd {
    0
}

#[no_mangle]
pub extern "C" fn hdEnable(cap: c_uint) {
    with_state!(|s| {
        if cap == HD_FORCE_OUTPUT {
            s.force_output = true;
            s.event("force_output_on", 0);
        }
    })
}

#[no_mangle]
pub extern "C" fn hdDisable(cap: c_uint) {
    with_state!(|s| {
        if cap == HD_FORCE_OUTPUT {
            s.event("force_output_off", 0);
            s.force_output = false;
            s.rendered = [0.0; 3];
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
            let due: Vec<c_uint> = s
                .scripted_errors
                .iter()
                .filter(|(t, _)| *t == tick)
                .map(|(_, c)| *c)
                .collect();
            for code in due {
                s.errors.push_back(code);
                s.event("error", code);
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
        s.event("stop_scheduler", 0);
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
        s.event("unschedule", 0);
        s.callbacks.retain(|c| c.handle != handle);
    })
}

#[no_mangle]
pub extern "C" fn hdBeginFrame(_hhd: Hhd) {
    with_state!(|s| {
        if s.in_frame {
            s.errors.push_back(HD_ILLEGAL_BEGIN);
        }
        s.in_frame = true;
        s.frame_force = s.rendered;
    })
}

#[no_mangle]
pub extern "C" fn hdEndFrame(_hhd: Hhd) {
    with_state!(|s| {
        if !s.in_frame {
            s.errors.push_back(HD_ILLEGAL_END);
            return;
        }
        s.in_frame = false;
        s.rendered = if s.force_output {
            s.frame_force
        } else {
            [0.0; 3]
        };
        s.event("frame", 0);
    })
}

#[no_mangle]
pub unsafe extern "C" fn hdGetDoublev(what: c_uint, out: *mut f64) {
    let values: Vec<f64> = with_state!(|s| {
        let row = s.row(s.tick);
        let prev = s.row(s.tick.saturating_sub(1));
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
            HD_CURRENT_FORCE => s.rendered.to_vec(),
            HD_NOMINAL_MAX_FORCE => vec![MAX_FORCE],
            HD_NOMINAL_MAX_CONTINUOUS_FORCE => vec![MAX_CONTINUOUS_FORCE],
            HD_NOMINAL_MAX_STIFFNESS => vec![MAX_STIFFNESS],
            HD_NOMINAL_MAX_DAMPING => vec![0.003],
            HD_USABLE_WORKSPACE_DIMENSIONS => WORKSPACE.to_vec(),
            _ => {
                s.errors.push_back(HD_INVALID_ENUM);
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
    with_state!(|s| match what {
        HD_CURRENT_BUTTONS => unsafe { *out = s.row(s.tick)[3] as c_int },
        _ => s.errors.push_back(HD_INVALID_ENUM),
    })
}

#[no_mangle]
pub unsafe extern "C" fn hdSetDoublev(what: c_uint, values: *const f64) {
    let v = unsafe { [*values, *values.add(1), *values.add(2)] };
    with_state!(|s| {
        if what != HD_CURRENT_FORCE {
            s.errors.push_back(HD_INVALID_ENUM);
            return;
        }
        if !s.in_frame {
            s.errors.push_back(HD_INVALID_OPERATION);
            return;
        }
        let magnitude = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        if !magnitude.is_finite() || magnitude > MAX_FORCE * (1.0 + 1e-9) {
            // Like the device: refuse and render nothing.
            s.errors.push_back(HD_EXCEEDED_MAX_FORCE);
            s.event("exceeded", HD_EXCEEDED_MAX_FORCE);
            s.frame_force = [0.0; 3];
            return;
        }
        s.frame_force = v;
    })
}

#[no_mangle]
pub extern "C" fn hdGetError() -> HdErrorInfo {
    with_state!(|s| HdErrorInfo {
        error_code: s.errors.pop_front().unwrap_or(HD_SUCCESS),
        internal_error_code: 0,
        hhd: 0,
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
