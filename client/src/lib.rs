//! `lop-client`: attach to a running `lopd` read-only.
//!
//! ```no_run
//! use std::time::Duration;
//! let mut lop = lop_client::Attachment::open("lop", Duration::from_secs(10))?;
//! let topology = lop.wait_topology(Duration::from_secs(5))?.clone();
//! let frame = lop.next_frame(Duration::from_secs(1))?;
//! for body in topology.bodies() {
//!     let nodes = &frame.nodes[body.node_offset as usize..][..body.node_count as usize];
//!     println!("{}: first node at {:?}", body.name_str(), nodes[0].position);
//! }
//! # Ok::<(), lop_client::ClientError>(())
//! ```
//!
//! Everything here opens the daemon's services as a client: subscribers map the daemon's memory
//! read-only, safe overflow means a slow client only loses old samples, and nothing a client does
//! can stall the daemon. The blackboard is never opened.

use std::time::{Duration, Instant};

use iceoryx2::prelude::*;
use lop_ipc::services::{IpcError, Role};
pub use lop_ipc::*;

/// What can go wrong attaching to the daemon.
#[derive(Debug, thiserror::Error)]
pub enum ClientError {
    /// Creating or opening a service failed.
    #[error(transparent)]
    Ipc(#[from] IpcError),
    /// Nothing arrived in time.
    #[error("no {what} from lopd within {waited:?} (prefix {prefix:?})")]
    Timeout {
        /// What we waited for.
        what: &'static str,
        /// How long.
        waited: Duration,
        /// The service prefix.
        prefix: String,
    },
    /// Received data of another contract version.
    #[error("lopd speaks contract version {found}, this client {expected}")]
    Version {
        /// Version in the data.
        found: u32,
        /// Our version.
        expected: u32,
    },
}

/// The static part of a scene: bodies, surface triangles, tetrahedra.
#[derive(Debug, Clone)]
pub struct Topology {
    /// The header as published.
    pub header: TopologyHeader,
    /// Outward surface triangles, global node indices.
    pub triangles: Vec<[u32; 3]>,
    /// Tetrahedra, global node indices.
    pub tets: Vec<[u32; 4]>,
    /// Render surfaces' triangles, global render vertex indices (see
    /// [`BodyTopology::render_triangle_offset`]).
    pub render_triangles: Vec<[u32; 3]>,
    /// Render vertices: where each sits in the mesh.
    pub render_vertices: Vec<RenderVertex>,
}

/// A vertex of a render surface: it follows four nodes by fixed weights.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RenderVertex {
    /// Global node indices.
    pub nodes: [u32; 4],
    /// Weights (sum 1).
    pub weights: [f32; 4],
}

impl RenderVertex {
    /// `Σ wᵢ · f(nodeᵢ)` over the frame's nodes (a position, a temperature…); 0 for a node
    /// out of the frame's range.
    pub fn blend<const N: usize>(
        &self,
        nodes: &[NodeSample],
        f: impl Fn(&NodeSample) -> [f32; N],
    ) -> [f32; N] {
        let mut out = [0.0f32; N];
        for (&k, &w) in self.nodes.iter().zip(&self.weights) {
            if let Some(s) = nodes.get(k as usize) {
                for (o, v) in out.iter_mut().zip(f(s)) {
                    *o += w * v;
                }
            }
        }
        out
    }
}

impl Topology {
    /// The bodies in use.
    pub fn bodies(&self) -> &[BodyTopology] {
        &self.header.bodies[..(self.header.body_count as usize).min(MAX_BODIES)]
    }

    /// Every render vertex's position in `frame` (empty when the scene has no render surface).
    pub fn render_positions(&self, frame: &Frame) -> Vec<[f32; 3]> {
        self.render_vertices
            .iter()
            .map(|v| v.blend(&frame.nodes, |s| s.position))
            .collect()
    }
}

/// One received frame (copied out of shared memory).
#[derive(Debug, Clone)]
pub struct Frame {
    /// The header as published.
    pub header: FrameHeader,
    /// Every node, bodies concatenated in topology order.
    pub nodes: Vec<NodeSample>,
    /// When this client received it ([`clock::monotonic_ns`]).
    pub received_ns: u64,
}

impl Frame {
    /// The bodies' per-frame state.
    pub fn bodies(&self) -> &[BodyFrame] {
        &self.header.bodies[..(self.header.body_count as usize).min(MAX_BODIES)]
    }
}

/// A read-only attachment to one daemon (one service prefix).
pub struct Attachment {
    node: Node<ipc::Service>,
    names: ServiceNames,
    topology_sub: services::TopologySubscriber,
    frame_sub: services::FrameSubscriber,
    tool_sub: Option<services::ToolSubscriber>,
    telemetry_sub: Option<services::TelemetrySubscriber>,
    topology: Option<Topology>,
}

impl Attachment {
    /// Opens the scene services under `prefix`, retrying until `timeout` (the daemon may still
    /// be starting).
    pub fn open(prefix: &str, timeout: Duration) -> Result<Attachment, ClientError> {
        let names = ServiceNames::new(prefix)?;
        let node = services::node(&format!("lop-client-{}", std::process::id()))?;
        let topology_sub = services::open_retry(&names.topology, timeout, || {
            let s = services::topology_service(&node, &names, Role::Client)?;
            s.subscriber_builder()
                .create()
                .map_err(|e| lop_ipc::limits::subscriber_create_error(&names.topology, e))
        })?;
        let frame_sub = services::open_retry(&names.frame, timeout, || {
            let s = services::frame_service(&node, &names, Role::Client)?;
            s.subscriber_builder()
                .buffer_size(services::FRAME_BUFFER)
                .create()
                .map_err(|e| lop_ipc::limits::subscriber_create_error(&names.frame, e))
        })?;
        Ok(Attachment {
            node,
            names,
            topology_sub,
            frame_sub,
            tool_sub: None,
            telemetry_sub: None,
            topology: None,
        })
    }

    /// The service names in use.
    pub fn names(&self) -> &ServiceNames {
        &self.names
    }

    /// Takes a newly published topology, if any, and returns the current one.
    pub fn poll_topology(&mut self) -> Result<Option<&Topology>, ClientError> {
        while let Ok(Some(s)) = self.topology_sub.receive() {
            let h = *s.user_header();
            if h.contract_version != CONTRACT_VERSION {
                return Err(ClientError::Version {
                    found: h.contract_version,
                    expected: CONTRACT_VERSION,
                });
            }
            let data = s.payload();
            let nt = (h.triangle_count as usize).min(data.len() / 3);
            let triangles = data[..nt * 3]
                .chunks_exact(3)
                .map(|c| [c[0], c[1], c[2]])
                .collect();
            let rest = &data[nt * 3..];
            let ne = (h.tet_count as usize).min(rest.len() / 4);
            let tets = rest[..ne * 4]
                .chunks_exact(4)
                .map(|c| [c[0], c[1], c[2], c[3]])
                .collect();
            let rest = &rest[ne * 4..];
            let nr = (h.render_triangle_count as usize).min(rest.len() / 3);
            let render_triangles = rest[..nr * 3]
                .chunks_exact(3)
                .map(|c| [c[0], c[1], c[2]])
                .collect();
            let rest = &rest[nr * 3..];
            let nv = (h.render_vertex_count as usize).min(rest.len() / RENDER_VERTEX_WORDS);
            let render_vertices = rest[..nv * RENDER_VERTEX_WORDS]
                .chunks_exact(RENDER_VERTEX_WORDS)
                .map(|c| RenderVertex {
                    nodes: [c[0], c[1], c[2], c[3]],
                    weights: [4, 5, 6, 7].map(|i| f32::from_bits(c[i])),
                })
                .collect();
            self.topology = Some(Topology {
                header: h,
                triangles,
                tets,
                render_triangles,
                render_vertices,
            });
        }
        Ok(self.topology.as_ref())
    }

    /// The current topology (the last one polled), without polling: the one every frame
    /// [`Attachment::frames`] or [`Attachment::latest_frame`] just returned belongs to.
    pub fn topology(&self) -> Option<&Topology> {
        self.topology.as_ref()
    }

    /// Waits for a topology.
    pub fn wait_topology(&mut self, timeout: Duration) -> Result<&Topology, ClientError> {
        let start = Instant::now();
        loop {
            if self.poll_topology()?.is_some() {
                return Ok(self.topology.as_ref().expect("just polled"));
            }
            if start.elapsed() > timeout {
                return Err(self.timeout("topology", timeout));
            }
            std::thread::sleep(Duration::from_millis(5));
        }
    }

    /// The newest frame received since the last call, without waiting. Frames of a topology
    /// other than the current one are skipped (a new topology is taken first).
    pub fn latest_frame(&mut self) -> Result<Option<Frame>, ClientError> {
        let mut newest = None;
        while let Ok(Some(s)) = self.frame_sub.receive() {
            newest = Some(Frame {
                header: *s.user_header(),
                nodes: s.payload().to_vec(),
                received_ns: clock::monotonic_ns(),
            });
        }
        let Some(frame) = newest else {
            return Ok(None);
        };
        if frame.header.contract_version != CONTRACT_VERSION {
            return Err(ClientError::Version {
                found: frame.header.contract_version,
                expected: CONTRACT_VERSION,
            });
        }
        self.poll_topology()?;
        match &self.topology {
            Some(t) if t.header.topology_id == frame.header.topology_id => Ok(Some(frame)),
            _ => Ok(None),
        }
    }

    /// Every frame received since the last call, oldest first (up to the subscriber's buffer),
    /// without waiting; frames of another topology are dropped.
    pub fn frames(&mut self) -> Result<Vec<Frame>, ClientError> {
        let mut out = Vec::new();
        while let Ok(Some(s)) = self.frame_sub.receive() {
            out.push(Frame {
                header: *s.user_header(),
                nodes: s.payload().to_vec(),
                received_ns: clock::monotonic_ns(),
            });
        }
        self.poll_topology()?;
        let id = self.topology.as_ref().map(|t| t.header.topology_id);
        out.retain(|f| {
            Some(f.header.topology_id) == id && f.header.contract_version == CONTRACT_VERSION
        });
        Ok(out)
    }

    /// Waits up to `timeout` for a frame newer than anything taken so far.
    pub fn next_frame(&mut self, timeout: Duration) -> Result<Frame, ClientError> {
        let start = Instant::now();
        loop {
            if let Some(f) = self.latest_frame()? {
                return Ok(f);
            }
            if start.elapsed() > timeout {
                return Err(self.timeout("frame", timeout));
            }
            std::thread::sleep(Duration::from_millis(1));
        }
    }

    /// Tool states received since the last call (appended to `out`); opens the tool service on
    /// first use. Returns how many were appended.
    pub fn tool_states(&mut self, out: &mut Vec<ToolState>) -> usize {
        if self.tool_sub.is_none() {
            self.tool_sub = services::tool_service(&self.node, &self.names, Role::Client)
                .ok()
                .and_then(|s| {
                    s.subscriber_builder()
                        .buffer_size(services::TOOL_BUFFER)
                        .create()
                        .ok()
                });
        }
        let Some(sub) = &self.tool_sub else {
            return 0;
        };
        let before = out.len();
        while let Ok(Some(s)) = sub.receive() {
            out.push(*s);
        }
        out.len() - before
    }

    /// The newest haptic telemetry since the last call; opens the service on first use.
    pub fn telemetry(&mut self) -> Option<HapticTelemetry> {
        if self.telemetry_sub.is_none() {
            self.telemetry_sub = services::telemetry_service(&self.node, &self.names, Role::Client)
                .ok()
                .and_then(|s| s.subscriber_builder().create().ok());
        }
        let sub = self.telemetry_sub.as_ref()?;
        let mut newest = None;
        while let Ok(Some(s)) = sub.receive() {
            newest = Some(*s);
        }
        newest
    }

    fn timeout(&self, what: &'static str, waited: Duration) -> ClientError {
        ClientError::Timeout {
            what,
            waited,
            prefix: self.names.prefix.clone(),
        }
    }
}

pub mod vtk;
