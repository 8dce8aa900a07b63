//! `lopd haptic` as a whole process: [`HapticProcess::builder`] takes the validated scene,
//! config and the opened device, [`HapticProcessBuilder::run`] starts the device, locks memory,
//! derives the loop's settings (the scene's one tool law per body, clamped to the device),
//! chooses the recording wrapper once, starts the publisher thread and runs the loop on the
//! pacing the device asks for (a timed real-time thread, or the device's own servo callback),
//! then stops everything, zero force first.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use anyhow::{bail, Context, Result};
use lop_config::{DaemonConfig, Scene};
use lop_drivers::forcedimension::ForceDimensionDevice;
use lop_drivers::hand::HandDevice;
use lop_drivers::mock::MockDevice;
use lop_drivers::openhaptics::OpenHapticsDevice;
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
    /// A haptic process for `scene` under `config` on the opened `device`; `device_spec` is
    /// the `--device` text, kept in recordings.
    pub fn builder(
        scene: Scene,
        config: DaemonConfig,
        names: ServiceNames,
        device: Device,
        device_spec: &str,
    ) -> HapticProcessBuilder {
        HapticProcessBuilder {
            scene,
            config,
            names,
            device,
            device_spec: device_spec.to_string(),
            duration: None,
            record: None,
            force_log: None,
        }
    }
}

/// Options of a haptic process (see [`HapticProcess::builder`]).
pub struct HapticProcessBuilder {
    scene: Scene,
    config: DaemonConfig,
    names: ServiceNames,
    device: Device,
    device_spec: String,
    duration: Option<Duration>,
    record: Option<PathBuf>,
    force_log: Option<PathBuf>,
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

    /// Write the mock's rendered forces to this CSV at the end (`--force-log`).
    pub fn force_log(mut self, path: Option<PathBuf>) -> Self {
        self.force_log = path;
        self
    }

    /// Runs the process until a stop signal, the duration or a fatal device error.
    pub fn run(self) -> Result<()> {
        let HapticProcessBuilder {
            scene,
            config,
            names,
            mut device,
            device_spec,
            duration,
            record,
            force_log,
        } = self;
        device.as_dyn().start().context("starting the device")?;
        if config.haptic.lock_memory {
            match rt::lock_memory() {
                Ok(()) => MEMORY_LOCKED.store(true, Ordering::Relaxed),
                Err(e) => tracing::warn!("memory not locked: {e}"),
            }
        }
        let limits = device.as_ref_dyn().limits();
        let settings = HapticSettings::new(&config, &scene, limits);
        let max_ticks =
            duration.map(|d| (d.as_secs_f64() * settings.pipeline.rate_hz).round() as u64);
        let rt_request = RtRequest {
            core: rt::haptic_core(&config.haptic),
            priority: config.haptic.rt_priority,
        };
        let pacing = device.as_ref_dyn().pacing();
        if let Some(w) = servo::stiffness_warning(&scene, &limits) {
            tracing::warn!("{w}");
        }
        tracing::info!(
            "haptic loop: {} Hz on {}{}, force clamp {:.2} N, stale limit {} ms",
            settings.pipeline.rate_hz,
            device.as_ref_dyn().name(),
            if pacing == Pacing::DeviceClock {
                " (the device's servo callback is the clock)"
            } else {
                ""
            },
            settings.pipeline.max_force,
            settings.stale_ns / 1_000_000
        );
        let (mut tap, writer) = match &record {
            Some(path) => {
                let header = record::header(
                    settings.pipeline.rate_hz,
                    limits,
                    &scene.name,
                    &scene.path,
                    &device_spec,
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
                            // The recording wrapper, chosen once for the whole run.
                            let mut recorded;
                            let dev: &mut dyn HapticDevice = match tap.as_mut() {
                                Some(tap) => {
                                    recorded = Recorded {
                                        device: device.as_dyn(),
                                        tap,
                                    };
                                    &mut recorded
                                }
                                None => device.as_dyn(),
                            };
                            haptic::run_loop(
                                &names,
                                settings,
                                dev,
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
                servo::run(device.as_dyn(), task)
            }
        };
        done.store(true, Ordering::Release);
        let _ = publisher.join();
        device.as_dyn().stop();
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
        if let Device::OpenHaptics(o) = &device {
            let s = o.stats();
            if s.clamped_forces + s.non_finite_forces + s.recoverable_errors > 0 {
                tracing::info!(
                    "device: {} forces clamped to its peak, {} non-finite refused, {} force errors",
                    s.clamped_forces,
                    s.non_finite_forces,
                    s.recoverable_errors
                );
            }
        }
        if let Device::ForceDimension(f) = &device {
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
        let summary = result?;
        if let Some(path) = &force_log {
            device
                .write_force_csv(path)
                .with_context(|| format!("writing {}", path.display()))?;
        }
        let last = device.last_force();
        tracing::info!(
            "haptic loop stopped after {} ticks, {} overruns{}{}",
            summary.ticks,
            summary.overruns,
            match last {
                Some(f) => format!("; last force written [{}, {}, {}] N", f[0], f[1], f[2]),
                None => String::new(),
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
