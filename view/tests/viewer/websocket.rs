//! lop-view's WebSocket against a live daemon: the topology comes first, then frames whose
//! node count matches it; the control panel's requests reach the daemon and bad ones get typed
//! errors; when the daemon is stopped and started again, the same WebSocket delivers the new
//! topology (the viewer re-attaches by itself).

use crate::common;

use std::net::TcpStream;
use std::time::{Duration, Instant};

use common::Viewer;
use lop_system_tests::{unique_prefix, Daemon};
use lop_view::wire::{
    FRAME_BODY_BYTES, FRAME_HEADER_BYTES, FRAME_TOOL_BYTES, KIND_FRAME, KIND_TRIANGLES,
};
use tungstenite::stream::MaybeTlsStream;
use tungstenite::{Message, WebSocket};

type Ws = WebSocket<MaybeTlsStream<TcpStream>>;

fn u32_at(b: &[u8], o: usize) -> u32 {
    u32::from_le_bytes(b[o..o + 4].try_into().unwrap())
}

/// Reads messages until `pick` returns something, for at most `limit`.
fn until<T>(ws: &mut Ws, limit: Duration, mut pick: impl FnMut(&Message) -> Option<T>) -> T {
    let start = Instant::now();
    while start.elapsed() < limit {
        match ws.read() {
            Ok(m) => {
                if let Some(v) = pick(&m) {
                    return v;
                }
            }
            Err(tungstenite::Error::Io(e))
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                ) => {}
            Err(e) => panic!("websocket: {e}"),
        }
    }
    panic!("nothing expected arrived within {limit:?}");
}

fn json(m: &Message, kind: &str) -> Option<serde_json::Value> {
    let Message::Text(t) = m else { return None };
    let v: serde_json::Value = serde_json::from_str(t.as_str()).ok()?;
    (v["type"] == kind).then_some(v)
}

/// Sends `req` with the viewer's control token and waits for the answer.
fn control(ws: &mut Ws, token: &str, mut req: serde_json::Value) -> serde_json::Value {
    req["token"] = token.into();
    ws.send(Message::text(req.to_string())).unwrap();
    until(ws, Duration::from_secs(40), |m| json(m, "control"))
}

fn start_daemon(prefix: &str) -> Daemon {
    Daemon::spawn(
        &["run", "--scene", "abdomen", "--prefix", prefix, "--quiet"],
        prefix,
        Duration::from_secs(180),
    )
}

#[test]
fn websocket_streams_frames_forwards_control_and_survives_a_daemon_restart() {
    let prefix = unique_prefix("view-ws");
    let mut daemon = start_daemon(&prefix);
    let viewer = Viewer::spawn(&prefix, Duration::from_secs(180));
    let (mut ws, _) = tungstenite::connect(format!("ws://{}/ws", viewer.addr)).expect("connect");
    if let MaybeTlsStream::Plain(s) = ws.get_ref() {
        s.set_read_timeout(Some(Duration::from_millis(200)))
            .unwrap();
    }

    // Topology, its triangles, then frames of that many vertices: the nodes, then the liver's
    // render surface.
    let topo = until(&mut ws, Duration::from_secs(60), |m| json(m, "topology"));
    let nodes = topo["vertex_count"].as_u64().unwrap() as usize;
    let liver = &topo["bodies"][0];
    assert_eq!(liver["render_vertex_count"], 1890, "{topo}");
    assert_eq!(
        nodes,
        topo["node_count"].as_u64().unwrap() as usize + 1890,
        "{topo}"
    );
    let names: Vec<&str> = topo["bodies"]
        .as_array()
        .unwrap()
        .iter()
        .map(|b| b["name"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["liver", "spleen", "stomach", "pancreas"]);
    let tris = until(&mut ws, Duration::from_secs(5), |m| match m {
        Message::Binary(b) if u32_at(b, 0) == KIND_TRIANGLES => Some(b.to_vec()),
        _ => None,
    });
    assert_eq!(
        u32_at(&tris, 4) as u64,
        topo["triangle_count"].as_u64().unwrap()
    );
    assert!(tris[8..]
        .chunks_exact(4)
        .all(|c| (u32::from_le_bytes(c.try_into().unwrap()) as usize) < nodes));
    // The liver is drawn by its render surface's 3,776 triangles, over the render vertices.
    let first_render = topo["node_count"].as_u64().unwrap() as u32;
    let render_refs = tris[8..]
        .chunks_exact(4)
        .filter(|c| u32::from_le_bytes((*c).try_into().unwrap()) >= first_render)
        .count();
    assert_eq!(render_refs, 3 * 3776);
    let frame = until(&mut ws, Duration::from_secs(30), |m| match m {
        Message::Binary(b) if u32_at(b, 0) == KIND_FRAME => Some(b.to_vec()),
        _ => None,
    });
    assert_eq!(u32_at(&frame, 4) as usize, nodes);
    assert_eq!(u32_at(&frame, 8), 4);
    // The scene's one tool, once the haptic loop has published a state: tool 0.
    let tools = u32_at(&frame, 12) as usize;
    assert!(tools <= 1, "{tools} tools");
    if tools == 1 {
        assert_eq!(u32_at(&frame, FRAME_HEADER_BYTES), 0, "tool index");
    }
    let bodies0 = FRAME_HEADER_BYTES + tools * FRAME_TOOL_BYTES;
    let expected = bodies0 + 4 * FRAME_BODY_BYTES + nodes * 16 + nodes.div_ceil(4) * 4;
    assert_eq!(frame.len(), expected);
    // Every body carries the period of its next step (its model's: the cage's 20 ms, or the
    // precise model's 1 ms or, on a machine too slow for it, longer) and a real-time factor in
    // [0, 2).
    for k in 0..4 {
        let rec = bodies0 + k * FRAME_BODY_BYTES;
        let f = |o: usize| f32::from_le_bytes(frame[rec + o..rec + o + 4].try_into().unwrap());
        assert!(
            f(28) > 0.0 && f(28) <= 100.0,
            "body {k}: period {} ms",
            f(28)
        );
        assert!(
            (0.0..2.0).contains(&f(32)),
            "body {k}: real-time factor {}",
            f(32)
        );
    }
    let pos0 = bodies0 + 4 * FRAME_BODY_BYTES;
    let temps = &frame[pos0 + 12 * nodes..pos0 + 16 * nodes];
    let t0 = f32::from_le_bytes(temps[..4].try_into().unwrap());
    assert!((20.0..=100.0).contains(&t0), "temperature {t0}");

    // Control through the page's channel, with the token of the printed URL.
    let token = viewer
        .token
        .clone()
        .expect("a loopback viewer prints a token");
    let r = control(
        &mut ws,
        &token,
        serde_json::json!({"op": "get", "body": "spleen"}),
    );
    assert_eq!(r["ok"], true, "{r}");
    assert_eq!(r["body"], "spleen");
    let young = r["params"]
        .as_array()
        .unwrap()
        .iter()
        .find(|p| p["key"] == "fem.young")
        .unwrap();
    assert_eq!(young["value"], 18000.0);
    let r = control(
        &mut ws,
        &token,
        serde_json::json!({"op": "set", "body": "spleen", "key": "fem.poisson", "value": 0.7}),
    );
    assert_eq!(r["status_name"], "bad value", "{r}");
    assert!(
        r["message"].as_str().unwrap().contains("fem.poisson = 0.7"),
        "{r}"
    );
    let r = control(
        &mut ws,
        &token,
        serde_json::json!({"op": "pin", "body": "kidney", "model": "fem"}),
    );
    assert_eq!(r["status_name"], "unknown body", "{r}");
    let r = control(&mut ws, &token, serde_json::json!({"op": "pause"}));
    assert_eq!(
        (r["ok"].clone(), r["paused"].clone()),
        (true.into(), true.into()),
        "{r}"
    );
    let r = control(&mut ws, &token, serde_json::json!({"op": "resume"}));
    assert_eq!(r["paused"], false, "{r}");

    // Stop the daemon and start another one under the same prefix: the viewer re-attaches and
    // the open WebSocket gets the new topology.
    let old_id = topo["id"].as_str().unwrap().to_string();
    daemon.signal(libc::SIGINT);
    assert!(daemon
        .wait(Duration::from_secs(20))
        .expect("stops")
        .success());
    let down = until(&mut ws, Duration::from_secs(20), |m| {
        json(m, "status").filter(|s| s["connected"] == false)
    });
    assert_eq!(down["prefix"], prefix.as_str());
    let _daemon2 = start_daemon(&prefix);
    let topo2 = until(&mut ws, Duration::from_secs(60), |m| json(m, "topology"));
    assert_ne!(topo2["id"].as_str().unwrap(), old_id);
    let frame2 = until(&mut ws, Duration::from_secs(30), |m| match m {
        Message::Binary(b) if u32_at(b, 0) == KIND_FRAME => Some(b.len()),
        _ => None,
    });
    assert_eq!(frame2, expected);
    drop(viewer);
}
