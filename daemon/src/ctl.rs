//! `lopd ctl`: the command line of the control service `PREFIX/control`.
//!
//! ```text
//! lopd ctl [--prefix P] get BODY                 pin, model and parameters of a body
//! lopd ctl [--prefix P] set BODY KEY VALUE       e.g. set liver fem.young 300
//! lopd ctl [--prefix P] pin BODY gc|msd|fem      run the body on one model
//! lopd ctl [--prefix P] release BODY             back to the levels-of-precision controller
//! lopd ctl [--prefix P] reset | pause | resume
//! ```
//!
//! BODY is a name or an index. Exit codes: 0 done, 1 no daemon / no answer / the rebuild failed,
//! 2 a bad request (unknown body or key, bad value, not allowed), with the daemon's message.
//! A busy answer (a rebuild running, or the tool touching the body) is retried for a while.

use std::time::{Duration, Instant};

use lop_ipc::control::*;
use lop_ipc::{services, BodyModel, ServiceNames};

/// How long `ctl` waits for the daemon's services to appear.
const OPEN_TIMEOUT: Duration = Duration::from_secs(5);
/// How long one request may take (a rebuild of a large FEM body included).
const ANSWER_TIMEOUT: Duration = Duration::from_secs(30);
/// How long a busy answer is retried.
const BUSY_RETRY: Duration = Duration::from_secs(10);

/// A parsed `lopd ctl` command.
#[derive(Debug, Clone, PartialEq)]
pub enum CtlCommand {
    /// `get BODY`
    Get(String),
    /// `set BODY KEY VALUE`
    Set(String, String, f64),
    /// `pin BODY MODEL`
    Pin(String, BodyModel),
    /// `release BODY`
    Release(String),
    /// `reset`
    Reset,
    /// `pause`
    Pause,
    /// `resume`
    Resume,
}

/// A command line that is not a control command; the message names the bad word.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct CtlUsage(pub String);

impl CtlCommand {
    /// Parses the words after `lopd ctl`.
    pub fn parse(words: &[String]) -> Result<CtlCommand, CtlUsage> {
        let w: Vec<&str> = words.iter().map(String::as_str).collect();
        let usage = "use: get BODY | set BODY KEY VALUE | pin BODY gc|msd|fem | release BODY | reset | pause | resume";
        Ok(match w.as_slice() {
            ["get", body] => CtlCommand::Get(body.to_string()),
            ["set", body, key, value] => {
                let v: f64 = value.parse().map_err(|_| {
                    CtlUsage(format!("set {body} {key}: value {value:?} is not a number"))
                })?;
                CtlCommand::Set(body.to_string(), key.to_string(), v)
            }
            ["pin", body, model] => CtlCommand::Pin(
                body.to_string(),
                match model.to_ascii_lowercase().as_str() {
                    "gc" => BodyModel::Gc,
                    "msd" => BodyModel::Msd,
                    "fem" => BodyModel::Fem,
                    _ => {
                        return Err(CtlUsage(format!(
                            "pin {body}: model {model:?} is not one of gc, msd, fem"
                        )))
                    }
                },
            ),
            ["release", body] => CtlCommand::Release(body.to_string()),
            ["reset"] => CtlCommand::Reset,
            ["pause"] => CtlCommand::Pause,
            ["resume"] => CtlCommand::Resume,
            [] => return Err(CtlUsage(format!("no command; {usage}"))),
            [op, ..] => {
                return Err(CtlUsage(format!(
                    "{:?} with {} argument(s) is not a control command; {usage}",
                    op,
                    w.len() - 1
                )))
            }
        })
    }

    /// The wire request.
    pub fn request(&self) -> ControlRequest {
        let mut r = match self {
            CtlCommand::Get(b) => ControlRequest::new(CONTROL_OP_GET, b),
            CtlCommand::Set(b, k, v) => ControlRequest::set(b, k, *v),
            CtlCommand::Pin(b, m) => ControlRequest::pin(b, *m),
            CtlCommand::Release(b) => ControlRequest::new(CONTROL_OP_RELEASE, b),
            CtlCommand::Reset => ControlRequest::new(CONTROL_OP_RESET, ""),
            CtlCommand::Pause => ControlRequest::new(CONTROL_OP_PAUSE, ""),
            CtlCommand::Resume => ControlRequest::new(CONTROL_OP_RESUME, ""),
        };
        // A numeric BODY is an index.
        if let Ok(i) = r.body_str().parse::<i32>() {
            r.body_index = i;
        }
        r
    }
}

/// Sends `cmd` to the daemon under `names`, prints the answer, and returns the exit code.
pub fn run(names: &ServiceNames, cmd: &CtlCommand) -> anyhow::Result<i32> {
    let node = services::node(&format!("lopd-ctl-{}", std::process::id()))?;
    let client = ControlClient::open(&node, names, OPEN_TIMEOUT)?;
    let req = cmd.request();
    let start = Instant::now();
    let resp = loop {
        let resp = client.request(&req, ANSWER_TIMEOUT)?;
        if resp.status != CONTROL_STATUS_BUSY || start.elapsed() > BUSY_RETRY {
            break resp;
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    print!("{}", format_response(&resp));
    Ok(match resp.status {
        CONTROL_STATUS_OK => 0,
        CONTROL_STATUS_BUSY | CONTROL_STATUS_FAILED => {
            eprintln!(
                "lopd ctl: error: {}: {}",
                resp.status_name(),
                resp.message_str()
            );
            1
        }
        _ => {
            eprintln!(
                "lopd ctl: error: {}: {}",
                resp.status_name(),
                resp.message_str()
            );
            2
        }
    })
}

/// The human-readable form of a response (what `lopd ctl` prints on stdout).
pub fn format_response(r: &ControlResponse) -> String {
    let mut s = String::new();
    if r.status == CONTROL_STATUS_OK && !r.message_str().is_empty() {
        s.push_str(&format!("ok: {}\n", r.message_str()));
    }
    if r.status != CONTROL_STATUS_OK {
        return s;
    }
    if r.body_index >= 0 {
        let pin = match r.pin {
            CONTROL_PIN_AUTO => "auto (levels of precision)",
            p => BodyModel::from_u8(p).map_or("?", BodyModel::as_str),
        };
        let model = BodyModel::from_u8(r.model).map_or("?", BodyModel::as_str);
        s.push_str(&format!(
            "{} (body {}): pin {pin}, model {model}{}\n",
            r.body_str(),
            r.body_index,
            if r.paused != 0 { ", paused" } else { "" }
        ));
        for p in r.params() {
            s.push_str(&format!(
                "  {:<16} {:<12} {}\n",
                p.key_str(),
                p.value,
                if p.flags & CONTROL_PARAM_LIVE != 0 {
                    "live"
                } else {
                    ""
                }
            ));
        }
    } else {
        s.push_str(if r.paused != 0 {
            "paused\n"
        } else {
            "running\n"
        });
    }
    s
}
