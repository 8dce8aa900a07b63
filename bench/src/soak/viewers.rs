//! Viewers coming and going: at planned times a WebSocket opens to the viewer `lopd run --view`
//! started (`ws://ADDR/ws`), reads the topology and frames for a while, sends one control
//! request (`get`), and goes away — closed politely, or dropped as a crashed tab would. Four
//! kinds: with the token of the URL the daemon printed, without a token, with a wrong one, and
//! from a page of another origin.
//!
//! Checked: every handshake but the cross-origin one is accepted and gets the topology (the
//! viewer keeps serving through every fault); every cross-origin handshake is refused with
//! HTTP 403; every control request without the right token is refused as read-only, at once
//! (the viewer decides that alone); a request with the printed token is never refused as
//! read-only. Whether it is answered OK depends on the deformation process being up at that
//! moment: counted.

use std::collections::BTreeMap;
use std::net::{SocketAddr, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use serde::Serialize;
use tungstenite::client::IntoClientRequest;
use tungstenite::{HandshakeError, Message, WebSocket};

use super::report::{check, Check, Evidence};
use super::schedule::{ViewerEvent, ViewerKind};

/// How long a session waits for the topology (a viewer that connects while the deformation
/// process restarts gets it once the scene is loaded again), and a refused control request for
/// its answer.
const WAIT: Duration = Duration::from_secs(30);
/// How long a control request with the token waits (the viewer waits up to 35 s on the daemon).
const CONTROL_WAIT: Duration = Duration::from_secs(5);
/// Violations kept with their details.
const KEPT: usize = 20;

/// Sessions of one kind.
#[derive(Debug, Clone, Default, Serialize)]
pub struct KindTally {
    /// Sessions run.
    pub sessions: u64,
    /// Handshakes accepted.
    pub accepted: u64,
    /// Handshakes refused with HTTP 403.
    pub refused_403: u64,
    /// Sessions that got the topology.
    pub topology: u64,
    /// Sessions that got at least one frame.
    pub framed: u64,
    /// Binary messages (frames, triangles) received.
    pub binary_messages: u64,
    /// Control answers `ok`.
    pub control_ok: u64,
    /// Control answers refused as read-only.
    pub control_read_only: u64,
    /// Control answers with another error (the daemon did not answer in time).
    pub control_error: u64,
    /// Control requests not answered within the wait.
    pub control_unanswered: u64,
    /// Sessions dropped without a close.
    pub abrupt: u64,
}

/// How the viewer sessions went.
#[derive(Debug, Clone, Default, Serialize)]
pub struct ViewerReport {
    /// Per kind.
    pub kinds: BTreeMap<ViewerKind, KindTally>,
    /// Sessions that broke a rule.
    pub wrong: u64,
    /// The first of them, described.
    pub violations: Vec<String>,
}

impl ViewerReport {
    fn violation(&mut self, what: String) {
        self.wrong += 1;
        if self.violations.len() < KEPT {
            self.violations.push(what);
        }
    }
}

type Ws = WebSocket<TcpStream>;

fn open(addr: &str, origin: &str) -> Result<Ws, String> {
    let sock: SocketAddr = addr
        .parse()
        .map_err(|e| format!("viewer address {addr:?}: {e}"))?;
    let stream = TcpStream::connect_timeout(&sock, Duration::from_secs(5))
        .map_err(|e| format!("connect {addr}: {e}"))?;
    stream
        .set_read_timeout(Some(Duration::from_secs(5)))
        .map_err(|e| e.to_string())?;
    let mut req = format!("ws://{addr}/ws")
        .into_client_request()
        .map_err(|e| e.to_string())?;
    req.headers_mut().insert(
        "Origin",
        origin
            .parse()
            .map_err(|e| format!("origin {origin:?}: {e}"))?,
    );
    match tungstenite::client(req, stream) {
        Ok((ws, _)) => {
            let _ = ws
                .get_ref()
                .set_read_timeout(Some(Duration::from_millis(100)));
            Ok(ws)
        }
        Err(HandshakeError::Failure(tungstenite::Error::Http(resp))) => {
            Err(format!("HTTP {}", resp.status().as_u16()))
        }
        Err(HandshakeError::Failure(e)) => Err(format!("handshake: {e}")),
        Err(HandshakeError::Interrupted(_)) => Err("handshake timed out".into()),
    }
}

/// The next message, `None` after a read timeout, `Err` when the connection is gone.
fn read(ws: &mut Ws) -> Result<Option<Message>, String> {
    match ws.read() {
        Ok(m) => Ok(Some(m)),
        Err(tungstenite::Error::Io(e))
            if matches!(
                e.kind(),
                std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
            ) =>
        {
            Ok(None)
        }
        Err(e) => Err(e.to_string()),
    }
}

fn json_type(m: &Message) -> Option<(String, serde_json::Value)> {
    let Message::Text(t) = m else { return None };
    let v: serde_json::Value = serde_json::from_str(t.as_str()).ok()?;
    Some((v["type"].as_str()?.to_string(), v))
}

/// One session; returns a violation if it broke a rule.
fn session(
    addr: &str,
    token: &str,
    body: &str,
    e: &ViewerEvent,
    t: &mut KindTally,
) -> Option<String> {
    t.sessions += 1;
    let own = format!("http://{addr}");
    let origin = match e.kind {
        ViewerKind::CrossOrigin => "http://evil.example",
        _ => own.as_str(),
    };
    let mut ws = match (open(addr, origin), e.kind) {
        (Err(why), ViewerKind::CrossOrigin) if why == "HTTP 403" => {
            t.refused_403 += 1;
            return None;
        }
        (Err(why), kind) => {
            return Some(format!(
                "{} session at {:.1} s: handshake failed: {why}",
                kind.label(),
                e.at_s
            ))
        }
        (Ok(_), ViewerKind::CrossOrigin) => {
            t.accepted += 1;
            return Some(format!(
                "a page of http://evil.example opened the WebSocket at {:.1} s",
                e.at_s
            ));
        }
        (Ok(ws), _) => ws,
    };
    t.accepted += 1;

    // The topology comes first, then frames; read for the session's hold time.
    let start = Instant::now();
    let mut topology = false;
    let mut binaries = 0u64;
    while start.elapsed() < WAIT && (!topology || start.elapsed().as_secs_f64() < e.hold_s) {
        match read(&mut ws) {
            Ok(Some(m)) => {
                if json_type(&m).is_some_and(|(ty, _)| ty == "topology") {
                    topology = true;
                }
                if matches!(m, Message::Binary(_)) && topology {
                    binaries += 1;
                }
            }
            Ok(None) => {}
            Err(why) => {
                return Some(format!(
                    "{} session at {:.1} s: connection lost while reading: {why}",
                    e.kind.label(),
                    e.at_s
                ))
            }
        }
    }
    if !topology {
        return Some(format!(
            "{} session at {:.1} s: no topology within {WAIT:?}",
            e.kind.label(),
            e.at_s
        ));
    }
    t.topology += 1;
    t.binary_messages += binaries;
    // The first binary message is the triangles; frames follow.
    if binaries >= 2 {
        t.framed += 1;
    }

    // One control request.
    let mut req = serde_json::json!({"op": "get", "body": body});
    match e.kind {
        ViewerKind::Token => req["token"] = token.into(),
        ViewerKind::WrongToken => req["token"] = "0123456789abcdef0123456789abcdef".into(),
        _ => {}
    }
    if let Err(why) = ws.send(Message::text(req.to_string())) {
        return Some(format!(
            "{} session at {:.1} s: sending a control request: {why}",
            e.kind.label(),
            e.at_s
        ));
    }
    let wait = match e.kind {
        ViewerKind::Token => CONTROL_WAIT,
        _ => WAIT,
    };
    let sent = Instant::now();
    let mut answer = None;
    while sent.elapsed() < wait && answer.is_none() {
        match read(&mut ws) {
            Ok(Some(m)) => {
                if let Some((ty, v)) = json_type(&m) {
                    if ty == "control" {
                        answer = Some(v);
                    }
                }
            }
            Ok(None) => {}
            Err(why) => {
                return Some(format!(
                    "{} session at {:.1} s: connection lost awaiting the control answer: {why}",
                    e.kind.label(),
                    e.at_s
                ))
            }
        }
    }
    let mut wrong = None;
    match (&answer, e.kind) {
        (None, ViewerKind::Token) => t.control_unanswered += 1,
        (None, kind) => {
            t.control_unanswered += 1;
            wrong = Some(format!(
                "{} session at {:.1} s: the viewer did not refuse the control request within \
                 {WAIT:?}",
                kind.label(),
                e.at_s
            ));
        }
        (Some(v), kind) => {
            let ok = v["ok"] == true;
            let read_only = v["read_only"] == true;
            if ok {
                t.control_ok += 1;
            } else if read_only {
                t.control_read_only += 1;
            } else {
                t.control_error += 1;
            }
            match kind {
                ViewerKind::Token if read_only => {
                    wrong = Some(format!(
                        "session at {:.1} s: the printed token was refused: {v}",
                        e.at_s
                    ))
                }
                ViewerKind::NoToken | ViewerKind::WrongToken if !read_only || ok => {
                    wrong = Some(format!(
                        "{} session at {:.1} s: control not refused as read-only: {v}",
                        kind.label(),
                        e.at_s
                    ))
                }
                _ => {}
            }
        }
    }

    if e.abrupt {
        t.abrupt += 1;
        drop(ws);
    } else {
        let _ = ws.close(None);
        let closing = Instant::now();
        while closing.elapsed() < Duration::from_secs(2) {
            match read(&mut ws) {
                Ok(_) => {}
                Err(_) => break,
            }
        }
    }
    wrong
}

/// Runs the planned sessions at their times after `t0`, until `stop`.
pub fn churn(
    addr: String,
    token: String,
    body: String,
    events: Vec<ViewerEvent>,
    t0: Instant,
    stop: Arc<AtomicBool>,
) -> ViewerReport {
    let mut rep = ViewerReport::default();
    for e in events {
        while t0.elapsed().as_secs_f64() < e.at_s {
            if stop.load(Ordering::Relaxed) {
                return rep;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        if stop.load(Ordering::Relaxed) {
            return rep;
        }
        let mut tally = rep.kinds.remove(&e.kind).unwrap_or_default();
        let wrong = session(&addr, &token, &body, &e, &mut tally);
        rep.kinds.insert(e.kind, tally);
        if let Some(w) = wrong {
            rep.violation(w);
        }
    }
    rep
}

// ---------------------------------------------------------------------------------------------
// The checks on this evidence.

/// Viewers served through every fault, control only with the printed token, other origins
/// refused.
pub(super) fn check_access(e: &Evidence<'_>) -> Check {
    let v = e.viewers;
    let tally = |k: ViewerKind| v.kinds.get(&k).cloned().unwrap_or_default();
    let (tok, none, wrong, cross) = (
        tally(ViewerKind::Token),
        tally(ViewerKind::NoToken),
        tally(ViewerKind::WrongToken),
        tally(ViewerKind::CrossOrigin),
    );
    check(
        "viewers: served through every fault; control only with the printed token; other origins refused",
        v.wrong == 0 && tok.sessions + none.sessions + wrong.sessions + cross.sessions > 0,
        format!(
            "{} sessions with the token ({} controlled, {} daemon busy or down), {} without and \
             {} with a wrong token ({} refused read-only), {} from another origin ({} refused \
             with 403); {} got frames, {} dropped without a close; {} broke a rule",
            tok.sessions,
            tok.control_ok,
            tok.control_error + tok.control_unanswered,
            none.sessions,
            wrong.sessions,
            none.control_read_only + wrong.control_read_only,
            cross.sessions,
            cross.refused_403,
            tok.framed + none.framed + wrong.framed,
            tok.abrupt + none.abrupt + wrong.abrupt,
            v.wrong
        ),
    )
}
