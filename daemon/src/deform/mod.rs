//! `lopd deform`: the deformation process, as a task ([`DeformLoop`]: `new` → `tick`). `new`
//! loads the scene (`lop_scene`), publishes its topology once and opens the ports; each `tick`
//! waits for its period, takes the newest state of every tool, serves control requests, runs
//! one round of the world (`lop_sim::world::World::round`: collision, the bodies due at the wall
//! clock's simulated time, each on its own `dt`, heat) and publishes a frame.
//!
//! Tool coupling (force coupling, DESIGN's choice for the tissue response): the newest state of
//! each of the scene's tools comes from its entry of the haptic side's blackboard. Where a
//! tool's god-object touches or holds a body, that body receives the opposite of that hand's
//! force at the god-object's material point — the spring between god-object and device,
//! integrated implicitly inside the body's step (`lop_sim::model::ToolAnchor`), so the tissue
//! receives the force the hand feels (up to the multirate delay: the haptic loop renders
//! against the last frame) and a stiff tool on light tissue stays stable. Tissue pressed by two
//! tools is solved as one contact patch, so each hand feels the other's press through it; each
//! tool's contact goes to its own entry of the frame (`FrameHeader::contacts`). The grab button
//! turns a tool's contact into a hold that also pulls.
//!
//! Heat (thesis §5.3): with a tool's heat button pressed while touching, the touched point
//! receives that tool's `heat_power`; the heat model (`lop_sim::heat`, one implicit step per
//! `[heat] dt` of simulated time) diffuses it, loses it to the air and passes it to organs that
//! touch. Frames carry every node's temperature and its burned flag.

use std::time::Duration;

use anyhow::{Context, Result};
use iceoryx2::port::reader::EntryHandle;
use iceoryx2::port::update_connections::UpdateConnections;
use iceoryx2::prelude::*;
use lop_config::{DaemonConfig, Scene};
use lop_ipc::services::{self, Role, ToolBoard};
use lop_ipc::*;
use lop_scene::{DeviceClamp, LoadedScene, ToolLaws, Topology};
use lop_sim::haptic::LocalModel;
use lop_sim::model::{Model, ModelKind, ToolAnchor};
use lop_sim::world::pace::RealTimeMeter;
use lop_sim::world::{Coupling, World};

mod pace;

use pace::{pace_bodies, set_period, warn_behind, Paced};

use crate::rt;
use crate::signals;
use lop_scene::{Rounds, TickTool};

/// A tool state older than this is ignored (the haptic process is gone or restarting, or that
/// tool's device stopped), ns; each tool's on its own.
const TOOL_STALE_NS: u64 = 100_000_000;
/// When the newest of the tools' states is older than this, the deformation process closes the
/// tool blackboard, ns. A haptic process killed while writing leaves the blackboard's entries
/// marked as held (the iceoryx2 0.10 blackboard does not release a dead writer's entry
/// handle), so a restarted one cannot write them while the service lives; the service goes
/// once its last reader closes it, and the restarted haptic process then creates it again
/// (`haptic::HapticLoop::new` waits for that). One haptic process writes every tool's entry,
/// so while any tool's state is younger the process lives and the board stays open: closing it
/// then would only cut the live tools off the tissue until it is open again. A tool whose entry
/// was never written (the haptic side drives fewer devices than the scene has tools) neither
/// holds the board open nor closes it. Longer than [`TOOL_STALE_NS`], so that a late tick never
/// closes it, and shorter than the supervisor's first restart delay (0.2 s).
const TOOL_DROP_NS: u64 = 150_000_000;
/// After closing a stale tool blackboard, the deformation process opens it again this much
/// later, ns: a haptic process stopped (SIGSTOP) and continued is coupled to the tissue again
/// within it (with 0.5 s, the tissue relaxed away from the tool meanwhile and the force rose to
/// the 3 N clamp after a 1 s stop, against 1.08 N while the blackboard stayed open). Reopening
/// the dead process's blackboard between a restarted one's attempts holds it only for a tick.
const TOOL_REOPEN_NS: u64 = 50_000_000;
/// Largest nodal speed under which a body counts as at rest, m/s.
const REST_SPEED: f64 = 1e-3;
/// Wall time over which the real-time factor is measured, s.
const REAL_TIME_WINDOW: f64 = 1.0;

/// Options of one deformation run.
pub struct DeformOptions {
    /// The scene.
    pub scene: Scene,
    /// Service names.
    pub names: ServiceNames,
    /// Daemon configuration.
    pub config: DaemonConfig,
    /// Stop after this long.
    pub duration: Option<Duration>,
}

/// The tool blackboard, open for reading.
struct ToolInput {
    _board: ToolBoard,
    _reader: iceoryx2::port::reader::Reader<ipc::Service, u32>,
    /// Per tool of the scene, in its order: the entry of its newest state.
    entries: Vec<EntryHandle<ipc::Service, u32, ToolState>>,
}

/// Opens the tool blackboard and the entries of the first `tools` tools; `None` while the
/// haptic side has not made it.
fn open_tool_input(
    node: &Node<ipc::Service>,
    names: &ServiceNames,
    tools: usize,
) -> Option<ToolInput> {
    let board = services::tool_board_reader(node, names).ok()?;
    let reader = board.reader_builder().create().ok()?;
    let entries = (0..tools)
        .map(|t| {
            reader
                .entry::<ToolState>(&services::tool_latest_key(t))
                .ok()
        })
        .collect::<Option<Vec<_>>>()?;
    Some(ToolInput {
        _board: board,
        _reader: reader,
        entries,
    })
}

/// What one read of the tool blackboard found.
#[derive(Debug, Clone, Copy, PartialEq)]
struct ToolRead {
    /// Per tool (by index): its state, if younger than [`TOOL_STALE_NS`]; `None`: stale or
    /// never written.
    fresh: [Option<ToolState>; MAX_TOOLS],
    /// The newest of the states is older than [`TOOL_DROP_NS`]: close the blackboard.
    close: bool,
}

/// Judges the tools' `states` (by tool index, at most [`MAX_TOOLS`]) read at `read_ns`: each
/// is fresh on its own ([`TOOL_STALE_NS`]), and the blackboard is closed only when every
/// state ever written is older than [`TOOL_DROP_NS`] (see there why).
fn judge_tools(states: &[ToolState], read_ns: u64) -> ToolRead {
    let age = |s: &ToolState| read_ns.saturating_sub(s.stamp_ns);
    let mut fresh = [None; MAX_TOOLS];
    for (slot, s) in fresh.iter_mut().zip(states) {
        if s.stamp_ns > 0 && age(s) < TOOL_STALE_NS {
            *slot = Some(*s);
        }
    }
    let newest = states.iter().max_by_key(|s| s.stamp_ns);
    ToolRead {
        fresh,
        close: newest.is_some_and(|s| s.stamp_ns > 0 && age(s) > TOOL_DROP_NS),
    }
}

/// A tool's contact patch of a round, as a frame carries it: the body, where the patch
/// balanced the tool (m), and its local model for the haptic loop.
type PatchContact = (u32, [f64; 3], Option<LocalModel>);

/// A topology id that differs between loads and processes; never 0.
fn new_topology_id() -> u64 {
    let t = rt::now_ns();
    let pid = std::process::id() as u64;
    (t ^ (pid << 48)).max(1)
}

/// The deformation process as a task: [`DeformLoop::new`] loads the scene and opens every
/// port, [`DeformLoop::tick`] runs one paced iteration (tool state → control → one round of
/// the world → frame).
pub struct DeformLoop {
    scene: Scene,
    world: World,
    /// The rounds, with each tool's laws from the scene (no device clamp): each round takes
    /// the haptic loop's stiffness against the touched body from that tool's state, so the
    /// tissue gets the hand's spring.
    rounds: Rounds,
    /// The scene's tools (at most [`MAX_TOOLS`]): the blackboard entries read, the frames'
    /// `tool_count`.
    tools: usize,
    topology: TopologyHeader,
    /// The topology as published (the header's indices), to build the next one from when a
    /// cut lands.
    published: Topology,
    node_offsets: Vec<usize>,
    node_count: usize,
    node: Node<ipc::Service>,
    names: ServiceNames,
    topo_pub: iceoryx2::port::publisher::Publisher<ipc::Service, [u32], TopologyHeader>,
    frame_pub: iceoryx2::port::publisher::Publisher<ipc::Service, [NodeSample], FrameHeader>,
    /// Notified after each frame: the haptic process's frame thread sleeps on it.
    frame_ready: Option<iceoryx2::port::notifier::Notifier<ipc::Service>>,
    tool_input: Option<ToolInput>,
    control: crate::control::ControlServer,
    last_connection_update: u64,
    /// When to try opening the tool blackboard next (while it is not open), ns.
    tool_retry_at: u64,
    period: u64,
    start: u64,
    deadline: u64,
    sequence: u64,
    /// Duration of each body's last step, ns.
    step_ns: Vec<u32>,
    lagged: u64,
    /// Per body with an FEM model: the period its cost allows (`lop_sim::world::pace`).
    paces: Vec<Option<Paced>>,
    /// Per body: simulated over wall time.
    meters: Vec<RealTimeMeter>,
    /// Per body: whether it ran FEM in the last round.
    ran_fem: Vec<bool>,
    /// Per body: whether it was reported falling behind even at its longest period.
    warned_behind: Vec<bool>,
}

impl DeformLoop {
    /// Pins the process, loads the scene, publishes its topology and opens the frame
    /// publisher, the tool input and the control service.
    pub fn new(opts: &DeformOptions) -> Result<DeformLoop> {
        if let Some(core) = opts.config.deform.core {
            if let Err(e) = rt::pin_to_core(core) {
                tracing::warn!("deformation process not pinned: {e}");
            }
        }
        let LoadedScene {
            scene,
            mut world,
            topology,
        } = lop_scene::load(opts.scene.clone())?;
        // `[deform] threads` (validated against the machine's cores by lop-config).
        world.set_threads(opts.config.deform.threads);
        let tools = scene.tools.len().min(MAX_TOOLS);
        let laws: Vec<ToolLaws> = (0..tools)
            .map(|t| ToolLaws::of_tool(&scene, t, DeviceClamp::NONE))
            .collect();
        let mut header = wire_topology(&scene, &topology)?;
        let names = opts.names.clone();
        let node = services::node("lopd-deform")?;
        let cleaned = services::cleanup_dead_nodes(&node);
        if cleaned > 0 {
            tracing::info!("cleaned {cleaned} dead iceoryx2 node(s) left by a crashed process");
        }

        // Topology, with history so late subscribers get it; again after each cut, with a new
        // id. A cut only removes tetrahedra and render surfaces, and a tetrahedron adds at most
        // its 4 faces (12 indices) to a surface: room for 16 words a tetrahedron plus the
        // render surfaces holds every topology a cut can leave.
        header.topology_id = new_topology_id();
        let render_words =
            topology.indices.len() - 3 * topology.triangle_count - 4 * topology.tet_count;
        let topo_room = topology
            .indices
            .len()
            .max(16 * topology.tet_count + render_words);
        let topo_pub = services::topology_service(&node, &names, Role::Owner)?
            .publisher_builder()
            .initial_max_slice_len(topo_room)
            .create()
            .context("topology publisher")?;
        send_topology(&topo_pub, &header, &topology.indices)?;

        let node_count = topology.node_count;
        let frame_pub = services::frame_service(&node, &names, Role::Owner)?
            .publisher_builder()
            .initial_max_slice_len(node_count)
            .max_loaned_samples(2)
            .create()
            .context("frame publisher")?;
        // Without it the haptic process still polls for frames, a millisecond apart.
        let frame_ready = match services::frame_ready_service(&node, &names)
            .map_err(anyhow::Error::from)
            .and_then(|s| Ok(s.notifier_builder().create()?))
        {
            Ok(n) => Some(n),
            Err(e) => {
                tracing::warn!("frame-ready event unavailable ({e:#}): the haptic loop polls");
                None
            }
        };

        tracing::info!(
            "scene {:?}: {} bodies, {} tool(s), {} nodes, {} surface triangles; topology {:#x}",
            scene.name,
            world.bodies.len(),
            tools,
            node_count,
            header.triangle_count,
            header.topology_id
        );
        for b in &world.bodies {
            tracing::info!(
                "  {}: {} nodes, {:?}, dt {} s in {} sub-steps",
                b.name,
                b.mesh.nodes.len(),
                b.model.kind(),
                b.model.dt(),
                b.model.substeps()
            );
        }

        let paces = pace_bodies(
            &mut world,
            &scene,
            &laws[0],
            opts.config.deform.max_period_ms,
            opts.config.deform.threads,
        );
        let tool_input = open_tool_input(&node, &names, tools);
        let control = crate::control::ControlServer::new(&node, &names, &scene, &world);
        let now = rt::now_ns();
        let period = (1e9 / scene.rates.deform_max_hz).round() as u64;
        Ok(DeformLoop {
            rounds: Rounds::live(laws[0].clone(), period).with_tools(laws),
            tools,
            step_ns: vec![0u32; world.bodies.len()],
            paces,
            meters: vec![RealTimeMeter::new(REAL_TIME_WINDOW); world.bodies.len()],
            ran_fem: vec![false; world.bodies.len()],
            warned_behind: vec![false; world.bodies.len()],
            node_offsets: topology.node_offsets(),
            scene,
            world,
            topology: header,
            published: topology,
            node_count,
            node,
            names,
            topo_pub,
            frame_pub,
            frame_ready,
            tool_input,
            control,
            last_connection_update: now,
            tool_retry_at: now + 500_000_000,
            period,
            start: now,
            deadline: now,
            sequence: 0,
            lagged: 0,
        })
    }

    /// The scene it runs.
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// When the loop started, ns (`CLOCK_MONOTONIC`).
    pub fn start_ns(&self) -> u64 {
        self.start
    }

    /// Frames published so far.
    pub fn frames(&self) -> u64 {
        self.sequence
    }

    /// One iteration: waits for the next period, takes the newest state of every tool, serves
    /// control requests, runs one round of the world up to the wall clock's simulated time and
    /// publishes a frame if anything advanced.
    pub fn tick(&mut self) {
        self.deadline += self.period;
        // A body still behind the wall clock after a round (its steps took the round's budget)
        // gets the next round at once, each round's frame published (`Rounds::live`).
        let catching_up = self.world.last_round().bodies.iter().any(|b| b.due);
        let now = if catching_up {
            rt::now_ns()
        } else {
            rt::sleep_until(self.deadline, 0)
        };
        if now > self.deadline + self.period {
            // Fell behind: do not burst. The next deadline stays on the grid of whole periods
            // from the start, which the bodies' clocks keep to (`World::round`).
            self.deadline += (now - self.deadline) / self.period * self.period;
        }

        // Late subscribers get the topology from the history when the publisher notices them.
        if now - self.last_connection_update > 50_000_000 {
            let _ = self.topo_pub.update_connections();
            self.last_connection_update = now;
        }
        // The newest state of every tool, if the haptic process is up.
        if self.tool_input.is_none() && now > self.tool_retry_at {
            self.tool_input = open_tool_input(&self.node, &self.names, self.tools);
            self.tool_retry_at = now + 500_000_000;
        }
        let mut tool_read = 0;
        let mut fresh = [None; MAX_TOOLS];
        if let Some(input) = &self.tool_input {
            let mut states = [ToolState::default(); MAX_TOOLS];
            for (s, e) in states.iter_mut().zip(&input.entries) {
                *s = *e.get();
            }
            // One read time for every tool: they are read back to back.
            tool_read = rt::now_ns();
            let read = judge_tools(&states[..input.entries.len()], tool_read);
            fresh = read.fresh;
            if read.close {
                // The haptic process is gone (or stopped): let go of its blackboard so that a
                // restarted one can make it anew (`TOOL_DROP_NS`), and open it again soon: a
                // stopped one that goes on presses the tissue again within that time.
                self.tool_input = None;
                self.tool_retry_at = now + TOOL_REOPEN_NS;
            }
        }
        // The header's tool stamp is the first tool's (`FrameHeader::tool_stamp_ns`).
        let tool_stamp = fresh[0].map_or(0, |s| s.stamp_ns);
        // One slot per tool of the scene, by its index: a tool without a fresh state is absent
        // (`None`: it acts on no body this round) rather than left out, so the tools after it
        // keep their index, which the world reports each tool's contact by
        // (`Body::contacts`) and the frame carries it under (`FrameHeader::contacts`). Not a
        // tool at its last position without contact: its sphere near a body would still hold
        // that body at its precise level of detail while its device is gone.
        let mut tools = [None; MAX_TOOLS];
        for (slot, s) in tools.iter_mut().zip(&fresh) {
            *slot = s.map(|s| TickTool {
                center: s.device_position,
                coupling: Coupling::GodObject(god_object_hold(&s, &self.topology, &self.world)),
                heat: s.flags & TOOL_FLAG_HEAT != 0,
                cut: s.flags & TOOL_FLAG_CUT != 0,
                stiffness: Some(s.tool_stiffness),
            });
        }
        let tools = &tools[..self.tools];

        let sim_now = (now - self.start) as f64 * 1e-9;
        // Control requests (PREFIX/control) are served here, between rounds; paused: no
        // stepping, frames keep coming with frozen positions.
        let paused = self.control.poll(&mut self.world, sim_now);
        self.rounds
            .advance_tools(&mut self.world, sim_now, tools, &[], paused, rt::now_ns);
        let report = self.world.last_round();
        for (i, r) in report.bodies.iter().enumerate() {
            if r.steps > 0 {
                self.step_ns[i] = r.last_step_ns.min(u32::MAX as u64) as u32;
            }
            if paused {
                self.meters[i].restart(sim_now);
            } else {
                // The simulated time it dropped as lag (`BodyRound::dropped`).
                self.meters[i].record(sim_now, r.dropped);
            }
            if let Some(cause) = r.blow_up {
                tracing::warn!(
                    "body {:?} blew up ({cause:?}); reset to rest",
                    self.world.bodies[i].name
                );
            }
            if r.lagged() {
                self.lagged += 1;
                if self.lagged.is_power_of_two() {
                    tracing::warn!(
                        "deformation lags the wall clock ({} times so far)",
                        self.lagged
                    );
                }
            }
        }
        if let Some(e) = &report.heat_error {
            tracing::warn!("heat model stopped: {e}");
        }
        if !report.cuts.is_empty() {
            self.publish_cut_topology();
        }
        let report = self.world.last_round();
        let (stepped, world_step_ns) = (report.stepped(), report.total_ns);
        self.follow_cost();
        if !(paused || stepped) {
            return;
        }
        for b in self.world.bodies.iter_mut() {
            log_switch(b);
        }
        // Each tool's press's contact patch, balanced where its haptic loop should rest its
        // proxy. With it, the local model that loop renders between frames.
        let mut contacts: [Option<PatchContact>; MAX_TOOLS] = [None; MAX_TOOLS];
        for (k, (slot, t)) in contacts.iter_mut().zip(tools).enumerate() {
            *slot = t.as_ref().and_then(|t| {
                let (b, p) = self.world.contact_proxy(k, t.coupling)?;
                let local = self.world.contact_local(k, t.coupling).map(|(_, m)| m);
                Some((b as u32, p, local))
            });
        }
        self.publish(sim_now, tool_stamp, tool_read, world_step_ns, &contacts);
    }

    /// Publishes the topology the cuts of the last round left, under a new id: the frames
    /// from this round on carry it, and every reader (the haptic loop's contact index, the
    /// viewers, the recorder) reads it before it draws or touches them
    /// ([`FrameHeader::topology_id`]). Logs each cut landed or refused.
    fn publish_cut_topology(&mut self) {
        for e in &self.world.last_round().cuts {
            match e {
                lop_sim::cut::CutEvent::Landed { report: r, waited } => tracing::info!(
                    "{}: cut: {r}{}",
                    self.world.bodies[r.body].name,
                    if *waited {
                        " (the step waited for it)"
                    } else {
                        ""
                    }
                ),
                lop_sim::cut::CutEvent::Refused(why) => tracing::warn!("cut refused: {why}"),
                lop_sim::cut::CutEvent::Asked { .. } => {}
            }
        }
        let landed = self
            .world
            .last_round()
            .cuts
            .iter()
            .any(|e| matches!(e, lop_sim::cut::CutEvent::Landed { .. }));
        if !landed {
            return;
        }
        let topology = self.published.after_cuts(&self.world);
        let mut header = match wire_topology(&self.scene, &topology) {
            Ok(h) => h,
            Err(e) => {
                tracing::error!("the cut topology cannot be published: {e:#}");
                return;
            }
        };
        header.topology_id = new_topology_id().max(self.topology.topology_id + 1);
        if let Err(e) = send_topology(&self.topo_pub, &header, &topology.indices) {
            tracing::error!("the cut topology was not published: {e:#}");
            return;
        }
        tracing::info!("topology {:#x} published", header.topology_id);
        self.topology = header;
        self.published = topology;
    }

    /// Gives each FEM body's pace the cost of the steps it just took while running FEM, and
    /// applies a new period when the pace chooses one (made on the body's factor thread and
    /// taken `PERIOD_CHANGE_DELAY_STEPS` steps later).
    fn follow_cost(&mut self) {
        for i in 0..self.world.bodies.len() {
            let r = self.world.last_round().bodies[i];
            let running_fem = matches!(self.world.bodies[i].model, Model::Fem(_));
            let took_over = running_fem && !self.ran_fem[i];
            self.ran_fem[i] = running_fem;
            let Some(paced) = self.paces[i].as_mut() else {
                continue;
            };
            let factor_cost = paced.factor_cost;
            let pace = &mut paced.pace;
            if took_over {
                pace.restart(); // its first steps start cold
            }
            if !running_fem || r.steps == 0 {
                continue;
            }
            // One observation per step taken (a round catching up takes several), and whether
            // a tool touched the body in them: only touched steps may bring the period down.
            let cost = r.step_ns as f64 * 1e-9 / f64::from(r.steps);
            let touched = self.world.bodies[i]
                .contacts
                .iter()
                .any(|c| c.force_on_tissue.iter().any(|&f| f != 0.0));
            let before = pace.period();
            let changed = (0..r.steps).fold(None, |c, _| pace.observe(cost, touched).or(c));
            if let Some(period) = changed {
                tracing::info!(
                    "{}: a step costs {:.2} ms here; period {} -> {} ms",
                    self.world.bodies[i].name,
                    pace.judged_cost() * 1e3,
                    before * 1e3,
                    period * 1e3
                );
                if let Err(e) = set_period(&mut self.world, &self.scene, i, period, factor_cost) {
                    tracing::warn!("{}: period not changed: {e}", self.world.bodies[i].name);
                }
            }
            if let (Some(cost), false) = (pace.behind(), self.warned_behind[i]) {
                self.warned_behind[i] = true;
                warn_behind(&self.world.bodies[i].name, cost, pace.period());
            }
        }
    }

    /// Publishes the frame of the current state: `contacts` per tool (by index), the first
    /// tool's state's stamp `tool_stamp` (0: none fresh) and when the tools' states were read,
    /// `tool_read` (every tool's in the same round, so the time is theirs too), ns.
    fn publish(
        &mut self,
        sim_now: f64,
        tool_stamp: u64,
        tool_read: u64,
        world_step_ns: u64,
        contacts: &[Option<PatchContact>],
    ) {
        let world = &self.world;
        let Ok(mut sample) = self.frame_pub.loan_slice_uninit(self.node_count) else {
            return;
        };
        let header = sample.user_header_mut();
        header.contract_version = CONTRACT_VERSION;
        header.body_count = world.bodies.len() as u32;
        header.topology_id = self.topology.topology_id;
        header.sequence = self.sequence;
        header.sim_time = sim_now;
        header.tool_stamp_ns = tool_stamp;
        header.tool_read_ns = tool_read;
        header.step_ns = world_step_ns;
        header.node_count = self.node_count as u32;
        header.tool_count = self.tools as u32;
        header._pad2 = 0;
        header.contacts = [ContactFrame::default(); MAX_TOOLS];
        for (c, contact) in header.contacts.iter_mut().zip(contacts) {
            if let Some((body, proxy, local)) = contact {
                *c = crate::haptic::contact_frame(*body, *proxy, local.as_ref());
            }
        }
        for (i, b) in world.bodies.iter().enumerate() {
            let bf = &mut header.bodies[i];
            let (lo, hi) = bounds(b.model.positions());
            bf.aabb_min = lo;
            bf.aabb_max = hi;
            bf.kinetic_energy = b.model.kinetic_energy() as f32;
            let speed = b.model.max_speed();
            bf.max_speed = speed as f32;
            bf.step_ns = self.step_ns[i];
            bf.resets = b.resets;
            bf.model = body_model(b.model.kind()) as u8;
            bf.switches = b.lop.as_ref().map_or(0, |l| l.switches());
            bf.period_us = (b.model.dt() * 1e6).round() as u32;
            bf.real_time_factor = self.meters[i].factor().unwrap_or(0.0) as f32;
            // Under the controller the level is the state; a pinned body is active while it
            // moves or is touched.
            let active = match &b.lop {
                Some(_) => b.model.kind() != ModelKind::Gc,
                None => b.touched() || speed > REST_SPEED,
            };
            bf.state = if active {
                BODY_STATE_ACTIVE
            } else {
                BODY_STATE_REST
            };
        }
        let payload = sample.payload_mut();
        let heat = world.heat();
        for (i, b) in world.bodies.iter().enumerate() {
            let off = self.node_offsets[i];
            let hb = heat.and_then(|h| h.bodies().get(i));
            let temps = hb.map_or(&[][..], |h| h.temperatures());
            let burned = hb.map_or(&[][..], |h| h.burned());
            for (k, p) in b.model.positions().iter().enumerate() {
                payload[off + k].write(NodeSample {
                    position: [p[0] as f32, p[1] as f32, p[2] as f32],
                    temperature: temps.get(k).copied().unwrap_or(f64::NAN) as f32,
                    flags: if burned.get(k).copied().unwrap_or(false) {
                        NODE_FLAG_BURNED
                    } else {
                        0
                    },
                });
            }
        }
        // SAFETY: every element was written above (node offsets tile 0..node_count).
        let mut sample = unsafe { sample.assume_init() };
        sample.user_header_mut().publish_ns = rt::now_ns();
        if let Err(e) = sample.send() {
            tracing::warn!("frame not sent: {e:?}");
        }
        if let Some(n) = &self.frame_ready {
            let _ = n.notify();
        }
        self.sequence += 1;
    }
}

/// Runs the deformation process until a stop signal or the duration.
pub fn run(opts: DeformOptions) -> Result<()> {
    let mut task = DeformLoop::new(&opts)?;
    // The loop's scheduling (`[deform] rt_priority`), taken once the scene is loaded so that
    // loading never holds a core at real-time priority. Threads the step starts later (a
    // second FEM thread, the background factor) inherit it.
    let fifo = match opts.config.deform.rt_priority {
        0 => {
            tracing::info!("deformation thread at the normal scheduler ([deform] rt_priority = 0)");
            false
        }
        p => match rt::set_fifo(p) {
            Ok(()) => {
                tracing::info!("deformation thread at SCHED_FIFO {p}");
                true
            }
            Err(e) => {
                tracing::warn!(
                    "deformation thread at the normal scheduler, so other busy processes can \
                     delay the tissue: {e}"
                );
                false
            }
        },
    };
    // At real-time priority, and unless `[deform] core` pins it, the thread keeps off the
    // haptic loop's core: there it would count against that core's real-time budget (the
    // kernel throttles every real-time thread of a core that spends more than 95 % of a
    // second on them). At the normal scheduler it may use that core's idle time.
    if fifo {
        // A cut's preparation (a new factorisation of the organ) runs beside the loop, in the
        // time its steps leave: at SCHED_FIFO it would hold the loop's core until done.
        task.world.set_cut_thread_setup(std::sync::Arc::new(|| {
            if let Err(e) = rt::set_normal() {
                tracing::warn!("cut thread kept the loop's real-time priority: {e}");
            }
        }));
    }
    if fifo && opts.config.deform.core.is_none() {
        if let Some(core) = rt::haptic_core(&opts.config.haptic) {
            if let Err(e) = rt::avoid_core(core) {
                tracing::info!("deformation thread may share the haptic core: {e}");
            }
        }
    }
    let end = opts.duration.map(|d| task.start_ns() + rt::ns(d));
    while !signals::stop_requested() && end.is_none_or(|e| rt::now_ns() < e) {
        task.tick();
    }
    tracing::info!("deformation stopped after {} frames", task.frames());
    Ok(())
}

/// Publishes a topology: `header` over `indices`.
fn send_topology(
    publisher: &iceoryx2::port::publisher::Publisher<ipc::Service, [u32], TopologyHeader>,
    header: &TopologyHeader,
    indices: &[u32],
) -> Result<()> {
    let mut sample = publisher
        .loan_slice_uninit(indices.len())
        .context("loan topology")?;
    *sample.user_header_mut() = *header;
    sample
        .write_from_slice(indices)
        .send()
        .context("send topology")?;
    Ok(())
}

/// The wire's topology header of a loaded scene (ids left for the publisher). Refuses a scene
/// with more bodies than a frame holds.
pub fn wire_topology(scene: &Scene, topology: &Topology) -> Result<TopologyHeader> {
    if topology.bodies.len() > MAX_BODIES {
        anyhow::bail!(
            "scene {} has {} bodies; the frame format holds at most {MAX_BODIES}",
            scene.path.display(),
            topology.bodies.len()
        );
    }
    let mut h = TopologyHeader {
        contract_version: CONTRACT_VERSION,
        body_count: topology.bodies.len() as u32,
        node_count: topology.node_count as u32,
        triangle_count: topology.triangle_count as u32,
        tet_count: topology.tet_count as u32,
        render_triangle_count: topology.render_triangle_count as u32,
        render_vertex_count: topology.render_vertex_count as u32,
        ..Default::default()
    };
    for (bt, b) in h.bodies.iter_mut().zip(&topology.bodies) {
        bt.set_name(&b.name);
        bt.node_offset = b.node_offset as u32;
        bt.node_count = b.node_count as u32;
        bt.triangle_offset = b.triangle_offset as u32;
        bt.triangle_count = b.triangle_count as u32;
        bt.tet_offset = b.tet_offset as u32;
        bt.tet_count = b.tet_count as u32;
        bt.render_vertex_offset = b.render_vertex_offset as u32;
        bt.render_vertex_count = b.render_vertex_count as u32;
        bt.render_triangle_offset = b.render_triangle_offset as u32;
        bt.render_triangle_count = b.render_triangle_count as u32;
        bt.color = b.color;
        bt.importance = if b.important {
            IMPORTANCE_IMPORTANT
        } else {
            IMPORTANCE_NORMAL
        };
    }
    Ok(h)
}

/// Where the haptic loop's god-object touches or holds a body, as the body's anchor: the
/// touched body, its local triangle, and the god-object's offset from that material point
/// now. `None` without contact, or if the tool state refers to another topology.
fn god_object_hold(
    s: &ToolState,
    topology: &TopologyHeader,
    world: &World,
) -> Option<(usize, ToolAnchor)> {
    if s.flags & (TOOL_FLAG_CONTACT | TOOL_FLAG_GRAB) == 0
        || s.topology_id != topology.topology_id
        || s.contact_body < 0
    {
        return None;
    }
    let b = s.contact_body as usize;
    let body = world.bodies.get(b)?;
    let local = s
        .contact_triangle
        .checked_sub(topology.bodies.get(b)?.triangle_offset)?;
    let anchor = ToolAnchor::from_proxy(
        &body.mesh.surface,
        body.model.positions(),
        local,
        s.contact_barycentric,
        s.proxy_position,
        s.flags & TOOL_FLAG_GRAB != 0,
    )?;
    Some((b, anchor))
}

/// The wire's model code.
pub fn body_model(kind: ModelKind) -> BodyModel {
    match kind {
        ModelKind::MassSpring => BodyModel::Msd,
        ModelKind::Fem => BodyModel::Fem,
        ModelKind::Gc => BodyModel::Gc,
    }
}

/// Logs a body's levels-of-precision transition, if it just made one.
fn log_switch(b: &mut lop_sim::world::Body) {
    let Some(sw) = b.lop.as_mut().and_then(|l| l.take_switch()) else {
        return;
    };
    tracing::info!(
        "{}: {} -> {} ({:?}) at t = {:.2} s; jump {:.2e} m, cage fit residual {:.2e} m (blended)",
        b.name,
        body_model(sw.from).as_str(),
        body_model(sw.to).as_str(),
        sw.reason,
        sw.time,
        sw.jump,
        sw.residual
    );
}

fn bounds(p: &[[f64; 3]]) -> ([f32; 3], [f32; 3]) {
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for x in p {
        for k in 0..3 {
            lo[k] = lo[k].min(x[k] as f32);
            hi[k] = hi[k].max(x[k] as f32);
        }
    }
    (lo, hi)
}
const _: () = assert!(lop_scene::RENDER_VERTEX_WORDS == lop_ipc::RENDER_VERTEX_WORDS);
// A frame holds a contact for every tool a round takes.
const _: () = assert!(lop_sim::world::MAX_TOOLS == lop_ipc::MAX_TOOLS);

#[cfg(test)]
mod tests {
    //! The tool blackboard's read rules: each tool fresh on its own, under its own index; the
    //! board closed only when every state ever written is older than `TOOL_DROP_NS`.

    use super::*;

    const NOW: u64 = 10_000_000_000;

    fn stamped(stamp_ns: u64) -> ToolState {
        ToolState {
            stamp_ns,
            ..ToolState::default()
        }
    }

    #[test]
    fn each_tool_is_fresh_on_its_own_under_its_own_index() {
        let r = judge_tools(
            &[stamped(NOW - TOOL_STALE_NS - 1), stamped(NOW - 1_000_000)],
            NOW,
        );
        assert_eq!(r.fresh[0], None);
        assert_eq!(r.fresh[1].map(|s| s.stamp_ns), Some(NOW - 1_000_000));
        assert!(!r.close);
        // Never written: not fresh.
        assert_eq!(judge_tools(&[stamped(0)], NOW).fresh[0], None);
    }

    #[test]
    fn the_board_closes_only_when_every_written_state_is_that_old() {
        let gone = stamped(NOW - TOOL_DROP_NS - 1);
        let live = stamped(NOW - 1_000_000);
        // One haptic process writes every tool: a live tool means a live process.
        assert!(!judge_tools(&[gone, live], NOW).close);
        assert!(!judge_tools(&[live, gone], NOW).close);
        // Stale but not yet that old: ignored, the board kept.
        let stale = stamped(NOW - TOOL_STALE_NS - 1);
        let r = judge_tools(&[gone, stale], NOW);
        assert_eq!((r.fresh[0], r.fresh[1], r.close), (None, None, false));
        // Every tool that old: the process is gone.
        assert!(judge_tools(&[gone, gone], NOW).close);
        // A tool never written neither holds the board open nor closes it alone.
        assert!(judge_tools(&[gone, stamped(0)], NOW).close);
        assert!(judge_tools(&[stamped(0), gone], NOW).close);
        assert!(!judge_tools(&[stamped(0), stamped(0)], NOW).close);
        assert!(!judge_tools(&[], NOW).close);
    }
}
