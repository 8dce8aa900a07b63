//! `lopd haptic` as a whole process: [`HapticProcess::builder`] takes the validated scene,
//! config and the opened devices (one per tool of the scene, in order),
//! [`HapticProcessBuilder::run`] starts them, locks memory, derives the loop's settings (each
//! tool's law per body, clamped to its device), chooses the recording wrapper once, starts the
//! publisher thread and runs the loop on the pacing the devices ask for (a timed real-time
//! thread, or the vendor's servo callback), then stops everything, zero force first.
//!
//! Several devices run in one loop, on one clock: lop's own timed loop (mock, hand, replay,
//! dhd), or the OpenHaptics library's one scheduler, whose servo callback ticks the loop with
//! every OpenHaptics device of the run (each initialised by its configured name). The clocks do
//! not mix: an OpenHaptics device beside a device of lop's own clock is refused with that
//! reason. Recording the device stream (`--record`) takes one device.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use anyhow::{bail, Context, Result};
use lop_config::{DaemonConfig, Scene};
use lop_drivers::forcedimension::ForceDimensionDevice;
use lop_drivers::hand::HandDevice;
use lop_drivers::mock::MockDevice;
use lop_drivers::openhaptics::{OpenHapticsDevice, OpenHapticsScheduler};
use lop_drivers::replay::ReplayDevice;
use lop_drivers::{HapticDevice, Pacing};
use lop_ipc::ServiceNames;

use crate::haptic::{self, HapticSettings, RtRequest};
use crate::record::{self, Recorded};
use crate::{rt, servo, signals, MEMORY_LOCKED};

/// The opened device, concrete so device-specific extras (the mock's force record, the
/// OpenHaptics counters) stay reachable after the loop.
pub enum Device {
    /// `--device mock[:SCRIPT]`.
    Mock(MockDevice),
    /// `--device hand[:SCRIPT]`.
    Hand(Box<HandDevice>),
    /// `--device replay:PATH`.
    Replay(ReplayDevice),
    /// `--device openhaptics[:NAME]`.
    OpenHaptics(Box<OpenHapticsDevice>),
    /// `--device dhd[:ID]`.
    ForceDimension(Box<ForceDimensionDevice>),
}

impl Device {
    /// The device behind the common interface.
    pub fn as_dyn(&mut self) -> &mut dyn HapticDevice {
        match self {
            Device::Mock(m) => m,
            Device::Hand(h) => h.as_mut(),
            Device::Replay(r) => r,
            Device::OpenHaptics(o) => o.as_mut(),
            Device::ForceDimension(f) => f.as_mut(),
        }
    }

    /// The device behind the common interface, read-only.
    pub fn as_ref_dyn(&self) -> &dyn HapticDevice {
        match self {
            Device::Mock(m) => m,
            Device::Hand(h) => h.as_ref(),
            Device::Replay(r) => r,
            Device::OpenHaptics(o) => o.as_ref(),
            Device::ForceDimension(f) => f.as_ref(),
        }
    }

    /// The mock, if it is one.
    pub fn mock(&self) -> Option<&MockDevice> {
        match self {
            Device::Mock(m) => Some(m),
            _ => None,
        }
    }

    /// The force last rendered, for the scripted devices that keep a record (mock, hand).
    pub fn last_force(&self) -> Option<[f64; 3]> {
        match self {
            Device::Mock(m) => Some(m.last_force()),
            Device::Hand(h) => Some(h.last_force()),
            _ => None,
        }
    }

    /// Writes the rendered-force record as CSV (`--force-log`), for the devices that keep one;
    /// `Ok(false)` for the others.
    pub fn write_force_csv(&self, path: &std::path::Path) -> std::io::Result<bool> {
        match self {
            Device::Mock(m) => m.write_force_csv(path).map(|()| true),
            Device::Hand(h) => h.write_force_csv(path).map(|()| true),
            _ => Ok(false),
        }
    }
}

/// The haptic process, ready to run.
pub struct HapticProcess;

impl HapticProcess {
    /// A haptic process for `scene` under `config` on the opened `devices`, the `t`-th driving
    /// the scene's tool `t`, each with its `--device` text (kept in recordings and logs).
    pub fn builder(
        scene: Scene,
        config: DaemonConfig,
        names: ServiceNames,
        devices: Vec<(Device, String)>,
    ) -> HapticProcessBuilder {
        HapticProcessBuilder {
            scene,
            config,
            names,
            devices,
            duration: None,
            record: None,
            force_log: Vec::new(),
        }
    }
}

/// Options of a haptic process (see [`HapticProcess::builder`]).
pub struct HapticProcessBuilder {
    scene: Scene,
    config: DaemonConfig,
    names: ServiceNames,
    devices: Vec<(Device, String)>,
    duration: Option<Duration>,
    record: Option<PathBuf>,
    force_log: Vec<PathBuf>,
}

impl HapticProcessBuilder {
    /// Stop after this long.
    pub fn duration(mut self, d: Option<Duration>) -> Self {
        self.duration = d;
        self
    }

    /// Record the device stream to this file (`--record`).
    pub fn record(mut self, path: Option<PathBuf>) -> Self {
        self.record = path;
        self
    }

    /// Write each scripted device's rendered forces to these CSVs at the end, one per device
    /// in order (`--force-log`).
    pub fn force_log(mut self, paths: Vec<PathBuf>) -> Self {
        self.force_log = paths;
        self
    }

    /// Runs the process until a stop signal, the duration or a fatal device error.
    pub fn run(self) -> Result<()> {
        let HapticProcessBuilder {
            scene,
            config,
            names,
            devices,
            duration,
            record,
            force_log,
        } = self;
        let pacing = check_devices(&scene, &devices, record.is_some(), force_log.len())?;
        let (mut devices, specs): (Vec<Device>, Vec<String>) = devices.into_iter().unzip();
        // The OpenHaptics devices start together on the library's one scheduler.
        let mut scheduler = OpenHapticsScheduler::new();
        match pacing {
            Pacing::DeviceClock => scheduler
                .start(&mut servo_clocked(&mut devices, &specs)?)
                .with_context(|| match specs.as_slice() {
                    [one] => format!("starting the device {one}"),
                    all => format!("starting the devices {}", all.join(", ")),
                })?,
            Pacing::SelfPaced => {
                for (d, spec) in devices.iter_mut().zip(&specs) {
                    d.as_dyn()
                        .start()
                        .with_context(|| format!("starting the device {spec}"))?;
                }
            }
        }
        if config.haptic.lock_memory {
            match rt::lock_memory() {
                Ok(()) => MEMORY_LOCKED.store(true, Ordering::Relaxed),
                Err(e) => tracing::warn!("memory not locked: {e}"),
            }
        }
        let all_limits: Vec<_> = devices.iter().map(|d| d.as_ref_dyn().limits()).collect();
        let limits = all_limits[0];
        let settings = HapticSettings::for_devices(&config, &scene, &all_limits);
        let max_ticks =
            duration.map(|d| (d.as_secs_f64() * settings.pipeline().rate_hz).round() as u64);
        let rt_request = RtRequest {
            core: rt::haptic_core(&config.haptic),
            priority: config.haptic.rt_priority,
        };
        for (t, l) in all_limits.iter().enumerate() {
            if let Some(w) = servo::stiffness_warning(&scene, t, l) {
                tracing::warn!("{w}");
            }
        }
        for ((t, d), p) in devices.iter().enumerate().zip(&settings.tools) {
            tracing::info!(
                "haptic loop: {} Hz, tool {:?} on {}{}, force clamp {:.2} N, stale limit {} ms",
                p.rate_hz,
                scene.tools[t].name,
                d.as_ref_dyn().name(),
                if pacing == Pacing::DeviceClock {
                    " (the OpenHaptics servo callback is the clock)"
                } else {
                    ""
                },
                p.max_force,
                settings.stale_ns / 1_000_000
            );
        }
        let device_spec = &specs[0];
        let (mut tap, writer) = match &record {
            Some(path) => {
                let header = record::header(
                    settings.pipeline().rate_hz,
                    limits,
                    &scene.name,
                    &scene.path,
                    device_spec,
                );
                let (tap, writer) = record::start(path, &header)?;
                tracing::info!("recording the device stream to {}", writer.path().display());
                (Some(tap), Some(writer))
            }
            None => (None, None),
        };
        let ((tool_tx, tool_rx), (tel_tx, tel_rx)) = haptic::rings(&settings)?;
        let done = Arc::new(AtomicBool::new(false));
        let publisher = {
            let names = names.clone();
            let done = done.clone();
            std::thread::Builder::new()
                .name("lop-tool-pub".into())
                .spawn(move || haptic::run_publisher(&names, tool_rx, tel_rx, done))?
        };
        let result = match pacing {
            Pacing::SelfPaced => {
                let joined = std::thread::scope(|scope| {
                    std::thread::Builder::new()
                        .name("lop-haptic-rt".into())
                        .stack_size(1 << 20)
                        .spawn_scoped(scope, || {
                            // The recording wrapper (one device), chosen once for the run.
                            let mut recorded;
                            let mut devs: Vec<&mut dyn HapticDevice> = match tap.as_mut() {
                                Some(tap) => {
                                    recorded = Recorded {
                                        device: devices[0].as_dyn(),
                                        tap,
                                    };
                                    vec![&mut recorded]
                                }
                                None => devices.iter_mut().map(Device::as_dyn).collect(),
                            };
                            haptic::run_loop(
                                &names,
                                settings,
                                &mut devs,
                                &rt_request,
                                &signals::STOP,
                                max_ticks,
                                tool_tx,
                                tel_tx,
                            )
                        })
                        .map(|h| h.join())
                })?;
                match joined {
                    Ok(r) => r,
                    Err(_) => {
                        done.store(true, Ordering::Release);
                        let _ = publisher.join();
                        bail!("the haptic loop panicked; zero force was written by its guard")
                    }
                }
            }
            Pacing::DeviceClock => {
                // The vendor's servo thread runs the tick at the vendor's priority: the frame
                // thread must not take its core, so it runs unpinned at the default policy.
                let settings = HapticSettings {
                    frames: haptic::FramePlacement::default(),
                    ..settings
                };
                let task = servo::ServoTask::new(
                    &names,
                    settings,
                    rt_request.core,
                    &signals::STOP,
                    max_ticks,
                    tool_tx,
                    tel_tx,
                    tap.as_mut(),
                );
                servo::run(task, |tick| {
                    let mut clocked = servo_clocked(&mut devices, &specs)?;
                    let run = scheduler.run_clocked(&mut clocked, tick);
                    scheduler.stop(&mut clocked);
                    Ok(run?)
                })
            }
        };
        done.store(true, Ordering::Release);
        let _ = publisher.join();
        for d in &mut devices {
            d.as_dyn().stop();
        }
        if let Some(writer) = writer {
            let path = writer.path().to_path_buf();
            let records = writer.finish()?;
            let dropped = tap.as_ref().map_or(0, |t| t.dropped());
            tracing::info!(
                "recorded {records} device samples to {}{}",
                path.display(),
                if dropped > 0 {
                    format!(" ({dropped} lost: the writer fell behind)")
                } else {
                    String::new()
                }
            );
        }
        for device in &devices {
            report_counters(device);
        }
        let summary = result?;
        for (device, path) in devices.iter().zip(&force_log) {
            device
                .write_force_csv(path)
                .with_context(|| format!("writing {}", path.display()))?;
        }
        let last: Vec<String> = devices
            .iter()
            .filter_map(Device::last_force)
            .map(|f| format!("[{}, {}, {}] N", f[0], f[1], f[2]))
            .collect();
        tracing::info!(
            "haptic loop stopped after {} ticks, {} overruns{}{}",
            summary.ticks,
            summary.overruns,
            if last.is_empty() {
                String::new()
            } else {
                format!("; last force written {}", last.join(", "))
            },
            if summary.ring_drops > 0 {
                format!("; {} tool states not published", summary.ring_drops)
            } else {
                String::new()
            }
        );
        if let Some(e) = summary.fatal {
            bail!("device error stopped the haptic loop: {e}");
        }
        Ok(())
    }
}

/// Whether `devices` (the `t`-th driving the scene's tool `t`, each with its `--device` text)
/// can run together, and on which clock: one device per tool at most, one clock for all
/// (lop's own loop, or the OpenHaptics servo callback for every device: the two do not mix),
/// `--record` with one device, at most one `--force-log` per device. No side effects: the
/// devices are opened, not started.
pub fn check_devices(
    scene: &Scene,
    devices: &[(Device, String)],
    record: bool,
    force_logs: usize,
) -> Result<Pacing> {
    if devices.is_empty() || devices.len() > scene.tools.len() {
        bail!(
            "{} devices for the {} tool(s) of the scene: give one per tool",
            devices.len(),
            scene.tools.len()
        );
    }
    let pacing = devices[0].0.as_ref_dyn().pacing();
    if let Some(k) = devices
        .iter()
        .position(|(d, _)| d.as_ref_dyn().pacing() != pacing)
    {
        let (clocked, own) = match pacing {
            Pacing::DeviceClock => (0, k),
            Pacing::SelfPaced => (k, 0),
        };
        bail!(
            "--device {} beside --device {}: the OpenHaptics device runs on the vendor's servo \
             clock, the other on lop's own loop, and one run has one clock; give every tool an \
             OpenHaptics device (they share the one scheduler), or none",
            devices[clocked].1,
            devices[own].1
        );
    }
    if pacing == Pacing::DeviceClock {
        if let Some((_, spec)) = devices
            .iter()
            .find(|(d, _)| !matches!(d, Device::OpenHaptics(_)))
        {
            bail!("--device {spec}: only OpenHaptics devices run on the vendor's servo clock");
        }
    }
    if record && devices.len() > 1 {
        bail!("--record takes one device; this run has {}", devices.len());
    }
    if force_logs > devices.len() {
        bail!(
            "{force_logs} --force-log files for {} device(s): give at most one per device",
            devices.len()
        );
    }
    Ok(pacing)
}

/// The devices of a run on the OpenHaptics servo clock, in order. Err: a device that is not
/// an OpenHaptics device ([`check_devices`] refuses such a run first).
fn servo_clocked<'a>(
    devices: &'a mut [Device],
    specs: &[String],
) -> Result<Vec<&'a mut OpenHapticsDevice>> {
    devices
        .iter_mut()
        .zip(specs)
        .map(|(d, spec)| match d {
            Device::OpenHaptics(o) => Ok(o.as_mut()),
            _ => bail!("--device {spec}: only OpenHaptics devices run on the vendor's servo clock"),
        })
        .collect()
}

/// Logs a vendor device's counters at exit (forces clamped, refused, errors), if any.
fn report_counters(device: &Device) {
    if let Device::OpenHaptics(o) = device {
        let s = o.stats();
        if s.clamped_forces + s.non_finite_forces + s.recoverable_errors > 0 {
            tracing::info!(
                "device {}: {} forces clamped to its peak, {} non-finite refused, {} force errors",
                o.label(),
                s.clamped_forces,
                s.non_finite_forces,
                s.recoverable_errors
            );
        }
    }
    if let Device::ForceDimension(f) = device {
        let s = f.stats();
        if s.clamped_forces + s.non_finite_forces + s.saturated_forces > 0
            || s.velocity_unavailable > 0
            || s.last_error_code != 0
        {
            let last = match s.last_error_code {
                0 => String::new(),
                code => format!(
                    "; last DHD error: {} ({code})",
                    lop_drivers::forcedimension::ffi::error_name(code)
                ),
            };
            tracing::info!(
                "device: {} forces clamped to its peak, {} non-finite refused, {} saturated by \
                 the SDK, {} reads without a velocity estimate yet{last}",
                s.clamped_forces,
                s.non_finite_forces,
                s.saturated_forces,
                s.velocity_unavailable
            );
        }
    }
}
