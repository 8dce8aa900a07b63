//! [`OpenHapticsDevice`]: lifecycle, limits, the servo callback and the safe stop.

use std::ffi::{c_uint, c_void, CStr, CString};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::Path;
use std::sync::atomic::{AtomicU64, AtomicU8, Ordering};
use std::time::{Duration, Instant};

use super::ffi::{self, HdApi, HdCallbackCode, HdEnum, HdSchedulerHandle, Hhd};
use crate::device::{
    monotonic_ns, DeviceError, DeviceLimits, DeviceOpenError, DeviceSample, HapticDevice, Pacing,
    ServoClock, ServoControl, ServoEnd, ServoRun, ServoTick,
};

/// A servo loop that has not called back for this long (outside a callback) has stalled: the
/// run ends with [`ServoEnd::Stalled`].
pub const SERVO_STALL_LIMIT: Duration = Duration::from_secs(2);

/// How many queued errors one `hdGetError` drain reads at most (the stack is short; a bound
/// keeps a misbehaving library from spinning the servo thread).
const MAX_ERRORS_PER_DRAIN: usize = 16;

/// Maps an HD error code to the driver's error class; `None` for `HD_SUCCESS`.
///
/// Force errors are recoverable; device, communication, timer errors and everything unknown or
/// unexpected (invalid enum, frame errors, …) are not — an unknown state is not a safe one.
pub fn classify_error(code: c_uint) -> Option<DeviceError> {
    Some(match code {
        ffi::HD_SUCCESS => return None,
        ffi::HD_WARM_MOTORS => DeviceError::MotorsWarm,
        ffi::HD_EXCEEDED_MAX_FORCE | ffi::HD_EXCEEDED_MAX_FORCE_IMPULSE | ffi::HD_FORCE_ERROR => {
            DeviceError::ForceLimitExceeded
        }
        ffi::HD_EXCEEDED_MAX_VELOCITY => DeviceError::VelocityLimitExceeded,
        ffi::HD_COMM_ERROR | ffi::HD_COMM_CONFIG_ERROR => DeviceError::Communication,
        _ => DeviceError::Fault,
    })
}

/// Counters of one device's servo traffic.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct OpenHapticsStats {
    /// Forces scaled down to the device's peak force.
    pub clamped_forces: u64,
    /// Forces refused as non-finite (zero written instead).
    pub non_finite_forces: u64,
    /// Recoverable (force) errors the device reported.
    pub recoverable_errors: u64,
    /// The last HD error code seen (0 if none).
    pub last_error_code: u32,
}

/// The device as seen inside a servo frame: what the tick closure reads and writes.
struct ServoFrame {
    api: &'static HdApi,
    hhd: Hhd,
    name: String,
    limits: DeviceLimits,
    /// Inside `hdBeginFrame`/`hdEndFrame`.
    open: bool,
    /// An error seen at the end of the previous frame, reported by the next `read`.
    pending: Option<DeviceError>,
    /// An unrecoverable error was handed to the tick (it must stop).
    fatal_reported: Option<DeviceError>,
    stats: OpenHapticsStats,
}

impl ServoFrame {
    fn begin(&mut self) {
        // SAFETY: valid handle of a started device; called on the scheduler thread.
        unsafe { (self.api.begin_frame)(self.hhd) };
        self.open = true;
    }

    fn end(&mut self) {
        if self.open {
            // SAFETY: as `begin`.
            unsafe { (self.api.end_frame)(self.hhd) };
            self.open = false;
        }
    }

    /// Reads the error stack until `HD_SUCCESS`; returns the worst error (unrecoverable over
    /// recoverable). Allocation-free.
    fn drain(&mut self) -> Option<DeviceError> {
        let mut worst: Option<DeviceError> = None;
        for _ in 0..MAX_ERRORS_PER_DRAIN {
            // SAFETY: plain HD call returning a 12-byte struct by value.
            let info = unsafe { (self.api.get_error)() };
            let Some(e) = classify_error(info.error_code) else {
                break;
            };
            self.stats.last_error_code = info.error_code;
            if e.is_recoverable() {
                self.stats.recoverable_errors += 1;
            }
            worst = match worst {
                Some(w) if !w.is_recoverable() => Some(w),
                _ => Some(e),
            };
        }
        worst
    }

    /// Errors raised by `hdEndFrame` (the force is committed there): kept for the next read.
    fn collect_end_of_frame_errors(&mut self) {
        if let Some(e) = self.drain() {
            self.pending = match self.pending {
                Some(p) if !p.is_recoverable() => Some(p),
                _ => Some(e),
            };
        }
    }

    fn set_force_raw(&mut self, f: [f64; 3]) {
        // SAFETY: three doubles, as HD_CURRENT_FORCE expects.
        unsafe { (self.api.set_doublev)(ffi::HD_CURRENT_FORCE, f.as_ptr()) };
    }

    fn report(&mut self, e: DeviceError) -> DeviceError {
        if !e.is_recoverable() {
            self.fatal_reported = Some(e);
        }
        e
    }

    fn get3(&self, what: HdEnum) -> [f64; 3] {
        let mut v = [0.0; 3];
        // SAFETY: three doubles for position / velocity.
        unsafe { (self.api.get_doublev)(what, v.as_mut_ptr()) };
        v
    }
}

impl HapticDevice for ServoFrame {
    fn name(&self) -> &str {
        &self.name
    }

    fn limits(&self) -> DeviceLimits {
        self.limits
    }

    fn pacing(&self) -> Pacing {
        Pacing::DeviceClock
    }

    fn start(&mut self) -> Result<(), DeviceOpenError> {
        Ok(())
    }

    /// Position, velocity and buttons of this servo frame; any error the device reported since
    /// the last check (including at the end of the previous frame) fails the read.
    fn read(&mut self, _t: f64) -> Result<DeviceSample, DeviceError> {
        let position_mm = self.get3(ffi::HD_CURRENT_POSITION);
        let velocity_mm_s = self.get3(ffi::HD_CURRENT_VELOCITY);
        let mut buttons: std::ffi::c_int = 0;
        // SAFETY: one int for HD_CURRENT_BUTTONS.
        unsafe { (self.api.get_integerv)(ffi::HD_CURRENT_BUTTONS, &mut buttons) };
        let now = self.drain();
        let earlier = self.pending.take();
        let worst = match (earlier, now) {
            (Some(a), _) if !a.is_recoverable() => Some(a),
            (_, Some(b)) => Some(b),
            (a, None) => a,
        };
        if let Some(e) = worst {
            return Err(self.report(e));
        }
        Ok(DeviceSample {
            position_mm,
            velocity_mm_s,
            buttons: buttons as u32,
        })
    }

    /// Writes the force, scaled down to the device's peak force if above it; a non-finite force
    /// or a force error from the device writes zero instead and returns the error.
    fn write_force(&mut self, force_n: [f64; 3]) -> Result<(), DeviceError> {
        let magnitude = force_n.iter().map(|f| f * f).sum::<f64>().sqrt();
        if !magnitude.is_finite() {
            self.stats.non_finite_forces += 1;
            self.set_force_raw([0.0; 3]);
            return Err(DeviceError::NonFiniteForce);
        }
        let max = self.limits.max_force_n;
        let force = if magnitude > max {
            self.stats.clamped_forces += 1;
            let k = max / magnitude;
            [force_n[0] * k, force_n[1] * k, force_n[2] * k]
        } else {
            force_n
        };
        self.set_force_raw(force);
        if let Some(e) = self.drain() {
            self.set_force_raw([0.0; 3]);
            return Err(self.report(e));
        }
        Ok(())
    }

    /// Zero force in the current frame (the tick's own stop; the driver's `stop` releases).
    fn stop(&mut self) {
        self.set_force_raw([0.0; 3]);
    }
}

const IDLE: u8 = 0;
const IN_CALLBACK: u8 = 1;
const FINISHED: u8 = 2;

/// Shared between `run_clocked` (waiting) and the servo callback (on the scheduler thread).
///
/// Protocol: the callback enters only by moving `state` IDLE → IN_CALLBACK and leaves to IDLE
/// or FINISHED; `run_clocked` declares a stall only by moving IDLE → FINISHED. Once FINISHED,
/// the callback touches nothing but `state` and returns `HD_CALLBACK_DONE`, so the tick closure
/// may go away while the context itself lives on until the scheduler is stopped.
struct ServoContext {
    api: &'static HdApi,
    frame: *mut ServoFrame,
    tick: *mut ServoTick<'static>,
    state: AtomicU8,
    ticks: AtomicU64,
    end: AtomicU8,
    handle: HdSchedulerHandle,
}

fn encode_end(end: ServoEnd) -> u8 {
    match end {
        ServoEnd::Requested => 1,
        ServoEnd::Panicked => 2,
        ServoEnd::Stalled => 3,
        ServoEnd::Device(DeviceError::Communication) => 4,
        ServoEnd::Device(_) => 5,
    }
}

fn decode_end(code: u8) -> ServoEnd {
    match code {
        2 => ServoEnd::Panicked,
        3 => ServoEnd::Stalled,
        4 => ServoEnd::Device(DeviceError::Communication),
        5 => ServoEnd::Device(DeviceError::Fault),
        _ => ServoEnd::Requested,
    }
}

/// The servo callback: one tick of the caller's closure inside a frame.
unsafe extern "C" fn servo_callback(data: *mut c_void) -> HdCallbackCode {
    // SAFETY: `data` is the ServoContext registered in run_clocked; it outlives every callback.
    let ctx = unsafe { &*(data as *const ServoContext) };
    if ctx
        .state
        .compare_exchange(IDLE, IN_CALLBACK, Ordering::AcqRel, Ordering::Acquire)
        .is_err()
    {
        return ffi::HD_CALLBACK_DONE;
    }
    let clock = ServoClock {
        tick: ctx.ticks.load(Ordering::Relaxed),
        now_ns: monotonic_ns(),
    };
    // SAFETY: while the state is IN_CALLBACK, run_clocked is blocked and the device (which
    // owns the frame) and the closure are alive and not otherwise touched.
    let frame = unsafe { &mut *ctx.frame };
    let tick = unsafe { &mut *ctx.tick };
    let ran = catch_unwind(AssertUnwindSafe(|| {
        frame.begin();
        let control = tick(frame, clock);
        frame.end();
        frame.collect_end_of_frame_errors();
        control
    }));
    ctx.ticks.store(clock.tick + 1, Ordering::Relaxed);
    let end = match ran {
        Ok(ServoControl::Continue) => frame.fatal_reported.map(ServoEnd::Device),
        Ok(ServoControl::Stop) => Some(
            frame
                .fatal_reported
                .map_or(ServoEnd::Requested, ServoEnd::Device),
        ),
        Err(_) => Some(ServoEnd::Panicked),
    };
    match end {
        None => {
            ctx.state.store(IDLE, Ordering::Release);
            ffi::HD_CALLBACK_CONTINUE
        }
        Some(end) => {
            // The last frame of the run: zero force, whatever happened.
            if !frame.open {
                frame.begin();
            }
            frame.set_force_raw([0.0; 3]);
            frame.end();
            let _ = frame.drain();
            ctx.end.store(encode_end(end), Ordering::Relaxed);
            ctx.state.store(FINISHED, Ordering::Release);
            ffi::HD_CALLBACK_DONE
        }
    }
}

/// Writes zero force in one scheduler frame (`hdScheduleSynchronous`).
unsafe extern "C" fn zero_force_callback(data: *mut c_void) -> HdCallbackCode {
    // SAFETY: `data` is the device's boxed ServoFrame; the caller blocks until we return.
    let frame = unsafe { &mut *(data as *mut ServoFrame) };
    frame.begin();
    frame.set_force_raw([0.0; 3]);
    frame.end();
    frame.collect_end_of_frame_errors();
    ffi::HD_CALLBACK_DONE
}

/// A read or write done in one scheduler frame, outside `run_clocked`.
struct SyncIo {
    frame: *mut ServoFrame,
    write: Option<[f64; 3]>,
    result: Result<DeviceSample, DeviceError>,
}

unsafe extern "C" fn sync_io_callback(data: *mut c_void) -> HdCallbackCode {
    // SAFETY: `data` is a SyncIo on the caller's stack; the caller blocks until we return.
    let io = unsafe { &mut *(data as *mut SyncIo) };
    let frame = unsafe { &mut *io.frame };
    frame.begin();
    io.result = match io.write {
        None => frame.read(0.0),
        Some(f) => frame.write_force(f).map(|()| DeviceSample::default()),
    };
    frame.end();
    frame.collect_end_of_frame_errors();
    ffi::HD_CALLBACK_DONE
}

/// A Phantom Omni / Touch through OpenHaptics. See the [module docs](super).
pub struct OpenHapticsDevice {
    api: &'static HdApi,
    /// Device name as configured in the vendor's setup tool; `None`: the default device.
    device_name: Option<CString>,
    /// For messages: `openhaptics (NAME)`.
    label: String,
    hhd: Option<Hhd>,
    scheduler_running: bool,
    /// The device as the servo callback sees it (boxed: the callback holds a pointer to it).
    frame: Box<ServoFrame>,
    /// A servo context that may still be called (a stalled run); freed after the scheduler stops.
    stalled: Option<Box<ServoContext>>,
    model: Option<String>,
}

// SAFETY: the raw pointers in `stalled` point into this device's own boxes and the leaked,
// immutable API table; nothing is shared with another owner.
unsafe impl Send for OpenHapticsDevice {}
// SAFETY: ServoFrame holds only the immutable API table, plain data and counters.
unsafe impl Send for ServoFrame {}

impl OpenHapticsDevice {
    /// Loads the HD library (see the [module docs](super) for which file). Does not touch the
    /// device yet. `name`: the configured device name, `None` for the default device.
    pub fn open(
        name: Option<&str>,
        configured_library: Option<&Path>,
    ) -> Result<OpenHapticsDevice, DeviceOpenError> {
        let label = match name {
            Some(n) => format!("openhaptics:{n}"),
            None => "openhaptics".to_string(),
        };
        let candidates = ffi::library_candidates(configured_library);
        let api = HdApi::load(&candidates).map_err(|why| DeviceOpenError::Unavailable {
            device: label.clone(),
            reason: format!(
                "the OpenHaptics HD library could not be loaded ({why}). Install OpenHaptics and \
                 the device driver (docs/deploy.md), or point {} (or `hd_library` under [device] \
                 in the daemon config) at libHD.so",
                ffi::LIBRARY_ENV
            ),
        })?;
        let device_name = match name {
            Some(n) => Some(CString::new(n).map_err(|_| DeviceOpenError::Unavailable {
                device: label.clone(),
                reason: "the device name contains a NUL byte".into(),
            })?),
            None => None,
        };
        Ok(OpenHapticsDevice {
            api,
            device_name,
            frame: Box::new(ServoFrame {
                api,
                hhd: ffi::HD_INVALID_HANDLE,
                name: format!("{label} via {}", api.path.display()),
                limits: omni_nominal_limits(),
                open: false,
                pending: None,
                fatal_reported: None,
                stats: OpenHapticsStats::default(),
            }),
            label,
            hhd: None,
            scheduler_running: false,
            stalled: None,
            model: None,
        })
    }

    /// The library file that was loaded.
    pub fn library_path(&self) -> &Path {
        &self.api.path
    }

    /// The device model the library reports (after `start`), if it reports one.
    pub fn model(&self) -> Option<&str> {
        self.model.as_deref()
    }

    /// Counters of forces and errors so far.
    pub fn stats(&self) -> OpenHapticsStats {
        self.frame.stats
    }

    /// Drains the error stack; the first error as (code, internal code).
    fn first_error(&self) -> Option<(c_uint, i32)> {
        let mut first = None;
        for _ in 0..MAX_ERRORS_PER_DRAIN {
            // SAFETY: plain HD call.
            let info = unsafe { (self.api.get_error)() };
            if info.error_code == ffi::HD_SUCCESS {
                break;
            }
            first.get_or_insert((info.error_code, info.internal_error_code));
        }
        first
    }

    fn start_error(&self, what: &str, code: c_uint, internal: i32) -> DeviceOpenError {
        let hint = match code {
            ffi::HD_COMM_ERROR => {
                "; check the cable and power; an Ethernet Touch needs a link-local IPv4 address \
                 on its interface, a FireWire Omni the firewire-ohci driver and access to \
                 /dev/fw* (docs/deploy.md)"
            }
            ffi::HD_COMM_CONFIG_ERROR => {
                "; the device configuration is missing or wrong: run the vendor's Touch Setup / \
                 Phantom Configuration tool and check the device name"
            }
            ffi::HD_DEVICE_FAULT => {
                "; is the device connected and powered, is the name right (none = the default \
                 device, else the name from the vendor's setup tool), and may this user open it \
                 (plugdev group / udev rule, docs/deploy.md)?"
            }
            ffi::HD_DEVICE_ALREADY_INITIATED => "; another process holds the device",
            _ => "",
        };
        DeviceOpenError::Start {
            device: self.label.clone(),
            reason: format!(
                "{what}: {} (0x{code:04x}, internal {internal}){hint}",
                ffi::error_name(code)
            ),
        }
    }

    fn get_doubles<const N: usize>(&self, what: HdEnum) -> [f64; N] {
        let mut v = [f64::NAN; N];
        // SAFETY: `what` is a query returning N doubles.
        unsafe { (self.api.get_doublev)(what, v.as_mut_ptr()) };
        v
    }

    fn read_limits(&self) -> Result<DeviceLimits, DeviceOpenError> {
        let [max_force_n] = self.get_doubles::<1>(ffi::HD_NOMINAL_MAX_FORCE);
        let [max_continuous_force_n] = self.get_doubles::<1>(ffi::HD_NOMINAL_MAX_CONTINUOUS_FORCE);
        let [max_stiffness_n_per_mm] = self.get_doubles::<1>(ffi::HD_NOMINAL_MAX_STIFFNESS);
        let ws = self.get_doubles::<6>(ffi::HD_USABLE_WORKSPACE_DIMENSIONS);
        if let Some((code, internal)) = self.first_error() {
            return Err(self.start_error("reading the device limits", code, internal));
        }
        let limits = DeviceLimits {
            max_force_n,
            max_continuous_force_n,
            max_stiffness_n_per_mm,
            workspace_min_mm: [ws[0], ws[1], ws[2]],
            workspace_max_mm: [ws[3], ws[4], ws[5]],
        };
        let positive = |v: f64| v.is_finite() && v > 0.0;
        let ok = positive(max_force_n)
            && positive(max_continuous_force_n)
            && positive(max_stiffness_n_per_mm)
            && ws.iter().all(|v| v.is_finite())
            && (0..3).all(|k| ws[k] < ws[k + 3]);
        if !ok {
            return Err(DeviceOpenError::Start {
                device: self.label.clone(),
                reason: format!("the device reports unusable limits: {limits:?}"),
            });
        }
        Ok(limits)
    }

    fn running_handle(&self) -> Result<Hhd, DeviceOpenError> {
        self.hhd.ok_or_else(|| DeviceOpenError::Start {
            device: self.label.clone(),
            reason: "run_clocked before start".into(),
        })
    }
}

/// Limits before the device has reported its own: the Omni's nominal figures
/// (the vendor's published specifications).
fn omni_nominal_limits() -> DeviceLimits {
    DeviceLimits {
        max_force_n: 3.3,
        max_continuous_force_n: 0.88,
        max_stiffness_n_per_mm: 0.7,
        workspace_min_mm: [-80.0, -60.0, -35.0],
        workspace_max_mm: [80.0, 60.0, 35.0],
    }
}

impl HapticDevice for OpenHapticsDevice {
    fn name(&self) -> &str {
        &self.frame.name
    }

    /// The device's own limits once started (nominal Omni figures before).
    fn limits(&self) -> DeviceLimits {
        self.frame.limits
    }

    fn pacing(&self) -> Pacing {
        Pacing::DeviceClock
    }

    fn start(&mut self) -> Result<(), DeviceOpenError> {
        if self.hhd.is_some() {
            return Ok(());
        }
        let _ = self.first_error(); // errors left over from before are not ours
        let name_ptr = self
            .device_name
            .as_ref()
            .map_or(std::ptr::null(), |n| n.as_ptr());
        // SAFETY: NULL (default device) or a valid C string.
        let hhd = unsafe { (self.api.init_device)(name_ptr) };
        let shown = match &self.device_name {
            Some(n) => format!("hdInitDevice(\"{}\")", n.to_string_lossy()),
            None => "hdInitDevice(HD_DEFAULT_DEVICE)".to_string(),
        };
        if let Some((code, internal)) = self.first_error() {
            return Err(self.start_error(&shown, code, internal));
        }
        if hhd == ffi::HD_INVALID_HANDLE {
            return Err(self.start_error(&shown, ffi::HD_DEVICE_FAULT, 0));
        }
        // SAFETY: a handle hdInitDevice just returned.
        unsafe { (self.api.make_current_device)(hhd) };
        let limits = match self.read_limits() {
            Ok(l) => l,
            Err(e) => {
                // SAFETY: as above.
                unsafe { (self.api.disable_device)(hhd) };
                return Err(e);
            }
        };
        self.model = self.api.get_string.and_then(|get| {
            // SAFETY: hdGetString returns NULL or a static NUL-terminated string.
            let p = unsafe { get(ffi::HD_DEVICE_MODEL_TYPE) };
            (!p.is_null()).then(|| unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned())
        });
        // SAFETY: plain HD calls on the current device.
        unsafe {
            (self.api.enable)(ffi::HD_FORCE_OUTPUT);
            (self.api.enable)(ffi::HD_MAX_FORCE_CLAMPING);
            (self.api.start_scheduler)();
        }
        if let Some((code, internal)) = self.first_error() {
            // SAFETY: as above.
            unsafe {
                (self.api.disable)(ffi::HD_FORCE_OUTPUT);
                (self.api.disable_device)(hhd);
            }
            return Err(self.start_error(
                "enabling force output and starting the servo scheduler",
                code,
                internal,
            ));
        }
        self.frame.hhd = hhd;
        self.frame.limits = limits;
        self.frame.pending = None;
        self.frame.fatal_reported = None;
        if let Some(model) = &self.model {
            self.frame.name = format!("{} ({model}) via {}", self.label, self.api.path.display());
        }
        self.hhd = Some(hhd);
        self.scheduler_running = true;
        Ok(())
    }

    /// One read in a scheduler frame (`hdScheduleSynchronous`). The haptic loop does not use
    /// this: it reads inside `run_clocked`.
    fn read(&mut self, _t: f64) -> Result<DeviceSample, DeviceError> {
        self.sync_io(None)
    }

    /// One write in a scheduler frame; see `read`.
    fn write_force(&mut self, force_n: [f64; 3]) -> Result<(), DeviceError> {
        self.sync_io(Some(force_n)).map(|_| ())
    }

    fn stop(&mut self) {
        let Some(hhd) = self.hhd.take() else {
            return;
        };
        let frame: *mut ServoFrame = &mut *self.frame;
        // SAFETY (the block): HD calls on the started device, in the documented order: zero
        // force first, then unschedule, stop the scheduler, disable force output and the device.
        unsafe {
            if self.scheduler_running && self.stalled.is_none() {
                (self.api.schedule_synchronous)(
                    zero_force_callback,
                    frame as *mut c_void,
                    ffi::HD_MAX_SCHEDULER_PRIORITY,
                );
            } else {
                // The scheduler stopped calling: best effort, a frame from this thread.
                zero_force_callback(frame as *mut c_void);
            }
            if let Some(ctx) = &self.stalled {
                (self.api.unschedule)(ctx.handle);
            }
            if self.scheduler_running {
                (self.api.stop_scheduler)();
                self.scheduler_running = false;
            }
            (self.api.disable)(ffi::HD_FORCE_OUTPUT);
            (self.api.disable_device)(hhd);
        }
        let _ = self.first_error();
        // The scheduler is stopped: no callback can run any more.
        self.stalled = None;
    }

    fn run_clocked(&mut self, tick: &mut ServoTick<'_>) -> Result<ServoRun, DeviceOpenError> {
        self.running_handle()?;
        if self.stalled.is_some() {
            return Err(DeviceOpenError::Start {
                device: self.label.clone(),
                reason: "the servo loop stalled earlier; stop and start the device again".into(),
            });
        }
        self.frame.pending = None;
        self.frame.fatal_reported = None;
        // SAFETY: the closure is only called while this function waits below (the state
        // protocol on ServoContext); erasing its lifetime never lets it be called later.
        let tick: *mut ServoTick<'static> =
            unsafe { std::mem::transmute::<*mut ServoTick<'_>, *mut ServoTick<'static>>(tick) };
        let mut ctx = Box::new(ServoContext {
            api: self.api,
            frame: &mut *self.frame,
            tick,
            state: AtomicU8::new(IDLE),
            ticks: AtomicU64::new(0),
            end: AtomicU8::new(0),
            handle: 0,
        });
        let data = &*ctx as *const ServoContext as *mut c_void;
        let _ = self.first_error();
        // SAFETY: `data` stays valid until the callback returned DONE or the scheduler stopped.
        ctx.handle = unsafe {
            (ctx.api.schedule_asynchronous)(servo_callback, data, ffi::HD_MAX_SCHEDULER_PRIORITY)
        };
        if let Some((code, internal)) = self.first_error() {
            ctx.state.store(FINISHED, Ordering::Release);
            // SAFETY: the handle just returned.
            unsafe { (self.api.unschedule)(ctx.handle) };
            self.stalled = Some(ctx);
            return Err(self.start_error("hdScheduleAsynchronous", code, internal));
        }

        let mut seen = 0;
        let mut since = Instant::now();
        let end = loop {
            std::thread::sleep(Duration::from_millis(2));
            if ctx.state.load(Ordering::Acquire) == FINISHED {
                break decode_end(ctx.end.load(Ordering::Relaxed));
            }
            let n = ctx.ticks.load(Ordering::Relaxed);
            if n != seen {
                seen = n;
                since = Instant::now();
            } else if since.elapsed() > SERVO_STALL_LIMIT
                && ctx
                    .state
                    .compare_exchange(IDLE, FINISHED, Ordering::AcqRel, Ordering::Acquire)
                    .is_ok()
            {
                break ServoEnd::Stalled;
            }
        };
        let ticks = ctx.ticks.load(Ordering::Relaxed);
        if end == ServoEnd::Stalled {
            // The scheduler may still call the callback (it returns DONE): keep the context
            // until `stop` has stopped the scheduler.
            self.stalled = Some(ctx);
        } else {
            // The callback returned DONE: the scheduler will not call it again.
            drop(ctx);
        }
        Ok(ServoRun {
            ticks,
            end: match end {
                ServoEnd::Device(_) => {
                    ServoEnd::Device(self.frame.fatal_reported.unwrap_or(DeviceError::Fault))
                }
                other => other,
            },
        })
    }
}

impl OpenHapticsDevice {
    fn sync_io(&mut self, write: Option<[f64; 3]>) -> Result<DeviceSample, DeviceError> {
        if self.hhd.is_none() {
            return Err(DeviceError::NotStarted);
        }
        let mut io = SyncIo {
            frame: &mut *self.frame,
            write,
            result: Err(DeviceError::NotStarted),
        };
        // SAFETY: `io` lives on this stack until the synchronous call returns.
        unsafe {
            (self.api.schedule_synchronous)(
                sync_io_callback,
                &mut io as *mut SyncIo as *mut c_void,
                ffi::HD_MAX_SCHEDULER_PRIORITY,
            )
        };
        io.result
    }
}

impl Drop for OpenHapticsDevice {
    fn drop(&mut self) {
        self.stop();
    }
}

impl std::fmt::Debug for OpenHapticsDevice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("OpenHapticsDevice")
            .field("label", &self.label)
            .field("library", &self.api.path)
            .field("started", &self.hhd.is_some())
            .finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    #[test]
    fn force_errors_are_recoverable_device_errors_stop() {
        assert_eq!(classify_error(ffi::HD_SUCCESS), None);
        for code in [0x0200, 0x0201, 0x0202, 0x0203, 0x0204] {
            assert!(classify_error(code).unwrap().is_recoverable(), "{code:#x}");
        }
        for code in [
            0x0300, 0x0301, 0x0302, 0x0303, 0x0304, 0x0100, 0x0402, 0x9999,
        ] {
            assert!(!classify_error(code).unwrap().is_recoverable(), "{code:#x}");
        }
        assert_eq!(classify_error(0x0302), Some(DeviceError::Communication));
    }

    #[test]
    fn missing_library_names_the_paths_and_the_fix() {
        let missing = PathBuf::from("/nonexistent/lop-test/libHD.so");
        // LOP_HD_LIBRARY would override the configured path; the test leaves it alone.
        if std::env::var_os(ffi::LIBRARY_ENV).is_some() {
            return;
        }
        let e = OpenHapticsDevice::open(Some("Omni"), Some(&missing)).unwrap_err();
        let text = e.to_string();
        assert!(text.contains("/nonexistent/lop-test/libHD.so"), "{text}");
        assert!(text.contains("LOP_HD_LIBRARY"), "{text}");
        assert!(matches!(e, DeviceOpenError::Unavailable { .. }), "{text}");
    }
}
