//! Shared by the real-time allocation tests: the deformation process's side of the IPC (the
//! organs' topology once, a frame of rest positions on demand). The counting allocator is
//! `lop_test_support::alloc`.
#![allow(dead_code)] // each test binary uses what it needs

use iceoryx2::prelude::*;
use lop_ipc::services::{self, FramePublisher, Role, TopologyPublisher};
use lop_ipc::*;
use lop_scene::LoadedScene;

/// A local model of the press the tool state `s` rendered, as a frame would carry it: the
/// body, the proxy, and the model with the tissue half as stiff as the tool spring.
pub fn local_model_of(s: &ToolState) -> (u32, [f64; 3], lop_sim::haptic::LocalModel) {
    let k = 0.5 * s.tool_stiffness;
    (
        s.contact_body as u32,
        s.proxy_position,
        lop_sim::haptic::LocalModel {
            device: s.device_position,
            force: s.force.map(|c| -c),
            stiffness: [[k, 0.0, 0.0], [0.0, k, 0.0], [0.0, 0.0, k]],
            drift: [0.0; 3],
            horizon: 1e-3,
        },
    )
}

/// The topology id the fake deformation side publishes.
pub const TOPOLOGY_ID: u64 = 42;

/// The deformation process's side, played by a test: the scene's topology and frames of its
/// rest positions.
pub struct DeformSide {
    _node: Node<ipc::Service>,
    topo_pub: TopologyPublisher,
    frame_pub: FramePublisher,
    frame_ready: iceoryx2::port::notifier::Notifier<ipc::Service>,
    topology: TopologyHeader,
    indices: Vec<u32>,
    /// Per body: bounds of the rest nodes.
    bounds: Vec<([f32; 3], [f32; 3])>,
    nodes: Vec<NodeSample>,
}

impl DeformSide {
    /// Creates the topology and frame publishers for `loaded` under `names`.
    pub fn new(node_name: &str, names: &ServiceNames, loaded: &LoadedScene) -> DeformSide {
        let node = services::node(node_name).unwrap();
        let topo_pub = services::topology_service(&node, names, Role::Owner)
            .unwrap()
            .publisher_builder()
            .initial_max_slice_len(loaded.topology.indices.len())
            .create()
            .unwrap();
        let frame_pub = services::frame_service(&node, names, Role::Owner)
            .unwrap()
            .publisher_builder()
            .initial_max_slice_len(loaded.topology.node_count)
            .create()
            .unwrap();
        let frame_ready = services::frame_ready_service(&node, names)
            .unwrap()
            .notifier_builder()
            .create()
            .unwrap();
        let mut topology =
            lop_daemon::deform::wire_topology(&loaded.scene, &loaded.topology).unwrap();
        topology.topology_id = TOPOLOGY_ID;
        let bounds = loaded
            .world
            .bodies
            .iter()
            .map(|b| {
                let (lo, hi) = lop_sim::mesh::bounds(&b.mesh.nodes);
                (lo.map(|c| c as f32), hi.map(|c| c as f32))
            })
            .collect();
        let nodes = loaded
            .world
            .bodies
            .iter()
            .flat_map(|b| &b.mesh.nodes)
            .map(|p| NodeSample {
                position: p.map(|c| c as f32),
                temperature: 37.0,
                flags: 0,
            })
            .collect();
        DeformSide {
            _node: node,
            topo_pub,
            frame_pub,
            frame_ready,
            topology,
            indices: loaded.topology.indices.clone(),
            bounds,
            nodes,
        }
    }

    /// Publishes the topology.
    pub fn publish_topology(&self) {
        let mut s = self.topo_pub.loan_slice_uninit(self.indices.len()).unwrap();
        *s.user_header_mut() = self.topology;
        s.write_from_slice(&self.indices).send().unwrap();
    }

    /// Publishes frame `seq` of the rest positions, stamped now.
    pub fn publish_frame(&self, seq: u64) {
        self.publish_frame_local(seq, None);
    }

    /// A frame at rest that carries `local`: a contact patch on a body balanced with its proxy
    /// at a point, and its local model, as `lopd deform` publishes them for the scene's one
    /// tool (`FrameHeader::contacts[0]`, `tool_count` 1).
    #[allow(dead_code)]
    pub fn publish_frame_local(
        &self,
        seq: u64,
        local: Option<(u32, [f64; 3], lop_sim::haptic::LocalModel)>,
    ) {
        let s = self.frame_pub.loan_slice_uninit(self.nodes.len()).unwrap();
        let mut s = s.write_from_slice(&self.nodes);
        let h = s.user_header_mut();
        h.contract_version = CONTRACT_VERSION;
        h.topology_id = TOPOLOGY_ID;
        h.sequence = seq;
        h.body_count = self.topology.body_count;
        h.node_count = self.nodes.len() as u32;
        h.publish_ns = clock::monotonic_ns();
        h.tool_read_ns = h.publish_ns;
        h.tool_count = 1;
        h.contacts = [ContactFrame::default(); MAX_TOOLS];
        if let Some((body, proxy, m)) = local {
            h.contacts[0] = lop_daemon::haptic::contact_frame(body, proxy, Some(&m));
        }
        for (bf, (lo, hi)) in h.bodies.iter_mut().zip(&self.bounds) {
            bf.aabb_min = *lo;
            bf.aabb_max = *hi;
        }
        s.send().unwrap();
        self.frame_ready.notify().unwrap();
    }
}
