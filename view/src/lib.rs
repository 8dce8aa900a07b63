//! `lop-view`: a web viewer of a running `lopd`, attached read-only.
//!
//! One process, three kinds of thread, nothing shared with the daemon but read-only mappings:
//! - the **hub** attaches to `PREFIX/…` through [`lop_client::Attachment`] (retrying while the
//!   daemon starts, re-attaching when frames stop for [`REATTACH_AFTER`]), takes the newest
//!   frame, tool state and haptic telemetry, and encodes them once into [`wire`] messages held
//!   as "the latest"; it never waits on a browser;
//! - one **connection** thread per browser: serves the page (`web/`, embedded in the binary) or
//!   speaks WebSocket: it sends the topology on connect and whenever its id changes, then the
//!   newest frame at most `fps` times a second. A slow browser only ever gets the newest frame
//!   later (older ones are dropped), so nothing queues and shared memory is never back-pressured;
//! - the **control** thread owns the one client of `PREFIX/control` and forwards the control
//!   panel's requests to the daemon.
//!
//! Only the rig's user drives the daemon ([`access`]): the WebSocket handshake is refused
//! (HTTP 403) to a page of another origin, and each control request must carry the run's
//! control token, which only the printed URL holds (`http://127.0.0.1:8733/#token=…`); without
//! it a connection is read-only. On a non-loopback bind control needs a token given explicitly.
//!
//! The page is plain WebGL 1 and a 2D canvas, no JavaScript library: nothing is fetched at run
//! time.

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream, ToSocketAddrs};
use std::sync::mpsc;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use lop_client::{Attachment, ControlRequest, ControlResponse, ServiceNames};

pub mod access;
pub mod wire;

/// Where `lop-view` listens unless told otherwise (same as `lopd run --view`): loopback only.
pub const BIND_DEFAULT: &str = "127.0.0.1:8733";
/// Frames a browser gets per second at most.
pub const FPS_DEFAULT: f64 = 30.0;
/// No frame for this long: the daemon is gone; drop the attachment and attach anew.
pub const REATTACH_AFTER: Duration = Duration::from_secs(2);

const INDEX_HTML: &str = include_str!("../web/index.html");
const APP_JS: &str = include_str!("../web/app.js");

/// Options of one viewer.
#[derive(Debug, Clone)]
pub struct ViewOptions {
    /// The daemon's service prefix.
    pub prefix: String,
    /// Frames per second sent to each browser.
    pub fps: f64,
    /// The control token (see [`access::control_token`]); `None`: every connection is
    /// read-only.
    pub token: Option<String>,
    /// Origins accepted besides the viewer's own (`--allow-origin`).
    pub allow_origins: Vec<String>,
}

/// What the hub last read, encoded for the browsers.
#[derive(Default)]
struct Latest {
    connected: bool,
    /// Topology id, its JSON description and its binary triangle list.
    topology: Option<(u64, Arc<String>, Arc<Vec<u8>>)>,
    /// Frame counter and the encoded frame.
    frame: Option<(u64, Arc<Vec<u8>>)>,
    /// Telemetry counter and its JSON.
    telemetry: Option<(u64, Arc<String>)>,
}

type ControlJob = (
    ControlRequest,
    mpsc::Sender<Result<ControlResponse, String>>,
);

struct Shared {
    opts: ViewOptions,
    /// Where the listener is bound (for the origin check).
    local: SocketAddr,
    latest: Mutex<Latest>,
    control: Mutex<mpsc::Sender<ControlJob>>,
}

/// Binds `bind` (e.g. `127.0.0.1:8733`, port 0 for any free port).
pub fn bind(bind: &str) -> Result<TcpListener> {
    let addr = bind
        .to_socket_addrs()
        .with_context(|| format!("--bind {bind:?}: not an address:port"))?
        .next()
        .with_context(|| format!("--bind {bind:?}: resolves to nothing"))?;
    TcpListener::bind(addr).with_context(|| format!("--bind {bind}: cannot listen"))
}

/// Serves the viewer on `listener` until the process ends.
pub fn serve(listener: TcpListener, opts: ViewOptions) -> Result<()> {
    let names = ServiceNames::new(&opts.prefix).map_err(anyhow::Error::new)?;
    let local = listener.local_addr().context("the listener's address")?;
    let (tx, rx) = mpsc::channel::<ControlJob>();
    let shared = Arc::new(Shared {
        opts,
        local,
        latest: Mutex::new(Latest::default()),
        control: Mutex::new(tx),
    });
    {
        let shared = shared.clone();
        std::thread::Builder::new()
            .name("lop-view-hub".into())
            .spawn(move || hub(&shared))?;
    }
    std::thread::Builder::new()
        .name("lop-view-control".into())
        .spawn(move || control_thread(&names, rx))?;
    for stream in listener.incoming() {
        let Ok(stream) = stream else { continue };
        let shared = shared.clone();
        let _ = std::thread::Builder::new()
            .name("lop-view-conn".into())
            .spawn(move || {
                let _ = connection(stream, &shared);
            });
    }
    Ok(())
}

/// Attaches, reads the newest data, encodes it; re-attaches when the daemon goes away.
fn hub(shared: &Shared) {
    let prefix = shared.opts.prefix.clone();
    let mut frame_counter = 0u64;
    let mut telemetry_counter = 0u64;
    let mut jitter_history = wire::TelemetryHistory::default();
    loop {
        let mut att = match Attachment::open(&prefix, Duration::from_secs(1)) {
            Ok(a) => a,
            Err(_) => {
                set_connected(shared, false);
                std::thread::sleep(Duration::from_millis(500));
                continue;
            }
        };
        let mut last_frame = Instant::now();
        let mut tools = Vec::new();
        let mut tool = None;
        loop {
            if let Ok(Some(t)) = att.poll_topology() {
                let id = t.header.topology_id;
                let mut latest = shared.latest.lock().expect("hub lock");
                if latest.topology.as_ref().map(|x| x.0) != Some(id) {
                    latest.topology = Some((
                        id,
                        Arc::new(wire::topology_json(t, &prefix)),
                        Arc::new(wire::topology_binary(t)),
                    ));
                }
            }
            tools.clear();
            att.tool_states(&mut tools);
            if let Some(t) = tools.last() {
                tool = Some(*t);
            }
            if let Some(tel) = att.telemetry() {
                jitter_history.push(&tel);
                telemetry_counter += 1;
                shared.latest.lock().expect("hub lock").telemetry =
                    Some((telemetry_counter, Arc::new(jitter_history.json(&tel))));
            }
            match att.latest_frame() {
                Ok(Some(f)) => {
                    last_frame = Instant::now();
                    frame_counter += 1;
                    let bytes = wire::frame_binary(&f, tool.as_ref());
                    let mut latest = shared.latest.lock().expect("hub lock");
                    latest.frame = Some((frame_counter, Arc::new(bytes)));
                    latest.connected = true;
                }
                Ok(None) => {}
                Err(_) => break,
            }
            if last_frame.elapsed() > REATTACH_AFTER {
                break;
            }
            std::thread::sleep(Duration::from_millis(8));
        }
        set_connected(shared, false);
    }
}

fn set_connected(shared: &Shared, connected: bool) {
    shared.latest.lock().expect("hub lock").connected = connected;
}

/// Owns the viewer's one control client; (re)opens it on demand.
fn control_thread(names: &ServiceNames, rx: mpsc::Receiver<ControlJob>) {
    let Ok(node) = lop_client::services::node(&format!("lop-view-ctl-{}", std::process::id()))
    else {
        return;
    };
    let mut client: Option<lop_client::ControlClient> = None;
    for (req, reply) in rx {
        if client.is_none() {
            match lop_client::ControlClient::open(&node, names, Duration::from_secs(2)) {
                Ok(c) => client = Some(c),
                Err(e) => {
                    let _ = reply.send(Err(e.to_string()));
                    continue;
                }
            }
        }
        let c = client.as_ref().expect("opened above");
        let r = c.request(&req, Duration::from_secs(30));
        if r.is_err() {
            client = None; // the daemon may have restarted: open anew next time
        }
        let _ = reply.send(r.map_err(|e| e.to_string()));
    }
}

/// Reads the request head without consuming it (a WebSocket upgrade hands the stream to
/// tungstenite, which reads the head itself).
fn peek_head(stream: &TcpStream) -> Option<String> {
    let mut buf = [0u8; 4096];
    let start = Instant::now();
    loop {
        let n = stream.peek(&mut buf).ok()?;
        let text = String::from_utf8_lossy(&buf[..n]).into_owned();
        if text.contains("\r\n\r\n") || n == buf.len() {
            return Some(text);
        }
        if n == 0 || start.elapsed() > Duration::from_secs(5) {
            return None;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
}

fn connection(mut stream: TcpStream, shared: &Shared) -> Result<()> {
    stream.set_read_timeout(Some(Duration::from_secs(5)))?;
    let head = peek_head(&stream).context("no request")?;
    let path = head.split_whitespace().nth(1).unwrap_or("/").to_string();
    let is_upgrade = head.to_ascii_lowercase().contains("upgrade: websocket");
    if path.starts_with("/ws") && is_upgrade {
        return websocket(stream, shared);
    }
    // Consume the head and answer with one of the embedded files.
    let mut sink = vec![0u8; head.len()];
    stream.read_exact(&mut sink)?;
    let (status, kind, body) = match path.split('?').next().unwrap_or("/") {
        "/" | "/index.html" => ("200 OK", "text/html; charset=utf-8", INDEX_HTML),
        "/app.js" => ("200 OK", "text/javascript; charset=utf-8", APP_JS),
        _ => ("404 Not Found", "text/plain", "not found\n"),
    };
    write!(
        stream,
        "HTTP/1.1 {status}\r\nContent-Type: {kind}\r\nContent-Length: {}\r\nCache-Control: no-store\r\nConnection: close\r\n\r\n",
        body.len()
    )?;
    stream.write_all(body.as_bytes())?;
    Ok(())
}

fn websocket(stream: TcpStream, shared: &Shared) -> Result<()> {
    use tungstenite::handshake::server::{ErrorResponse, Request, Response};
    use tungstenite::Message;
    let peer = stream
        .peer_addr()
        .map_or_else(|_| "?".to_string(), |a| a.to_string());
    // The error type is tungstenite's, as its callback signature wants it.
    #[allow(clippy::result_large_err)]
    let check_origin = |req: &Request, resp: Response| -> Result<Response, ErrorResponse> {
        let header = |name: &str| req.headers().get(name).map(|v| v.to_str().unwrap_or("?"));
        let Some(origin) = header("origin") else {
            // Not a browser page: accepted, read-only unless it brings the token.
            return Ok(resp);
        };
        if access::origin_allowed(
            origin,
            header("host"),
            shared.local,
            &shared.opts.allow_origins,
        ) {
            return Ok(resp);
        }
        eprintln!(
            "lop-view: refused WebSocket from {peer}: origin {origin:?} is not this viewer's \
             (http://{}) nor an --allow-origin",
            shared.local
        );
        let mut refusal = ErrorResponse::new(Some(format!(
            "origin {origin:?} may not connect to this viewer\n"
        )));
        *refusal.status_mut() = tungstenite::http::StatusCode::FORBIDDEN;
        Err(refusal)
    };
    let mut ws = tungstenite::accept_hdr(stream.try_clone()?, check_origin)
        .map_err(|e| anyhow::anyhow!("websocket handshake with {peer}: {e}"))?;
    // Short reads so the loop can send frames; a browser that does not take a frame within the
    // write timeout is dropped (it reconnects and starts from the newest frame).
    stream.set_read_timeout(Some(Duration::from_millis(5)))?;
    stream.set_write_timeout(Some(Duration::from_secs(5)))?;
    let period = Duration::from_secs_f64(1.0 / shared.opts.fps.clamp(1.0, 120.0));
    let mut sent_topology = 0u64;
    let mut sent_frame = 0u64;
    let mut sent_telemetry = 0u64;
    let mut sent_connected = None;
    let mut next = Instant::now();
    loop {
        // Control requests from the page.
        match ws.read() {
            Ok(Message::Text(t)) => {
                let reply = handle_control(shared, t.as_str(), &peer);
                ws.send(Message::text(reply))?;
            }
            Ok(Message::Close(_)) => return Ok(()),
            Ok(_) => {}
            Err(tungstenite::Error::Io(e))
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                ) => {}
            Err(e) => return Err(e.into()),
        }
        if Instant::now() < next {
            continue;
        }
        next = Instant::now() + period;
        let (connected, topology, frame, telemetry) = {
            let l = shared.latest.lock().expect("hub lock");
            (
                l.connected,
                l.topology.clone(),
                l.frame.clone(),
                l.telemetry.clone(),
            )
        };
        if sent_connected != Some(connected) {
            sent_connected = Some(connected);
            ws.send(Message::text(wire::status_json(
                connected,
                &shared.opts.prefix,
            )))?;
        }
        if let Some((id, json, bin)) = topology {
            if id != sent_topology {
                sent_topology = id;
                ws.send(Message::text(json.as_str()))?;
                ws.send(Message::binary(bin.as_slice().to_vec()))?;
            }
        }
        if let Some((n, bytes)) = frame {
            if n != sent_frame && sent_topology != 0 {
                sent_frame = n;
                ws.send(Message::binary(bytes.as_slice().to_vec()))?;
            }
        }
        if let Some((n, json)) = telemetry {
            if n != sent_telemetry {
                sent_telemetry = n;
                ws.send(Message::text(json.as_str()))?;
            }
        }
    }
}

/// Turns the page's JSON control request into a daemon request, forwards it if it carries the
/// run's token, and returns the JSON answer (always a `{"type":"control",…}` object, errors and
/// refusals included).
fn handle_control(shared: &Shared, text: &str, peer: &str) -> String {
    let (op, token) = wire::control_op_and_token(text);
    let refusal = match (&shared.opts.token, token) {
        (Some(expected), Some(given)) if access::token_matches(expected, &given) => None,
        (None, _) => {
            Some("control is disabled in this viewer (bound beyond loopback without --token)")
        }
        (Some(_), None) => Some("the request carries no control token"),
        (Some(_), Some(_)) => Some("the request's control token is wrong"),
    };
    if let Some(why) = refusal {
        eprintln!("lop-view: refused control request {op:?} from {peer}: {why}");
        return wire::control_read_only_json(&format!(
            "read-only: {why}; open the URL lopd printed to control"
        ));
    }
    let req = match wire::control_request(text) {
        Ok(r) => r,
        Err(e) => return wire::control_error_json(&e),
    };
    let (tx, rx) = mpsc::channel();
    if shared
        .control
        .lock()
        .expect("control lock")
        .send((req, tx))
        .is_err()
    {
        return wire::control_error_json("control is not available in this viewer");
    }
    match rx.recv_timeout(Duration::from_secs(35)) {
        Ok(Ok(resp)) => wire::control_response_json(&resp),
        Ok(Err(e)) => wire::control_error_json(&e),
        Err(_) => wire::control_error_json("no answer from the daemon"),
    }
}
