//! [`ForceDimensionDevice`]: lifecycle, the RT read and write, the safe stop, and the listing
//! of every device the SDK sees.

use std::ffi::{c_char, c_int, c_ushort};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

use super::ffi::{self, DhdApi};
use super::frame;
use super::models::{model_for, DeviceModel};
use crate::device::{
    DeviceError, DeviceLimits, DeviceOpenError, DeviceSample, HapticDevice, Pacing,
};
use crate::{BUTTON_GRAB, BUTTON_HEAT};

/// The largest device index `dhdOpenID` takes (its argument is a C `char`).
pub const MAX_DEVICE_INDEX: u8 = 127;

/// The device indices this process holds open: one driver per device, so two tools can never
/// both command the same device (the last force written would win, silently).
static CLAIMED: [AtomicBool; MAX_DEVICE_INDEX as usize + 1] =
    [const { AtomicBool::new(false) }; MAX_DEVICE_INDEX as usize + 1];

/// Maps a DHD error number to the driver's error class.
///
/// DHD has no recoverable force errors (a saturated motor is a success code), so every error
/// ends the loop: link and timeout errors as [`DeviceError::Communication`], everything else —
/// forces disabled by the device's own safety, a device not ready, anything unknown — as
/// [`DeviceError::Fault`]: an unknown state is not a safe one.
pub fn classify_error(code: c_int) -> DeviceError {
    match code {
        ffi::DHD_ERROR_COM
        | ffi::DHD_ERROR_TIMEOUT
        | ffi::DHD_ERROR_DHC_BUSY
        | ffi::DHD_ERROR_NO_DEVICE_FOUND
        | ffi::DHD_ERROR_NO_DRIVER_FOUND => DeviceError::Communication,
        _ => DeviceError::Fault,
    }
}

/// Counters of one device's traffic.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ForceDimensionStats {
    /// Forces scaled down to the device's force limit.
    pub clamped_forces: u64,
    /// Forces refused as non-finite (zero written instead).
    pub non_finite_forces: u64,
    /// Forces the SDK reported scaled to what the motors deliver (`DHD_MOTOR_SATURATED`).
    pub saturated_forces: u64,
    /// Reads whose velocity the SDK could not estimate yet (`DHD_ERROR_TIMEOUT` from
    /// `dhdGetLinearVelocity`: too few position updates in its window); zero velocity was
    /// reported instead.
    pub velocity_unavailable: u64,
    /// The last DHD error number seen (0 if none).
    pub last_error_code: i32,
}

/// One device the SDK sees, as `lopd doctor` lists it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DeviceListing {
    /// The SDK's enumeration index (`--device dhd:INDEX`).
    pub index: u8,
    /// `dhdGetSystemType`, or the error that prevented opening the device.
    pub system_type: Result<i32, String>,
    /// `dhdGetSystemName`, if the library names it.
    pub system_name: Option<String>,
    /// `dhdGetSerialNumber`, if the device reports one.
    pub serial: Option<u16>,
    /// The model lop's limits table knows it as (None: not opened, or unknown type).
    pub model: Option<&'static str>,
}

/// What the library reports without driving any device.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Discovery {
    /// The library loaded.
    pub library: PathBuf,
    /// Its SDK version, `major.minor.release-revision`.
    pub sdk_version: String,
    /// Every device found, by index.
    pub devices: Vec<DeviceListing>,
}

/// A Force Dimension device (omega.x, sigma.x, delta.x, Falcon) through the DHD SDK.
pub struct ForceDimensionDevice {
    api: &'static DhdApi,
    /// The SDK's enumeration index to open.
    index: u8,
    /// `--device` as the user wrote it.
    label: String,
    /// Name for logs: label, model, serial and library once started.
    name: String,
    /// The device ID `dhdOpenID` returned, while the device is open.
    id: Option<c_char>,
    /// Stopped after a start: reads and writes report [`DeviceError::Stopped`].
    stopped: bool,
    model: DeviceModel,
    serial: Option<u16>,
    stats: ForceDimensionStats,
}

impl ForceDimensionDevice {
    /// Loads the DHD library for the device at SDK index `index` (`None`: index 0). Nothing
    /// touches the device until [`HapticDevice::start`]. `configured` is the daemon config's
    /// `[device] dhd_library` (`LOP_DHD_LIBRARY` wins over it).
    pub fn open(index: Option<u8>, configured: Option<&Path>) -> Result<Self, DeviceOpenError> {
        let label = match index {
            Some(i) => format!("dhd:{i}"),
            None => "dhd".to_string(),
        };
        let index = index.unwrap_or(0);
        if index > MAX_DEVICE_INDEX {
            return Err(DeviceOpenError::Unavailable {
                device: label,
                reason: format!("device index {index} is above the SDK's {MAX_DEVICE_INDEX}"),
            });
        }
        let api = load(&label, configured)?;
        Ok(ForceDimensionDevice {
            api,
            index,
            name: label.clone(),
            label,
            id: None,
            stopped: false,
            model: model_for(-1),
            serial: None,
            stats: ForceDimensionStats::default(),
        })
    }

    /// Loads the library and lists every device it sees (index, type, name, serial), opening
    /// each just long enough to ask and closing it again; force is never enabled.
    pub fn discover(configured: Option<&Path>) -> Result<Discovery, DeviceOpenError> {
        let api = load("dhd", configured)?;
        // SAFETY: plain DHD call.
        let count = unsafe { (api.get_device_count)() };
        if count < 0 {
            let (code, text) = api.last_error();
            return Err(DeviceOpenError::Start {
                device: "dhd".into(),
                reason: format!(
                    "dhdGetDeviceCount failed: {} ({code}) {text}",
                    ffi::error_name(code)
                ),
            });
        }
        let count = count.min(MAX_DEVICE_INDEX as c_int + 1) as u8;
        let devices = (0..count)
            .map(|index| {
                // SAFETY: an index below the device count.
                let id = unsafe { (api.open_id)(index as c_char) };
                if id < 0 {
                    let (code, text) = api.last_error();
                    return DeviceListing {
                        index,
                        system_type: Err(format!(
                            "dhdOpenID failed: {} ({code}) {text}",
                            ffi::error_name(code)
                        )),
                        system_name: None,
                        serial: None,
                        model: None,
                    };
                }
                let id = id as c_char;
                let (system_type, system_name, serial) = identify(api, id);
                // SAFETY: the ID just opened.
                unsafe { (api.close)(id) };
                let model = model_for(system_type);
                DeviceListing {
                    index,
                    system_type: Ok(system_type),
                    system_name,
                    serial,
                    model: model.known.then_some(model.name),
                }
            })
            .collect();
        Ok(Discovery {
            library: api.path.clone(),
            sdk_version: api.version_text(),
            devices,
        })
    }

    /// The library file that was loaded.
    pub fn library_path(&self) -> &Path {
        &self.api.path
    }

    /// The SDK index this driver opens.
    pub fn index(&self) -> u8 {
        self.index
    }

    /// The device model from the limits table (after `start`; the unknown floor before).
    pub fn model(&self) -> DeviceModel {
        self.model
    }

    /// The device's serial number, if it reports one (after `start`).
    pub fn serial(&self) -> Option<u16> {
        self.serial
    }

    /// Counters of forces and errors so far.
    pub fn stats(&self) -> ForceDimensionStats {
        self.stats
    }

    fn start_error(&self, what: &str) -> DeviceOpenError {
        let (code, text) = self.api.last_error();
        let hint = match code {
            ffi::DHD_ERROR_NO_DEVICE_FOUND | ffi::DHD_ERROR_INVALID_INDEX => {
                "; is the device connected and powered, and may this user open it (udev rule for \
                 the device's USB IDs, docs/deploy.md)? `lopd doctor --device dhd` lists what \
                 the SDK sees"
            }
            ffi::DHD_ERROR_DEVICE_IN_USE => "; another program holds the device",
            ffi::DHD_ERROR_COM => "; check the USB cable and the controller's power",
            _ => "",
        };
        DeviceOpenError::Start {
            device: self.label.clone(),
            reason: format!("{what}: {} ({code}) {text}{hint}", ffi::error_name(code)),
        }
    }

    /// The error class of the thread's last DHD error; counts it.
    fn device_error(&mut self) -> DeviceError {
        // SAFETY: plain DHD call, no allocation.
        let code = unsafe { (self.api.error_get_last)() };
        self.stats.last_error_code = code;
        classify_error(code)
    }

    fn open_id(&self) -> Result<c_char, DeviceError> {
        match self.id {
            Some(id) => Ok(id),
            None if self.stopped => Err(DeviceError::Stopped),
            None => Err(DeviceError::NotStarted),
        }
    }

    fn read3(
        &self,
        f: unsafe extern "C" fn(*mut f64, *mut f64, *mut f64, c_char) -> c_int,
        id: c_char,
    ) -> (c_int, [f64; 3]) {
        let mut v = [0.0; 3];
        let [x, y, z] = &mut v;
        // SAFETY: three valid f64 pointers and an open device ID.
        let r = unsafe { f(x, y, z, id) };
        (r, v)
    }
}

fn load(label: &str, configured: Option<&Path>) -> Result<&'static DhdApi, DeviceOpenError> {
    let candidates = ffi::library_candidates(configured);
    DhdApi::load(&candidates).map_err(|why| DeviceOpenError::Unavailable {
        device: label.to_string(),
        reason: format!(
            "the Force Dimension DHD library could not be loaded (tried {}): {why}; install \
             the Force Dimension SDK (its `make install` puts libdhd.so in /usr/local/lib) or \
             set {} or `[device] dhd_library` in the daemon config to the library's path",
            candidates
                .iter()
                .map(|p| p.display().to_string())
                .collect::<Vec<_>>()
                .join(", "),
            ffi::LIBRARY_ENV
        ),
    })
}

/// Type, name and serial of an open device.
fn identify(api: &DhdApi, id: c_char) -> (c_int, Option<String>, Option<u16>) {
    // SAFETY: plain DHD calls on an open ID; the name is a static string in the library.
    let system_type = unsafe { (api.get_system_type)(id) };
    let system_name = unsafe { ffi::c_text((api.get_system_name)(id)) };
    let mut serial: c_ushort = 0;
    // SAFETY: a valid pointer to an unsigned short.
    let serial = (unsafe { (api.get_serial_number)(&mut serial, id) } == 0).then_some(serial);
    (system_type, system_name, serial)
}

impl HapticDevice for ForceDimensionDevice {
    fn name(&self) -> &str {
        &self.name
    }

    /// The limits of the device's type from the table in `models` (the conservative floor
    /// before `start` and for a type the table does not list).
    fn limits(&self) -> DeviceLimits {
        self.model.limits
    }

    /// lop's own 1 kHz loop calls `read` and `write_force`: the SDK has no servo callback.
    fn pacing(&self) -> Pacing {
        Pacing::SelfPaced
    }

    fn start(&mut self) -> Result<(), DeviceOpenError> {
        if self.id.is_some() {
            return Ok(());
        }
        // SAFETY: plain DHD call.
        let count = unsafe { (self.api.get_device_count)() };
        if count < 0 {
            return Err(self.start_error("dhdGetDeviceCount"));
        }
        if c_int::from(self.index) >= count {
            return Err(DeviceOpenError::Start {
                device: self.label.clone(),
                reason: format!(
                    "no Force Dimension device at index {}: the SDK ({}) sees {count}{}; \
                     `lopd doctor --device dhd` lists them",
                    self.index,
                    self.api.path.display(),
                    match count {
                        0 => String::new(),
                        1 => " (index 0)".to_string(),
                        n => format!(" (indices 0 to {})", n - 1),
                    }
                ),
            });
        }
        let claim = &CLAIMED[self.index as usize];
        if claim
            .compare_exchange(false, true, Ordering::AcqRel, Ordering::Acquire)
            .is_err()
        {
            return Err(DeviceOpenError::Start {
                device: self.label.clone(),
                reason: format!(
                    "Force Dimension device index {} is already driven by another device in \
                     this process",
                    self.index
                ),
            });
        }
        // SAFETY: an index below the device count.
        let id = unsafe { (self.api.open_id)(self.index as c_char) };
        if id < 0 {
            claim.store(false, Ordering::Release);
            return Err(self.start_error(&format!("dhdOpenID({})", self.index)));
        }
        let id = id as c_char;
        let (system_type, system_name, serial) = identify(self.api, id);
        // Zero force before the motors are enabled, so the first thing felt is nothing.
        // SAFETY: plain DHD calls on the ID just opened.
        let enabled = unsafe {
            (self.api.set_force)(0.0, 0.0, 0.0, id);
            (self.api.enable_force)(ffi::DHD_ON, id)
        };
        if enabled < 0 {
            let e = self.start_error("dhdEnableForce(DHD_ON)");
            // SAFETY: as above.
            unsafe {
                (self.api.enable_force)(ffi::DHD_OFF, id);
                (self.api.close)(id);
            }
            claim.store(false, Ordering::Release);
            return Err(e);
        }
        self.model = model_for(system_type);
        self.serial = serial;
        self.name = format!(
            "{} ({}{}{}) via {}",
            self.label,
            system_name.as_deref().unwrap_or(self.model.name),
            if self.model.known {
                String::new()
            } else {
                format!(", type {system_type} not in lop's table: conservative limits")
            },
            serial.map(|s| format!(", serial {s}")).unwrap_or_default(),
            self.api.path.display()
        );
        self.id = Some(id);
        self.stopped = false;
        Ok(())
    }

    /// Position, velocity and buttons in lop's frame and units (see [`super::frame`]).
    /// Buttons 0 and 1 of the device's mask are lop's grab and heat buttons.
    fn read(&mut self, _t: f64) -> Result<DeviceSample, DeviceError> {
        let id = self.open_id()?;
        let (r, position) = self.read3(self.api.get_position, id);
        if r < 0 {
            return Err(self.device_error());
        }
        let (r, mut velocity) = self.read3(self.api.get_linear_velocity, id);
        if r < 0 {
            // SAFETY: plain DHD call.
            let code = unsafe { (self.api.error_get_last)() };
            if code != ffi::DHD_ERROR_TIMEOUT {
                self.stats.last_error_code = code;
                return Err(classify_error(code));
            }
            self.stats.velocity_unavailable += 1;
            velocity = [0.0; 3];
        }
        // SAFETY: plain DHD call on an open ID.
        let mask = unsafe { (self.api.get_button_mask)(id) };
        Ok(DeviceSample {
            position_mm: frame::to_lop_mm(position),
            velocity_mm_s: frame::to_lop_mm(velocity),
            buttons: mask & (BUTTON_GRAB | BUTTON_HEAT),
        })
    }

    /// Sends `force_n` (lop's frame) to the device, scaled down to its force limit; a
    /// non-finite force is refused and zero sent instead.
    fn write_force(&mut self, force_n: [f64; 3]) -> Result<(), DeviceError> {
        let id = self.open_id()?;
        let finite = force_n.iter().all(|f| f.is_finite());
        let mut f = if finite { force_n } else { [0.0; 3] };
        let magnitude = (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt();
        let max = self.model.limits.max_force_n;
        if magnitude > max {
            let s = max / magnitude;
            f = [f[0] * s, f[1] * s, f[2] * s];
            self.stats.clamped_forces += 1;
        }
        let [x, y, z] = frame::force_to_dhd(f);
        // SAFETY: plain DHD call on an open ID.
        let r = unsafe { (self.api.set_force)(x, y, z, id) };
        if r < 0 {
            return Err(self.device_error());
        }
        if r == ffi::DHD_MOTOR_SATURATED {
            self.stats.saturated_forces += 1;
        }
        if !finite {
            self.stats.non_finite_forces += 1;
            return Err(DeviceError::NonFiniteForce);
        }
        Ok(())
    }

    /// Zero force, then motors off (BRAKE mode), then the device closed. Idempotent, no
    /// allocation; also on drop.
    fn stop(&mut self) {
        let Some(id) = self.id.take() else {
            return;
        };
        // SAFETY: DHD calls on the open ID, in this order: the last force sent is zero even
        // if disabling fails.
        unsafe {
            (self.api.set_force)(0.0, 0.0, 0.0, id);
            (self.api.enable_force)(ffi::DHD_OFF, id);
            (self.api.close)(id);
        }
        CLAIMED[self.index as usize].store(false, Ordering::Release);
        self.stopped = true;
    }
}

impl Drop for ForceDimensionDevice {
    fn drop(&mut self) {
        self.stop();
    }
}

impl std::fmt::Debug for ForceDimensionDevice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ForceDimensionDevice")
            .field("label", &self.label)
            .field("library", &self.api.path)
            .field("started", &self.id.is_some())
            .finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn link_errors_are_communication_everything_else_a_fault() {
        assert_eq!(
            classify_error(ffi::DHD_ERROR_COM),
            DeviceError::Communication
        );
        assert_eq!(
            classify_error(ffi::DHD_ERROR_TIMEOUT),
            DeviceError::Communication
        );
        for code in [1, 6, 12, 19, 20, 99, -3] {
            assert_eq!(classify_error(code), DeviceError::Fault, "{code}");
        }
    }

    #[test]
    fn missing_library_names_the_path_and_the_variable() {
        // LOP_DHD_LIBRARY would override the configured path; the test leaves it alone.
        if std::env::var_os(ffi::LIBRARY_ENV).is_some() {
            return;
        }
        let missing = PathBuf::from("/nonexistent/lop-test/libdhd.so");
        let e = ForceDimensionDevice::open(Some(1), Some(&missing)).unwrap_err();
        let text = e.to_string();
        assert!(matches!(e, DeviceOpenError::Unavailable { .. }), "{text}");
        assert!(text.contains("/nonexistent/lop-test/libdhd.so"), "{text}");
        assert!(text.contains("LOP_DHD_LIBRARY"), "{text}");
        assert!(text.contains("dhd:1"), "{text}");
    }
}
