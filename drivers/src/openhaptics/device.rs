//! [`OpenHapticsDevice`]: one device — the library loaded, its initialisation by name, its
//! limits, and its life alone on a scheduler of its own (several devices share one through
//! [`OpenHapticsScheduler`]).

use std::ffi::{c_uint, c_void, CStr, CString};
use std::path::Path;

use super::ffi::{self, HdApi, HdCallbackCode, HdEnum, Hhd};
use super::frame::{OpenHapticsStats, ServoFrame, MAX_ERRORS_PER_DRAIN};
use super::scheduler::OpenHapticsScheduler;
use crate::device::{
    DeviceError, DeviceLimits, DeviceOpenError, DeviceSample, HapticDevice, Pacing, ServoRun,
    ServoTick,
};

/// Drains the library's error stack; the first error as (code, internal code).
pub(super) fn first_error(api: &HdApi) -> Option<(c_uint, i32)> {
    let mut first = None;
    for _ in 0..MAX_ERRORS_PER_DRAIN {
        // SAFETY: plain HD call.
        let info = unsafe { (api.get_error)() };
        if info.error_code == ffi::HD_SUCCESS {
            break;
        }
        first.get_or_insert((info.error_code, info.internal_error_code));
    }
    first
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
    /// For messages: `openhaptics:NAME`.
    label: String,
    hhd: Option<Hhd>,
    /// Force output is on (between `init` and `release`).
    force_output: bool,
    /// The device as the servo callback sees it (boxed: the callback holds a pointer to it).
    frame: Box<ServoFrame>,
    /// The scheduler it runs on when it runs alone (`HapticDevice::start`).
    own: OpenHapticsScheduler,
    model: Option<String>,
}

// SAFETY: the frame holds the leaked, immutable API table and plain data; the own scheduler's
// context points into this device's own box; nothing is shared with another owner.
unsafe impl Send for OpenHapticsDevice {}

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
                parked: None,
            }),
            label,
            hhd: None,
            force_output: false,
            own: OpenHapticsScheduler::new(),
            model: None,
        })
    }

    /// The library file that was loaded.
    pub fn library_path(&self) -> &Path {
        &self.api.path
    }

    /// The device as the user named it: `openhaptics` or `openhaptics:NAME`.
    pub fn label(&self) -> &str {
        &self.label
    }

    /// The device model the library reports (after `start`), if it reports one.
    pub fn model(&self) -> Option<&str> {
        self.model.as_deref()
    }

    /// Counters of forces and errors so far.
    pub fn stats(&self) -> OpenHapticsStats {
        self.frame.stats
    }

    pub(super) fn api(&self) -> &'static HdApi {
        self.api
    }

    pub(super) fn is_started(&self) -> bool {
        self.hhd.is_some()
    }

    pub(super) fn handle(&self) -> Option<Hhd> {
        self.hhd
    }

    pub(super) fn frame_mut(&mut self) -> &mut ServoFrame {
        &mut self.frame
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
            ffi::HD_DEVICE_ALREADY_INITIATED => {
                "; another process (or another --device of this run) holds the device"
            }
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

    /// The current device's limits.
    fn read_limits(&self) -> Result<DeviceLimits, DeviceOpenError> {
        let [max_force_n] = self.get_doubles::<1>(ffi::HD_NOMINAL_MAX_FORCE);
        let [max_continuous_force_n] = self.get_doubles::<1>(ffi::HD_NOMINAL_MAX_CONTINUOUS_FORCE);
        let [max_stiffness_n_per_mm] = self.get_doubles::<1>(ffi::HD_NOMINAL_MAX_STIFFNESS);
        let ws = self.get_doubles::<6>(ffi::HD_USABLE_WORKSPACE_DIMENSIONS);
        if let Some((code, internal)) = first_error(self.api) {
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

    /// The device's part of a start: `hdInitDevice` by name, made current, its limits and
    /// model read, force output and the library's force clamping enabled. On error the device
    /// is disabled again. The scheduler is the caller's.
    pub(super) fn init(&mut self) -> Result<(), DeviceOpenError> {
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
        if let Some((code, internal)) = first_error(self.api) {
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
        }
        if let Some((code, internal)) = first_error(self.api) {
            // SAFETY: as above.
            unsafe {
                (self.api.disable)(ffi::HD_FORCE_OUTPUT);
                (self.api.disable_device)(hhd);
            }
            return Err(self.start_error("enabling force output", code, internal));
        }
        self.frame.hhd = hhd;
        self.frame.limits = limits;
        self.frame.pending = None;
        self.frame.fatal_reported = None;
        if let Some(model) = &self.model {
            self.frame.name = format!("{} ({model}) via {}", self.label, self.api.path.display());
        }
        self.hhd = Some(hhd);
        self.force_output = true;
        Ok(())
    }

    /// The device's part of a stop, after its zero force and the scheduler's stop: made
    /// current, force output off, `hdDisableDevice`. Nothing if not started.
    pub(super) fn release(&mut self) {
        let Some(hhd) = self.hhd.take() else {
            return;
        };
        // SAFETY: HD calls on a started device.
        unsafe {
            (self.api.make_current_device)(hhd);
            if self.force_output {
                (self.api.disable)(ffi::HD_FORCE_OUTPUT);
            }
            (self.api.disable_device)(hhd);
        }
        self.force_output = false;
        self.frame.parked = None;
    }

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

    /// The device alone on a scheduler of its own (see [`OpenHapticsScheduler::start`]).
    fn start(&mut self) -> Result<(), DeviceOpenError> {
        if self.hhd.is_some() {
            return Ok(());
        }
        let mut own = std::mem::take(&mut self.own);
        let started = own.start(&mut [&mut *self]);
        self.own = own;
        started
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

    /// Zero force, then the scheduler stopped and the device disabled (see
    /// [`OpenHapticsScheduler::stop`]). A device started with others on a shared scheduler
    /// and stopped alone writes its zero force from this thread.
    fn stop(&mut self) {
        let mut own = std::mem::take(&mut self.own);
        own.stop(&mut [&mut *self]);
        self.own = own;
    }

    fn run_clocked(&mut self, tick: &mut ServoTick<'_>) -> Result<ServoRun, DeviceOpenError> {
        let mut own = std::mem::take(&mut self.own);
        let run = own.run_clocked(&mut [&mut *self], tick);
        self.own = own;
        run
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
