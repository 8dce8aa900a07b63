//! `lopd deform`: the deformation process. Loads the scene, publishes its topology once, then
//! steps every body at real-time pace (simulated time follows the wall clock; each body keeps its
//! own `dt`) with the tool pressing on it, and publishes a frame after every step.
//!
//! Tool coupling (force coupling, DESIGN's choice for the tissue response): the newest tool state
//! comes from the haptic loop's blackboard. Where its god-object touches or holds a body, that
//! body receives the opposite of the hand's force at the god-object's material point — the
//! spring between god-object and device, integrated implicitly inside the body's step
//! (`lop_sim::model::ToolAnchor`), so the tissue receives the force the hand feels (up to the
//! multirate delay: the haptic loop renders against the last frame) and a stiff tool on light
//! tissue stays stable. The grab button turns the contact into a hold that also pulls.
//!
//! Heat (thesis §5.3): with the heat button pressed while touching, the touched point receives
//! `[tool] heat_power`; the heat model (`lop_sim::heat`, one implicit step per `[heat] dt` of
//! simulated time) diffuses it, loses it to the air and passes it to organs that touch. Frames
//! carry every node's temperature and its burned flag.

use std::time::Duration;

use anyhow::{Context, Result};
use iceoryx2::port::reader::EntryHandle;
use iceoryx2::port::update_connections::UpdateConnections;
use iceoryx2::prelude::*;
use lop_config::{DaemonConfig, Scene};
use lop_ipc::services::{self, Role, ToolBoard};
use lop_ipc::*;
use lop_sim::model::{ModelKind, ToolAnchor};
use lop_sim::world::{Coupling, World};

use crate::rt;
use crate::scene::{self, tool_sphere, LoadedScene};
use crate::signals;

/// A tool state older than this is ignored (the haptic process is gone or restarting), ns.
const TOOL_STALE_NS: u64 = 100_000_000;
/// Most steps a body may take in one pass to catch up with the wall clock; beyond that its
/// simulated time is dropped rather than spiralling (counted as lag).
const MAX_CATCH_UP: u32 = 4;
/// Largest nodal speed under which a body counts as at rest, m/s.
const REST_SPEED: f64 = 1e-3;
/// Most heat steps in one pass to catch up with the wall clock.
const MAX_HEAT_CATCH_UP: u32 = 8;

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

struct ToolInput {
    _board: ToolBoard,
    _reader: iceoryx2::port::reader::Reader<ipc::Service, u32>,
    entry: EntryHandle<ipc::Service, u32, ToolState>,
}

fn open_tool_input(node: &Node<ipc::Service>, names: &ServiceNames) -> Option<ToolInput> {
    let board = services::tool_board_reader(node, names).ok()?;
    let reader = board.reader_builder().create().ok()?;
    let entry = reader.entry::<ToolState>(&services::TOOL_LATEST_KEY).ok()?;
    Some(ToolInput {
        _board: board,
        _reader: reader,
        entry,
    })
}

/// A topology id that differs between loads and processes; never 0.
fn new_topology_id() -> u64 {
    let t = rt::now_ns();
    let pid = std::process::id() as u64;
    (t ^ (pid << 48)).max(1)
}

/// Runs the deformation process until a stop signal or the duration.
pub fn run(opts: DeformOptions) -> Result<()> {
    if let Some(core) = opts.config.deform.core {
        if let Err(e) = rt::pin_to_core(core) {
            tracing::warn!("deformation process not pinned: {e}");
        }
    }
    let LoadedScene {
        scene,
        mut world,
        mut topology,
        topology_indices,
        node_offsets,
    } = scene::load(opts.scene)?;
    let mut heat = scene::heat_world(&scene, &world)?;
    let heat_dt = heat
        .bodies()
        .first()
        .map_or(scene::HEAT_DT_DEFAULT, |b| b.dt());
    let mut heat_time = 0.0;
    let mut heat_failed = false;
    let names = opts.names;
    let node = services::node("lopd-deform")?;
    let cleaned = services::cleanup_dead_nodes(&node);
    if cleaned > 0 {
        tracing::info!("cleaned {cleaned} dead iceoryx2 node(s) left by a crashed process");
    }

    // Topology, once, with history so late subscribers get it.
    topology.topology_id = new_topology_id();
    let topo_pub = services::topology_service(&node, &names, Role::Owner)?
        .publisher_builder()
        .initial_max_slice_len(topology_indices.len())
        .create()
        .context("topology publisher")?;
    let mut sample = topo_pub
        .loan_slice_uninit(topology_indices.len())
        .context("loan topology")?;
    *sample.user_header_mut() = topology;
    sample
        .write_from_slice(&topology_indices)
        .send()
        .context("send topology")?;

    let node_count = topology.node_count as usize;
    let frame_pub = services::frame_service(&node, &names, Role::Owner)?
        .publisher_builder()
        .initial_max_slice_len(node_count)
        .max_loaned_samples(2)
        .create()
        .context("frame publisher")?;

    tracing::info!(
        "scene {:?}: {} bodies, {} nodes, {} surface triangles; topology {:#x}",
        scene.name,
        world.bodies.len(),
        node_count,
        topology.triangle_count,
        topology.topology_id
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

    let mut tool_input = open_tool_input(&node, &names);
    let mut control = crate::control::ControlServer::new(&node, &names, &scene, &world);
    let mut last_connection_update = rt::now_ns();
    let mut last_tool_try = rt::now_ns();
    let period = (1e9 / scene.rates.deform_max_hz).round() as u64;
    let start = rt::now_ns();
    let end = opts.duration.map(|d| start + rt::ns(d));
    let mut deadline = start;
    let mut sequence = 0u64;
    let mut step_ns = vec![0u32; world.bodies.len()];
    let mut lagged = 0u64;

    while !signals::stop_requested() && end.is_none_or(|e| rt::now_ns() < e) {
        deadline += period;
        let now = rt::sleep_until(deadline, 0);
        if now > deadline + period {
            deadline = now; // fell behind: do not burst
        }

        // The newest tool state, if the haptic process is up.
        // Late subscribers get the topology from the history when the publisher notices them.
        if now - last_connection_update > 50_000_000 {
            let _ = topo_pub.update_connections();
            last_connection_update = now;
        }
        if tool_input.is_none() && now - last_tool_try > 500_000_000 {
            tool_input = open_tool_input(&node, &names);
            last_tool_try = now;
        }
        let mut tool_stamp = 0;
        let mut tool_read = 0;
        let mut tool_state = None;
        if let Some(t) = &tool_input {
            let state = *t.entry.get();
            tool_read = rt::now_ns();
            if state.stamp_ns > 0 && tool_read.saturating_sub(state.stamp_ns) < TOOL_STALE_NS {
                tool_stamp = state.stamp_ns;
                tool_state = Some(state);
            }
        }
        let held = tool_state.and_then(|s| god_object_hold(&s, &topology, &world));
        world.coupling = Coupling::GodObject(held);

        // Step every body that is due, on its own dt.
        let sim_now = (now - start) as f64 * 1e-9;
        // Control requests (PREFIX/control) are served here, between steps; paused: no stepping,
        // frames keep coming with frozen positions.
        let paused = control.poll(&mut world, sim_now);
        let step_start = rt::now_ns();
        // Organ-to-organ contacts at the current shapes, for the steps about to be taken.
        if !paused && (0..world.bodies.len()).any(|i| world.body_due(i, sim_now)) {
            world.detect_collisions();
        }
        let mut stepped = paused;
        for (i, last_ns) in step_ns.iter_mut().enumerate().filter(|_| !paused) {
            let mut steps = 0;
            let tool = tool_state.map(|s| {
                let mut t = tool_sphere(&scene.tool, s.device_position);
                if let Some(k) = scene.bodies[i].tool_stiffness {
                    t.stiffness = k;
                }
                t
            });
            while world.body_due(i, sim_now) && steps < MAX_CATCH_UP {
                let t0 = rt::now_ns();
                if let Err(cause) = world.step_body(i, tool.as_ref()) {
                    tracing::warn!(
                        "body {:?} blew up ({cause:?}); reset to rest",
                        world.bodies[i].name
                    );
                }
                *last_ns = (rt::now_ns() - t0).min(u32::MAX as u64) as u32;
                log_switch(&mut world.bodies[i]);
                steps += 1;
                stepped = true;
            }
            if world.body_due(i, sim_now) {
                world.bodies[i].time = sim_now;
                lagged += 1;
                if lagged.is_power_of_two() {
                    tracing::warn!("deformation lags the wall clock ({lagged} times so far)");
                }
            }
        }
        // Heat: the cautery on the touched point, then the heat steps that are due.
        if !heat_failed {
            for b in 0..world.bodies.len() {
                if let Ok(h) = heat.body_mut(b) {
                    h.clear_sources();
                }
            }
            if let (Some(s), Some((b, a))) = (tool_state, held) {
                if s.flags & TOOL_FLAG_HEAT != 0 && !a.grab {
                    let tri = world.bodies[b].mesh.surface[a.triangle as usize];
                    if let Ok(h) = heat.body_mut(b) {
                        let _ = h.heat_point(tri, a.bary, scene.tool.heat_power);
                    }
                }
            }
            let mut heat_steps = 0;
            while heat_time + heat_dt <= sim_now + 1e-12 && heat_steps < MAX_HEAT_CATCH_UP {
                if let Err(e) = heat.step() {
                    tracing::warn!("heat model stopped: {e}");
                    heat_failed = true;
                    break;
                }
                heat_time += heat_dt;
                heat_steps += 1;
                stepped = true;
            }
            if heat_time + heat_dt <= sim_now {
                heat_time = sim_now; // fell behind: drop simulated heat time
            }
        }
        if !stepped {
            continue;
        }
        let world_step_ns = rt::now_ns() - step_start;

        // Publish the frame.
        let Ok(mut sample) = frame_pub.loan_slice_uninit(node_count) else {
            continue;
        };
        let header = sample.user_header_mut();
        header.contract_version = CONTRACT_VERSION;
        header.body_count = world.bodies.len() as u32;
        header.topology_id = topology.topology_id;
        header.sequence = sequence;
        header.sim_time = sim_now;
        header.tool_stamp_ns = tool_stamp;
        header.tool_read_ns = tool_read;
        header.step_ns = world_step_ns;
        header.node_count = node_count as u32;
        for (i, b) in world.bodies.iter().enumerate() {
            let bf = &mut header.bodies[i];
            let (lo, hi) = bounds(b.model.positions());
            bf.aabb_min = lo;
            bf.aabb_max = hi;
            bf.kinetic_energy = b.model.kinetic_energy() as f32;
            let speed = b.model.max_speed();
            bf.max_speed = speed as f32;
            bf.step_ns = step_ns[i];
            bf.resets = b.resets;
            bf.model = body_model(b.model.kind()) as u8;
            bf.switches = b.lop.as_ref().map_or(0, |l| l.switches());
            // Under the controller the level is the state; a pinned body is active while it
            // moves or is touched.
            let active = match &b.lop {
                Some(_) => b.model.kind() != ModelKind::Gc,
                None => b.last_contact.depth > 0.0 || speed > REST_SPEED,
            };
            bf.state = if active {
                BODY_STATE_ACTIVE
            } else {
                BODY_STATE_REST
            };
        }
        let payload = sample.payload_mut();
        for (i, b) in world.bodies.iter().enumerate() {
            let off = node_offsets[i];
            let hb = &heat.bodies()[i];
            let (temps, burned) = (hb.temperatures(), hb.burned());
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
        sequence += 1;
    }
    tracing::info!("deformation stopped after {sequence} frames");
    Ok(())
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
