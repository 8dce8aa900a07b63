/* lop_ipc.h — lop's shared-memory contract for C and C++ renderers.
 *
 * Mirrors ipc/src/types.rs and ipc/src/control.rs field by field (see docs/ipc.md for the
 * services, their QoS and the rules for clients). Every padding byte is an explicit _pad field;
 * the _Static_asserts below pin sizes and offsets, and ipc/tests/c_header.rs compiles this
 * header and compares every offset with the Rust layout.
 *
 * Type names to give iceoryx2 when opening a service (they must match exactly):
 *   "lop::ToolState", "lop::FrameHeader", "lop::NodeSample", "lop::TopologyHeader",
 *   "u32" (topology payload), "lop::HapticTelemetry", "lop::ControlRequest",
 *   "lop::ControlResponse".
 */
#ifndef LOP_IPC_H
#define LOP_IPC_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define LOP_CONTRACT_VERSION 10u
/* uint32_t words per render vertex in the topology payload: 4 node indices, 4 float weights. */
#define LOP_RENDER_VERTEX_WORDS 8
#define LOP_MAX_BODIES 16
/* Most tools a scene may hold (one per haptic device). */
#define LOP_MAX_TOOLS 4
#define LOP_BODY_NAME_LEN 32
#define LOP_MAX_SUBSCRIBERS 16
#define LOP_TOOL_BUFFER 64
#define LOP_FRAME_BUFFER 4
#define LOP_TELEMETRY_BUFFER 16

/* ToolState.flags */
#define LOP_TOOL_FLAG_CONTACT      (1u << 0)
#define LOP_TOOL_FLAG_RAMPING      (1u << 1)
#define LOP_TOOL_FLAG_STALE_FRAME  (1u << 2)
#define LOP_TOOL_FLAG_DEVICE_ERROR (1u << 3)
#define LOP_TOOL_FLAG_GRAB         (1u << 4)
#define LOP_TOOL_FLAG_HEAT         (1u << 5)
#define LOP_TOOL_FLAG_LOCAL_MODEL  (1u << 6)

/* BodyFrame.model */
#define LOP_MODEL_GC  0u
#define LOP_MODEL_MSD 1u
#define LOP_MODEL_FEM 2u
/* BodyFrame.state */
#define LOP_BODY_STATE_REST   0u
#define LOP_BODY_STATE_ACTIVE 1u
#define LOP_BODY_STATE_RESET  2u
/* NodeSample.flags */
#define LOP_NODE_FLAG_BURNED (1u << 0)
/* BodyTopology.importance */
#define LOP_IMPORTANCE_NORMAL    0u
#define LOP_IMPORTANCE_IMPORTANT 1u
/* HapticTelemetry.rt_flags */
#define LOP_RT_FLAG_FIFO    (1u << 0)
#define LOP_RT_FLAG_PINNED  (1u << 1)
#define LOP_RT_FLAG_MLOCKED (1u << 2)

/* "lop::ToolState", service PREFIX/tool (every tool's states, told apart by .tool). 160 bytes,
 * align 8. */
typedef struct lop_ToolState {
    uint32_t contract_version;
    uint32_t flags;
    uint64_t sequence;
    uint64_t stamp_ns;
    double device_position[3];
    double proxy_position[3];
    double force[3];
    double tool_radius;
    double contact_barycentric[3];
    uint32_t buttons;
    int32_t contact_body;
    uint32_t contact_triangle;
    uint32_t tool;            /* the tool's index in the scene's tool list (0: the only one) */
    uint64_t topology_id;
    double tool_stiffness;
} lop_ToolState;

/* "lop::BodyFrame", inside FrameHeader. 56 bytes, align 4. */
typedef struct lop_BodyFrame {
    float aabb_min[3];
    float aabb_max[3];
    float kinetic_energy;
    float max_speed;
    uint32_t step_ns;
    uint32_t resets;
    uint8_t model;
    uint8_t state;
    uint8_t _pad[2];
    uint32_t switches;
    uint32_t period_us;       /* the period of the body's next step, us */
    float real_time_factor;   /* simulated over wall time in the last second; 0: not yet */
} lop_BodyFrame;

/* "lop::ContactFrame", one tool's contact patch inside FrameHeader. 184 bytes, align 8. */
typedef struct lop_ContactFrame {
    double proxy[3];          /* the tool's contact patch balanced here, m */
    /* The patch's local model, valid when local is 1: the force on the tissue follows
       F + K (c - device) + drift * min(t, horizon) between frames. */
    double force[3];          /* N, on the tissue */
    double device[3];         /* m, the device position the step balanced against */
    double stiffness[9];      /* dF/dc, row-major, N/m */
    double drift[3];          /* N/s, with the device held */
    double horizon;           /* s, how long the drift may be extrapolated */
    uint32_t body;            /* the body the patch pressed, or LOP_NO_CONTACT */
    uint32_t local;           /* 1: force ... horizon are valid */
} lop_ContactFrame;

/* "lop::FrameHeader", user header of PREFIX/scene/frame. 1712 bytes, align 8.
 * tool_stamp_ns / tool_read_ns are the first tool's (tool 0). */
typedef struct lop_FrameHeader {
    uint32_t contract_version;
    uint32_t body_count;
    uint64_t topology_id;
    uint64_t sequence;
    double sim_time;
    uint64_t publish_ns;
    uint64_t tool_stamp_ns;
    uint64_t tool_read_ns;
    uint64_t step_ns;
    uint32_t node_count;
    uint32_t _pad;
    lop_BodyFrame bodies[LOP_MAX_BODIES];
    uint32_t tool_count;      /* contacts[0 .. tool_count) are meaningful */
    uint32_t _pad2;
    lop_ContactFrame contacts[LOP_MAX_TOOLS]; /* indexed by ToolState.tool */
} lop_FrameHeader;

#define LOP_NO_CONTACT 0xFFFFFFFFu

/* "lop::NodeSample", payload element of PREFIX/scene/frame. 20 bytes, align 4. */
typedef struct lop_NodeSample {
    float position[3];
    float temperature;
    uint32_t flags;
} lop_NodeSample;

/* "lop::BodyTopology", inside TopologyHeader. 88 bytes, align 4. render_vertex_count 0: the
 * body has no render surface; draw its surface triangles over the frame's nodes. */
typedef struct lop_BodyTopology {
    uint8_t name[LOP_BODY_NAME_LEN];
    uint32_t node_offset;
    uint32_t node_count;
    uint32_t triangle_offset;
    uint32_t triangle_count;
    uint32_t tet_offset;
    uint32_t tet_count;
    float color[3];
    uint8_t importance;
    uint8_t _pad[3];
    uint32_t render_vertex_offset;
    uint32_t render_vertex_count;
    uint32_t render_triangle_offset;
    uint32_t render_triangle_count;
} lop_BodyTopology;

/* "lop::TopologyHeader", user header of PREFIX/scene/topology. 1448 bytes. Payload, uint32_t[]:
 * 3 * triangle_count node indices (surface triangles), 4 * tet_count (tetrahedra),
 * 3 * render_triangle_count render vertex indices (render triangles), then per render vertex
 * LOP_RENDER_VERTEX_WORDS words: 4 node indices and 4 weights (float bits). A render vertex is
 * drawn at sum(weight[i] * position[node[i]]) over the frame's nodes. */
typedef struct lop_TopologyHeader {
    uint32_t contract_version;
    uint32_t body_count;
    uint64_t topology_id;
    uint32_t node_count;
    uint32_t triangle_count;
    uint32_t tet_count;
    uint32_t render_triangle_count;
    uint32_t render_vertex_count;
    uint32_t _pad;
    lop_BodyTopology bodies[LOP_MAX_BODIES];
} lop_TopologyHeader;

/* "lop::Percentiles", inside HapticTelemetry. 40 bytes. */
typedef struct lop_Percentiles {
    uint64_t count;
    uint64_t p50;
    uint64_t p99;
    uint64_t p999;
    uint64_t max;
} lop_Percentiles;

/* "lop::HapticTelemetry", service PREFIX/telemetry/haptic. 312 bytes, align 8. */
typedef struct lop_HapticTelemetry {
    uint32_t contract_version;
    uint32_t rt_flags;
    uint64_t stamp_ns;
    uint64_t ticks;
    uint64_t overruns;
    uint64_t stale_ticks;
    uint64_t device_faults;
    double rate_hz;
    double force_norm;
    lop_Percentiles window_jitter;
    lop_Percentiles window_compute;
    lop_Percentiles window_frame_age;
    lop_Percentiles total_jitter;
    lop_Percentiles total_compute;
    lop_Percentiles total_frame_age;
    int32_t pinned_core;
    uint32_t _pad;
    lop_Percentiles window_frame_age_contact;
    lop_Percentiles total_frame_age_contact;
} lop_HapticTelemetry;

/* ---- control: request-response service PREFIX/control ---------------------------------- */
#define LOP_CONTROL_KEY_LEN 32
#define LOP_CONTROL_MESSAGE_LEN 128
#define LOP_CONTROL_MAX_PARAMS 16
#define LOP_CONTROL_MAX_CLIENTS 8
#define LOP_CONTROL_MAX_ACTIVE_REQUESTS 2

#define LOP_CONTROL_OP_GET     1u
#define LOP_CONTROL_OP_SET     2u
#define LOP_CONTROL_OP_PIN     3u
#define LOP_CONTROL_OP_RELEASE 4u
#define LOP_CONTROL_OP_RESET   5u
#define LOP_CONTROL_OP_PAUSE   6u
#define LOP_CONTROL_OP_RESUME  7u

#define LOP_CONTROL_STATUS_OK           0u
#define LOP_CONTROL_STATUS_UNKNOWN_BODY 1u
#define LOP_CONTROL_STATUS_UNKNOWN_KEY  2u
#define LOP_CONTROL_STATUS_BAD_VALUE    3u
#define LOP_CONTROL_STATUS_NOT_ALLOWED  4u
#define LOP_CONTROL_STATUS_BUSY         5u
#define LOP_CONTROL_STATUS_BAD_REQUEST  6u
#define LOP_CONTROL_STATUS_FAILED       7u

#define LOP_CONTROL_PIN_AUTO 255u
#define LOP_CONTROL_PARAM_LIVE (1u << 0)

/* "lop::ControlRequest". 88 bytes, align 8. */
typedef struct lop_ControlRequest {
    uint32_t contract_version;
    uint32_t op;
    int32_t body_index;
    uint32_t model;
    uint8_t body[LOP_BODY_NAME_LEN];
    uint8_t key[LOP_CONTROL_KEY_LEN];
    double value;
} lop_ControlRequest;

/* "lop::ControlParam", inside ControlResponse. 48 bytes, align 8. */
typedef struct lop_ControlParam {
    uint8_t key[LOP_CONTROL_KEY_LEN];
    double value;
    uint32_t flags;
    uint32_t _pad;
} lop_ControlParam;

/* "lop::ControlResponse". 952 bytes, align 8. */
typedef struct lop_ControlResponse {
    uint32_t contract_version;
    uint32_t status;
    int32_t body_index;
    uint8_t pin;
    uint8_t model;
    uint8_t paused;
    uint8_t _pad0;
    uint32_t param_count;
    uint32_t _pad1;
    uint8_t body[LOP_BODY_NAME_LEN];
    uint8_t message[LOP_CONTROL_MESSAGE_LEN];
    lop_ControlParam params[LOP_CONTROL_MAX_PARAMS];
} lop_ControlResponse;

#if defined(__STDC_VERSION__) && __STDC_VERSION__ >= 201112L
#define LOP_ASSERT(c, m) _Static_assert(c, m)
#elif defined(__cplusplus)
#define LOP_ASSERT(c, m) static_assert(c, m)
#else
#define LOP_ASSERT(c, m)
#endif

LOP_ASSERT(sizeof(lop_ToolState) == 160, "ToolState size");
LOP_ASSERT(offsetof(lop_ToolState, device_position) == 24, "ToolState.device_position");
LOP_ASSERT(offsetof(lop_ToolState, proxy_position) == 48, "ToolState.proxy_position");
LOP_ASSERT(offsetof(lop_ToolState, buttons) == 128, "ToolState.buttons");
LOP_ASSERT(offsetof(lop_ToolState, tool) == 140, "ToolState.tool");
LOP_ASSERT(offsetof(lop_ToolState, topology_id) == 144, "ToolState.topology_id");
LOP_ASSERT(offsetof(lop_ToolState, tool_stiffness) == 152, "ToolState.tool_stiffness");
LOP_ASSERT(sizeof(lop_BodyFrame) == 56, "BodyFrame size");
LOP_ASSERT(offsetof(lop_BodyFrame, model) == 40, "BodyFrame.model");
LOP_ASSERT(offsetof(lop_BodyFrame, switches) == 44, "BodyFrame.switches");
LOP_ASSERT(offsetof(lop_BodyFrame, period_us) == 48, "BodyFrame.period_us");
LOP_ASSERT(offsetof(lop_BodyFrame, real_time_factor) == 52, "BodyFrame.real_time_factor");
LOP_ASSERT(sizeof(lop_ContactFrame) == 184, "ContactFrame size");
LOP_ASSERT(offsetof(lop_ContactFrame, stiffness) == 72, "ContactFrame.stiffness");
LOP_ASSERT(offsetof(lop_ContactFrame, horizon) == 168, "ContactFrame.horizon");
LOP_ASSERT(offsetof(lop_ContactFrame, body) == 176, "ContactFrame.body");
LOP_ASSERT(offsetof(lop_ContactFrame, local) == 180, "ContactFrame.local");
LOP_ASSERT(sizeof(lop_FrameHeader) == 80 + 56 * LOP_MAX_BODIES + 184 * LOP_MAX_TOOLS, "FrameHeader size");
LOP_ASSERT(offsetof(lop_FrameHeader, tool_count) == 72 + 56 * LOP_MAX_BODIES, "FrameHeader.tool_count");
LOP_ASSERT(offsetof(lop_FrameHeader, contacts) == 80 + 56 * LOP_MAX_BODIES, "FrameHeader.contacts");
LOP_ASSERT(offsetof(lop_FrameHeader, node_count) == 64, "FrameHeader.node_count");
LOP_ASSERT(offsetof(lop_FrameHeader, bodies) == 72, "FrameHeader.bodies");
LOP_ASSERT(sizeof(lop_NodeSample) == 20, "NodeSample size");
LOP_ASSERT(offsetof(lop_NodeSample, flags) == 16, "NodeSample.flags");
LOP_ASSERT(sizeof(lop_BodyTopology) == 88, "BodyTopology size");
LOP_ASSERT(offsetof(lop_BodyTopology, render_vertex_offset) == 72, "BodyTopology.render_vertex_offset");
LOP_ASSERT(offsetof(lop_BodyTopology, color) == 56, "BodyTopology.color");
LOP_ASSERT(offsetof(lop_BodyTopology, importance) == 68, "BodyTopology.importance");
LOP_ASSERT(sizeof(lop_TopologyHeader) == 40 + 88 * LOP_MAX_BODIES, "TopologyHeader size");
LOP_ASSERT(offsetof(lop_TopologyHeader, bodies) == 40, "TopologyHeader.bodies");
LOP_ASSERT(sizeof(lop_Percentiles) == 40, "Percentiles size");
LOP_ASSERT(sizeof(lop_HapticTelemetry) == 392, "HapticTelemetry size");
LOP_ASSERT(offsetof(lop_HapticTelemetry, window_jitter) == 64, "HapticTelemetry.window_jitter");
LOP_ASSERT(offsetof(lop_HapticTelemetry, pinned_core) == 304, "HapticTelemetry.pinned_core");
LOP_ASSERT(offsetof(lop_HapticTelemetry, total_frame_age_contact) == 352,
           "HapticTelemetry.total_frame_age_contact");
LOP_ASSERT(sizeof(lop_ControlRequest) == 88, "ControlRequest size");
LOP_ASSERT(offsetof(lop_ControlRequest, body) == 16, "ControlRequest.body");
LOP_ASSERT(offsetof(lop_ControlRequest, key) == 48, "ControlRequest.key");
LOP_ASSERT(offsetof(lop_ControlRequest, value) == 80, "ControlRequest.value");
LOP_ASSERT(sizeof(lop_ControlParam) == 48, "ControlParam size");
LOP_ASSERT(sizeof(lop_ControlResponse) == 952, "ControlResponse size");
LOP_ASSERT(offsetof(lop_ControlResponse, pin) == 12, "ControlResponse.pin");
LOP_ASSERT(offsetof(lop_ControlResponse, body) == 24, "ControlResponse.body");
LOP_ASSERT(offsetof(lop_ControlResponse, message) == 56, "ControlResponse.message");
LOP_ASSERT(offsetof(lop_ControlResponse, params) == 184, "ControlResponse.params");

#ifdef __cplusplus
}
#endif
#endif /* LOP_IPC_H */
