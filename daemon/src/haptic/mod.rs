//! `lopd haptic`: the hard-real-time 1 kHz loop that owns the devices, one per tool of the
//! scene.
//!
//! Life of the process, copper-style: `new` (allocate everything: iceoryx2 ports, histograms,
//! rings) → `start` (lock memory, pin, `SCHED_FIFO`, pre-fault the stack) → `tick` × N (no
//! allocation, no lock, no formatting; the only syscalls are the deadline sleep and the device)
//! → stop (zero force first, on every path, panics included).
//!
//! One tick: read every device → take the newest frame → per tool, its newest contact index
//! and its haptic pipeline
//! ([`lop_sim::haptic::HapticPipeline`]: validate, the newest surface around the tool, the
//! god-object, the force from the frame's local model or the force law, passivity, safety —
//! the same value the offline closed loop drives) → write every device its own force → each
//! tool's state to its entry of the
//! blackboard (for `lopd deform`, which applies the opposite force to the tissue at the
//! god-object's anchor) and to a lock-free ring (drained by a normal thread that publishes
//! `PREFIX/tool` for viewers) → timing into preallocated histograms. This module is the
//! pipeline's live adapter: shared memory, the deadline and the statistics.
//!
//! Several tools (two hands) run in the one loop and the one tick: every device is read before
//! any force is computed and every force is written in the same tick, so the hands feel the
//! same frame. Each tool has its own god-object, contact index, pipeline and tool state; the
//! frame, the deadline and the statistics are shared (the tick's compute covers every tool).
//!
//! The surfaces' index (adjacency, hierarchies, the god-object's buffers) is sized by the
//! topology, so it is built off the RT thread (one index: the surfaces, shared by the tools, and
//! a god-object per tool): a helper thread subscribes to the topology,
//! builds the index for each new one and hands it over through a lock-free ring; the RT thread
//! swaps it in and hands the old one back to be freed there. Frames come the same way, from a
//! thread that receives them from shared memory (so the RT thread never maps a publisher's
//! segment) and copies each into a reused buffer ([`frames`]). A new frame only refreshes the
//! positions (no allocation).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use anyhow::{Context, Result};
use iceoryx2::port::writer::EntryHandleMut;
use iceoryx2::prelude::*;
use lop_config::{DaemonConfig, Scene};
use lop_drivers::{DeviceLimits, HapticDevice};
use lop_ipc::services::{self, Role, ToolBoard};
use lop_ipc::*;
use lop_sim::haptic::{DeviceReading, HapticPipeline, PipelineSettings};

use crate::rt;

mod frames;
mod index;
mod telemetry;

use frames::FrameFeed;
pub use frames::{FrameCopy, FramePlacement};
pub use index::{contact_frame, frame_local, IndexSlot};
use index::{ContactIndex, IndexFeed, LiveSurfaces};
use telemetry::{telemetry, COMPUTE, FRAME_AGE, FRAME_AGE_CONTACT, JITTER};
pub use telemetry::{TelemetryRx, TelemetryTx, TelemetryWindow};

/// Tool states the ring to the publisher thread holds: 0.5 s at 1 kHz.
const TOOL_RING: usize = 512;

/// Everything the loop needs that is decided before it starts.
#[derive(Debug, Clone)]
pub struct HapticSettings {
    /// Per tool, in the scene's order (tool `t` is driven by the `t`-th device): the tick
    /// itself ([`lop_scene::tool_pipeline_settings`]). The index names the tool's states
    /// (`ToolState::tool`), its tool blackboard entry ([`services::tool_latest_key`]) and its
    /// contact in a frame (`FrameHeader::contacts`). At least one, at most [`MAX_TOOLS`].
    pub tools: Vec<PipelineSettings>,
    /// Frames older than this ramp the force to zero, ns.
    pub stale_ns: u64,
    /// Busy-wait before each deadline, ns.
    pub spin_ns: u64,
    /// Where the thread that receives the frames runs ([`frames`]).
    pub frames: FramePlacement,
}

impl HapticSettings {
    /// Derives the settings from the daemon config, the scene and the one device (driving
    /// the scene's first tool).
    pub fn new(config: &DaemonConfig, scene: &Scene, limits: DeviceLimits) -> HapticSettings {
        HapticSettings::for_devices(config, scene, &[limits])
    }

    /// Derives the settings from the daemon config, the scene and the devices, the `t`-th
    /// driving the scene's tool `t`.
    pub fn for_devices(
        config: &DaemonConfig,
        scene: &Scene,
        limits: &[DeviceLimits],
    ) -> HapticSettings {
        let h = &config.haptic;
        HapticSettings {
            tools: limits
                .iter()
                .enumerate()
                .map(|(t, l)| lop_scene::tool_pipeline_settings(config, scene, t, l))
                .collect(),
            stale_ns: (h.stale_frame_ms * 1e6) as u64,
            spin_ns: (h.spin_us * 1e3) as u64,
            // The loop's core, one priority below it: it runs while the loop sleeps.
            frames: FramePlacement {
                core: rt::haptic_core(h),
                priority: h.rt_priority.saturating_sub(1),
            },
        }
    }

    /// The first tool's pipeline settings (the rate and the clamp of a one-device loop).
    pub fn pipeline(&self) -> &PipelineSettings {
        &self.tools[0]
    }

    /// Tick period, ns (every tool ticks at the scene's haptic rate).
    pub fn period_ns(&self) -> u64 {
        (1e9 / self.pipeline().rate_hz).round() as u64
    }
}

/// One tool of the loop: its tick and its tool state's entry (its god-object is in the
/// shared contact index).
struct ToolLoop {
    /// The tick itself: validate, surface, god-object, force, passivity, safety.
    pipeline: HapticPipeline,
    entry: ToolEntry,
}

/// The haptic loop's state. Built on the RT thread (iceoryx2 ports are not `Send`).
pub struct HapticLoop {
    settings: HapticSettings,
    /// Per tool, in the scene's order.
    tools: Vec<ToolLoop>,
    _node: Node<ipc::Service>,
    frame_feed: FrameFeed,
    /// The surfaces and every tool's god-object, built per topology on their own thread.
    index_feed: IndexFeed,
    index: IndexSlot<ContactIndex>,
    _board: ToolBoard,
    _writer: ToolWriter,
    frame: IndexSlot<FrameCopy>,
    tool_ring: rtrb::Producer<ToolState>,
    telemetry: TelemetryTx,
    tick: u64,
    /// When the last tick woke, ns (0 before the first).
    last_wake_ns: u64,
    overruns: u64,
    stale_ticks: u64,
    device_faults: u64,
    ring_drops: u64,
    rt_flags: u32,
    pinned_core: i32,
    window_start_ns: u64,
    window_start_tick: u64,
    telemetry_every: u64,
}

/// What a tick hands back to the caller (for the pacing loop and tests).
#[derive(Debug, Clone, Copy)]
pub struct TickOutcome {
    /// The states published this tick, one per tool (the first `tools`).
    pub states: [ToolState; MAX_TOOLS],
    /// Tools ticked.
    pub tools: usize,
    /// A device error that makes continuing unsafe.
    pub fatal: Option<lop_drivers::DeviceError>,
}

/// The tool blackboard's writer and its entry of the newest state of the loop's tool.
type ToolWriter = iceoryx2::port::writer::Writer<ipc::Service, u32>;
type ToolEntry = EntryHandleMut<ipc::Service, u32, ToolState>;

impl TickOutcome {
    /// The first tool's state (a one-device loop's).
    pub fn state(&self) -> &ToolState {
        &self.states[0]
    }
}

/// How long a starting haptic process waits for the tool blackboard's entry to be free.
const TOOL_BOARD_WAIT: Duration = Duration::from_secs(3);

/// The tool blackboard (created, or opened if it exists), its writer and the entry of the
/// newest state of tool `tool`. A haptic process killed while writing leaves the entry marked
/// as held: the iceoryx2 0.10 blackboard does not release a dead writer's entry handle, even
/// once the dead node is cleaned up, so the entry cannot be had while the service lives. The
/// service goes when its readers close it — the deformation process does once the tool state
/// is older than 150 ms (`deform::TOOL_DROP_NS`) — so a restarted process lets go of it too
/// and tries again, for up to [`TOOL_BOARD_WAIT`], before it gives up with the cause.
fn tool_board_writer(
    node: &Node<ipc::Service>,
    names: &ServiceNames,
    tools: usize,
) -> Result<(ToolBoard, ToolWriter, Vec<ToolEntry>)> {
    let start = std::time::Instant::now();
    let mut waited = false;
    loop {
        services::cleanup_dead_nodes(node);
        let board = services::tool_board_owner(node, names)?;
        let writer = board
            .writer_builder()
            .create()
            .context("tool blackboard writer (is another lopd haptic running with this prefix?)")?;
        let entries: std::result::Result<Vec<ToolEntry>, _> = (0..tools)
            .map(|t| writer.entry::<ToolState>(&services::tool_latest_key(t)))
            .collect();
        match entries {
            Ok(entries) => {
                if waited {
                    tracing::info!(
                        "tool blackboard made anew after {:.0} ms (the last haptic process \
                         died holding its entry)",
                        start.elapsed().as_secs_f64() * 1e3
                    );
                }
                return Ok((board, writer, entries));
            }
            Err(e) if start.elapsed() < TOOL_BOARD_WAIT => {
                if !waited {
                    tracing::info!(
                        "tool blackboard entry still held ({e:?}): a haptic process died \
                         writing it; waiting for its readers to close it"
                    );
                }
                waited = true;
                drop(writer);
                drop(board);
                std::thread::sleep(Duration::from_millis(20));
            }
            Err(e) => {
                return Err(anyhow::anyhow!("{e:?}")).context(format!(
                    "tool blackboard entry: still held {:.1} s after start (a haptic process \
                     died writing it, and a reader of {} keeps the service open)",
                    TOOL_BOARD_WAIT.as_secs_f64(),
                    names.tool_latest
                ));
            }
        }
    }
}

impl HapticLoop {
    /// Creates the ports and buffers. Call on the thread that will run the ticks.
    pub fn new(
        names: &ServiceNames,
        settings: HapticSettings,
        tool_ring: rtrb::Producer<ToolState>,
        telemetry: TelemetryTx,
    ) -> Result<HapticLoop> {
        let count = settings.tools.len();
        anyhow::ensure!(
            (1..=MAX_TOOLS).contains(&count),
            "haptic loop: {count} tools; the contract carries 1 to {MAX_TOOLS}"
        );
        let node = services::node("lopd-haptic-rt")?;
        services::cleanup_dead_nodes(&node);
        let frame_feed = FrameFeed::start(names, settings.frames)?;
        let (board, writer, entries) = tool_board_writer(&node, names, count)?;
        let mut tools = Vec::with_capacity(count);
        for (pipeline, entry) in settings.tools.iter().zip(entries) {
            tools.push(ToolLoop {
                pipeline: HapticPipeline::new(pipeline.clone()),
                entry,
            });
        }
        let radii = settings.tools.iter().map(|p| p.tool.radius).collect();
        let index_feed = IndexFeed::start(names, radii)?;
        let rate = settings.pipeline().rate_hz.round() as u64;
        Ok(HapticLoop {
            settings,
            tools,
            _node: node,
            frame_feed,
            index_feed,
            index: IndexSlot::default(),
            _board: board,
            _writer: writer,
            frame: IndexSlot::default(),
            tool_ring,
            telemetry,
            tick: 0,
            last_wake_ns: 0,
            overruns: 0,
            stale_ticks: 0,
            device_faults: 0,
            ring_drops: 0,
            rt_flags: 0,
            pinned_core: -1,
            window_start_ns: rt::now_ns(),
            window_start_tick: 0,
            telemetry_every: (rate / 4).max(1),
        })
    }

    /// Records which real-time privileges the loop got (for telemetry).
    pub fn set_rt_state(&mut self, flags: u32, pinned_core: i32) {
        self.rt_flags = flags;
        self.pinned_core = pinned_core;
    }

    /// Counts a missed deadline.
    pub fn count_overrun(&mut self) {
        self.overruns += 1;
    }

    /// Whether the contact index of a topology has arrived from its thread (until then the
    /// tools render no contact).
    pub fn contact_ready(&self) -> bool {
        self.index.is_ready()
    }

    /// Tools the loop drives.
    pub fn tool_count(&self) -> usize {
        self.tools.len()
    }

    /// Waits, sleeping, until the frame thread has handed over the frame of `sequence`, and
    /// takes it; false after `timeout`. For tests that tick faster than real time and publish
    /// the frames themselves: the live loop takes whatever frame has arrived at each tick.
    pub fn await_frame(&mut self, sequence: u64, timeout: Duration) -> bool {
        let start = std::time::Instant::now();
        loop {
            self.frame
                .take_newest(&mut self.frame_feed.rx, &mut self.frame_feed.back);
            if self
                .frame
                .current()
                .is_some_and(|f| f.user_header().sequence == sequence)
            {
                return true;
            }
            if start.elapsed() > timeout {
                return false;
            }
            std::thread::sleep(Duration::from_micros(100));
        }
    }

    /// Ticks run so far.
    pub fn ticks(&self) -> u64 {
        self.tick
    }

    /// Tool states dropped because the publisher thread fell behind.
    pub fn ring_drops(&self) -> u64 {
        self.ring_drops
    }

    /// One haptic tick: `devices[t]` drives tool `t` (devices beyond the tools are left alone;
    /// tools beyond the devices render nothing). `wake_ns` is when the loop woke,
    /// `deadline_ns` when it should have. Every device is read first, then every tool's force
    /// is computed against the same frame, then every device is written. Allocation-free.
    pub fn tick(
        &mut self,
        devices: &mut [&mut dyn HapticDevice],
        wake_ns: u64,
        deadline_ns: u64,
    ) -> TickOutcome {
        let n = self.tools.len().min(devices.len());
        // A loop that did not tick for longer than the stale limit (its process was stopped,
        // or the machine held it) has not driven the devices meanwhile: the forces start over
        // from zero against the surface as it is now, rather than going on from the last ones.
        if self.last_wake_ns != 0
            && wake_ns.saturating_sub(self.last_wake_ns) > self.settings.stale_ns
        {
            self.tools
                .iter_mut()
                .for_each(|t| t.pipeline.restart_force());
        }
        self.last_wake_ns = wake_ns;
        let t = self.tick as f64 / self.settings.pipeline().rate_hz;
        let mut fatal = None;

        // 1. Read every device.
        let mut samples = [None; MAX_TOOLS];
        for (sample, device) in samples.iter_mut().zip(devices.iter_mut()).take(n) {
            *sample = match device.read(t) {
                Ok(s) => Some(s),
                Err(e) => {
                    if !e.is_recoverable() {
                        fatal = Some(e);
                    }
                    None
                }
            };
        }

        // 2. Take the newest frame and contact index from their threads; a retired one goes
        // back to its thread (to be freed, or filled again).
        self.index.take_newest_carrying(
            &mut self.index_feed.rx,
            &mut self.index_feed.back,
            ContactIndex::carry_from,
        );
        self.frame
            .take_newest(&mut self.frame_feed.rx, &mut self.frame_feed.back);
        let frame_age = match self.frame.current() {
            Some(f) => wake_ns.saturating_sub(f.user_header().publish_ns),
            None => u64::MAX,
        };
        let fresh = frame_age <= self.settings.stale_ns;
        if fresh {
            self.telemetry.record(FRAME_AGE, frame_age);
        } else {
            self.stale_ticks += 1;
        }

        // 3. Per tool, the pipeline: validate, surface, god-object, force, passivity, safety.
        let mut states = [ToolState::default(); MAX_TOOLS];
        let mut forces = [[0.0; 3]; MAX_TOOLS];
        let mut in_contact = false;
        let mut largest = [0.0; 3];
        for (k, (tool, settings)) in self
            .tools
            .iter_mut()
            .zip(&self.settings.tools)
            .enumerate()
            .take(n)
        {
            let state = &mut states[k];
            *state = ToolState {
                contract_version: CONTRACT_VERSION,
                sequence: self.tick,
                stamp_ns: wake_ns,
                tool_radius: settings.tool.radius,
                contact_body: -1,
                tool: k as u32,
                ..Default::default()
            };
            if !fresh {
                state.flags |= TOOL_FLAG_STALE_FRAME;
            }
            let sample = samples[k];
            let reading = sample.map(|s| DeviceReading {
                position_mm: s.position_mm,
                velocity_mm_s: s.velocity_mm_s,
                grab: s.pressed(lop_drivers::BUTTON_GRAB),
            });
            let topology_id = self.index.current().map_or(0, |ix| ix.topology_id);
            let mut surfaces = LiveSurfaces {
                index: self.index.current(),
                frame: self.frame.current().map(|f| &*f),
                local_model: settings.local_model,
                tool: k,
                wake_ns,
            };
            let out = tool
                .pipeline
                .tick(reading, fresh, &mut surfaces, rt::now_ns);
            if !out.valid {
                self.device_faults += 1;
                state.flags |= TOOL_FLAG_DEVICE_ERROR;
            }
            if let (Some(s), Some(p)) = (sample.filter(|_| out.valid), out.tip) {
                state.device_position = p;
                state.proxy_position = p;
                state.buttons = s.buttons;
                if let Some(g) = out.god {
                    state.proxy_position = g.proxy;
                    state.topology_id = topology_id;
                }
                if let Some(a) = out.anchor() {
                    // The proxy stays the god-object's (the deformation process gathers the
                    // patch around it, as offline).
                    state.tool_stiffness = out.stiffness;
                    state.contact_body = a.body as i32;
                    state.contact_triangle = a.triangle as u32;
                    state.contact_barycentric = a.bary;
                    if out.pressing() {
                        state.flags |= TOOL_FLAG_CONTACT;
                    }
                    if out.grabbing() {
                        state.flags |= TOOL_FLAG_GRAB;
                    }
                    if settings.cauterizes && s.pressed(lop_drivers::BUTTON_HEAT) {
                        state.flags |= TOOL_FLAG_HEAT;
                    }
                    if settings.cauterizes && s.pressed(lop_drivers::BUTTON_CUT) {
                        state.flags |= TOOL_FLAG_CUT;
                    }
                    if out.local {
                        state.flags |= TOOL_FLAG_LOCAL_MODEL;
                    }
                }
            }
            in_contact |= state.flags & (TOOL_FLAG_CONTACT | TOOL_FLAG_GRAB) != 0;
            if !out.healthy {
                state.flags |= TOOL_FLAG_RAMPING;
            }
            state.force = out.force;
            forces[k] = out.device_force;
            if norm2(out.force) > norm2(largest) {
                largest = out.force;
            }
        }
        if fresh && in_contact {
            self.telemetry.record(FRAME_AGE_CONTACT, frame_age);
        }

        // 4. Write every device its own force.
        for (k, device) in devices.iter_mut().enumerate().take(n) {
            if let Err(e) = device.write_force(forces[k]) {
                self.device_faults += 1;
                states[k].flags |= TOOL_FLAG_DEVICE_ERROR;
                if !e.is_recoverable() {
                    fatal = Some(e);
                }
            }
        }

        // 5. Publish: blackboard for the deformation process, ring for viewers.
        for (tool, state) in self.tools.iter_mut().zip(&states).take(n) {
            tool.entry.update_with_copy(*state);
            if self.tool_ring.push(*state).is_err() {
                self.ring_drops += 1;
            }
        }

        // 6. Timing.
        let done = rt::now_ns();
        self.telemetry
            .record(JITTER, wake_ns.saturating_sub(deadline_ns));
        self.telemetry.record(COMPUTE, done.saturating_sub(wake_ns));
        self.tick += 1;
        if self.tick.is_multiple_of(self.telemetry_every) {
            self.emit_telemetry(done, largest);
        }
        TickOutcome {
            states,
            tools: n,
            fatal,
        }
    }

    /// Ends the statistics window: the counters now; the quantiles are the publisher's.
    fn emit_telemetry(&mut self, now: u64, force: [f64; 3]) {
        let ticks = self.tick - self.window_start_tick;
        let secs = now.saturating_sub(self.window_start_ns) as f64 * 1e-9;
        let counters = HapticTelemetry {
            contract_version: CONTRACT_VERSION,
            rt_flags: self.rt_flags,
            stamp_ns: now,
            ticks: self.tick,
            overruns: self.overruns,
            stale_ticks: self.stale_ticks,
            device_faults: self.device_faults,
            rate_hz: if secs > 0.0 { ticks as f64 / secs } else { 0.0 },
            force_norm: (force[0] * force[0] + force[1] * force[1] + force[2] * force[2]).sqrt(),
            pinned_core: self.pinned_core,
            ..Default::default()
        };
        if self.telemetry.send(counters) {
            self.window_start_ns = now;
            self.window_start_tick = self.tick;
        }
    }
}

/// `|v|²`.
fn norm2(v: [f64; 3]) -> f64 {
    v[0] * v[0] + v[1] * v[1] + v[2] * v[2]
}

/// Writes zero force to every device when dropped (all of them first, then stops them), so a
/// panic on the RT thread still leaves every device safe.
struct ZeroForceGuard<'a, 'b>(&'a mut [&'b mut dyn HapticDevice]);

impl Drop for ZeroForceGuard<'_, '_> {
    fn drop(&mut self) {
        for d in self.0.iter_mut() {
            let _ = d.write_force([0.0; 3]);
        }
        for d in self.0.iter_mut() {
            d.stop();
        }
    }
}

/// How the haptic process ended.
#[derive(Debug, Clone)]
pub struct HapticSummary {
    /// Ticks run.
    pub ticks: u64,
    /// Missed deadlines.
    pub overruns: u64,
    /// Tool states the publisher thread missed.
    pub ring_drops: u64,
    /// Set when a device error stopped the loop.
    pub fatal: Option<lop_drivers::DeviceError>,
}

/// Real-time set-up requested for the loop thread.
#[derive(Debug, Clone)]
pub struct RtRequest {
    /// Core to pin to.
    pub core: Option<usize>,
    /// `SCHED_FIFO` priority.
    pub priority: u8,
}

/// Runs the loop on the calling thread until `stop` is set, `max_ticks` is reached or a device
/// fails; `devices[t]` drives tool `t`. Every device is zeroed and stopped before this
/// returns, and also if it panics.
#[allow(clippy::too_many_arguments)] // each is a distinct input of the loop's start-up
pub fn run_loop(
    names: &ServiceNames,
    settings: HapticSettings,
    devices: &mut [&mut dyn HapticDevice],
    rt_request: &RtRequest,
    stop: &AtomicBool,
    max_ticks: Option<u64>,
    tool_ring: rtrb::Producer<ToolState>,
    telemetry: TelemetryTx,
) -> Result<HapticSummary> {
    let guard = ZeroForceGuard(devices);
    let spin_ns = settings.spin_ns;
    let period = settings.period_ns();
    let mut hl = HapticLoop::new(names, settings, tool_ring, telemetry)?;

    // Start: privileges (each optional, reported once), then a warm stack.
    let state = rt::set_up_thread(
        "haptic loop",
        rt_request.core,
        rt::Priority::Fifo(rt_request.priority),
        256 * 1024,
    );
    hl.set_rt_state(state.flags, state.pinned_core);

    // Process: absolute deadlines; a late tick is counted, never caught up in a burst.
    let mut fatal = None;
    let mut deadline = rt::now_ns() + period;
    while !stop.load(Ordering::Relaxed) && max_ticks.is_none_or(|m| hl.ticks() < m) {
        let wake = rt::sleep_until(deadline, spin_ns);
        let outcome = hl.tick(guard.0, wake, deadline);
        if let Some(e) = outcome.fatal {
            fatal = Some(e);
            break;
        }
        deadline += period;
        let now = rt::now_ns();
        if now > deadline {
            let missed = (now - deadline) / period + 1;
            for _ in 0..missed {
                hl.count_overrun();
            }
            deadline += missed * period;
        }
    }
    let summary = HapticSummary {
        ticks: hl.ticks(),
        overruns: hl.overruns,
        ring_drops: hl.ring_drops(),
        fatal,
    };
    // Stop: zero force first (the guard's drop), then release the ports.
    drop(guard);
    drop(hl);
    Ok(summary)
}

/// Drains the rings and publishes `PREFIX/tool` and `PREFIX/telemetry/haptic`. Runs on a normal
/// thread: iceoryx2's publish path allocates, which the RT thread must not do.
pub fn run_publisher(
    names: &ServiceNames,
    mut tool_ring: rtrb::Consumer<ToolState>,
    mut telemetry: TelemetryRx,
    done: Arc<AtomicBool>,
) -> Result<()> {
    let node = services::node("lopd-haptic-pub")?;
    let tool_pub = services::tool_service(&node, names, Role::Owner)?
        .publisher_builder()
        .create()
        .context("tool publisher")?;
    let telemetry_pub = services::telemetry_service(&node, names, Role::Owner)?
        .publisher_builder()
        .create()
        .context("telemetry publisher")?;
    let mut last_faults = 0;
    let mut last_stale = 0;
    loop {
        let finished = done.load(Ordering::Acquire);
        while let Ok(s) = tool_ring.pop() {
            let _ = tool_pub.send_copy(s);
        }
        while let Some(t) = telemetry.pop() {
            if t.device_faults > last_faults {
                tracing::warn!(
                    "device faults: {} (+{})",
                    t.device_faults,
                    t.device_faults - last_faults
                );
                last_faults = t.device_faults;
            }
            if t.stale_ticks > last_stale + t.ticks / 100 && t.ticks > 2000 {
                tracing::debug!("ticks with a stale frame: {}", t.stale_ticks);
                last_stale = t.stale_ticks;
            }
            let _ = telemetry_pub.send_copy(t);
        }
        if finished {
            return Ok(());
        }
        std::thread::sleep(Duration::from_micros(500));
    }
}

/// Both ends of a lock-free ring.
pub type Ring<T> = (rtrb::Producer<T>, rtrb::Consumer<T>);

/// Creates the channels between the RT thread and the publisher thread: the tool states' ring
/// and the statistics windows (totals from one second after start, start-up left out).
pub fn rings(settings: &HapticSettings) -> Result<(Ring<ToolState>, (TelemetryTx, TelemetryRx))> {
    let warmup_ticks = settings.pipeline().rate_hz.round() as u64;
    Ok((rtrb::RingBuffer::new(TOOL_RING), telemetry(warmup_ticks)?))
}
