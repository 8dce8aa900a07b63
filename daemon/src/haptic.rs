//! `lopd haptic`: the hard-real-time 1 kHz loop that owns the device.
//!
//! Life of the process, copper-style: `new` (allocate everything: iceoryx2 ports, histograms,
//! rings) → `start` (lock memory, pin, `SCHED_FIFO`, pre-fault the stack) → `tick` × N (no
//! allocation, no lock, no formatting; the only syscalls are the deadline sleep and the device)
//! → stop (zero force first, on every path, panics included).
//!
//! One tick: read device → validate (finite, inside the workspace) → take the newest frame →
//! god-object against the newest surface and the force law (`lop_sim::haptic`: the proxy stays
//! on the surface while the device penetrates; `F = k d N` or the thesis' `k d² N`, per-body
//! stiffness, optional damping; picking with the grab button) → safety (clamp, ramp to zero on
//! stale or broken data, per-tick step limit) → write device → tool state to the blackboard
//! (for `lopd deform`, which applies the opposite force to the tissue at the god-object's
//! anchor) and to a lock-free ring (drained by a normal thread that publishes `PREFIX/tool`
//! for viewers) → timing into preallocated histograms.
//!
//! The surfaces' index (adjacency, hierarchies, the god-object's buffers) is sized by the
//! topology, so it is built off the RT thread: a helper thread subscribes to the topology,
//! builds the index for each new one and hands it over through a lock-free ring; the RT thread
//! swaps it in and hands the old one back to be freed there. A new frame only refreshes the
//! positions (copied from shared memory, no allocation).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use anyhow::{Context, Result};
use hdrhistogram::Histogram;
use iceoryx2::port::writer::EntryHandleMut;
use iceoryx2::prelude::*;
use iceoryx2::sample::Sample;
use lop_config::{DaemonConfig, Scene, WorkspaceTransform};
use lop_drivers::{DeviceLimits, HapticDevice};
use lop_ipc::services::{self, Role, ToolBoard};
use lop_ipc::*;
use lop_sim::contact::ToolSphere;
use lop_sim::haptic::{contact_force, GodObject, LocalModel, PassivityController, SurfaceSet};

use crate::rt;
use crate::safety::ForceSafety;
use lop_scene::{DeviceClamp, ToolLaws};

/// A body's positions are copied into the contact index once the device or the god-object is
/// this close to its bounds, m: well beyond what the tool covers between frames.
const REACH: f64 = 0.02;
/// A value that changes whenever body `bf`'s positions may have changed between two frames:
/// its last step's wall time (to the nanosecond), kinetic energy, top speed, bounds and model
/// switches, mixed. A body that did not step carries them unchanged (the deformation process
/// only updates them when it steps); two different steps giving all of them identical to the
/// bit is not a case worth a copy of every node on each tick.
fn body_stamp(bf: &BodyFrame) -> u64 {
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    let mut mix = |x: u64| {
        h ^= x;
        h = h.wrapping_mul(0x0100_0000_01b3).rotate_left(23);
    };
    mix(u64::from(bf.step_ns));
    mix(u64::from(bf.kinetic_energy.to_bits()) << 32 | u64::from(bf.max_speed.to_bits()));
    for k in 0..3 {
        mix(u64::from(bf.aabb_min[k].to_bits()) << 32 | u64::from(bf.aabb_max[k].to_bits()));
    }
    mix(u64::from(bf.switches) << 32 | u64::from(bf.resets) << 8 | u64::from(bf.model));
    h
}

/// The local model a frame carries for the patch it balanced: the body and the model; `None`
/// when the frame has none.
pub fn frame_local(h: &FrameHeader) -> Option<(usize, LocalModel)> {
    if h.contact_local != 1 || h.contact_body == NO_CONTACT {
        return None;
    }
    let k = &h.contact_stiffness;
    Some((
        h.contact_body as usize,
        LocalModel {
            device: h.contact_device,
            force: h.contact_force,
            stiffness: [[k[0], k[1], k[2]], [k[3], k[4], k[5]], [k[6], k[7], k[8]]],
            drift: h.contact_drift,
            horizon: h.contact_horizon,
        },
    ))
}

/// Device samples farther than this outside the device's workspace are rejected as broken, mm.
const WORKSPACE_SLACK_MM: f64 = 20.0;
/// Tool states the ring to the publisher thread holds: 0.5 s at 1 kHz.
const TOOL_RING: usize = 512;

/// Everything the loop needs that is decided before it starts.
#[derive(Debug, Clone)]
pub struct HapticSettings {
    /// Loop rate, Hz.
    pub rate_hz: f64,
    /// Frames older than this ramp the force to zero, ns.
    pub stale_ns: u64,
    /// Ticks from full force to zero when data goes bad.
    pub ramp_ticks: u32,
    /// Force clamp, N: min(daemon config, scene tool, device).
    pub max_force: f64,
    /// Largest force change per tick, N (except at contact onset).
    pub max_step: f64,
    /// Busy-wait before each deadline, ns.
    pub spin_ns: u64,
    /// Device → scene mapping.
    pub workspace: WorkspaceTransform,
    /// The tool tip (centre updated each tick).
    pub tool: ToolSphere,
    /// Device limits (workspace check).
    pub limits: DeviceLimits,
    /// Tool stiffness against each body, in topology order (`[body] tool_stiffness`, else the
    /// tool's).
    pub body_stiffness: Vec<f64>,
    /// Tool damping, N·s/m.
    pub damping: f64,
    /// Render with the frames' local model between frames.
    pub local_model: bool,
    /// The passivity controller's largest damping, N·s/m (0: off).
    pub passivity_max_damping: f64,
}

impl HapticSettings {
    /// Derives the settings from the daemon config, the scene and the device.
    pub fn new(config: &DaemonConfig, scene: &Scene, limits: DeviceLimits) -> HapticSettings {
        let rate = scene.rates.haptic_hz;
        let h = &config.haptic;
        // The one tool law per body, clamped to what the device renders (the deformation
        // process receives the same stiffness with every tool state).
        let laws = ToolLaws::new(
            scene,
            DeviceClamp {
                max_stiffness_n_per_mm: limits.max_stiffness_n_per_mm,
            },
        );
        HapticSettings {
            rate_hz: rate,
            stale_ns: (h.stale_frame_ms * 1e6) as u64,
            ramp_ticks: ((h.ramp_ms * 1e-3 * rate).round() as u32).max(1),
            max_force: h
                .max_force_n
                .min(scene.tool.max_force)
                .min(limits.max_force_n),
            max_step: h.max_force_step_n,
            spin_ns: (h.spin_us * 1e3) as u64,
            workspace: scene.workspace.transform(),
            tool: laws.tool,
            limits,
            body_stiffness: laws.bodies.iter().map(|t| t.stiffness).collect(),
            damping: laws.damping,
            local_model: h.local_model,
            passivity_max_damping: h.passivity_max_damping,
        }
    }

    /// Tick period, ns.
    pub fn period_ns(&self) -> u64 {
        (1e9 / self.rate_hz).round() as u64
    }
}

/// The contact index of one topology: every body's surface and the god-object over it.
struct ContactIndex {
    topology_id: u64,
    set: SurfaceSet,
    god: GodObject,
    /// Sequence of the newest frame seen.
    frame_sequence: Option<u64>,
}

impl ContactIndex {
    /// Builds the index of a topology (allocates; off the RT thread). `None` if the topology is
    /// not this contract's.
    fn build(h: &TopologyHeader, indices: &[u32], radius: f64) -> Option<ContactIndex> {
        if h.contract_version != CONTRACT_VERSION {
            return None;
        }
        let tri_count = (h.triangle_count as usize).min(indices.len() / 3);
        let triangles: Vec<[u32; 3]> = indices[..tri_count * 3]
            .chunks_exact(3)
            .map(|c| [c[0], c[1], c[2]])
            .collect();
        let bodies = (h.body_count as usize).min(MAX_BODIES);
        let mut slices = Vec::with_capacity(bodies);
        for b in &h.bodies[..bodies] {
            let start = (b.triangle_offset as usize).min(tri_count);
            let end = (start + b.triangle_count as usize).min(tri_count);
            slices.push(&triangles[start..end]);
        }
        let set = SurfaceSet::new(h.node_count as usize, &slices);
        let god = GodObject::new(radius, set.triangles().len());
        Some(ContactIndex {
            topology_id: h.topology_id,
            set,
            god,
            frame_sequence: None,
        })
    }
}

/// The thread that builds contact indices for the RT thread, and frees the ones it retires.
struct IndexFeed {
    rx: rtrb::Consumer<Box<ContactIndex>>,
    back: rtrb::Producer<Box<ContactIndex>>,
    stop: Arc<AtomicBool>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl IndexFeed {
    fn start(names: &ServiceNames, radius: f64) -> Result<IndexFeed> {
        let (mut tx, rx) = rtrb::RingBuffer::<Box<ContactIndex>>::new(2);
        let (back, mut retired) = rtrb::RingBuffer::<Box<ContactIndex>>::new(8);
        let stop = Arc::new(AtomicBool::new(false));
        let names = names.clone();
        let flag = stop.clone();
        let (ready_tx, ready_rx) = std::sync::mpsc::channel::<()>();
        let thread = std::thread::Builder::new()
            .name("lop-haptic-index".into())
            .spawn(move || {
                let mut run = || -> Result<()> {
                    let node = services::node("lopd-haptic-index")?;
                    let topologies = services::topology_service(&node, &names, Role::Owner)?
                        .subscriber_builder()
                        .create()
                        .context("topology subscriber")?;
                    let _ = ready_tx.send(());
                    while !flag.load(Ordering::Relaxed) {
                        while let Ok(Some(t)) = topologies.receive() {
                            if let Some(ix) =
                                ContactIndex::build(t.user_header(), t.payload(), radius)
                            {
                                // A full ring means the RT thread has not taken the previous
                                // index yet; it takes this one on a later tick.
                                let _ = tx.push(Box::new(ix));
                            }
                        }
                        while let Ok(old) = retired.pop() {
                            drop(old);
                        }
                        std::thread::sleep(Duration::from_millis(2));
                    }
                    Ok(())
                };
                if let Err(e) = run() {
                    tracing::warn!("haptic contact index thread stopped: {e:#}");
                }
            })?;
        // Subscribed before the loop starts, so a topology published right after is not missed
        // (the deformation process also re-offers its topology to late subscribers).
        let _ = ready_rx.recv_timeout(Duration::from_secs(2));
        Ok(IndexFeed {
            rx,
            back,
            stop,
            thread: Some(thread),
        })
    }
}

impl Drop for IndexFeed {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// Preallocated latency histograms: one window (reset at each telemetry sample) and one total
/// (reset once, after warm-up) per quantity.
struct Stats {
    window: [Histogram<u64>; 4],
    total: [Histogram<u64>; 4],
}

const JITTER: usize = 0;
const COMPUTE: usize = 1;
const FRAME_AGE: usize = 2;
/// The frame age of ticks that rendered a contact (the tool pressing or holding a body): how
/// old the surface under the hand was.
const FRAME_AGE_CONTACT: usize = 3;

impl Stats {
    fn new() -> Result<Stats> {
        let h = || Histogram::<u64>::new_with_bounds(1, 10_000_000_000, 2);
        Ok(Stats {
            window: [h()?, h()?, h()?, h()?],
            total: [h()?, h()?, h()?, h()?],
        })
    }
    #[inline]
    fn record(&mut self, which: usize, v: u64) {
        let v = v.max(1);
        // saturating_record never allocates and never fails.
        self.window[which].saturating_record(v);
        self.total[which].saturating_record(v);
    }
}

fn percentiles(h: &Histogram<u64>) -> Percentiles {
    if h.is_empty() {
        return Percentiles::default();
    }
    Percentiles {
        count: h.len(),
        p50: h.value_at_quantile(0.5),
        p99: h.value_at_quantile(0.99),
        p999: h.value_at_quantile(0.999),
        max: h.max(),
    }
}

/// The haptic loop's state. Built on the RT thread (iceoryx2 ports are not `Send`).
pub struct HapticLoop {
    settings: HapticSettings,
    safety: ForceSafety,
    passivity: PassivityController,
    _node: Node<ipc::Service>,
    frames: services::FrameSubscriber,
    index_feed: IndexFeed,
    index: Option<Box<ContactIndex>>,
    _board: ToolBoard,
    _writer: iceoryx2::port::writer::Writer<ipc::Service, u32>,
    tool_entry: EntryHandleMut<ipc::Service, u32, ToolState>,
    frame: Option<Sample<ipc::Service, [NodeSample], FrameHeader>>,
    tool_ring: rtrb::Producer<ToolState>,
    telemetry_ring: rtrb::Producer<HapticTelemetry>,
    stats: Stats,
    tick: u64,
    overruns: u64,
    stale_ticks: u64,
    device_faults: u64,
    ring_drops: u64,
    rt_flags: u32,
    pinned_core: i32,
    window_start_ns: u64,
    window_start_tick: u64,
    telemetry_every: u64,
    warmup_ticks: u64,
}

/// What a tick hands back to the caller (for the pacing loop and tests).
#[derive(Debug, Clone, Copy)]
pub struct TickOutcome {
    /// The state published this tick.
    pub state: ToolState,
    /// A device error that makes continuing unsafe.
    pub fatal: Option<lop_drivers::DeviceError>,
}

impl HapticLoop {
    /// Creates the ports and buffers. Call on the thread that will run the ticks.
    pub fn new(
        names: &ServiceNames,
        settings: HapticSettings,
        tool_ring: rtrb::Producer<ToolState>,
        telemetry_ring: rtrb::Producer<HapticTelemetry>,
    ) -> Result<HapticLoop> {
        let node = services::node("lopd-haptic-rt")?;
        services::cleanup_dead_nodes(&node);
        let frame_service = services::frame_service(&node, names, Role::Owner)?;
        let frames = frame_service
            .subscriber_builder()
            .buffer_size(2)
            .create()
            .context("frame subscriber")?;
        let index_feed = IndexFeed::start(names, settings.tool.radius)?;
        let board = services::tool_board_owner(&node, names)?;
        let writer = board
            .writer_builder()
            .create()
            .context("tool blackboard writer (is another lopd haptic running with this prefix?)")?;
        let tool_entry = writer
            .entry::<ToolState>(&services::TOOL_LATEST_KEY)
            .context("tool blackboard entry")?;
        let rate = settings.rate_hz.round() as u64;
        Ok(HapticLoop {
            // The device's continuous force, as a mean over about 2 s.
            safety: ForceSafety::new(settings.max_force, settings.max_step, settings.ramp_ticks)
                .with_continuous(
                    settings.limits.max_continuous_force_n,
                    (2.0 * settings.rate_hz) as u32,
                ),
            passivity: PassivityController::new(settings.passivity_max_damping),
            settings,
            _node: node,
            frames,
            index_feed,
            index: None,
            _board: board,
            _writer: writer,
            tool_entry,
            frame: None,
            tool_ring,
            telemetry_ring,
            stats: Stats::new()?,
            tick: 0,
            overruns: 0,
            stale_ticks: 0,
            device_faults: 0,
            ring_drops: 0,
            rt_flags: 0,
            pinned_core: -1,
            window_start_ns: rt::now_ns(),
            window_start_tick: 0,
            telemetry_every: (rate / 4).max(1),
            warmup_ticks: rate,
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
    /// loop renders no contact).
    pub fn contact_ready(&self) -> bool {
        self.index.is_some()
    }

    /// Ticks run so far.
    pub fn ticks(&self) -> u64 {
        self.tick
    }

    /// Tool states dropped because the publisher thread fell behind.
    pub fn ring_drops(&self) -> u64 {
        self.ring_drops
    }

    /// One haptic tick. `wake_ns` is when the loop woke, `deadline_ns` when it should have.
    /// Allocation-free.
    pub fn tick(
        &mut self,
        device: &mut dyn HapticDevice,
        wake_ns: u64,
        deadline_ns: u64,
    ) -> TickOutcome {
        let t = self.tick as f64 / self.settings.rate_hz;
        let mut state = ToolState {
            contract_version: CONTRACT_VERSION,
            sequence: self.tick,
            stamp_ns: wake_ns,
            tool_radius: self.settings.tool.radius,
            contact_body: -1,
            ..Default::default()
        };
        let mut fatal = None;

        // 1. Read and validate the device.
        let mut healthy = true;
        let sample = match device.read(t) {
            Ok(s) if s.is_finite() && self.in_workspace(s.position_mm) => Some(s),
            Ok(_) => None,
            Err(e) => {
                if !e.is_recoverable() {
                    fatal = Some(e);
                }
                None
            }
        };
        if sample.is_none() {
            healthy = false;
            self.device_faults += 1;
            state.flags |= TOOL_FLAG_DEVICE_ERROR;
        }

        // 2. Take the newest contact index and frame. Receiving never allocates; a retired
        // index goes back to its thread to be freed.
        while let Ok(ix) = self.index_feed.rx.pop() {
            if let Some(old) = self.index.replace(ix) {
                let _ = self.index_feed.back.push(old);
            }
        }
        while let Ok(Some(s)) = self.frames.receive() {
            self.frame = Some(s);
        }
        let frame_age = match &self.frame {
            Some(f) => wake_ns.saturating_sub(f.user_header().publish_ns),
            None => u64::MAX,
        };
        if frame_age > self.settings.stale_ns {
            healthy = false;
            self.stale_ticks += 1;
            state.flags |= TOOL_FLAG_STALE_FRAME;
        } else {
            self.stats.record(FRAME_AGE, frame_age);
        }
        let tip = sample.map(|s| self.settings.workspace.device_to_scene(s.position_mm));
        let surface_ready = self.refresh_surface(tip);

        // 3. God-object and force against the newest surface.
        let mut desired = [0.0; 3];
        if let (Some(s), Some(p)) = (sample, tip) {
            state.device_position = p;
            state.proxy_position = p;
            state.buttons = s.buttons;
            if let (true, Some(ix)) = (surface_ready, self.index.as_deref_mut()) {
                let grab = s.pressed(lop_drivers::BUTTON_GRAB);
                let g = ix.god.update(&mut ix.set, p, grab);
                state.proxy_position = g.proxy;
                state.topology_id = ix.topology_id;
                if let Some(a) = g.anchor {
                    let k = self
                        .settings
                        .body_stiffness
                        .get(a.body)
                        .copied()
                        .unwrap_or(self.settings.tool.stiffness);
                    let scale = 1e-3 * self.settings.workspace.scale;
                    let v = self
                        .settings
                        .workspace
                        .device_dir_to_scene(s.velocity_mm_s)
                        .map(|c| c * scale);
                    // Between frames the frame's local model of the patch makes the force
                    // follow the hand; without one, the force law on the god-object's gap.
                    let local = self
                        .frame
                        .as_ref()
                        .filter(|_| self.settings.local_model)
                        .and_then(|f| frame_local(f.user_header()));
                    let elapsed = self.frame.as_ref().map_or(0.0, |f| {
                        wake_ns.saturating_sub(f.user_header().tool_read_ns) as f64 * 1e-9
                    });
                    let (f, used) = contact_force(
                        &g,
                        local.as_ref().map(|(b, m)| (*b, m)),
                        elapsed,
                        p,
                        self.settings.tool.law,
                        k,
                        self.settings.damping,
                        v,
                    );
                    // The proxy stays the god-object's (the deformation process gathers the
                    // patch around it, as offline).
                    desired = f;
                    if used {
                        state.flags |= TOOL_FLAG_LOCAL_MODEL;
                    }
                    state.tool_stiffness = k;
                    state.contact_body = a.body as i32;
                    state.contact_triangle = a.triangle as u32;
                    state.contact_barycentric = a.bary;
                    if g.depth > 0.0 {
                        state.flags |= TOOL_FLAG_CONTACT;
                    }
                    if g.grabbing {
                        state.flags |= TOOL_FLAG_GRAB;
                    }
                    if s.pressed(lop_drivers::BUTTON_HEAT) {
                        state.flags |= TOOL_FLAG_HEAT;
                    }
                }
            }
        }

        let fresh = frame_age <= self.settings.stale_ns;
        if fresh && state.flags & (TOOL_FLAG_CONTACT | TOOL_FLAG_GRAB) != 0 {
            self.stats.record(FRAME_AGE_CONTACT, frame_age);
        }

        // 4. Passivity at the device port, then safety: finite, clamped, ramped, rate-limited.
        // Then the device.
        match (sample, tip) {
            (Some(_), Some(p)) if healthy => {
                let scale = self.settings.workspace.scale;
                let port = p.map(|c| c / scale);
                desired = self
                    .passivity
                    .condition(port, desired, 1.0 / self.settings.rate_hz);
            }
            _ => self.passivity.reset(),
        }
        // The force may follow the tool spring as fast as the device moves (see `safety`).
        let k = state.tool_stiffness.max(self.settings.tool.stiffness);
        let force = self.safety.condition_moving(desired, healthy, tip, k);
        self.passivity.rendered(force);
        if !healthy {
            state.flags |= TOOL_FLAG_RAMPING;
        }
        state.force = force;
        if let Err(e) = device.write_force(self.settings.workspace.scene_dir_to_device(force)) {
            self.device_faults += 1;
            state.flags |= TOOL_FLAG_DEVICE_ERROR;
            if !e.is_recoverable() {
                fatal = Some(e);
            }
        }

        // 5. Publish: blackboard for the deformation process, ring for viewers.
        self.tool_entry.update_with_copy(state);
        if self.tool_ring.push(state).is_err() {
            self.ring_drops += 1;
        }

        // 6. Timing.
        let done = rt::now_ns();
        self.stats
            .record(JITTER, wake_ns.saturating_sub(deadline_ns));
        self.stats.record(COMPUTE, done.saturating_sub(wake_ns));
        self.tick += 1;
        if self.tick == self.warmup_ticks {
            self.stats.total.iter_mut().for_each(|h| h.reset());
        }
        if self.tick.is_multiple_of(self.telemetry_every) {
            self.emit_telemetry(done, force);
        }
        TickOutcome { state, fatal }
    }

    fn in_workspace(&self, mm: [f64; 3]) -> bool {
        let l = &self.settings.limits;
        (0..3).all(|k| {
            mm[k] >= l.workspace_min_mm[k] - WORKSPACE_SLACK_MM
                && mm[k] <= l.workspace_max_mm[k] + WORKSPACE_SLACK_MM
        })
    }

    /// Brings the contact index up to date with the newest frame for the bodies the tool can
    /// reach this tick: their positions are copied in (a few µs for an organ, so only bodies
    /// whose frame bounds are within [`REACH`] of the device or the god-object are, and only
    /// once per frame), the others are left out of the queries until they come within reach.
    /// The god-object is carried along with the tissue. False without a matching index and
    /// frame: then nothing is touched (and a stale frame ramps the force down anyway).
    fn refresh_surface(&mut self, device: Option<[f64; 3]>) -> bool {
        let (Some(ix), Some(frame)) = (self.index.as_deref_mut(), self.frame.as_ref()) else {
            return false;
        };
        let fh = frame.user_header();
        let nodes = frame.payload();
        if fh.topology_id != ix.topology_id
            || fh.contract_version != CONTRACT_VERSION
            || nodes.len() != ix.set.node_count()
        {
            return false;
        }
        let first = ix.frame_sequence.is_none();
        let new_frame = ix.frame_sequence != Some(fh.sequence);
        ix.frame_sequence = Some(fh.sequence);
        let proxy = ix.god.proxy();
        let points = [device.unwrap_or(proxy), proxy];
        let count = (fh.body_count as usize).min(MAX_BODIES);
        let bounds = |b: usize| match fh.bodies.get(b) {
            Some(bf) if b < count => (bf.aabb_min.map(|c| c as f64), bf.aabb_max.map(|c| c as f64)),
            _ => ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]),
        };
        // A body that did not step since the last frame keeps its positions: at 1 kHz frames
        // only the touched body changes in most, and its neighbours are not copied again.
        let stamp = |b: usize| match fh.bodies.get(b) {
            Some(bf) if b < count => body_stamp(bf),
            _ => fh.sequence,
        };
        let moved = ix
            .set
            .refresh_reachable(stamp, &points, REACH, bounds, |i| {
                nodes[i].position.map(|c| c as f64)
            });
        if first {
            ix.god.reset();
        } else if new_frame || moved {
            ix.god.follow_surface(&ix.set);
            // The press balanced as a contact patch: rest the proxy where the tissue put it.
            let b = fh.contact_body as usize;
            if new_frame && fh.contact_body != NO_CONTACT && b < count {
                ix.god.rest_at(&ix.set, b, fh.contact_proxy);
            }
        }
        true
    }

    fn emit_telemetry(&mut self, now: u64, force: [f64; 3]) {
        let ticks = self.tick - self.window_start_tick;
        let secs = now.saturating_sub(self.window_start_ns) as f64 * 1e-9;
        let s = &self.stats;
        let telemetry = HapticTelemetry {
            contract_version: CONTRACT_VERSION,
            rt_flags: self.rt_flags,
            stamp_ns: now,
            ticks: self.tick,
            overruns: self.overruns,
            stale_ticks: self.stale_ticks,
            device_faults: self.device_faults,
            rate_hz: if secs > 0.0 { ticks as f64 / secs } else { 0.0 },
            force_norm: (force[0] * force[0] + force[1] * force[1] + force[2] * force[2]).sqrt(),
            window_jitter: percentiles(&s.window[JITTER]),
            window_compute: percentiles(&s.window[COMPUTE]),
            window_frame_age: percentiles(&s.window[FRAME_AGE]),
            total_jitter: percentiles(&s.total[JITTER]),
            total_compute: percentiles(&s.total[COMPUTE]),
            total_frame_age: percentiles(&s.total[FRAME_AGE]),
            pinned_core: self.pinned_core,
            _pad: 0,
            window_frame_age_contact: percentiles(&s.window[FRAME_AGE_CONTACT]),
            total_frame_age_contact: percentiles(&s.total[FRAME_AGE_CONTACT]),
        };
        self.stats.window.iter_mut().for_each(|h| h.reset());
        self.window_start_ns = now;
        self.window_start_tick = self.tick;
        let _ = self.telemetry_ring.push(telemetry);
    }
}

/// Writes zero force when dropped, so a panic on the RT thread still leaves the device safe.
struct ZeroForceGuard<'a>(&'a mut dyn HapticDevice);

impl Drop for ZeroForceGuard<'_> {
    fn drop(&mut self) {
        let _ = self.0.write_force([0.0; 3]);
        self.0.stop();
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

/// Runs the loop on the calling thread until `stop` is set, `max_ticks` is reached or the device
/// fails. The device is zeroed and stopped before this returns, and also if it panics.
#[allow(clippy::too_many_arguments)] // each is a distinct input of the loop's start-up
pub fn run_loop(
    names: &ServiceNames,
    settings: HapticSettings,
    device: &mut dyn HapticDevice,
    rt_request: &RtRequest,
    stop: &AtomicBool,
    max_ticks: Option<u64>,
    tool_ring: rtrb::Producer<ToolState>,
    telemetry_ring: rtrb::Producer<HapticTelemetry>,
) -> Result<HapticSummary> {
    let guard = ZeroForceGuard(device);
    let spin_ns = settings.spin_ns;
    let period = settings.period_ns();
    let mut hl = HapticLoop::new(names, settings, tool_ring, telemetry_ring)?;

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
        let outcome = hl.tick(&mut *guard.0, wake, deadline);
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
    mut telemetry_ring: rtrb::Consumer<HapticTelemetry>,
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
        while let Ok(t) = telemetry_ring.pop() {
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

/// Creates the two rings between the RT thread and the publisher thread.
pub fn rings() -> (Ring<ToolState>, Ring<HapticTelemetry>) {
    (rtrb::RingBuffer::new(TOOL_RING), rtrb::RingBuffer::new(16))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tool_stiffness_is_clamped_to_what_the_device_renders() {
        let path = lop_config::resolve_scene("organs").unwrap();
        let scene = lop_config::load_scene(&path).unwrap();
        let mut limits = lop_drivers::mock::MockDevice::omni_limits();
        // The shipped 300 N/m at workspace scale 2 is 0.6 N/mm at the stylus.
        let s = HapticSettings::new(&DaemonConfig::default(), &scene, limits);
        assert_eq!(s.tool.stiffness, 300.0);
        assert!(s.body_stiffness.iter().all(|&k| k == 300.0));
        // A device that renders only 0.3 N/mm: 0.3 / (1e-3 · 2) = 150 N/m.
        limits.max_stiffness_n_per_mm = 0.3;
        let s = HapticSettings::new(&DaemonConfig::default(), &scene, limits);
        assert!((s.tool.stiffness - 150.0).abs() < 1e-9);
        assert!(s.body_stiffness.iter().all(|&k| (k - 150.0).abs() < 1e-9));
    }
}
