//! `lopd deform`: the deformation process. Loads the scene, publishes its topology once, then
//! steps every body at real-time pace (simulated time follows the wall clock; each body keeps its
//! own `dt`) with the tool pressing on it, and publishes a frame after every step.
//!
//! Tool coupling: the newest tool state comes from the haptic loop's blackboard. The tool tip is
//! a kinematic sphere; its penalty spring is integrated inside the body's sub-steps with the same
//! law the haptic loop renders, so the tissue receives the force the hand feels (up to the
//! multirate delay) and a stiff tool on light tissue stays stable.

use std::time::Duration;

use anyhow::{Context, Result};
use iceoryx2::port::reader::EntryHandle;
use iceoryx2::port::update_connections::UpdateConnections;
use iceoryx2::prelude::*;
use lop_config::{DaemonConfig, Scene};
use lop_ipc::services::{self, Role, ToolBoard};
use lop_ipc::*;
use lop_sim::model::ModelKind;

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
/// Temperature every node starts at, °C.
const BODY_TEMPERATURE: f32 = 37.0;

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
        let mut tool = None;
        if let Some(t) = &tool_input {
            let state = *t.entry.get();
            tool_read = rt::now_ns();
            if state.stamp_ns > 0 && tool_read.saturating_sub(state.stamp_ns) < TOOL_STALE_NS {
                tool_stamp = state.stamp_ns;
                tool = Some(tool_sphere(&scene.tool, state.device_position));
            }
        }

        // Step every body that is due, on its own dt.
        let sim_now = (now - start) as f64 * 1e-9;
        // Control requests (PREFIX/control) are served here, between steps; paused: no stepping,
        // frames keep coming with frozen positions.
        let paused = control.poll(&mut world, sim_now);
        let step_start = rt::now_ns();
        let mut stepped = paused;
        for (i, last_ns) in step_ns.iter_mut().enumerate().filter(|_| !paused) {
            let mut steps = 0;
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
            for (k, p) in b.model.positions().iter().enumerate() {
                payload[off + k].write(NodeSample {
                    position: [p[0] as f32, p[1] as f32, p[2] as f32],
                    temperature: BODY_TEMPERATURE,
                    flags: 0,
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
