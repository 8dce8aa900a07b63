//! The haptic loop on the devices' own clock (OpenHaptics: the servo callback of the vendor's
//! scheduler thread, 1 kHz, one callback for every device).
//!
//! Same loop, different pacing: where `haptic::run_loop` sleeps to absolute deadlines, here the
//! driver calls [`ServoTask::on_tick`] once per servo tick with every device inside its servo
//! frame, and it runs the existing `HapticLoop::tick` on all of them (every device read, every
//! tool's force against the same frame, every device written). iceoryx2 ports are not `Send`,
//! so the `HapticLoop` is built in the first callback, on the scheduler thread, and dropped in
//! the last one; that first callback only sets up and writes zero force (it may take a few ms:
//! no force is rendered yet). From the second callback on the RT rules hold — no allocation,
//! no lock, no formatting (tested against the stand-in libHD with two named devices in
//! `tests/rt_alloc_servo.rs`).
//!
//! Every way out writes zero force to every device in the last frame: a stop request (Ctrl-C,
//! SIGTERM, `--duration`), a fatal error of any device, a panic (the driver catches it), and the
//! driver's own `stop` writes zero again before unscheduling, stopping the scheduler and
//! disabling the devices.

use std::sync::atomic::{AtomicBool, Ordering};

use anyhow::{bail, Result};
use lop_config::{ForceLaw, Scene};
use lop_drivers::{
    DeviceError, DeviceLimits, HapticDevice, ServoClock, ServoControl, ServoEnd, ServoRun,
    ServoTick,
};
use lop_ipc::{ServiceNames, ToolState};

use crate::haptic::{HapticLoop, HapticSettings, HapticSummary, TelemetryTx};
use crate::record::{RecordTap, Recorded};
use crate::rt;

/// What the first callback needs to build the loop.
struct Setup {
    names: ServiceNames,
    settings: HapticSettings,
    tool_ring: rtrb::Producer<ToolState>,
    telemetry_ring: TelemetryTx,
    core: Option<usize>,
}

/// The servo-side state of a device-clocked run: the loop (once built) and its counters.
pub struct ServoTask<'a> {
    setup: Option<Setup>,
    hl: Option<HapticLoop>,
    build_error: Option<anyhow::Error>,
    stop: &'a AtomicBool,
    max_ticks: Option<u64>,
    period_ns: u64,
    last_wake_ns: u64,
    ticks: u64,
    overruns: u64,
    ring_drops: u64,
    fatal: Option<DeviceError>,
    record: Option<&'a mut RecordTap>,
}

impl<'a> ServoTask<'a> {
    /// A task that builds its loop from these in the first servo callback. `core`: pin the
    /// scheduler thread there (its priority is the vendor's). `record`: the first device's
    /// reads are recorded (a recorded run has one device; the others would not be ticked).
    #[allow(clippy::too_many_arguments)] // each is a distinct input of the loop's start-up
    pub fn new(
        names: &ServiceNames,
        settings: HapticSettings,
        core: Option<usize>,
        stop: &'a AtomicBool,
        max_ticks: Option<u64>,
        tool_ring: rtrb::Producer<ToolState>,
        telemetry_ring: TelemetryTx,
        record: Option<&'a mut RecordTap>,
    ) -> ServoTask<'a> {
        ServoTask {
            period_ns: settings.period_ns(),
            setup: Some(Setup {
                names: names.clone(),
                settings,
                tool_ring,
                telemetry_ring,
                core,
            }),
            hl: None,
            build_error: None,
            stop,
            max_ticks,
            last_wake_ns: 0,
            ticks: 0,
            overruns: 0,
            ring_drops: 0,
            fatal: None,
            record,
        }
    }

    /// One servo callback with every device of the clock (`devices[t]` drives tool `t`). The
    /// first builds the loop; the others tick it (allocation-free).
    pub fn on_tick(
        &mut self,
        devices: &mut [&mut dyn HapticDevice],
        clock: ServoClock,
    ) -> ServoControl {
        let Some(hl) = self.hl.as_mut() else {
            return self.set_up(devices, clock);
        };
        if self.stop.load(Ordering::Relaxed) || self.max_ticks.is_some_and(|m| hl.ticks() >= m) {
            return self.finish(devices);
        }
        // The device is the clock: a gap of more than one period and a half is a missed tick.
        let period = self.period_ns;
        let gap = clock.now_ns.saturating_sub(self.last_wake_ns);
        let deadline = self.last_wake_ns + period;
        if gap > period + period / 2 {
            let missed = (gap + period / 2) / period - 1;
            self.overruns += missed;
            for _ in 0..missed {
                hl.count_overrun();
            }
        }
        self.last_wake_ns = clock.now_ns;
        // Whether to record was decided once, in `new`; the wrapper itself is a value on this
        // callback's stack because the vendor lends the devices for one callback at a time.
        let outcome = match (self.record.as_deref_mut(), devices.first_mut()) {
            (Some(tap), Some(first)) => hl.tick(
                &mut [&mut Recorded {
                    device: &mut **first,
                    tap,
                }],
                clock.now_ns,
                deadline,
            ),
            _ => hl.tick(devices, clock.now_ns, deadline),
        };
        if let Some(e) = outcome.fatal {
            self.fatal = Some(e);
            return self.finish(devices);
        }
        ServoControl::Continue
    }

    fn set_up(&mut self, devices: &mut [&mut dyn HapticDevice], clock: ServoClock) -> ServoControl {
        zero_force(devices);
        let Some(s) = self.setup.take() else {
            return ServoControl::Stop;
        };
        // The vendor's thread: its priority is the vendor's, its stack is not ours to pre-fault.
        let state = rt::set_up_thread(
            "the device's servo thread",
            s.core,
            rt::Priority::Inherited,
            0,
        );
        match HapticLoop::new(&s.names, s.settings, s.tool_ring, s.telemetry_ring) {
            Ok(mut hl) => {
                hl.set_rt_state(state.flags, state.pinned_core);
                self.hl = Some(hl);
                self.last_wake_ns = clock.now_ns;
                ServoControl::Continue
            }
            Err(e) => {
                self.build_error = Some(e);
                ServoControl::Stop
            }
        }
    }

    /// The last tick: zero force to every device, counters kept, the loop dropped here on its
    /// own thread.
    fn finish(&mut self, devices: &mut [&mut dyn HapticDevice]) -> ServoControl {
        zero_force(devices);
        if let Some(hl) = self.hl.take() {
            self.ticks = hl.ticks();
            self.ring_drops = hl.ring_drops();
            drop(hl);
        }
        ServoControl::Stop
    }

    /// How the run went, once the device has returned from `run_clocked`.
    pub fn summary(&mut self, run: ServoRun) -> Result<HapticSummary> {
        if let Some(e) = self.build_error.take() {
            return Err(e.context("setting up the haptic loop in the servo callback"));
        }
        if let Some(hl) = self.hl.take() {
            // The run ended without a last tick (stall, panic): the scheduler no longer calls
            // back, so the loop is dropped here, never concurrently with its thread.
            self.ticks = hl.ticks();
            self.ring_drops = hl.ring_drops();
        }
        let fatal = match run.end {
            ServoEnd::Requested => self.fatal,
            ServoEnd::Device(e) => Some(self.fatal.unwrap_or(e)),
            ServoEnd::Stalled => {
                bail!(
                    "the device's servo loop stopped calling back (stalled) after {} ticks; \
                     force output was disabled",
                    run.ticks
                )
            }
            ServoEnd::Panicked => {
                bail!("the haptic tick panicked in the servo callback; zero force was written")
            }
        };
        Ok(HapticSummary {
            ticks: self.ticks,
            overruns: self.overruns,
            ring_drops: self.ring_drops,
            fatal,
        })
    }
}

/// Writes zero force to every device (in the servo frame).
fn zero_force(devices: &mut [&mut dyn HapticDevice]) {
    for device in devices.iter_mut() {
        let _ = device.write_force([0.0; 3]);
    }
}

/// Lets the task cross to the devices' scheduler thread.
///
/// SAFETY argument: the task's `HapticLoop` (iceoryx2 ports, not `Send`) is created in the
/// first servo callback and dropped in the last one, on the scheduler thread; the thread that
/// calls `run_clocked` blocks meanwhile and touches the task again only after the driver
/// returned, when no callback runs any more.
struct ServoCell<'a>(ServoTask<'a>);
// SAFETY: see above.
unsafe impl Send for ServoCell<'_> {}

impl ServoCell<'_> {
    fn call(&mut self, devices: &mut [&mut dyn HapticDevice], clock: ServoClock) -> ServoControl {
        self.0.on_tick(devices, clock)
    }
}

/// Runs `task` on the devices' clock: `run_clocked` hands the tick to the driver (e.g.
/// `OpenHapticsScheduler::run_clocked` with every device), which calls it once per servo tick
/// until it stops, then stops the devices (zero force first, then unschedule, stop the
/// scheduler, disable).
pub fn run(
    task: ServoTask<'_>,
    run_clocked: impl FnOnce(&mut ServoTick<'_>) -> Result<ServoRun>,
) -> Result<HapticSummary> {
    let mut cell = ServoCell(task);
    let run = {
        let cell = &mut cell;
        run_clocked(&mut |devices, clock| cell.call(devices, clock))
    };
    let run = run?;
    cell.0.summary(run)
}

/// A warning when tool `tool`'s spring, as felt at its device, is stiffer than the device's
/// nominal maximum (the stylus would buzz). Linear force law only.
pub fn stiffness_warning(scene: &Scene, tool: usize, limits: &DeviceLimits) -> Option<String> {
    let spec = scene.tools.get(tool)?;
    if spec.force_law != ForceLaw::Linear {
        return None;
    }
    // 1 mm at the device is 1e-3 · scale m in the scene; forces are not scaled.
    let scale = spec.workspace.transform().scale;
    let at_device = spec.stiffness * 1e-3 * scale;
    (at_device > limits.max_stiffness_n_per_mm).then(|| {
        format!(
            "the tool spring ({} N/m in the scene, workspace scale {scale}) is {at_device:.3} N/mm \
             at the device, above its nominal maximum {:.3} N/mm: expect buzzing; lower [tool] \
             stiffness or the workspace scale",
            spec.stiffness, limits.max_stiffness_n_per_mm
        )
    })
}
