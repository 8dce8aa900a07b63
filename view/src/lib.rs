//! `lop-view`: a web viewer of a running `lopd`, attached read-only.
//!
//! One process and a fixed set of three threads, nothing shared with the daemon but read-only
//! mappings:
//! - the **hub** attaches to `PREFIX/…` through [`lop_client::Attachment`] (retrying while the
//!   daemon starts, re-attaching when frames stop for [`REATTACH_AFTER`]), takes the newest
//!   frame, the newest state of each tool and haptic telemetry, and encodes them once into
//!   [`wire`] messages held as "the latest"; it never waits on a browser;
//! - the **server**, one event-loop thread (the one that calls [`serve`]) running every
//!   connection as a task: it serves the page (`web/`, embedded in the binary) or speaks
//!   WebSocket: it sends the topology on connect and whenever its id changes, then the newest
//!   frame at most `fps` times a second. Each WebSocket has one message in flight at most: a
//!   slow browser only ever gets the newest frame later (older ones are dropped, never
//!   queued), one that takes nothing for [`SEND_TIMEOUT`] is dropped, and shared memory is
//!   never back-pressured;
//! - the **control** thread owns the one client of `PREFIX/control` and forwards the control
//!   panel's requests to the daemon.
//!
//! ## The server and its bounds
//!
//! HTTP/1 is [hyper]'s (parsing, `Connection: close` answers, the upgrade hand-over) and the
//! WebSocket framing tungstenite's, through `tokio-tungstenite` on a one-thread tokio runtime
//! (no HTTP/2, no TLS, no default features). A blocking server was the first choice and was
//! set aside: `tiny_http` (the usual small one) gives each connection a pool thread for as long
//! as it stays open and grows the pool without limit, so a thousand idle sockets would be a
//! thousand threads; bounding that by hand means polling sockets, i.e. writing an event loop.
//! Build cost, measured with `cargo build -p lop-view --timings` on the 2-core development
//! machine shared with other builds: the new crates (tokio without its macros, hyper,
//! hyper-util, http-body-util, tokio-tungstenite, futures-util and their small dependencies)
//! take about 55 s of compiler time (tokio 29 s, hyper 13 s, futures-util 4 s, each other one
//! under 3 s), some 40 s of wall time, on top of a clean build that took 6 min 55 s before them
//! (iceoryx2 and its bindgen dominate). tokio's `macros` feature would cost 12 s more and is
//! not used.
//!
//! Bounds (constants):
//! - [`MAX_CONNECTIONS`] (512) TCP connections of every kind at once. When all are taken, a
//!   newcomer gets the slot of the connection that has waited longest for its request (idle or
//!   half-open), which is closed; only when none is waiting (all are WebSockets or answers
//!   under way) is the newcomer closed as soon as it is accepted (a stderr line says so, at
//!   most one a second). An idle connection costs a task and a socket, no thread.
//! - [`REQUEST_TIMEOUT`] (5 s) from accept to the end of the answer, for a page request or a
//!   WebSocket handshake: a connection that sends nothing, or half a request, is closed then,
//!   and its slot freed.
//! - [`MAX_REQUEST_BYTES`] (16 KiB) for a request head (hyper answers 431 beyond) and for a
//!   message from the page (the WebSocket is closed beyond).
//! - [`MAX_WEBSOCKETS`] (64) WebSocket clients at once; one more is answered 503. With a
//!   daemon running, a client that does not read stops taking frames and is dropped after
//!   [`SEND_TIMEOUT`] (5 s), freeing its slot.
//! - Threads: three (server, hub, control), whatever the number of connections; memory: per
//!   connection a task and hyper's buffers (a few KiB), per WebSocket at most one encoded frame
//!   (shared by all of them, not copied) in flight.
//!
//! `tests/flood.rs` holds 1,000 idle, half-open and non-reading connections open and checks
//! that a real client still gets the page and a WebSocket, the thread count and the resident
//! memory. Measured: 3 threads before and during the flood, resident memory from 6 MB to
//! 20 MB, the page in about 4 ms and the WebSocket's first message 2 ms later (the flood fills
//! all 512 slots; the real client takes an idle one's). Without that rule (refusing the
//! newcomer) the page came only once the flood's first connections timed out, after 5 s.
//! With a daemon and all 64 WebSocket slots taken by clients that never read, a real client
//! got a frame after 11 s (their socket buffers fill, then [`SEND_TIMEOUT`]), still 3 threads
//! and 10 MB to 20 MB resident.
//!
//! Nothing here can touch the haptic loop: it runs in the daemon, another process, on its own
//! real-time thread. The viewer only maps the daemon's shared-memory services read-only and
//! takes the newest sample (the daemon's services are set to overwrite the oldest sample, so a
//! publisher never waits on a subscriber), and its control requests go through
//! `PREFIX/control`, which the daemon's deformation loop serves, not the haptic loop. A flood can make the viewer slow or refuse browsers; it cannot make the
//! daemon wait.
//!
//! Only the rig's user drives the daemon ([`access`]): the WebSocket handshake is refused
//! (HTTP 403) to a page of another origin, and each control request must carry the run's
//! control token, which only the printed URL holds (`http://127.0.0.1:8733/#token=…`); without
//! it a connection is read-only. On a non-loopback bind control needs a token given explicitly.
//!
//! The page is plain WebGL 1 and a 2D canvas, no JavaScript library: nothing is fetched at run
//! time.

use std::net::{SocketAddr, TcpListener, ToSocketAddrs};
use std::sync::mpsc;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use lop_client::{Attachment, ControlRequest, ControlResponse, ServiceNames, Topology};
use std::collections::VecDeque;
use std::sync::atomic::{AtomicU64, Ordering};
use tokio::sync::{Notify, OwnedSemaphorePermit, Semaphore};

pub mod access;
pub mod wire;

/// Where `lop-view` listens unless told otherwise (same as `lopd run --view`): loopback only.
pub const BIND_DEFAULT: &str = "127.0.0.1:8733";
/// Frames a browser gets per second at most.
pub const FPS_DEFAULT: f64 = 30.0;
/// No frame for this long: the daemon is gone; drop the attachment and attach anew.
pub const REATTACH_AFTER: Duration = Duration::from_secs(2);
/// TCP connections open at once, of every kind (page requests, handshakes, WebSockets); the
/// next one takes the slot of the one that has waited longest for its request, or is closed if
/// none is waiting. Well under the usual 1,024 open files.
pub const MAX_CONNECTIONS: usize = 512;
/// WebSocket clients at once (each holds at most one frame in flight); the next handshake is
/// answered 503.
pub const MAX_WEBSOCKETS: usize = 64;
/// From accept to the end of the answer, for a page request or a WebSocket handshake: a
/// connection that sends nothing, or half a request, is closed then.
pub const REQUEST_TIMEOUT: Duration = Duration::from_secs(5);
/// Largest request head (HTTP) and largest message from a page (WebSocket). hyper takes no
/// less than 8 KiB.
pub const MAX_REQUEST_BYTES: usize = 16 * 1024;
/// A browser that takes no message for this long is dropped.
pub const SEND_TIMEOUT: Duration = Duration::from_secs(5);

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
    topology: Option<(u64, Arc<String>, bytes::Bytes)>,
    /// Frame counter and the encoded frame (shared by every browser's send, not copied).
    frame: Option<(u64, bytes::Bytes)>,
    /// Telemetry counter and its JSON.
    telemetry: Option<(u64, Arc<String>)>,
}

type ControlJob = (
    ControlRequest,
    tokio::sync::oneshot::Sender<Result<ControlResponse, String>>,
);

struct Shared {
    opts: ViewOptions,
    /// Where the listener is bound (for the origin check).
    local: SocketAddr,
    latest: Mutex<Latest>,
    control: Mutex<mpsc::Sender<ControlJob>>,
    /// Open TCP connections, of every kind ([`MAX_CONNECTIONS`]).
    connections: Arc<Semaphore>,
    /// Open WebSockets ([`MAX_WEBSOCKETS`]).
    websockets: Arc<Semaphore>,
    /// Connections whose request has not come in yet, oldest first, each with the bell that
    /// closes it to make room for a newcomer.
    waiting: Mutex<VecDeque<(u64, Arc<Notify>)>>,
    next_id: AtomicU64,
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
        connections: Arc::new(Semaphore::new(MAX_CONNECTIONS)),
        websockets: Arc::new(Semaphore::new(MAX_WEBSOCKETS)),
        waiting: Mutex::new(VecDeque::new()),
        next_id: AtomicU64::new(0),
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
    listener
        .set_nonblocking(true)
        .context("the listener (non-blocking mode)")?;
    // Every connection is a task of this one thread.
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_io()
        .enable_time()
        .build()
        .context("the viewer's event loop")?;
    runtime.block_on(accept_loop(listener, shared))
}

/// Accepts connections, at most [`MAX_CONNECTIONS`] open (see [`connection_slot`] for who
/// makes room). Each accepted one becomes a task of the one event-loop thread.
async fn accept_loop(listener: TcpListener, shared: Arc<Shared>) -> Result<()> {
    let listener =
        tokio::net::TcpListener::from_std(listener).context("the listener (event loop)")?;
    let mut refused = 0u64;
    let mut last_note: Option<Instant> = None;
    // At most one stderr line a second about refusals, however many there are.
    let mut note = |what: String| {
        if last_note.is_none_or(|t| t.elapsed() >= Duration::from_secs(1)) {
            last_note = Some(Instant::now());
            eprintln!("lop-view: {what}");
        }
    };
    loop {
        let (stream, peer) = match listener.accept().await {
            Ok(x) => x,
            Err(e) => {
                // Out of file descriptors (or the like): the open connections go on; accept
                // again a little later rather than spin.
                note(format!("cannot accept a connection: {e}"));
                tokio::time::sleep(Duration::from_millis(100)).await;
                continue;
            }
        };
        let Some(permit) = connection_slot(&shared).await else {
            refused += 1;
            note(format!(
                "refused connection from {peer}: {MAX_CONNECTIONS} connections are open, the \
                 most this viewer serves, none of them idle ({refused} refused so far)"
            ));
            drop(stream);
            continue;
        };
        let shared = shared.clone();
        tokio::spawn(http_connection(stream, peer, shared, Arc::new(permit)));
    }
}

/// A free connection slot; when all are taken, the one of the connection that has waited
/// longest for its request (an idle or half-open one: WebSockets and answers under way are not
/// candidates), which is closed for it. `None` if there is none such.
async fn connection_slot(shared: &Shared) -> Option<OwnedSemaphorePermit> {
    if let Ok(p) = shared.connections.clone().try_acquire_owned() {
        return Some(p);
    }
    let (_, bell) = shared.waiting.lock().expect("waiting lock").pop_front()?;
    bell.notify_one();
    // The closed connection's task gives its slot back as soon as this one yields.
    tokio::time::timeout(
        Duration::from_millis(500),
        shared.connections.clone().acquire_owned(),
    )
    .await
    .ok()?
    .ok()
}

fn stop_waiting(shared: &Shared, id: u64) {
    shared
        .waiting
        .lock()
        .expect("waiting lock")
        .retain(|(i, _)| *i != id);
}

/// One HTTP/1 exchange (hyper; `Connection: close`), bounded by [`REQUEST_TIMEOUT`] from
/// accept to the end of the answer; a WebSocket upgrade goes on in its own task.
async fn http_connection(
    stream: tokio::net::TcpStream,
    peer: SocketAddr,
    shared: Arc<Shared>,
    permit: Arc<OwnedSemaphorePermit>,
) {
    let _ = stream.set_nodelay(true);
    let id = shared.next_id.fetch_add(1, Ordering::Relaxed);
    let bell = Arc::new(Notify::new());
    shared
        .waiting
        .lock()
        .expect("waiting lock")
        .push_back((id, bell.clone()));
    let registry = shared.clone();
    let service = hyper::service::service_fn(move |req| {
        // The request is in: no longer a candidate for closing.
        stop_waiting(&shared, id);
        let answer = route(req, peer, &shared, &permit);
        std::future::ready(Ok::<_, std::convert::Infallible>(answer))
    });
    let conn = hyper::server::conn::http1::Builder::new()
        .max_buf_size(MAX_REQUEST_BYTES)
        .serve_connection(hyper_util::rt::TokioIo::new(stream), service)
        .with_upgrades();
    // Whatever is left undone then (a request never finished, an answer never read) is
    // dropped with the connection.
    let conn = std::pin::pin!(conn);
    let evicted = std::pin::pin!(bell.notified());
    let either = futures_util::future::select(conn, evicted);
    let _ = tokio::time::timeout(REQUEST_TIMEOUT, either).await;
    stop_waiting(&registry, id);
}

type Body = http_body_util::Full<bytes::Bytes>;

fn answer(status: u16, kind: &str, body: impl Into<bytes::Bytes>) -> hyper::Response<Body> {
    let mut r = hyper::Response::new(Body::new(body.into()));
    *r.status_mut() =
        hyper::StatusCode::from_u16(status).unwrap_or(hyper::StatusCode::INTERNAL_SERVER_ERROR);
    let h = r.headers_mut();
    if let Ok(v) = hyper::header::HeaderValue::from_str(kind) {
        h.insert(hyper::header::CONTENT_TYPE, v);
    }
    h.insert(
        hyper::header::CACHE_CONTROL,
        hyper::header::HeaderValue::from_static("no-store"),
    );
    // One request a connection (hyper closes after an answer saying so); the 101 of a
    // WebSocket handshake replaces this with `Upgrade`.
    h.insert(
        hyper::header::CONNECTION,
        hyper::header::HeaderValue::from_static("close"),
    );
    r
}

/// The page's files, `/ws`, or 404.
fn route(
    req: hyper::Request<hyper::body::Incoming>,
    peer: SocketAddr,
    shared: &Arc<Shared>,
    permit: &Arc<OwnedSemaphorePermit>,
) -> hyper::Response<Body> {
    let path = req.uri().path().to_string();
    let upgrade = req
        .headers()
        .get(hyper::header::UPGRADE)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|v| v.trim().eq_ignore_ascii_case("websocket"));
    if path.starts_with("/ws") && upgrade {
        return websocket_upgrade(req, peer, shared, permit);
    }
    match path.as_str() {
        "/" | "/index.html" => answer(200, "text/html; charset=utf-8", INDEX_HTML),
        "/app.js" => answer(200, "text/javascript; charset=utf-8", APP_JS),
        _ => answer(404, "text/plain", "not found\n"),
    }
}

/// Checks the handshake (origin, headers, the WebSocket bound), answers 101 and starts the
/// connection's task on the upgraded stream.
fn websocket_upgrade(
    mut req: hyper::Request<hyper::body::Incoming>,
    peer: SocketAddr,
    shared: &Arc<Shared>,
    permit: &Arc<OwnedSemaphorePermit>,
) -> hyper::Response<Body> {
    let header = |name: &str| {
        req.headers()
            .get(name)
            .map(|v| v.to_str().unwrap_or("?").to_string())
    };
    if let Some(origin) = header("origin") {
        let host = header("host");
        if !access::origin_allowed(
            &origin,
            host.as_deref(),
            shared.local,
            &shared.opts.allow_origins,
        ) {
            eprintln!(
                "lop-view: refused WebSocket from {peer}: origin {origin:?} is not this viewer's \
                 (http://{}) nor an --allow-origin",
                shared.local
            );
            return answer(
                403,
                "text/plain",
                format!("origin {origin:?} may not connect to this viewer\n"),
            );
        }
    }
    // Without an Origin: not a browser page; accepted, read-only unless it brings the token.
    if req.method() != hyper::Method::GET {
        return answer(
            405,
            "text/plain",
            format!("a WebSocket handshake is a GET, not {}\n", req.method()),
        );
    }
    let version = header("sec-websocket-version");
    if version.as_deref() != Some("13") {
        return answer(
            400,
            "text/plain",
            format!("Sec-WebSocket-Version {version:?}: this viewer speaks 13\n"),
        );
    }
    let Some(key) = header("sec-websocket-key") else {
        return answer(400, "text/plain", "no Sec-WebSocket-Key header\n");
    };
    let Ok(ws_permit) = shared.websockets.clone().try_acquire_owned() else {
        eprintln!(
            "lop-view: refused WebSocket from {peer}: {MAX_WEBSOCKETS} are open, the most this \
             viewer serves"
        );
        return answer(
            503,
            "text/plain",
            format!(
                "{MAX_WEBSOCKETS} WebSocket clients are connected, the most this viewer serves\n"
            ),
        );
    };
    let accept = tungstenite::handshake::derive_accept_key(key.as_bytes());
    let upgraded = hyper::upgrade::on(&mut req);
    let shared = shared.clone();
    let permit = permit.clone();
    tokio::spawn(async move {
        if let Ok(io) = upgraded.await {
            let config = tungstenite::protocol::WebSocketConfig::default()
                .max_message_size(Some(MAX_REQUEST_BYTES))
                .max_frame_size(Some(MAX_REQUEST_BYTES));
            let ws = tokio_tungstenite::WebSocketStream::from_raw_socket(
                hyper_util::rt::TokioIo::new(io),
                tungstenite::protocol::Role::Server,
                Some(config),
            )
            .await;
            let _ = websocket(ws, &shared, &peer.to_string()).await;
        }
        drop((ws_permit, permit));
    });
    let mut r = answer(101, "text/plain", bytes::Bytes::new());
    let h = r.headers_mut();
    h.remove(hyper::header::CONTENT_TYPE);
    h.insert(
        hyper::header::UPGRADE,
        hyper::header::HeaderValue::from_static("websocket"),
    );
    h.insert(
        hyper::header::CONNECTION,
        hyper::header::HeaderValue::from_static("Upgrade"),
    );
    if let Ok(v) = hyper::header::HeaderValue::from_str(&accept) {
        h.insert(hyper::header::SEC_WEBSOCKET_ACCEPT, v);
    }
    r
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
        let mut received = Vec::new();
        let mut tools = wire::LatestTools::default();
        let mut topology: Option<Topology> = None;
        loop {
            if let Ok(Some(t)) = att.poll_topology() {
                let id = t.header.topology_id;
                if topology.as_ref().map(|x| x.header.topology_id) != Some(id) {
                    topology = Some(t.clone());
                }
                let mut latest = shared.latest.lock().expect("hub lock");
                if latest.topology.as_ref().map(|x| x.0) != Some(id) {
                    latest.topology = Some((
                        id,
                        Arc::new(wire::topology_json(t, &prefix)),
                        bytes::Bytes::from(wire::topology_binary(t)),
                    ));
                }
            }
            received.clear();
            att.tool_states(&mut received);
            for t in &received {
                tools.update(t);
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
                    let bytes = wire::frame_binary(&f, topology.as_ref(), &tools);
                    let mut latest = shared.latest.lock().expect("hub lock");
                    latest.frame = Some((frame_counter, bytes::Bytes::from(bytes)));
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

type Ws = tokio_tungstenite::WebSocketStream<hyper_util::rt::TokioIo<hyper::upgrade::Upgraded>>;

/// Sends one message, or gives up on a client that has not taken it within [`SEND_TIMEOUT`].
async fn send(ws: &mut Ws, msg: tungstenite::Message) -> Result<()> {
    use futures_util::SinkExt;
    match tokio::time::timeout(SEND_TIMEOUT, ws.send(msg)).await {
        Ok(r) => r.map_err(anyhow::Error::new),
        Err(_) => anyhow::bail!("the client took nothing for {SEND_TIMEOUT:?}"),
    }
}

/// One browser: control requests in, the newest status, topology, frame and telemetry out at
/// most `fps` times a second. Only one message is ever in flight: a slow browser gets the
/// newest frame later (the ones in between are never queued), and one that takes nothing for
/// [`SEND_TIMEOUT`] is dropped (it reconnects and starts from the newest frame).
async fn websocket(mut ws: Ws, shared: &Shared, peer: &str) -> Result<()> {
    use futures_util::StreamExt;
    use tungstenite::Message;
    let period = Duration::from_secs_f64(1.0 / shared.opts.fps.clamp(1.0, 120.0));
    let mut sent_topology = 0u64;
    let mut sent_frame = 0u64;
    let mut sent_telemetry = 0u64;
    let mut sent_connected = None;
    let mut next = tokio::time::Instant::now();
    loop {
        // Control requests from the page until it is time to send.
        match tokio::time::timeout_at(next, ws.next()).await {
            Ok(Some(Ok(Message::Text(t)))) => {
                let reply = handle_control(shared, t.as_str(), peer).await;
                send(&mut ws, Message::text(reply)).await?;
                continue;
            }
            Ok(Some(Ok(Message::Close(_))) | None) => return Ok(()),
            Ok(Some(Ok(_))) => continue,
            Ok(Some(Err(e))) => return Err(e.into()),
            Err(_) => {}
        }
        next = tokio::time::Instant::now() + period;
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
            let status = wire::status_json(connected, &shared.opts.prefix);
            send(&mut ws, Message::text(status)).await?;
        }
        if let Some((id, json, bin)) = topology {
            if id != sent_topology {
                sent_topology = id;
                send(&mut ws, Message::text(json.as_str())).await?;
                send(&mut ws, Message::binary(bin)).await?;
            }
        }
        if let Some((n, bytes)) = frame {
            if n != sent_frame && sent_topology != 0 {
                sent_frame = n;
                send(&mut ws, Message::binary(bytes)).await?;
            }
        }
        if let Some((n, json)) = telemetry {
            if n != sent_telemetry {
                sent_telemetry = n;
                send(&mut ws, Message::text(json.as_str())).await?;
            }
        }
    }
}

/// Turns the page's JSON control request into a daemon request, forwards it if it carries the
/// run's token, and returns the JSON answer (always a `{"type":"control",…}` object, errors and
/// refusals included).
async fn handle_control(shared: &Shared, text: &str, peer: &str) -> String {
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
    let (tx, rx) = tokio::sync::oneshot::channel();
    if shared
        .control
        .lock()
        .expect("control lock")
        .send((req, tx))
        .is_err()
    {
        return wire::control_error_json("control is not available in this viewer");
    }
    match tokio::time::timeout(Duration::from_secs(35), rx).await {
        Ok(Ok(Ok(resp))) => wire::control_response_json(&resp),
        Ok(Ok(Err(e))) => wire::control_error_json(&e),
        Ok(Err(_)) | Err(_) => wire::control_error_json("no answer from the daemon"),
    }
}
