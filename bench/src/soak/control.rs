//! Control requests, hammered: a thread of this bench sends requests to `PREFIX/control` back to
//! back (one every `--hammer-ms`), a seeded mix of reads, parameter changes that rebuild models,
//! pins, pauses, resets and bad requests; and bursts of `lopd ctl` processes at planned times,
//! each its own iceoryx2 node and control client that comes and goes.
//!
//! Checked: no bad request is ever accepted (a NaN value, a Poisson ratio of 0.5, an unknown
//! body, key or op, another contract version), no good one is refused as bad, and every
//! `lopd ctl` exits with a code its request allows. Requests sent while the deformation process
//! is stopped or restarting go unanswered (it serves control between steps): counted, not a
//! fault.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use lop_client::{BodyModel, ServiceNames, CONTRACT_VERSION};
use lop_ipc::control::*;
use lop_ipc::services;
use serde::Serialize;

use super::report::{check, Check, Evidence};
use super::schedule::{CtlEvent, Rng};
use crate::pipeline::ChildGuard;

/// How long the hammer waits for one answer (the deformation process answers between steps,
/// within a few milliseconds; only a stopped or restarting one takes longer).
const ANSWER_TIMEOUT: Duration = Duration::from_secs(2);
/// Consecutive unanswered requests after which the hammer opens a new client.
const REOPEN_AFTER: u32 = 3;
/// Violations kept with their details.
const KEPT: usize = 20;

/// What the hammer did and saw.
#[derive(Debug, Clone, Default, Serialize)]
pub struct HammerReport {
    /// Requests sent.
    pub sent: u64,
    /// Requests answered.
    pub answered: u64,
    /// Requests not answered within 2 s (deformation process stopped or restarting).
    pub unanswered: u64,
    /// Answers by status name, good requests.
    pub good_status: BTreeMap<String, u64>,
    /// Answers by status name, bad requests.
    pub bad_status: BTreeMap<String, u64>,
    /// Bad requests sent.
    pub bad_sent: u64,
    /// Bad requests answered OK: accepted (a violation).
    pub bad_accepted: u64,
    /// Good requests refused as malformed (unknown body, key or op, bad value): a violation.
    pub good_refused: u64,
    /// Times the client was opened again after unanswered requests.
    pub reopens: u64,
    /// Times opening the client failed (the deformation process restarting).
    pub open_failures: u64,
    /// Requests by kind.
    pub kinds: BTreeMap<&'static str, u64>,
    /// The first violations, described.
    pub violations: Vec<String>,
}

/// One request of the mix and what its answer may be.
struct Planned {
    kind: &'static str,
    request: ControlRequest,
    /// A bad request: it must not be answered OK.
    bad: bool,
}

/// The bodies' names and the parameters they had at the start (set requests stay within a
/// factor of 1.25 of them, so the scene stays the scene).
#[derive(Debug, Clone)]
pub struct Bodies {
    /// Names in topology order.
    pub names: Vec<String>,
    /// Per body: the live keys and their values at the start.
    pub params: Vec<Vec<(String, f64)>>,
}

fn bad_request(rng: &mut Rng, bodies: &Bodies) -> (&'static str, ControlRequest) {
    let body = &bodies.names[0];
    match rng.below(7) {
        0 => (
            "bad: unknown body",
            ControlRequest::new(CONTROL_OP_GET, "no-such-organ"),
        ),
        1 => {
            let mut r = ControlRequest::new(CONTROL_OP_GET, "");
            r.body_index = 99;
            ("bad: body index 99", r)
        }
        2 => (
            "bad: NaN value",
            ControlRequest::set(body, "fem.young", f64::NAN),
        ),
        3 => (
            "bad: value out of range",
            ControlRequest::set(body, "fem.poisson", 0.5),
        ),
        4 => (
            "bad: unknown key",
            ControlRequest::set(body, "fem.colour", 3.0),
        ),
        5 => ("bad: unknown op", ControlRequest::new(99, body)),
        _ => {
            let mut r = ControlRequest::new(CONTROL_OP_GET, body);
            r.contract_version = CONTRACT_VERSION + 1;
            ("bad: other contract version", r)
        }
    }
}

/// The next requests of the mix (one, or a pair that undoes itself: pause then resume, pin
/// then release).
fn next(rng: &mut Rng, bodies: &Bodies) -> Vec<Planned> {
    let good = |kind, request| Planned {
        kind,
        request,
        bad: false,
    };
    let b = rng.below(bodies.names.len());
    let name = bodies.names[b].as_str();
    let roll = rng.below(100);
    let factor = if rng.below(2) == 0 { 0.8 } else { 1.25 };
    let set = |prefix: &str, rng: &mut Rng| {
        let keys: Vec<&(String, f64)> = bodies.params[b]
            .iter()
            .filter(|(k, _)| k.starts_with(prefix))
            .collect();
        (!keys.is_empty()).then(|| {
            let (k, v) = keys[rng.below(keys.len())];
            ControlRequest::set(name, k, v * factor)
        })
    };
    match roll {
        0..=59 => vec![good("get", ControlRequest::new(CONTROL_OP_GET, name))],
        60..=71 => match set("lop.", rng) {
            Some(r) => vec![good("set lop.*", r)],
            None => vec![good("get", ControlRequest::new(CONTROL_OP_GET, name))],
        },
        // Rebuilds the body's precise model and its cage (off the real-time path).
        72..=73 => {
            let prefix = if rng.below(2) == 0 {
                "fem.young"
            } else {
                "msd."
            };
            match set(prefix, rng) {
                Some(r) => vec![good("set fem/msd (rebuild)", r)],
                None => vec![good("get", ControlRequest::new(CONTROL_OP_GET, name))],
            }
        }
        74..=75 => {
            let model = [BodyModel::Gc, BodyModel::Msd, BodyModel::Fem][rng.below(3)];
            vec![
                good("pin", ControlRequest::pin(name, model)),
                good("release", ControlRequest::new(CONTROL_OP_RELEASE, name)),
            ]
        }
        76..=77 => vec![
            good("pause", ControlRequest::new(CONTROL_OP_PAUSE, "")),
            good("resume", ControlRequest::new(CONTROL_OP_RESUME, "")),
        ],
        78 => vec![good("reset", ControlRequest::new(CONTROL_OP_RESET, ""))],
        _ => {
            let (kind, request) = bad_request(rng, bodies);
            vec![Planned {
                kind,
                request,
                bad: true,
            }]
        }
    }
}

/// Reads every body's live parameters (`GET`), retrying until `stop`.
pub fn read_bodies(names: &ServiceNames, bodies: &[String], stop: &AtomicBool) -> Option<Bodies> {
    let node = services::node(&format!("lop-bench-soak-get-{}", std::process::id())).ok()?;
    let client = ControlClient::open(&node, names, Duration::from_secs(30)).ok()?;
    let mut params = Vec::new();
    for b in bodies {
        loop {
            if stop.load(Ordering::Relaxed) {
                return None;
            }
            match client.request(&ControlRequest::new(CONTROL_OP_GET, b), ANSWER_TIMEOUT) {
                Ok(r) if r.status == CONTROL_STATUS_OK => {
                    params.push(
                        r.params()
                            .iter()
                            .filter(|p| p.flags & CONTROL_PARAM_LIVE != 0)
                            .map(|p| (p.key_str().to_string(), p.value))
                            .collect(),
                    );
                    break;
                }
                _ => std::thread::sleep(Duration::from_millis(100)),
            }
        }
    }
    Some(Bodies {
        names: bodies.to_vec(),
        params,
    })
}

fn keep(rep: &mut HammerReport, what: String) {
    if rep.violations.len() < KEPT {
        rep.violations.push(what);
    }
}

/// Whether `status` says the request itself was malformed (as opposed to "not now", "not for
/// this body", or a rebuild that failed).
fn malformed(status: u32) -> bool {
    matches!(
        status,
        CONTROL_STATUS_UNKNOWN_BODY
            | CONTROL_STATUS_UNKNOWN_KEY
            | CONTROL_STATUS_BAD_VALUE
            | CONTROL_STATUS_BAD_REQUEST
    )
}

/// Hammers `PREFIX/control` until `stop`, one request every `interval`; the pipeline's bodies
/// are `bodies`. Ends with a `resume`, so the run never ends paused.
pub fn hammer(
    names: ServiceNames,
    bodies: Bodies,
    seed: u64,
    interval: Duration,
    stop: Arc<AtomicBool>,
) -> HammerReport {
    let mut rep = HammerReport::default();
    let mut rng = Rng::new(seed);
    let node = match services::node(&format!("lop-bench-soak-hammer-{}", std::process::id())) {
        Ok(n) => n,
        Err(e) => {
            rep.violations.push(format!("control hammer: no node: {e}"));
            return rep;
        }
    };
    let open = || ControlClient::open(&node, &names, Duration::from_secs(5)).ok();
    let mut client = open();
    let mut silent = 0u32;
    let mut queue: Vec<Planned> = Vec::new();
    let mut tries_after_stop = 0;
    loop {
        let stopping = stop.load(Ordering::Relaxed);
        if stopping {
            // Only the second half of a pair (resume, release) is still sent; a few tries.
            if queue.is_empty() || tries_after_stop >= 5 {
                break;
            }
            tries_after_stop += 1;
        }
        if queue.is_empty() {
            queue = next(&mut rng, &bodies);
            queue.reverse();
        }
        let Some(p) = queue.pop() else { continue };
        let Some(c) = &client else {
            client = open();
            if client.is_none() {
                rep.open_failures += 1;
                std::thread::sleep(Duration::from_millis(100));
            }
            queue.push(p);
            continue;
        };
        rep.sent += 1;
        *rep.kinds.entry(p.kind).or_default() += 1;
        if p.bad {
            rep.bad_sent += 1;
        }
        match c.request(&p.request, ANSWER_TIMEOUT) {
            Ok(r) => {
                rep.answered += 1;
                silent = 0;
                let name = status_name(r.status).to_string();
                if p.bad {
                    *rep.bad_status.entry(name).or_default() += 1;
                    if r.status == CONTROL_STATUS_OK {
                        rep.bad_accepted += 1;
                        keep(
                            &mut rep,
                            format!("{} accepted: {:?}", p.kind, r.message_str()),
                        );
                    }
                } else {
                    *rep.good_status.entry(name).or_default() += 1;
                    if malformed(r.status) {
                        rep.good_refused += 1;
                        keep(
                            &mut rep,
                            format!(
                                "{} refused as {}: {}",
                                p.kind,
                                status_name(r.status),
                                r.message_str()
                            ),
                        );
                    }
                }
            }
            Err(_) => {
                rep.unanswered += 1;
                silent += 1;
                // A pair's second half is sent again: a pause must be followed by a resume.
                if matches!(p.kind, "resume" | "release") {
                    queue.push(p);
                }
                if silent >= REOPEN_AFTER {
                    client = None;
                    silent = 0;
                    rep.reopens += 1;
                }
            }
        }
        if !stopping {
            std::thread::sleep(interval);
        }
    }
    rep
}

/// How the `lopd ctl` bursts went.
#[derive(Debug, Clone, Default, Serialize)]
pub struct CtlReport {
    /// `lopd ctl` processes run.
    pub runs: u64,
    /// Exit codes seen, by command.
    pub exits: BTreeMap<String, BTreeMap<i32, u64>>,
    /// Processes whose exit code their request does not allow, or that hung.
    pub wrong: u64,
    /// Their pids (for the leftover check).
    #[serde(skip)]
    pub pids: Vec<u32>,
    /// The first wrong ones, described.
    pub violations: Vec<String>,
}

/// Runs the planned `lopd ctl` bursts (each: a good `get`, a NaN `set`, an unknown body) at
/// their times after `t0`, until `stop`.
pub fn ctl_bursts(
    lopd: PathBuf,
    prefix: String,
    body: String,
    events: Vec<CtlEvent>,
    t0: Instant,
    stop: Arc<AtomicBool>,
) -> CtlReport {
    let mut rep = CtlReport::default();
    // Exit codes: 0 done, 1 no daemon or no answer (the deformation process may be stopped),
    // 2 a bad request refused.
    let commands: [(Vec<String>, &[i32]); 3] = [
        (vec!["get".into(), body.clone()], &[0, 1]),
        (
            vec!["set".into(), body.clone(), "fem.young".into(), "NaN".into()],
            &[1, 2],
        ),
        (vec!["get".into(), "99".into()], &[1, 2]),
    ];
    for e in events {
        while t0.elapsed().as_secs_f64() < e.at_s {
            if stop.load(Ordering::Relaxed) {
                return rep;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        for (words, allowed) in &commands {
            if stop.load(Ordering::Relaxed) {
                return rep;
            }
            let mut cmd = Command::new(&lopd);
            cmd.args(["ctl", "--prefix", &prefix])
                .args(words)
                .stdin(Stdio::null())
                .stdout(Stdio::null())
                .stderr(Stdio::null());
            let label = words.join(" ");
            let mut child = match ChildGuard::spawn("lopd ctl", cmd, Duration::from_secs(2)) {
                Ok(c) => c,
                Err(e) => {
                    rep.wrong += 1;
                    rep.violations.push(format!("lopd ctl {label}: {e:#}"));
                    continue;
                }
            };
            rep.runs += 1;
            rep.pids.push(child.id());
            // ctl's own limits: 5 s to open, 30 s for an answer, 10 s of busy retries.
            let code = child
                .wait_for(Duration::from_secs(60))
                .map(|s| s.code().unwrap_or(-1));
            let code = match code {
                Some(c) => c,
                None => {
                    child.stop();
                    -1
                }
            };
            *rep.exits
                .entry(label.clone())
                .or_default()
                .entry(code)
                .or_default() += 1;
            if !allowed.contains(&code) {
                rep.wrong += 1;
                if rep.violations.len() < KEPT {
                    rep.violations.push(format!(
                        "lopd ctl {label}: exit {code} (allowed {allowed:?}; -1: hung)"
                    ));
                }
            }
        }
    }
    rep
}

// ---------------------------------------------------------------------------------------------
// The checks on this evidence.

/// No bad control request accepted, no good one refused as bad, `lopd ctl` exit codes right.
pub(super) fn check_requests(e: &Evidence<'_>) -> Check {
    let h = e.hammer;
    check(
        "control: no bad request accepted, no good one refused as bad",
        h.bad_accepted == 0
            && h.good_refused == 0
            && e.ctl.wrong == 0
            && h.answered > 0
            && h.violations.is_empty(),
        format!(
            "{} requests ({:.0}/s), {} answered, {} unanswered (deformation process stopped or \
             restarting), {} bad ones sent, {} accepted, {} good ones refused as bad; lopd ctl: \
             {} runs, {} with a wrong exit code",
            h.sent,
            h.sent as f64 / e.settings.seconds,
            h.answered,
            h.unanswered,
            h.bad_sent,
            h.bad_accepted,
            h.good_refused,
            e.ctl.runs,
            e.ctl.wrong
        ),
    )
}
