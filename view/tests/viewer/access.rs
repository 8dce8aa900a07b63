//! Who may drive the daemon through lop-view: a WebSocket from a page of another origin is
//! refused at the handshake (403, logged); control requests without the printed URL's token,
//! or with a wrong one, are refused (read-only, logged) and never reach the daemon, while the
//! printed token works; on a non-loopback bind control is off unless a token was given.

use crate::common;

use std::net::TcpStream;
use std::time::{Duration, Instant};

use common::Viewer;
use lop_system_tests::{unique_prefix, Daemon};
use tungstenite::client::IntoClientRequest;
use tungstenite::stream::MaybeTlsStream;
use tungstenite::{Message, WebSocket};

type Ws = WebSocket<MaybeTlsStream<TcpStream>>;

/// Opens `ws://addr/ws`, with `Origin: origin` if given.
fn open(addr: &str, origin: Option<&str>) -> Result<Ws, tungstenite::Error> {
    let mut req = format!("ws://{addr}/ws").into_client_request().unwrap();
    if let Some(o) = origin {
        req.headers_mut().insert("Origin", o.parse().unwrap());
    }
    let (ws, _) = tungstenite::connect(req)?;
    if let MaybeTlsStream::Plain(s) = ws.get_ref() {
        s.set_read_timeout(Some(Duration::from_millis(200)))
            .unwrap();
    }
    Ok(ws)
}

/// Sends a control request and returns the `control` answer (other messages skipped).
fn control(ws: &mut Ws, req: serde_json::Value) -> serde_json::Value {
    ws.send(Message::text(req.to_string())).unwrap();
    let start = Instant::now();
    while start.elapsed() < Duration::from_secs(40) {
        match ws.read() {
            Ok(Message::Text(t)) => {
                let v: serde_json::Value = serde_json::from_str(t.as_str()).unwrap();
                if v["type"] == "control" {
                    return v;
                }
            }
            Ok(_) => {}
            Err(tungstenite::Error::Io(e))
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                ) => {}
            Err(e) => panic!("websocket: {e}"),
        }
    }
    panic!("no control answer to {req}");
}

fn assert_read_only(r: &serde_json::Value) {
    assert_eq!(r["ok"], false, "{r}");
    assert_eq!(r["read_only"], true, "{r}");
    assert!(r["message"].as_str().unwrap().contains("read-only"), "{r}");
}

fn param(r: &serde_json::Value, key: &str) -> f64 {
    r["params"]
        .as_array()
        .unwrap()
        .iter()
        .find(|p| p["key"] == key)
        .unwrap_or_else(|| panic!("no {key} in {r}"))["value"]
        .as_f64()
        .unwrap()
}

#[test]
fn handshake_from_another_origin_is_refused_and_logged() {
    // No daemon needed: the handshake is the viewer's alone.
    let viewer = Viewer::spawn(&unique_prefix("view-origin"), Duration::from_secs(60));
    match open(&viewer.addr, Some("http://evil.example")) {
        Err(tungstenite::Error::Http(resp)) => assert_eq!(resp.status().as_u16(), 403),
        Err(e) => panic!("expected HTTP 403, got {e}"),
        Ok(_) => panic!("a page of http://evil.example opened the WebSocket"),
    }
    viewer.log_line(&["refused WebSocket", "\"http://evil.example\""]);
    // Same host, other port: another server's page.
    let port: u16 = viewer.addr.rsplit(':').next().unwrap().parse().unwrap();
    let other = format!("http://127.0.0.1:{}", port.wrapping_add(1));
    assert!(matches!(
        open(&viewer.addr, Some(&other)),
        Err(tungstenite::Error::Http(r)) if r.status().as_u16() == 403
    ));
    viewer.log_line(&["refused WebSocket", &other]);
    // The viewer's own origin, its loopback equivalent, and a non-browser client (no Origin).
    for origin in [
        Some(format!("http://{}", viewer.addr)),
        Some(format!("http://localhost:{port}")),
        None,
    ] {
        let ws = open(&viewer.addr, origin.as_deref());
        assert!(ws.is_ok(), "origin {origin:?}: {:?}", ws.err());
    }
    // An allow-listed name.
    let viewer2 = Viewer::spawn_with(
        &unique_prefix("view-origin2"),
        Duration::from_secs(60),
        &[
            "--bind",
            "127.0.0.1:0",
            "--allow-origin",
            "http://rig.example:8080",
        ],
    );
    assert!(open(&viewer2.addr, Some("http://rig.example:8080")).is_ok());
    assert!(open(&viewer2.addr, Some("http://rig.example:8081")).is_err());
}

#[test]
fn control_needs_the_printed_token_and_refused_requests_never_reach_the_daemon() {
    let prefix = unique_prefix("view-token");
    let _daemon = Daemon::spawn(
        &["run", "--scene", "organs", "--prefix", &prefix, "--quiet"],
        &prefix,
        Duration::from_secs(180),
    );
    let viewer = Viewer::spawn(&prefix, Duration::from_secs(180));
    let token = viewer
        .token
        .clone()
        .expect("loopback: the URL carries a token");
    assert_eq!(token.len(), 32, "{}", viewer.line);
    assert!(token.chars().all(|c| c.is_ascii_hexdigit()));
    let mut ws = open(&viewer.addr, Some(&format!("http://{}", viewer.addr))).unwrap();

    // No token, then a wrong one (same length, last digit changed): refused and logged.
    let r = control(
        &mut ws,
        serde_json::json!({"op": "set", "body": "spleen", "key": "fem.young", "value": 1e9}),
    );
    assert_read_only(&r);
    viewer.log_line(&["refused control request \"set\"", "no control token"]);
    let mut wrong = token.clone();
    let last = if wrong.ends_with('0') { "1" } else { "0" };
    wrong.replace_range(31.., last);
    let r = control(&mut ws, serde_json::json!({"op": "pause", "token": wrong}));
    assert_read_only(&r);
    viewer.log_line(&["refused control request \"pause\"", "wrong"]);
    let r = control(
        &mut ws,
        serde_json::json!({"op": "set", "body": "spleen", "key": "fem.young", "value": 1e9, "token": ""}),
    );
    assert_read_only(&r);

    // The daemon saw none of it: the spleen keeps its stiffness, the scene runs.
    let r = control(
        &mut ws,
        serde_json::json!({"op": "get", "body": "spleen", "token": token}),
    );
    assert_eq!(r["ok"], true, "{r}");
    assert_eq!(param(&r, "fem.young"), 140.0, "{r}");
    assert_eq!(r["paused"], false, "{r}");

    // With the printed token control goes through.
    let r = control(
        &mut ws,
        serde_json::json!({"op": "set", "body": "spleen", "key": "fem.young", "value": 300, "token": token}),
    );
    assert_eq!(r["ok"], true, "{r}");
    let r = control(
        &mut ws,
        serde_json::json!({"op": "get", "body": "spleen", "token": token}),
    );
    assert_eq!(param(&r, "fem.young"), 300.0, "{r}");
}

#[test]
fn non_loopback_bind_is_read_only_without_an_explicit_token() {
    let viewer = Viewer::spawn_with(
        &unique_prefix("view-any"),
        Duration::from_secs(60),
        &["--bind", "0.0.0.0:0"],
    );
    // No token generated, and the line says why.
    assert!(viewer.token.is_none(), "{}", viewer.line);
    assert!(viewer.line.contains("read-only"), "{}", viewer.line);
    let addr = viewer.loopback_addr();
    let mut ws = open(&addr, None).unwrap();
    // Whatever token a client brings, nothing is forwarded.
    for req in [
        serde_json::json!({"op": "pause"}),
        serde_json::json!({"op": "pause", "token": "0123456789abcdef0123456789abcdef"}),
    ] {
        assert_read_only(&control(&mut ws, req));
    }
    viewer.log_line(&["refused control request \"pause\"", "disabled"]);

    // Given explicitly, the token is enabled there too: the request passes the check and is
    // forwarded (no daemon under this prefix, so the control thread's own error comes back).
    let given = "rig-token-0123456789";
    let viewer = Viewer::spawn_with(
        &unique_prefix("view-any2"),
        Duration::from_secs(60),
        &["--bind", "0.0.0.0:0", "--token", given],
    );
    assert_eq!(viewer.token.as_deref(), Some(given), "{}", viewer.line);
    let mut ws = open(&viewer.loopback_addr(), None).unwrap();
    assert_read_only(&control(&mut ws, serde_json::json!({"op": "pause"})));
    let r = control(&mut ws, serde_json::json!({"op": "pause", "token": given}));
    assert_eq!(r["ok"], false, "{r}");
    assert!(r.get("read_only").is_none(), "forwarded, not refused: {r}");
}
