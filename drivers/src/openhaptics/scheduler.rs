//! [`OpenHapticsScheduler`]: the vendor's servo scheduler as lop runs it — one scheduler and
//! one servo callback for one or several devices; the callback and the frames it drives.

use std::cell::UnsafeCell;
use std::ffi::c_void;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::atomic::{AtomicU64, AtomicU8, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use super::device::{first_error, OpenHapticsDevice};
use super::ffi::{self, HdApi, HdCallbackCode, HdSchedulerHandle, Hhd};
use super::frame::{ParkedErrors, ServoFrame};
use crate::device::{
    monotonic_ns, DeviceError, DeviceOpenError, HapticDevice, ServoClock, ServoControl, ServoEnd,
    ServoRun, ServoTick,
};

/// A servo loop that has not called back for this long (outside a callback) has stalled: the
/// run ends with [`ServoEnd::Stalled`].
pub const SERVO_STALL_LIMIT: Duration = Duration::from_secs(2);

const IDLE: u8 = 0;
const IN_CALLBACK: u8 = 1;
const FINISHED: u8 = 2;

/// Shared between `run_clocked` (waiting) and the servo callback (on the scheduler thread).
///
/// Protocol: the callback enters only by moving `state` IDLE → IN_CALLBACK and leaves to IDLE
/// or FINISHED; `run_clocked` declares a stall only by moving IDLE → FINISHED. Once FINISHED,
/// the callback touches nothing but `state` and returns `HD_CALLBACK_DONE`, so the devices and
/// the tick closure may go away while the context itself lives on until the scheduler is
/// stopped.
struct ServoContext {
    /// The devices' frames, in the caller's order.
    frames: Vec<*mut ServoFrame>,
    /// The same frames as the tick is given them (`&mut [&mut dyn HapticDevice]` in layout);
    /// only the callback touches it.
    devices: UnsafeCell<Vec<*mut dyn HapticDevice>>,
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

/// Zero force to every frame in one frame each: the frames not open are begun, every force
/// set to zero, every frame ended. Errors are read and dropped (the run is over).
///
/// # Safety
/// Each pointer is a live frame no one else touches meanwhile.
unsafe fn zero_frames(frames: &[*mut ServoFrame]) {
    for &f in frames {
        // SAFETY: the caller's contract.
        let frame = unsafe { &mut *f };
        if !frame.open {
            frame.begin();
        }
    }
    for &f in frames {
        // SAFETY: as above.
        unsafe { &mut *f }.set_force_raw([0.0; 3]);
    }
    for &f in frames {
        // SAFETY: as above.
        let frame = unsafe { &mut *f };
        frame.end();
        let _ = frame.drain();
    }
}

/// The servo callback: every device's frame begun, one tick of the caller's closure, every
/// frame ended.
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
    // SAFETY (the frames, the device list and the closure): while the state is IN_CALLBACK,
    // run_clocked is blocked and the devices (which own the frames) and the closure are alive
    // and not otherwise touched; the device list is only ever touched here.
    let tick = unsafe { &mut *ctx.tick };
    let ran = catch_unwind(AssertUnwindSafe(|| {
        for &f in &ctx.frames {
            unsafe { &mut *f }.begin();
        }
        let list = unsafe { &mut *ctx.devices.get() };
        // `*mut dyn HapticDevice` and `&mut dyn HapticDevice` have the same layout; every
        // pointer is a live, distinct frame.
        let devices: &mut [&mut dyn HapticDevice] =
            unsafe { std::slice::from_raw_parts_mut(list.as_mut_ptr().cast(), list.len()) };
        let control = tick(devices, clock);
        for &f in &ctx.frames {
            let frame = unsafe { &mut *f };
            frame.end();
            frame.collect_end_of_frame_errors();
        }
        control
    }));
    ctx.ticks.store(clock.tick + 1, Ordering::Relaxed);
    let fatal = ctx
        .frames
        .iter()
        .find_map(|&f| unsafe { &*f }.fatal_reported);
    let end = match ran {
        Ok(ServoControl::Continue) => fatal.map(ServoEnd::Device),
        Ok(ServoControl::Stop) => Some(fatal.map_or(ServoEnd::Requested, ServoEnd::Device)),
        Err(_) => Some(ServoEnd::Panicked),
    };
    match end {
        None => {
            ctx.state.store(IDLE, Ordering::Release);
            ffi::HD_CALLBACK_CONTINUE
        }
        Some(end) => {
            // The last frame of the run: zero force to every device, whatever happened.
            // SAFETY: as above.
            unsafe { zero_frames(&ctx.frames) };
            ctx.end.store(encode_end(end), Ordering::Relaxed);
            ctx.state.store(FINISHED, Ordering::Release);
            ffi::HD_CALLBACK_DONE
        }
    }
}

/// Writes zero force to every frame of a [`ZeroForce`] in one scheduler frame
/// (`hdScheduleSynchronous`).
unsafe extern "C" fn zero_force_callback(data: *mut c_void) -> HdCallbackCode {
    // SAFETY: `data` is a ZeroForce on the caller's stack; the caller blocks until we return.
    let zero = unsafe { &*(data as *const ZeroForce) };
    // SAFETY: its frames belong to devices the caller holds.
    unsafe { zero_frames(&zero.frames) };
    ffi::HD_CALLBACK_DONE
}

/// The frames `stop` zeroes.
struct ZeroForce {
    frames: Vec<*mut ServoFrame>,
}

/// The vendor's servo scheduler driving one or several [`OpenHapticsDevice`]s.
///
/// libHD has one scheduler per process; several devices share it and its callbacks. So the
/// devices of a run start together, then the scheduler once:
/// - [`start`](Self::start): per device `hdInitDevice(NAME)` (`NULL` for the default device),
///   `hdMakeCurrentDevice`, the limits read, `hdEnable(HD_FORCE_OUTPUT)` and
///   `hdEnable(HD_MAX_FORCE_CLAMPING)`; then one `hdStartScheduler`. A device that fails
///   releases the ones before it.
/// - [`run_clocked`](Self::run_clocked): one callback (`hdScheduleAsynchronous`); per servo
///   tick, for each device `hdMakeCurrentDevice` and `hdBeginFrame`; then the caller's tick with
///   every device (each read and write makes its device current first); then for each device
///   `hdEndFrame` and the `hdGetError` check. Force errors zero that device's force and the loop
///   goes on; an unrecoverable error of any device ends the run, as does the tick's stop or a
///   panic: zero force to every device in that last frame.
/// - [`stop`](Self::stop): zero force to every device in one more frame
///   (`hdScheduleSynchronous`), then `hdUnschedule` (a stalled run), `hdStopScheduler`, and per
///   device `hdMakeCurrentDevice`, `hdDisable(HD_FORCE_OUTPUT)` and `hdDisableDevice`.
///
/// The devices are lent to each call, in the same order every time (the tick sees them in
/// that order); `stop` takes the devices `start` started. A device alone runs on a scheduler
/// of its own through [`HapticDevice`]. Dropped while running, the scheduler stops; each device
/// released on its own then writes zero force from the calling thread.
#[derive(Default)]
pub struct OpenHapticsScheduler {
    api: Option<&'static HdApi>,
    /// The handles of the devices started, in order.
    handles: Vec<Hhd>,
    running: bool,
    /// A servo context that may still be called (a stalled run); freed after the scheduler stops.
    stalled: Option<Box<ServoContext>>,
}

// SAFETY: the raw pointers in `stalled` point into the devices' own boxed frames and the
// closure of a run that ended; once the run ended the callback touches only the context's
// atomic state, which lives in this box until the scheduler is stopped.
unsafe impl Send for OpenHapticsScheduler {}

fn labels(devices: &[&mut OpenHapticsDevice]) -> String {
    devices
        .iter()
        .map(|d| d.label())
        .collect::<Vec<_>>()
        .join(", ")
}

impl OpenHapticsScheduler {
    /// A scheduler that has started nothing yet.
    pub fn new() -> OpenHapticsScheduler {
        OpenHapticsScheduler::default()
    }

    /// Whether it has started devices and not stopped them.
    pub fn is_running(&self) -> bool {
        self.running
    }

    /// Starts `devices` on this scheduler: each initialised by its name, its limits read,
    /// force output enabled; then the scheduler. Err: the device that failed and why (the
    /// ones started before it are released), or a set that cannot run together (none, one
    /// named twice, different libraries, one already started).
    pub fn start(&mut self, devices: &mut [&mut OpenHapticsDevice]) -> Result<(), DeviceOpenError> {
        let refuse = |device: String, reason: String| DeviceOpenError::Start { device, reason };
        if self.running {
            return Err(refuse(
                labels(devices),
                "this scheduler already runs devices; stop it first".into(),
            ));
        }
        let Some(first) = devices.first() else {
            return Err(refuse("openhaptics".into(), "no device to start".into()));
        };
        let api = first.api();
        for (k, d) in devices.iter().enumerate() {
            if d.is_started() {
                return Err(refuse(
                    d.label().into(),
                    "already started; devices that share the scheduler start together".into(),
                ));
            }
            if d.library_path() != api.path {
                return Err(refuse(
                    d.label().into(),
                    format!(
                        "loaded {} but {} loaded {}: the devices of one scheduler share one \
                         HD library",
                        d.library_path().display(),
                        first.label(),
                        api.path.display()
                    ),
                ));
            }
            if devices[..k].iter().any(|e| e.label() == d.label()) {
                return Err(refuse(
                    d.label().into(),
                    "named twice: give each device of the rig its own name (from the vendor's \
                     setup tool)"
                        .into(),
                ));
            }
        }
        let _ = first_error(api); // errors left over from before are not ours
        for k in 0..devices.len() {
            if let Err(e) = devices[k].init() {
                release(&mut devices[..k]);
                return Err(e);
            }
        }
        // SAFETY: plain HD call; every device is initialised.
        unsafe { (api.start_scheduler)() };
        if let Some((code, internal)) = first_error(api) {
            let e = refuse(
                labels(devices),
                format!(
                    "starting the servo scheduler: {} (0x{code:04x}, internal {internal})",
                    ffi::error_name(code)
                ),
            );
            release(devices);
            return Err(e);
        }
        let handles: Vec<Hhd> = devices.iter().filter_map(|d| d.handle()).collect();
        let parked = Arc::new(ParkedErrors::new(&handles));
        for d in devices.iter_mut() {
            d.frame_mut().parked = Some(parked.clone());
        }
        self.api = Some(api);
        self.handles = handles;
        self.running = true;
        Ok(())
    }

    /// Runs `tick` inside one servo callback per servo tick with every device (in the order
    /// given), until it returns [`ServoControl::Stop`], a device fails or the scheduler
    /// stalls; blocks meanwhile. The RT rules hold from the tick's second call on (see
    /// [`HapticDevice::run_clocked`]). `devices`: the ones `start` started, in its order.
    pub fn run_clocked(
        &mut self,
        devices: &mut [&mut OpenHapticsDevice],
        tick: &mut ServoTick<'_>,
    ) -> Result<ServoRun, DeviceOpenError> {
        let (Some(api), true) = (self.api, self.running) else {
            return Err(DeviceOpenError::Start {
                device: labels(devices),
                reason: "run_clocked before start".into(),
            });
        };
        let handles: Vec<Hhd> = devices.iter().filter_map(|d| d.handle()).collect();
        if handles != self.handles {
            return Err(DeviceOpenError::Start {
                device: labels(devices),
                reason: "not the devices this scheduler started (or not in their order)".into(),
            });
        }
        if self.stalled.is_some() {
            return Err(DeviceOpenError::Start {
                device: labels(devices),
                reason: "the servo loop stalled earlier; stop and start the devices again".into(),
            });
        }
        let mut frames: Vec<*mut ServoFrame> = Vec::with_capacity(devices.len());
        for d in devices.iter_mut() {
            let frame = d.frame_mut();
            frame.pending = None;
            frame.fatal_reported = None;
            frames.push(frame);
        }
        let list: Vec<*mut dyn HapticDevice> =
            frames.iter().map(|&f| f as *mut dyn HapticDevice).collect();
        // SAFETY: the closure is only called while this function waits below (the state
        // protocol on ServoContext); erasing its lifetime never lets it be called later.
        let tick: *mut ServoTick<'static> =
            unsafe { std::mem::transmute::<*mut ServoTick<'_>, *mut ServoTick<'static>>(tick) };
        let mut ctx = Box::new(ServoContext {
            frames,
            devices: UnsafeCell::new(list),
            tick,
            state: AtomicU8::new(IDLE),
            ticks: AtomicU64::new(0),
            end: AtomicU8::new(0),
            handle: 0,
        });
        let data = &*ctx as *const ServoContext as *mut c_void;
        let _ = first_error(api);
        // SAFETY: `data` stays valid until the callback returned DONE or the scheduler stopped.
        ctx.handle = unsafe {
            (api.schedule_asynchronous)(servo_callback, data, ffi::HD_MAX_SCHEDULER_PRIORITY)
        };
        if let Some((code, internal)) = first_error(api) {
            ctx.state.store(FINISHED, Ordering::Release);
            // SAFETY: the handle just returned.
            unsafe { (api.unschedule)(ctx.handle) };
            self.stalled = Some(ctx);
            return Err(DeviceOpenError::Start {
                device: labels(devices),
                reason: format!(
                    "hdScheduleAsynchronous: {} (0x{code:04x}, internal {internal})",
                    ffi::error_name(code)
                ),
            });
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
        let fatal = devices
            .iter_mut()
            .find_map(|d| d.frame_mut().fatal_reported);
        Ok(ServoRun {
            ticks,
            end: match end {
                ServoEnd::Device(_) => ServoEnd::Device(fatal.unwrap_or(DeviceError::Fault)),
                other => other,
            },
        })
    }

    /// Zero force to every started device of `devices` (in a scheduler frame while the
    /// scheduler runs, else from this thread), then unschedules a stalled run, stops the
    /// scheduler and disables every device. Idempotent.
    pub fn stop(&mut self, devices: &mut [&mut OpenHapticsDevice]) {
        let zero = ZeroForce {
            frames: devices
                .iter_mut()
                .filter(|d| d.is_started())
                .map(|d| d.frame_mut() as *mut ServoFrame)
                .collect(),
        };
        let api = self.api.or_else(|| devices.first().map(|d| d.api()));
        if let Some(api) = api {
            let data = &zero as *const ZeroForce as *mut c_void;
            // SAFETY (the block): HD calls on started devices, in the documented order: zero
            // force first, then unschedule, stop the scheduler, then the devices.
            unsafe {
                if !zero.frames.is_empty() {
                    if self.running && self.stalled.is_none() {
                        (api.schedule_synchronous)(
                            zero_force_callback,
                            data,
                            ffi::HD_MAX_SCHEDULER_PRIORITY,
                        );
                    } else {
                        // The scheduler does not call back: best effort, a frame from this
                        // thread.
                        zero_force_callback(data);
                    }
                }
                self.halt(api);
            }
        }
        release(devices);
        if let Some(api) = api {
            let _ = first_error(api);
        }
    }

    /// Unschedules a stalled run and stops the scheduler, if running.
    ///
    /// # Safety
    /// Every device's force was zeroed first (or none was ever rendered).
    unsafe fn halt(&mut self, api: &'static HdApi) {
        // SAFETY: plain HD calls with a handle the library returned.
        unsafe {
            if let Some(ctx) = &self.stalled {
                (api.unschedule)(ctx.handle);
            }
            if self.running {
                (api.stop_scheduler)();
                self.running = false;
            }
        }
        // The scheduler is stopped: no callback can run any more.
        self.stalled = None;
        self.handles.clear();
    }
}

/// Force output off and the device disabled, for every started device of `devices`.
fn release(devices: &mut [&mut OpenHapticsDevice]) {
    for d in devices.iter_mut() {
        d.release();
    }
}

impl Drop for OpenHapticsScheduler {
    fn drop(&mut self) {
        if let Some(api) = self.api {
            // SAFETY: every run ended with zero force to every device in its last frame; a
            // device not stopped here releases itself (zero force first) when dropped. The
            // scheduler must stop before this value's stalled context is freed.
            unsafe { self.halt(api) };
        }
    }
}
