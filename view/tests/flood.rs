//! A flood of 1,000 connections does not take the viewer down: idle TCP connections, half
//! requests (a partial request line, headers never ended) and WebSocket clients that never
//! read are held open while a real client asks for the page and opens the WebSocket. The real
//! client is served within seconds, the viewer's threads stay a fixed handful and its memory
//! stays bounded, and the flood's half-open connections are closed by the viewer.
//!
//! No daemon for the flood: the page and the WebSocket (its first message is the `status`
//! one) are the viewer's alone, and the haptic loop is another process that the viewer only
//! reads from. With a daemon, WebSocket clients that never read are dropped once frames stop
//! going through, and a real client then gets frames.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use lop_view::{MAX_CONNECTIONS, MAX_WEBSOCKETS, REQUEST_TIMEOUT};
use tungstenite::Message;

/// Connections of the flood.
const FLOOD: usize = 1000;
/// Of which WebSocket clients that never read (fewer than the viewer takes, so a real one
/// still fits).
const SLOW_WEBSOCKETS: usize = 40;
/// The viewer's threads stay at most this many (it runs on three: event loop, hub, control).
const MAX_THREADS: u64 = 8;
/// Its resident memory grows by at most this much under the flood.
const MAX_RSS_GROWTH_KB: u64 = 64 * 1024;

struct Viewer {
    child: Child,
    addr: String,
}

impl Drop for Viewer {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn spawn_viewer() -> Viewer {
    spawn_viewer_of(&format!("flood-{}", std::process::id()))
}

fn spawn_viewer_of(prefix: &str) -> Viewer {
    let mut child = Command::new(env!("CARGO_BIN_EXE_lop-view"))
        .args(["--prefix", prefix, "--bind", "127.0.0.1:0"])
        .env_remove("LOP_VIEW_TOKEN")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("spawn lop-view");
    let pid = child.id() as i32;
    std::thread::spawn(move || {
        std::thread::sleep(Duration::from_secs(120));
        // SAFETY: kill on a process this test started; harmless if it is gone.
        unsafe { libc::kill(pid, libc::SIGKILL) };
    });
    let mut line = String::new();
    BufReader::new(child.stdout.take().expect("stdout"))
        .read_line(&mut line)
        .expect("lop-view prints its URL");
    let addr = line
        .split_whitespace()
        .find_map(|w| w.strip_prefix("http://"))
        .and_then(|u| u.split('/').next())
        .unwrap_or_else(|| panic!("no URL in {line:?}"))
        .to_string();
    Viewer { child, addr }
}

/// Raises the soft open-file limit towards `want` (and the hard one, where permitted); returns
/// the limit in force.
fn raise_open_files(want: u64) -> u64 {
    let mut lim = libc::rlimit {
        rlim_cur: 0,
        rlim_max: 0,
    };
    // SAFETY: plain syscalls on a local struct.
    unsafe {
        if libc::getrlimit(libc::RLIMIT_NOFILE, &mut lim) != 0 {
            return 1024;
        }
        if lim.rlim_cur < want as libc::rlim_t {
            // A privileged process (root on a CI machine) may raise the hard limit too.
            if lim.rlim_max < want as libc::rlim_t {
                let raised = libc::rlimit {
                    rlim_cur: want as libc::rlim_t,
                    rlim_max: want as libc::rlim_t,
                };
                libc::setrlimit(libc::RLIMIT_NOFILE, &raised);
                libc::getrlimit(libc::RLIMIT_NOFILE, &mut lim);
            }
            lim.rlim_cur = (want as libc::rlim_t).min(lim.rlim_max);
            libc::setrlimit(libc::RLIMIT_NOFILE, &lim);
            libc::getrlimit(libc::RLIMIT_NOFILE, &mut lim);
        }
    }
    lim.rlim_cur
}

/// A number field (`Threads:`, `VmRSS:` in kB) of `/proc/PID/status`.
fn proc_status(pid: u32, key: &str) -> u64 {
    let text = std::fs::read_to_string(format!("/proc/{pid}/status")).expect("proc status");
    text.lines()
        .find_map(|l| l.strip_prefix(key))
        .and_then(|v| v.split_whitespace().next())
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("no {key} in /proc/{pid}/status"))
}

/// `GET /` on a fresh connection; the answer if it is the page.
fn get_page(addr: &str) -> Option<String> {
    let mut s = TcpStream::connect(addr).ok()?;
    s.set_read_timeout(Some(Duration::from_secs(10))).ok()?;
    s.write_all(b"GET / HTTP/1.1\r\nHost: x\r\n\r\n").ok()?;
    let mut text = String::new();
    let _ = s.read_to_string(&mut text);
    (text.starts_with("HTTP/1.1 200") && text.contains("<title>lop-view</title>")).then_some(text)
}

/// Opens `/ws` and reads until the `status` message; `None` if refused or silent.
fn websocket_status(addr: &str) -> Option<serde_json::Value> {
    let (mut ws, _) = tungstenite::connect(format!("ws://{addr}/ws")).ok()?;
    if let tungstenite::stream::MaybeTlsStream::Plain(s) = ws.get_ref() {
        s.set_read_timeout(Some(Duration::from_secs(5))).ok()?;
    }
    loop {
        let Message::Text(t) = ws.read().ok()? else {
            continue;
        };
        let v: serde_json::Value = serde_json::from_str(t.as_str()).ok()?;
        if v["type"] == "status" {
            return Some(v);
        }
    }
}

/// Opens `/ws` and reads until a frame; its length, `None` if refused or none came.
fn websocket_frame(addr: &str) -> Option<usize> {
    let (mut ws, _) = tungstenite::connect(format!("ws://{addr}/ws")).ok()?;
    if let tungstenite::stream::MaybeTlsStream::Plain(s) = ws.get_ref() {
        s.set_read_timeout(Some(Duration::from_secs(5))).ok()?;
    }
    let start = Instant::now();
    while start.elapsed() < Duration::from_secs(20) {
        if let Message::Binary(b) = ws.read().ok()? {
            if b.len() >= 4 && b[..4] == lop_view::wire::KIND_FRAME.to_le_bytes() {
                return Some(b.len());
            }
        }
    }
    None
}

/// Retries `f` every 100 ms for up to `limit`; the value and how long it took.
fn within<T>(limit: Duration, mut f: impl FnMut() -> Option<T>) -> (T, Duration) {
    let start = Instant::now();
    loop {
        if let Some(v) = f() {
            return (v, start.elapsed());
        }
        assert!(start.elapsed() < limit, "nothing within {limit:?}");
        std::thread::sleep(Duration::from_millis(100));
    }
}

#[test]
fn a_flood_of_1000_connections_leaves_the_page_and_the_websocket_served() {
    // The flood's sockets, the viewer's (it inherits the limit) and some to spare.
    let files = raise_open_files(4096);
    // Where this process may not raise its hard limit past 1,024, the flood shrinks to what it
    // can open, but it must still outnumber the viewer's bound by far, or the test would prove
    // nothing about what happens beyond it.
    let flood = FLOOD.min((files as usize).saturating_sub(200));
    assert!(
        flood >= MAX_CONNECTIONS + 250,
        "open-file limit {files}: a flood beyond the viewer's {MAX_CONNECTIONS} connections \
         needs {} (raise the hard limit)",
        MAX_CONNECTIONS + 450
    );
    eprintln!("flood of {flood} connections (open-file limit {files})");
    let viewer = spawn_viewer();
    let pid = viewer.child.id();
    let addr = viewer.addr.clone();
    let (_, first) = within(Duration::from_secs(10), || get_page(&addr));
    let threads0 = proc_status(pid, "Threads:");
    let rss0 = proc_status(pid, "VmRSS:");
    eprintln!("before the flood: page in {first:?}, {threads0} threads, RSS {rss0} kB");

    // The flood: WebSocket clients that never read, then idle connections and half requests.
    let started = Instant::now();
    let mut slow = Vec::new();
    for _ in 0..SLOW_WEBSOCKETS {
        let (ws, _) = tungstenite::connect(format!("ws://{addr}/ws")).expect("a slow WebSocket");
        slow.push(ws);
    }
    let mut raw = Vec::new();
    let mut refused_connects = 0;
    for i in 0..flood - SLOW_WEBSOCKETS {
        let Ok(mut s) = TcpStream::connect(&addr) else {
            refused_connects += 1;
            continue;
        };
        let _ = match i % 3 {
            0 => Ok(()),                                                // connect, send nothing
            1 => s.write_all(b"GET / HT"),                              // half a request line
            _ => s.write_all(b"GET / HTTP/1.1\r\nHost: x\r\nX-Slow: "), // headers never end
        };
        raw.push(s);
    }
    eprintln!(
        "flood: {SLOW_WEBSOCKETS} WebSockets that never read, {} idle or half-open \
         connections ({refused_connects} connects failed) in {:?}",
        raw.len(),
        started.elapsed()
    );

    // A real client, while the flood is held open.
    let (page, to_page) = within(Duration::from_secs(30), || get_page(&addr));
    assert!(page.contains("app.js"));
    let (status, to_ws) = within(Duration::from_secs(30), || websocket_status(&addr));
    assert_eq!(status["connected"], false, "{status}");
    let threads = proc_status(pid, "Threads:");
    let rss = proc_status(pid, "VmRSS:");
    eprintln!(
        "under the flood: page in {to_page:?}, WebSocket status in {to_ws:?} more; \
         {threads} threads, RSS {rss} kB (+{} kB); bounds: {MAX_CONNECTIONS} connections, \
         {MAX_WEBSOCKETS} WebSockets, {REQUEST_TIMEOUT:?} per request",
        rss.saturating_sub(rss0)
    );
    // Served by closing an idle flood connection, not after the flood's ones time out.
    assert!(to_page < REQUEST_TIMEOUT, "page after {to_page:?}");
    assert!(threads <= MAX_THREADS, "{threads} threads under the flood");
    assert!(
        rss.saturating_sub(rss0) <= MAX_RSS_GROWTH_KB,
        "RSS grew from {rss0} kB to {rss} kB"
    );

    // The half-open connections were closed by the viewer (end of stream, or a reset when it
    // refused them at once); none is left hanging.
    std::thread::sleep(REQUEST_TIMEOUT + Duration::from_secs(1));
    let mut closed = 0;
    for s in &mut raw {
        s.set_read_timeout(Some(Duration::from_millis(50))).unwrap();
        let mut buf = [0u8; 512];
        // A 408 or 400 answer to half a request may come first; then the end of the stream
        // (or a reset, for one refused at once).
        for _ in 0..4 {
            match s.read(&mut buf) {
                Ok(0) => {
                    closed += 1;
                    break;
                }
                Ok(_) => {}
                Err(e)
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                    ) =>
                {
                    break
                }
                Err(_) => {
                    closed += 1;
                    break;
                }
            }
        }
    }
    eprintln!(
        "{closed} of {} flood connections closed by the viewer",
        raw.len()
    );
    assert_eq!(closed, raw.len(), "half-open connections left open");
    assert!(proc_status(pid, "Threads:") <= MAX_THREADS);
    drop(slow);
    drop(viewer);
}

#[test]
fn websockets_beyond_the_bound_get_503_and_a_freed_slot_is_taken_again() {
    let viewer = spawn_viewer();
    let addr = viewer.addr.clone();
    let mut open = Vec::new();
    for i in 0..MAX_WEBSOCKETS {
        let (ws, _) = tungstenite::connect(format!("ws://{addr}/ws"))
            .unwrap_or_else(|e| panic!("WebSocket {i} of {MAX_WEBSOCKETS}: {e}"));
        open.push(ws);
    }
    match tungstenite::connect(format!("ws://{addr}/ws")) {
        Err(tungstenite::Error::Http(resp)) => assert_eq!(resp.status().as_u16(), 503),
        Err(e) => panic!("expected HTTP 503, got {e}"),
        Ok(_) => panic!("WebSocket {} accepted", MAX_WEBSOCKETS + 1),
    }
    // The page is still served meanwhile.
    assert!(get_page(&addr).is_some());
    // One leaves: its slot is free again.
    let mut gone = open.pop().unwrap();
    let _ = gone.close(None);
    let _ = gone.flush();
    drop(gone);
    let (status, took) = within(Duration::from_secs(10), || websocket_status(&addr));
    assert_eq!(status["type"], "status");
    eprintln!("a freed WebSocket slot taken again after {took:?}");
}

#[test]
fn an_oversized_request_head_is_refused() {
    let viewer = spawn_viewer();
    let mut s = TcpStream::connect(&viewer.addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    let big = format!(
        "GET / HTTP/1.1\r\nHost: x\r\nX-Big: {}\r\n\r\n",
        "a".repeat(4 * lop_view::MAX_REQUEST_BYTES)
    );
    // The viewer may close before all of it is written.
    let _ = s.write_all(big.as_bytes());
    let mut text = String::new();
    let _ = s.read_to_string(&mut text);
    assert!(
        !text.starts_with("HTTP/1.1 200"),
        "a {}-byte head was served: {:?}",
        big.len(),
        text.lines().next()
    );
    eprintln!("a {}-byte head: {:?}", big.len(), text.lines().next());
    assert!(get_page(&viewer.addr).is_some());
}

#[test]
fn websockets_that_never_read_are_dropped_and_a_real_client_gets_frames() {
    // Frames flow only with a daemon: then a client that never reads fills its socket's
    // buffers, its send waits, and after SEND_TIMEOUT the viewer drops it.
    let prefix = lop_system_tests::unique_prefix("view-slow");
    let _daemon = lop_system_tests::Daemon::spawn(
        &["run", "--scene", "organs", "--prefix", &prefix, "--quiet"],
        &prefix,
        Duration::from_secs(180),
    );
    let viewer = spawn_viewer_of(&prefix);
    let pid = viewer.child.id();
    let addr = viewer.addr.clone();
    let (len, _) = within(Duration::from_secs(90), || websocket_frame(&addr));
    let rss0 = proc_status(pid, "VmRSS:");
    // Every WebSocket slot taken by a client that never reads.
    let mut slow = Vec::new();
    while slow.len() < MAX_WEBSOCKETS {
        let (ws, _) = within(Duration::from_secs(10), || {
            tungstenite::connect(format!("ws://{addr}/ws")).ok()
        });
        slow.push(ws);
    }
    let started = Instant::now();
    let (_, took) = within(Duration::from_secs(60), || websocket_frame(&addr));
    let threads = proc_status(pid, "Threads:");
    let rss = proc_status(pid, "VmRSS:");
    eprintln!(
        "{MAX_WEBSOCKETS} WebSockets that never read ({len}-byte frames): a real client got a \
         frame after {took:?} ({:?} in all); {threads} threads, RSS {rss0} kB -> {rss} kB",
        started.elapsed()
    );
    assert!(threads <= MAX_THREADS, "{threads} threads");
    assert!(
        rss.saturating_sub(rss0) <= MAX_RSS_GROWTH_KB,
        "RSS grew from {rss0} kB to {rss} kB"
    );
    drop(slow);
}
