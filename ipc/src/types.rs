//! Payload types. Every one is `#[repr(C)]`, `Copy`, heap-free and carries an explicit
//! language-neutral type name (`lop::…`), so the iceoryx2 service can be opened from C, C++ or
//! Python with a structure of the same layout. Padding is spelled out as `_pad` fields so the C
//! header and the Rust layout cannot drift apart silently; `tests/layout.rs` pins every size,
//! alignment and field offset.
//!
//! Units: SI (m, N, s, °C); timestamps are [`crate::clock::monotonic_ns`]; positions are in the
//! scene frame (y up), never in device millimetres.

use iceoryx2::prelude::ZeroCopySend;

/// Most bodies a scene may hold. Fixed so headers stay heap-free.
pub const MAX_BODIES: usize = 16;
/// Most tools a scene may hold (one per haptic device). Fixed so headers stay heap-free.
pub const MAX_TOOLS: usize = 4;
/// Bytes of a body name, NUL-padded UTF-8.
pub const BODY_NAME_LEN: usize = 32;

/// `ToolState::flags` bit: the tool touches a body this tick.
pub const TOOL_FLAG_CONTACT: u32 = 1 << 0;
/// `ToolState::flags` bit: the force is being ramped to zero (stale frame, NaN, device error).
pub const TOOL_FLAG_RAMPING: u32 = 1 << 1;
/// `ToolState::flags` bit: the newest frame is older than the stale limit (or there is none).
pub const TOOL_FLAG_STALE_FRAME: u32 = 1 << 2;
/// `ToolState::flags` bit: the device reported an error or an invalid sample this tick.
pub const TOOL_FLAG_DEVICE_ERROR: u32 = 1 << 3;
/// `ToolState::flags` bit: the grab button holds a piece of tissue (picking); the contact fields
/// name the grabbed point.
pub const TOOL_FLAG_GRAB: u32 = 1 << 4;
/// `ToolState::flags` bit: the heat button is pressed while touching: the contact point is being
/// cauterised.
pub const TOOL_FLAG_HEAT: u32 = 1 << 5;
/// `ToolState::flags` bit: the force this tick came from the frame's local model of the
/// contact patch (`ContactFrame::local` of this tool in `FrameHeader::contacts`), not from the
/// surface alone.
pub const TOOL_FLAG_LOCAL_MODEL: u32 = 1 << 6;
/// `ToolState::flags` bit: the cut button is pressed while a cautery touches: the tissue its
/// heat vaporises under the tip is cut away.
pub const TOOL_FLAG_CUT: u32 = 1 << 7;

/// One tool's haptic loop state after one tick: where the hand is, what it touches, what it
/// feels. Written every tick (1 kHz) to `PREFIX/tool` (publish–subscribe, for viewers; the
/// states of every tool share it, told apart by `tool`) and to the tool's entry of the
/// blackboard `PREFIX/tool/latest` (for the deformation process).
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[type_name("lop::ToolState")]
pub struct ToolState {
    /// [`crate::CONTRACT_VERSION`].
    pub contract_version: u32,
    /// `TOOL_FLAG_*` bits.
    pub flags: u32,
    /// Tick index since the haptic loop started.
    pub sequence: u64,
    /// When the device was read this tick.
    pub stamp_ns: u64,
    /// Device tip mapped into the scene, m.
    pub device_position: [f64; 3],
    /// Where the tool is drawn: on the surface while penetrating, else the device position, m.
    pub proxy_position: [f64; 3],
    /// Force rendered to the hand this tick, scene frame, N (finite, clamped).
    pub force: [f64; 3],
    /// Tool tip sphere radius, m.
    pub tool_radius: f64,
    /// Barycentric coordinates of the contact point on `contact_triangle`.
    pub contact_barycentric: [f64; 3],
    /// Device buttons: bit 0 grab, bit 1 heat.
    pub buttons: u32,
    /// Index of the touched body in the topology, or -1.
    pub contact_body: i32,
    /// Index of the touched triangle in the topology's global triangle list (valid with contact).
    pub contact_triangle: u32,
    /// The tool's index in the scene's tool list, below [`MAX_TOOLS`] (0 in a scene with one
    /// tool).
    pub tool: u32,
    /// `TopologyHeader::topology_id` the contact indices refer to.
    pub topology_id: u64,
    /// Stiffness of the tool law the hand feels against `contact_body` (N/m for the linear law,
    /// N/m² for the quadratic), after the device's clamp; 0 without contact. The deformation
    /// process gives the tissue this same spring, so action equals reaction.
    pub tool_stiffness: f64,
}

/// Level-of-precision model a body runs right now (`BodyFrame::model`).
#[repr(u8)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BodyModel {
    /// Green-coordinates cage.
    Gc = 0,
    /// Mass-spring-damper.
    Msd = 1,
    /// Finite elements.
    Fem = 2,
}

impl BodyModel {
    /// Decodes the wire value.
    pub fn from_u8(v: u8) -> Option<BodyModel> {
        match v {
            0 => Some(BodyModel::Gc),
            1 => Some(BodyModel::Msd),
            2 => Some(BodyModel::Fem),
            _ => None,
        }
    }
    /// Short display name.
    pub fn as_str(self) -> &'static str {
        match self {
            BodyModel::Gc => "GC",
            BodyModel::Msd => "MSD",
            BodyModel::Fem => "FEM",
        }
    }
}

/// `BodyFrame::state`: at rest (cheap model), or in motion (precise model).
pub const BODY_STATE_REST: u8 = 0;
/// `BodyFrame::state`: being touched or still settling.
pub const BODY_STATE_ACTIVE: u8 = 1;
/// `BodyFrame::state`: blew up this step and was reset (see `BodyFrame::resets`).
pub const BODY_STATE_RESET: u8 = 2;

/// Per-body part of a frame.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[type_name("lop::BodyFrame")]
pub struct BodyFrame {
    /// Axis-aligned bounds of the body's nodes this frame, m.
    pub aabb_min: [f32; 3],
    /// Axis-aligned bounds of the body's nodes this frame, m.
    pub aabb_max: [f32; 3],
    /// Kinetic energy, J.
    pub kinetic_energy: f32,
    /// Largest nodal speed, m/s.
    pub max_speed: f32,
    /// Wall time of this body's last model step, ns.
    pub step_ns: u32,
    /// Blow-ups detected (NaN, runaway energy) and reset since the scene loaded.
    pub resets: u32,
    /// [`BodyModel`] as u8.
    pub model: u8,
    /// `BODY_STATE_*`.
    pub state: u8,
    /// Padding, zero.
    pub _pad: [u8; 2],
    /// Levels-of-precision transitions (cage ↔ precise model) since the scene loaded.
    pub switches: u32,
    /// The period of the body's next step, µs: its configured period, or a longer one the
    /// deformation process chose because a step costs more than that on this machine.
    pub period_us: u32,
    /// Simulated time kept over wall time in the last second, `1 − dropped / elapsed` with
    /// `dropped` the simulated time the body lost as lag (1: real time; below: the body falls
    /// behind the wall clock); 0 before a second has passed.
    pub real_time_factor: f32,
}

/// User header of a scene frame (`PREFIX/scene/frame`); the payload is `[NodeSample]` with
/// `node_count` elements, bodies' nodes concatenated in topology order.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("lop::FrameHeader")]
pub struct FrameHeader {
    /// [`crate::CONTRACT_VERSION`].
    pub contract_version: u32,
    /// Bodies in use in `bodies`.
    pub body_count: u32,
    /// The topology these positions belong to. A reader must ignore frames whose id differs from
    /// the topology it holds and wait for the new topology.
    pub topology_id: u64,
    /// Frame counter since the deformation process started.
    pub sequence: u64,
    /// Simulated time, s.
    pub sim_time: f64,
    /// When the frame was published.
    pub publish_ns: u64,
    /// `ToolState::stamp_ns` of the newest state of the first tool (tool 0) the step used (0 if
    /// none yet).
    pub tool_stamp_ns: u64,
    /// When the deformation process read that state of the first tool (tool 0).
    pub tool_read_ns: u64,
    /// Wall time of the whole world step (all bodies, contact), ns.
    pub step_ns: u64,
    /// Elements in the payload slice.
    pub node_count: u32,
    /// Padding, zero.
    pub _pad: u32,
    /// Per-body state; the first `body_count` are valid.
    pub bodies: [BodyFrame; MAX_BODIES],
    /// Tools in the scene: `contacts[..tool_count]` are meaningful; a reader ignores the rest.
    pub tool_count: u32,
    /// Padding, zero.
    pub _pad2: u32,
    /// Per tool, indexed by `ToolState::tool`: the contact patch this step balanced for it.
    pub contacts: [ContactFrame; MAX_TOOLS],
}

/// `ContactFrame::body` when no contact patch was pressed this step.
pub const NO_CONTACT: u32 = u32::MAX;

impl Default for FrameHeader {
    /// Zeros, no tool, and no contact patch.
    fn default() -> FrameHeader {
        FrameHeader {
            contract_version: 0,
            body_count: 0,
            topology_id: 0,
            sequence: 0,
            sim_time: 0.0,
            publish_ns: 0,
            tool_stamp_ns: 0,
            tool_read_ns: 0,
            step_ns: 0,
            node_count: 0,
            _pad: 0,
            bodies: [BodyFrame::default(); MAX_BODIES],
            tool_count: 0,
            _pad2: 0,
            contacts: [ContactFrame::default(); MAX_TOOLS],
        }
    }
}

impl FrameHeader {
    /// The contact of tool `tool` this step: `None` for a tool beyond `tool_count` (or
    /// [`MAX_TOOLS`]). Its `body` is [`NO_CONTACT`] when the tool pressed no patch.
    pub fn contact(&self, tool: usize) -> Option<&ContactFrame> {
        self.contacts
            .get(tool)
            .filter(|_| tool < self.tool_count as usize)
    }
}

/// One tool's contact patch in a frame (`FrameHeader::contacts`): where the step balanced it,
/// and its local model, which the haptic loop renders between frames.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("lop::ContactFrame")]
pub struct ContactFrame {
    /// Where this step balanced the tool's contact patch (the tool sphere's centre, resting on
    /// the tissue and held by the tool spring), m; valid when `body` is a body index.
    /// The haptic loop rests its god-object there, so the hand feels what the tissue received.
    pub proxy: [f64; 3],
    /// The local model of the patch, for the haptic loop between frames (valid when `local`
    /// is 1): the force the tissue received this step, N.
    pub force: [f64; 3],
    /// The device position (tool centre) the step balanced the patch against, m.
    pub device: [f64; 3],
    /// `∂force / ∂device`, row-major 3 × 3, N/m: the tool spring in series with the tissue at
    /// the patch over one step. Symmetric, never stiffer than the tool.
    pub stiffness: [f64; 9],
    /// The patch's free motion: how fast the force changes with the device held, N/s.
    pub drift: [f64; 3],
    /// How long a reader may extrapolate `drift`, s (the touched body's step).
    pub horizon: f64,
    /// The body the patch pressed, or [`NO_CONTACT`].
    pub body: u32,
    /// 1: the `force` … `horizon` fields hold the local model of the patch on `body`; 0: this
    /// frame has none for this tool (render against the surface).
    pub local: u32,
}

impl Default for ContactFrame {
    /// Zeros, and no contact patch.
    fn default() -> ContactFrame {
        ContactFrame {
            proxy: [0.0; 3],
            force: [0.0; 3],
            device: [0.0; 3],
            stiffness: [0.0; 9],
            drift: [0.0; 3],
            horizon: 0.0,
            body: NO_CONTACT,
            local: 0,
        }
    }
}

/// One node of a frame.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[type_name("lop::NodeSample")]
pub struct NodeSample {
    /// Position, m, scene frame.
    pub position: [f32; 3],
    /// Temperature, °C.
    pub temperature: f32,
    /// `NODE_FLAG_*` bits.
    pub flags: u32,
}

/// `NodeSample::flags` bit: the tissue at this node has coagulated (burned).
pub const NODE_FLAG_BURNED: u32 = 1 << 0;

/// `BodyTopology::importance`: switches to FEM when touched.
pub const IMPORTANCE_IMPORTANT: u8 = 1;
/// `BodyTopology::importance`: switches to mass-spring when touched.
pub const IMPORTANCE_NORMAL: u8 = 0;

/// Static description of one body, in the topology header.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[type_name("lop::BodyTopology")]
pub struct BodyTopology {
    /// Name, UTF-8, NUL-padded.
    pub name: [u8; BODY_NAME_LEN],
    /// First node of the body in a frame's node slice.
    pub node_offset: u32,
    /// Nodes of the body.
    pub node_count: u32,
    /// First surface triangle of the body in the topology's triangle list.
    pub triangle_offset: u32,
    /// Surface triangles of the body.
    pub triangle_count: u32,
    /// First tetrahedron of the body in the topology's tetrahedron list.
    pub tet_offset: u32,
    /// Tetrahedra of the body.
    pub tet_count: u32,
    /// Display colour, sRGB 0..1.
    pub color: [f32; 3],
    /// `IMPORTANCE_*`.
    pub importance: u8,
    /// Padding, zero.
    pub _pad: [u8; 3],
    /// First vertex of the body's render surface in the topology's render vertex list.
    pub render_vertex_offset: u32,
    /// Render vertices of the body; 0 when it has no render surface (draw its surface
    /// triangles over the frame's nodes instead).
    pub render_vertex_count: u32,
    /// First triangle of the body's render surface in the topology's render triangle list.
    pub render_triangle_offset: u32,
    /// Render triangles of the body.
    pub render_triangle_count: u32,
}

impl BodyTopology {
    /// The name as a string (up to the first NUL; invalid UTF-8 yields "?").
    pub fn name_str(&self) -> &str {
        let end = self
            .name
            .iter()
            .position(|&b| b == 0)
            .unwrap_or(BODY_NAME_LEN);
        std::str::from_utf8(&self.name[..end]).unwrap_or("?")
    }
    /// Stores `name`, truncated to [`BODY_NAME_LEN`] bytes at a character boundary.
    pub fn set_name(&mut self, name: &str) {
        self.name = [0; BODY_NAME_LEN];
        let mut end = name.len().min(BODY_NAME_LEN);
        while !name.is_char_boundary(end) {
            end -= 1;
        }
        self.name[..end].copy_from_slice(&name.as_bytes()[..end]);
    }
}

/// User header of the topology (`PREFIX/scene/topology`), published once per scene load with
/// history 1 so late subscribers get it. The payload is `[u32]`, in this order:
/// - `3 × triangle_count` global node indices of the outward-wound surface triangles;
/// - `4 × tet_count` of the tetrahedra;
/// - `3 × render_triangle_count` global render vertex indices of the render surfaces'
///   triangles (the surfaces the scene draws in place of its bodies' mesh boundaries);
/// - [`RENDER_VERTEX_WORDS`]` × render_vertex_count`: per render vertex, the four global nodes
///   it follows, then its four weights as `f32` bits. Its position in a frame is
///   `Σ weightᵢ · position[nodeᵢ]` (weights sum to 1; a vertex just outside the mesh has some
///   negative). Renderers compute it: a frame carries the nodes only.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[type_name("lop::TopologyHeader")]
pub struct TopologyHeader {
    /// [`crate::CONTRACT_VERSION`].
    pub contract_version: u32,
    /// Bodies in use in `bodies`.
    pub body_count: u32,
    /// Identifies this scene load; frames name it. Never 0.
    pub topology_id: u64,
    /// Nodes over all bodies (the length of a frame's payload).
    pub node_count: u32,
    /// Surface triangles over all bodies.
    pub triangle_count: u32,
    /// Tetrahedra over all bodies.
    pub tet_count: u32,
    /// Render triangles over all bodies.
    pub render_triangle_count: u32,
    /// Render vertices over all bodies.
    pub render_vertex_count: u32,
    /// Padding, zero.
    pub _pad: u32,
    /// Per-body description; the first `body_count` are valid.
    pub bodies: [BodyTopology; MAX_BODIES],
}

/// `u32`s per render vertex in the topology payload: four node indices, four `f32` weights.
pub const RENDER_VERTEX_WORDS: usize = 8;

/// Latency percentiles of one measured quantity, ns.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[type_name("lop::Percentiles")]
pub struct Percentiles {
    /// Samples recorded.
    pub count: u64,
    /// Median.
    pub p50: u64,
    /// 99th percentile.
    pub p99: u64,
    /// 99.9th percentile.
    pub p999: u64,
    /// Largest sample.
    pub max: u64,
}

/// `HapticTelemetry::rt_flags` bit: the loop runs under `SCHED_FIFO`.
pub const RT_FLAG_FIFO: u32 = 1 << 0;
/// `HapticTelemetry::rt_flags` bit: the loop's thread is pinned to a core.
pub const RT_FLAG_PINNED: u32 = 1 << 1;
/// `HapticTelemetry::rt_flags` bit: the process's memory is locked (`mlockall`).
pub const RT_FLAG_MLOCKED: u32 = 1 << 2;

/// Haptic loop statistics (`PREFIX/telemetry/haptic`), published about 4× a second.
/// `window_*` cover the time since the previous telemetry sample; `total_*` cover everything
/// since one second after start (start-up transients excluded).
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[type_name("lop::HapticTelemetry")]
pub struct HapticTelemetry {
    /// [`crate::CONTRACT_VERSION`].
    pub contract_version: u32,
    /// `RT_FLAG_*` bits.
    pub rt_flags: u32,
    /// When this sample was taken.
    pub stamp_ns: u64,
    /// Ticks since start.
    pub ticks: u64,
    /// Ticks that started after their deadline.
    pub overruns: u64,
    /// Ticks whose newest frame was stale.
    pub stale_ticks: u64,
    /// Device samples rejected (NaN, outside the workspace) plus device read/write errors.
    pub device_faults: u64,
    /// Tick rate over the window, Hz.
    pub rate_hz: f64,
    /// Magnitude of the last force rendered, N (with several tools, the largest of theirs).
    pub force_norm: f64,
    /// Lateness of the wake-up (wake − deadline; the loop spins to the deadline, never early).
    pub window_jitter: Percentiles,
    /// Tick compute time (read → write → publish) over the window.
    pub window_compute: Percentiles,
    /// Age of the frame the tick rendered against, over the window.
    pub window_frame_age: Percentiles,
    /// Same as `window_jitter`, since warm-up.
    pub total_jitter: Percentiles,
    /// Same as `window_compute`, since warm-up.
    pub total_compute: Percentiles,
    /// Same as `window_frame_age`, since warm-up.
    pub total_frame_age: Percentiles,
    /// Core the loop is pinned to, or -1.
    pub pinned_core: i32,
    /// Padding, zero.
    pub _pad: u32,
    /// `window_frame_age` of the ticks that rendered a contact (pressing or holding a body):
    /// how old the surface under the hand was (contract 6).
    pub window_frame_age_contact: Percentiles,
    /// Same as `window_frame_age_contact`, since warm-up.
    pub total_frame_age_contact: Percentiles,
}
