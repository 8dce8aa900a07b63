//! What `lop-view` sends a browser over its WebSocket (`/ws`). Little-endian throughout.
//!
//! Text messages are JSON objects with a `type`:
//! - `status` `{connected, prefix}`: whether a daemon is attached;
//! - `topology` `{id, node_count, vertex_count, triangle_count, bodies: [{name, color,
//!   node_offset, node_count, render_vertex_offset, render_vertex_count, triangle_offset,
//!   triangle_count, importance}]}`, followed at once by the binary triangle message. The page
//!   draws `vertex_count` vertices: the frame's nodes, then every body's render surface
//!   vertices (`render_vertex_offset` counts from 0 over all of them, after the nodes). A body
//!   with a render surface is drawn by its render triangles, one without by its mesh's surface
//!   triangles;
//! - `telemetry` `{rate_hz, overruns, stale_ticks, force, jitter_p99_us, compute_p99_us,
//!   frame_age_p99_ms, history: {jitter, compute, age}}`, about 4 times a second;
//! - `control` `{ok, status, status_name, message, body, body_index, pin, model, paused,
//!   params: [{key, value, live}]}`, the answer to a control request; a request refused for its
//!   token is answered `{ok: false, status_name: "read-only", read_only: true, message}` and
//!   never reaches the daemon.
//!
//! Binary messages start with a `u32` kind:
//! - `1` triangles: `u32 1, u32 triangle_count`, then `3 × triangle_count` `u32` vertex
//!   indices (as drawn: nodes, then render vertices);
//! - `2` frame: a 24-byte header (`u32 2, u32 node_count, u32 body_count, u32 tool_count,
//!   f32 sim_time, f32 frame_age_ms` (publish → viewer receive)), then per tool with a state
//!   (the newest state of each `ToolState::tool` index, in index order; none before the first)
//!   12 × 4 bytes (`u32 tool, u32 flags` (`TOOL_FLAG_*`), `f32 device[3], f32 proxy[3],
//!   f32 tool_radius, f32 force[3]`), then per body 10 × 4 bytes (`u32 model, u32 state,
//!   u32 switches, u32 resets, f32 kinetic_energy, f32 max_speed, f32 step_ms, f32 period_ms,
//!   f32 real_time_factor, u32 0`), then `f32 position[3 × N]`,
//!   `f32 temperature[N]`, `u8 flags[N]` (`NODE_FLAG_*`) padded to 4 bytes, over the `N` drawn
//!   vertices: a render vertex's position and temperature are blended from its four nodes by
//!   its weights here, its flags are its heaviest node's.
//!
//! The page sends control requests as JSON text: `{"op": "get"|"set"|"pin"|"release"|"reset"|
//! "pause"|"resume", "body": NAME, "key": KEY, "value": NUMBER, "model": "gc"|"msd"|"fem",
//! "token": TOKEN}`. `token` is the run's control token (the `#token=…` of the URL the viewer
//! printed); every request, `get` included, needs it (see [`crate::access`]).

use lop_client::*;
use serde_json::{json, Value};

/// Binary message kind: triangles.
pub const KIND_TRIANGLES: u32 = 1;
/// Binary message kind: frame.
pub const KIND_FRAME: u32 = 2;
/// Bytes of a frame message's header.
pub const FRAME_HEADER_BYTES: usize = 24;
/// Bytes per tool in a frame message.
pub const FRAME_TOOL_BYTES: usize = 48;
/// Bytes per body in a frame message.
pub const FRAME_BODY_BYTES: usize = 40;

/// The newest state of each tool, by its index in the scene's tool list (`ToolState::tool`),
/// as the frame message carries them.
#[derive(Debug, Clone, Default)]
pub struct LatestTools {
    states: [Option<ToolState>; MAX_TOOLS],
}

impl LatestTools {
    /// Keeps `s` as the newest state of its tool. A state naming a tool beyond [`MAX_TOOLS`]
    /// is not the contract's and is dropped (false).
    pub fn update(&mut self, s: &ToolState) -> bool {
        match self.states.get_mut(s.tool as usize) {
            Some(slot) => {
                *slot = Some(*s);
                true
            }
            None => false,
        }
    }

    /// The tools with a state, in index order.
    pub fn states(&self) -> impl Iterator<Item = &ToolState> {
        self.states.iter().flatten()
    }
}

/// The topology's JSON description.
pub fn topology_json(t: &Topology, prefix: &str) -> String {
    let bodies: Vec<Value> = t
        .bodies()
        .iter()
        .map(|b| {
            json!({
                "name": b.name_str(),
                "color": b.color,
                "node_offset": b.node_offset,
                "node_count": b.node_count,
                "render_vertex_offset": b.render_vertex_offset,
                "render_vertex_count": b.render_vertex_count,
                "triangle_offset": b.triangle_offset,
                "triangle_count": b.triangle_count,
                "importance": if b.importance == IMPORTANCE_IMPORTANT { "important" } else { "normal" },
            })
        })
        .collect();
    json!({
        "type": "topology",
        "prefix": prefix,
        "id": format!("{:#x}", t.header.topology_id),
        "node_count": t.header.node_count,
        "vertex_count": t.header.node_count as usize + t.render_vertices.len(),
        "triangle_count": drawn_triangles(t).len(),
        "bodies": bodies,
    })
    .to_string()
}

/// The triangles drawn, over the drawn vertices (nodes, then render vertices): each body's
/// render surface if it has one, else its mesh's surface.
pub fn drawn_triangles(t: &Topology) -> Vec<[u32; 3]> {
    let nodes = t.header.node_count;
    let mut out = Vec::new();
    for b in t.bodies() {
        let (first, count) = (
            b.render_triangle_offset as usize,
            b.render_triangle_count as usize,
        );
        match t.render_triangles.get(first..first + count) {
            Some(render) if b.render_vertex_count > 0 && count > 0 => {
                out.extend(render.iter().map(|tri| tri.map(|k| k + nodes)));
            }
            _ => {
                let (first, count) = (b.triangle_offset as usize, b.triangle_count as usize);
                out.extend_from_slice(t.triangles.get(first..first + count).unwrap_or(&[]));
            }
        }
    }
    out
}

/// The triangle message.
pub fn topology_binary(t: &Topology) -> Vec<u8> {
    let triangles = drawn_triangles(t);
    let mut out = Vec::with_capacity(8 + triangles.len() * 12);
    out.extend_from_slice(&KIND_TRIANGLES.to_le_bytes());
    out.extend_from_slice(&(triangles.len() as u32).to_le_bytes());
    for tri in &triangles {
        for k in tri {
            out.extend_from_slice(&k.to_le_bytes());
        }
    }
    out
}

fn f32s(out: &mut Vec<u8>, v: &[f32]) {
    for x in v {
        out.extend_from_slice(&x.to_le_bytes());
    }
}

/// The frame message, over the frame's nodes and `topology`'s render vertices (none without a
/// topology, or when the frame belongs to another), with the newest state of each tool.
pub fn frame_binary(f: &Frame, topology: Option<&Topology>, tools: &LatestTools) -> Vec<u8> {
    let render: &[RenderVertex] = match topology {
        Some(t) if t.header.topology_id == f.header.topology_id => &t.render_vertices,
        _ => &[],
    };
    let n = f.nodes.len() + render.len();
    let bodies = f.bodies();
    let tool_count = tools.states().count();
    let mut out = Vec::with_capacity(
        FRAME_HEADER_BYTES
            + tool_count * FRAME_TOOL_BYTES
            + bodies.len() * FRAME_BODY_BYTES
            + n * 17
            + 4,
    );
    out.extend_from_slice(&KIND_FRAME.to_le_bytes());
    out.extend_from_slice(&(n as u32).to_le_bytes());
    out.extend_from_slice(&(bodies.len() as u32).to_le_bytes());
    out.extend_from_slice(&(tool_count as u32).to_le_bytes());
    let age_ms = f.received_ns.saturating_sub(f.header.publish_ns) as f64 * 1e-6;
    f32s(&mut out, &[f.header.sim_time as f32, age_ms as f32]);
    debug_assert_eq!(out.len(), FRAME_HEADER_BYTES);
    let p = |v: [f64; 3]| [v[0] as f32, v[1] as f32, v[2] as f32];
    for t in tools.states() {
        out.extend_from_slice(&t.tool.to_le_bytes());
        out.extend_from_slice(&t.flags.to_le_bytes());
        f32s(&mut out, &p(t.device_position));
        f32s(&mut out, &p(t.proxy_position));
        f32s(&mut out, &[t.tool_radius as f32]);
        f32s(&mut out, &p(t.force));
    }
    debug_assert_eq!(
        out.len(),
        FRAME_HEADER_BYTES + tool_count * FRAME_TOOL_BYTES
    );
    for b in bodies {
        for v in [b.model as u32, b.state as u32, b.switches, b.resets] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        f32s(
            &mut out,
            &[
                b.kinetic_energy,
                b.max_speed,
                b.step_ns as f32 * 1e-6,
                b.period_us as f32 * 1e-3,
                b.real_time_factor,
            ],
        );
        out.extend_from_slice(&0u32.to_le_bytes());
    }
    for s in &f.nodes {
        f32s(&mut out, &s.position);
    }
    for v in render {
        f32s(&mut out, &v.blend(&f.nodes, |s| s.position));
    }
    for s in &f.nodes {
        f32s(&mut out, &[s.temperature]);
    }
    for v in render {
        f32s(&mut out, &v.blend(&f.nodes, |s| [s.temperature]));
    }
    out.extend(f.nodes.iter().map(|s| s.flags.min(255) as u8));
    out.extend(render.iter().map(|v| {
        let heaviest = (0..4).fold(0, |m, i| if v.weights[i] > v.weights[m] { i } else { m });
        f.nodes
            .get(v.nodes[heaviest] as usize)
            .map_or(0, |s| s.flags.min(255) as u8)
    }));
    while out.len() % 4 != 0 {
        out.push(0);
    }
    out
}

/// The status message.
pub fn status_json(connected: bool, prefix: &str) -> String {
    json!({"type": "status", "connected": connected, "prefix": prefix}).to_string()
}

/// Recent telemetry windows, for the page's plots.
#[derive(Debug, Default)]
pub struct TelemetryHistory {
    jitter_us: Vec<f64>,
    compute_us: Vec<f64>,
    age_ms: Vec<f64>,
}

/// Telemetry samples kept for the plots (about 30 s at 4 Hz).
pub const HISTORY_LEN: usize = 120;

impl TelemetryHistory {
    /// Adds one telemetry sample (window p99s).
    pub fn push(&mut self, t: &HapticTelemetry) {
        for (v, x) in [
            (&mut self.jitter_us, t.window_jitter.p99 as f64 * 1e-3),
            (&mut self.compute_us, t.window_compute.p99 as f64 * 1e-3),
            (&mut self.age_ms, t.window_frame_age.p99 as f64 * 1e-6),
        ] {
            v.push(x);
            if v.len() > HISTORY_LEN {
                v.remove(0);
            }
        }
    }
    /// The telemetry message for the newest sample `t`.
    pub fn json(&self, t: &HapticTelemetry) -> String {
        json!({
            "type": "telemetry",
            "rate_hz": t.rate_hz,
            "ticks": t.ticks,
            "overruns": t.overruns,
            "stale_ticks": t.stale_ticks,
            "force": t.force_norm,
            "jitter_p99_us": t.window_jitter.p99 as f64 * 1e-3,
            "compute_p99_us": t.window_compute.p99 as f64 * 1e-3,
            "frame_age_p99_ms": t.window_frame_age.p99 as f64 * 1e-6,
            "history": {"jitter": self.jitter_us, "compute": self.compute_us, "age": self.age_ms},
        })
        .to_string()
    }
}

/// The `op` (for logs, `"?"` if none) and the `token` of a control request, if any.
pub fn control_op_and_token(text: &str) -> (String, Option<String>) {
    let v: Value = serde_json::from_str(text).unwrap_or(Value::Null);
    let op = v["op"].as_str().unwrap_or("?");
    // Keep a log line short whatever the page sent.
    let op: String = op.chars().take(32).collect();
    (op, v["token"].as_str().map(str::to_string))
}

/// Parses the page's control request. A refusal quotes the bad part as the page sent it (JSON:
/// `"sph"`, `null`, `5`), or serde_json's line and column for text that is not JSON.
pub fn control_request(text: &str) -> Result<ControlRequest, String> {
    let v: Value = serde_json::from_str(text).map_err(|e| format!("bad JSON: {e}"))?;
    let body = v["body"].as_str().unwrap_or("");
    Ok(match v["op"].as_str().unwrap_or("") {
        "get" => ControlRequest::new(CONTROL_OP_GET, body),
        "set" => {
            let key = v["key"].as_str().unwrap_or("");
            let value = match &v["value"] {
                Value::Number(n) => n.as_f64().unwrap_or(f64::NAN),
                Value::String(s) => s
                    .trim()
                    .parse()
                    .map_err(|_| format!("{key}: value {} is not a number", v["value"]))?,
                other => return Err(format!("{key}: value {other} is not a number")),
            };
            ControlRequest::set(body, key, value)
        }
        "pin" => {
            let model = match v["model"].as_str() {
                Some("gc") => BodyModel::Gc,
                Some("msd") => BodyModel::Msd,
                Some("fem") => BodyModel::Fem,
                _ => {
                    let m = &v["model"];
                    return Err(format!("pin: model {m} is not one of gc, msd, fem"));
                }
            };
            ControlRequest::pin(body, model)
        }
        "release" => ControlRequest::new(CONTROL_OP_RELEASE, body),
        "reset" => ControlRequest::new(CONTROL_OP_RESET, ""),
        "pause" => ControlRequest::new(CONTROL_OP_PAUSE, ""),
        "resume" => ControlRequest::new(CONTROL_OP_RESUME, ""),
        _ => return Err(format!("op {} is not a control operation", v["op"])),
    })
}

/// The control answer as JSON.
pub fn control_response_json(r: &ControlResponse) -> String {
    let params: Vec<Value> = r
        .params()
        .iter()
        .map(|p| json!({"key": p.key_str(), "value": p.value, "live": p.flags & CONTROL_PARAM_LIVE != 0}))
        .collect();
    json!({
        "type": "control",
        "ok": r.status == CONTROL_STATUS_OK,
        "status": r.status,
        "status_name": r.status_name(),
        "message": r.message_str(),
        "body": r.body_str(),
        "body_index": r.body_index,
        "pin": if r.pin == CONTROL_PIN_AUTO { "auto" } else { BodyModel::from_u8(r.pin).map_or("?", BodyModel::as_str) },
        "model": BodyModel::from_u8(r.model).map_or("?", BodyModel::as_str),
        "paused": r.paused != 0,
        "params": params,
    })
    .to_string()
}

/// A control error raised before the daemon was asked.
pub fn control_error_json(message: &str) -> String {
    json!({"type": "control", "ok": false, "status_name": "error", "message": message, "params": []})
        .to_string()
}

/// The answer to a control request refused for its token (the connection stays, read-only).
pub fn control_read_only_json(message: &str) -> String {
    json!({"type": "control", "ok": false, "status_name": "read-only", "read_only": true,
           "message": message, "params": []})
    .to_string()
}
