//! Runtime control: the request–response service `PREFIX/control`, served by the deformation
//! process between world steps (never by the haptic process, so no request can make the haptic
//! loop miss a deadline).
//!
//! One request, one response, both fixed-size `#[repr(C)]` (see `docs/ipc.md` and
//! `ipc/include/lop_ipc.h`). A body is named by index (`body_index >= 0`) or, with
//! `body_index = -1`, by its NUL-padded name. A bad request is answered with a typed
//! `CONTROL_STATUS_*` and a message naming the key and the offending value; it never changes
//! anything.
//!
//! | op                    | body | uses            | does                                                    |
//! |-----------------------|------|-----------------|---------------------------------------------------------|
//! | `CONTROL_OP_GET`      | yes  |                 | the body's pin, current model and parameters            |
//! | `CONTROL_OP_SET`      | yes  | `key`, `value`  | sets one live parameter (see [`CONTROL_KEYS`])          |
//! | `CONTROL_OP_PIN`      | yes  | `model`         | runs the body on one model (`BodyModel` as u32), no LoP |
//! | `CONTROL_OP_RELEASE`  | yes  |                 | hands the body back to the levels-of-precision controller |
//! | `CONTROL_OP_RESET`    | no   |                 | every body back to its rest shape, at rest              |
//! | `CONTROL_OP_PAUSE`    | no   |                 | stops stepping; frames keep coming with frozen positions |
//! | `CONTROL_OP_RESUME`   | no   |                 | steps again from where it stopped                       |

use iceoryx2::prelude::ZeroCopySend;

use crate::types::BODY_NAME_LEN;

/// Bytes of a parameter key, NUL-padded ASCII (`fem.young`).
pub const CONTROL_KEY_LEN: usize = 32;
/// Bytes of a response's message, NUL-padded UTF-8.
pub const CONTROL_MESSAGE_LEN: usize = 128;
/// Most parameters a `GET` response lists.
pub const CONTROL_MAX_PARAMS: usize = 16;

/// Reads a body's pin, model and parameters.
pub const CONTROL_OP_GET: u32 = 1;
/// Sets one parameter of a body.
pub const CONTROL_OP_SET: u32 = 2;
/// Pins a body to one model.
pub const CONTROL_OP_PIN: u32 = 3;
/// Releases a pinned body to the levels-of-precision controller.
pub const CONTROL_OP_RELEASE: u32 = 4;
/// Resets every body to rest.
pub const CONTROL_OP_RESET: u32 = 5;
/// Pauses the simulation.
pub const CONTROL_OP_PAUSE: u32 = 6;
/// Resumes the simulation.
pub const CONTROL_OP_RESUME: u32 = 7;

/// Done.
pub const CONTROL_STATUS_OK: u32 = 0;
/// No body has that index or name.
pub const CONTROL_STATUS_UNKNOWN_BODY: u32 = 1;
/// The key is not a parameter (see [`CONTROL_KEYS`]).
pub const CONTROL_STATUS_UNKNOWN_KEY: u32 = 2;
/// The value is out of range or not finite for the key (the message names both).
pub const CONTROL_STATUS_BAD_VALUE: u32 = 3;
/// The operation does not apply to this body (e.g. `fem.young` on a body without FEM
/// parameters, `lop.hold` on a pinned body, a pin to a model the body has no parameters for).
pub const CONTROL_STATUS_NOT_ALLOWED: u32 = 4;
/// The body is being touched by the tool: its model is not swapped under the hand. Retry.
pub const CONTROL_STATUS_BUSY: u32 = 5;
/// Unknown op, or another contract version.
pub const CONTROL_STATUS_BAD_REQUEST: u32 = 6;
/// Building the new model failed (the message says why); the body keeps its old one.
pub const CONTROL_STATUS_FAILED: u32 = 7;

/// `ControlResponse::pin`: the body is under the levels-of-precision controller.
pub const CONTROL_PIN_AUTO: u8 = 255;

/// `ControlParam::flags` bit: the parameter can be set at run time.
pub const CONTROL_PARAM_LIVE: u32 = 1 << 0;

/// The live-settable keys and their unit and valid range. `fem.*` and `msd.*` rebuild the
/// body's precise model and its cage off the real-time path (the motion carries over); `lop.*`
/// retune the body's controller at once.
pub const CONTROL_KEYS: [(&str, &str); 7] = [
    ("fem.young", "Pa, > 0"),
    ("fem.poisson", "0 <= v < 0.5"),
    ("fem.damping", "1/s, >= 0"),
    ("msd.stiffness", "N/m, > 0"),
    ("msd.damping", "N*s/m, >= 0"),
    ("lop.rest_speed", "m/s, > 0"),
    ("lop.hold", "s, >= 0"),
];

/// A control request (`PREFIX/control`, request type).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("lop::ControlRequest")]
pub struct ControlRequest {
    /// [`crate::CONTRACT_VERSION`].
    pub contract_version: u32,
    /// `CONTROL_OP_*`.
    pub op: u32,
    /// Body index in the topology, or -1 to name it in `body`.
    pub body_index: i32,
    /// `CONTROL_OP_PIN`: the model, a [`crate::BodyModel`] value.
    pub model: u32,
    /// Body name, UTF-8, NUL-padded (with `body_index = -1`).
    pub body: [u8; BODY_NAME_LEN],
    /// `CONTROL_OP_SET`: the parameter key, NUL-padded.
    pub key: [u8; CONTROL_KEY_LEN],
    /// `CONTROL_OP_SET`: the new value (SI units).
    pub value: f64,
}

impl Default for ControlRequest {
    fn default() -> Self {
        ControlRequest {
            contract_version: crate::CONTRACT_VERSION,
            op: 0,
            body_index: -1,
            model: 0,
            body: [0; BODY_NAME_LEN],
            key: [0; CONTROL_KEY_LEN],
            value: 0.0,
        }
    }
}

impl ControlRequest {
    /// A request of `op` on the body named `body` (empty: none).
    pub fn new(op: u32, body: &str) -> ControlRequest {
        let mut r = ControlRequest {
            op,
            ..Default::default()
        };
        put_str(&mut r.body, body);
        r
    }
    /// `SET body key = value`.
    pub fn set(body: &str, key: &str, value: f64) -> ControlRequest {
        let mut r = ControlRequest::new(CONTROL_OP_SET, body);
        put_str(&mut r.key, key);
        r.value = value;
        r
    }
    /// `PIN body model`.
    pub fn pin(body: &str, model: crate::BodyModel) -> ControlRequest {
        let mut r = ControlRequest::new(CONTROL_OP_PIN, body);
        r.model = model as u32;
        r
    }
    /// The body name.
    pub fn body_str(&self) -> &str {
        get_str(&self.body)
    }
    /// The key.
    pub fn key_str(&self) -> &str {
        get_str(&self.key)
    }
}

/// One parameter of a body, in a `GET` response.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[type_name("lop::ControlParam")]
pub struct ControlParam {
    /// Key, NUL-padded (`fem.young`).
    pub key: [u8; CONTROL_KEY_LEN],
    /// Current value, SI units.
    pub value: f64,
    /// `CONTROL_PARAM_*` bits.
    pub flags: u32,
    /// Padding, zero.
    pub _pad: u32,
}

impl ControlParam {
    /// The key.
    pub fn key_str(&self) -> &str {
        get_str(&self.key)
    }
}

/// The answer to one [`ControlRequest`] (`PREFIX/control`, response type).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("lop::ControlResponse")]
pub struct ControlResponse {
    /// [`crate::CONTRACT_VERSION`].
    pub contract_version: u32,
    /// `CONTROL_STATUS_*`.
    pub status: u32,
    /// The body the request named, or -1.
    pub body_index: i32,
    /// The body's pin: a [`crate::BodyModel`] value, or [`CONTROL_PIN_AUTO`].
    pub pin: u8,
    /// The model the body runs now ([`crate::BodyModel`]).
    pub model: u8,
    /// 1 while the simulation is paused.
    pub paused: u8,
    /// Padding, zero.
    pub _pad0: u8,
    /// Entries in use in `params`.
    pub param_count: u32,
    /// Padding, zero.
    pub _pad1: u32,
    /// The body's name, NUL-padded.
    pub body: [u8; BODY_NAME_LEN],
    /// Human-readable result; on an error it names the key and the bad value.
    pub message: [u8; CONTROL_MESSAGE_LEN],
    /// The body's parameters (after the request took effect).
    pub params: [ControlParam; CONTROL_MAX_PARAMS],
}

impl Default for ControlResponse {
    fn default() -> Self {
        ControlResponse {
            contract_version: crate::CONTRACT_VERSION,
            status: CONTROL_STATUS_OK,
            body_index: -1,
            pin: CONTROL_PIN_AUTO,
            model: 0,
            paused: 0,
            _pad0: 0,
            param_count: 0,
            _pad1: 0,
            body: [0; BODY_NAME_LEN],
            message: [0; CONTROL_MESSAGE_LEN],
            params: [ControlParam::default(); CONTROL_MAX_PARAMS],
        }
    }
}

impl ControlResponse {
    /// A response with `status` and `message` (truncated at a character boundary).
    pub fn with(status: u32, message: &str) -> ControlResponse {
        let mut r = ControlResponse {
            status,
            ..Default::default()
        };
        put_str(&mut r.message, message);
        r
    }
    /// The message.
    pub fn message_str(&self) -> &str {
        get_str(&self.message)
    }
    /// The body name.
    pub fn body_str(&self) -> &str {
        get_str(&self.body)
    }
    /// The parameters in use.
    pub fn params(&self) -> &[ControlParam] {
        &self.params[..(self.param_count as usize).min(CONTROL_MAX_PARAMS)]
    }
    /// Appends a parameter (ignored beyond [`CONTROL_MAX_PARAMS`]).
    pub fn push_param(&mut self, key: &str, value: f64, live: bool) {
        let n = self.param_count as usize;
        if n < CONTROL_MAX_PARAMS {
            put_str(&mut self.params[n].key, key);
            self.params[n].value = value;
            self.params[n].flags = if live { CONTROL_PARAM_LIVE } else { 0 };
            self.param_count += 1;
        }
    }
    /// The name of `status`.
    pub fn status_name(&self) -> &'static str {
        status_name(self.status)
    }
}

/// The name of a `CONTROL_STATUS_*` value.
pub fn status_name(status: u32) -> &'static str {
    match status {
        CONTROL_STATUS_OK => "ok",
        CONTROL_STATUS_UNKNOWN_BODY => "unknown body",
        CONTROL_STATUS_UNKNOWN_KEY => "unknown key",
        CONTROL_STATUS_BAD_VALUE => "bad value",
        CONTROL_STATUS_NOT_ALLOWED => "not allowed",
        CONTROL_STATUS_BUSY => "busy",
        CONTROL_STATUS_BAD_REQUEST => "bad request",
        CONTROL_STATUS_FAILED => "failed",
        _ => "unknown status",
    }
}

/// Writes `s` NUL-padded into `dst`, truncated at a character boundary.
pub fn put_str(dst: &mut [u8], s: &str) {
    dst.fill(0);
    let mut end = s.len().min(dst.len());
    while !s.is_char_boundary(end) {
        end -= 1;
    }
    dst[..end].copy_from_slice(&s.as_bytes()[..end]);
}

/// The string in a NUL-padded field (invalid UTF-8 yields "?").
pub fn get_str(src: &[u8]) -> &str {
    let end = src.iter().position(|&b| b == 0).unwrap_or(src.len());
    std::str::from_utf8(&src[..end]).unwrap_or("?")
}

/// Most clients `PREFIX/control` accepts at once (`lopd ctl` invocations, viewers).
pub const CONTROL_MAX_CLIENTS: usize = 8;
/// Requests one client may have in flight.
pub const CONTROL_MAX_ACTIVE_REQUESTS: usize = 2;

/// The control service's name under `names.prefix`: `PREFIX/control`.
pub fn control_service_name(names: &crate::ServiceNames) -> String {
    format!("{}/control", names.prefix)
}

/// The control service type.
pub type ControlService = iceoryx2::service::port_factory::request_response::PortFactory<
    iceoryx2::service::ipc::Service,
    ControlRequest,
    (),
    ControlResponse,
    (),
>;

/// Opens (client) or opens-or-creates (owner: the deformation process) `PREFIX/control` with
/// the contract's QoS: one server, [`CONTROL_MAX_CLIENTS`] clients, safe overflow both ways so a
/// frozen client never blocks the server.
pub fn control_service(
    node: &iceoryx2::node::Node<iceoryx2::service::ipc::Service>,
    names: &crate::ServiceNames,
    role: crate::services::Role,
) -> Result<ControlService, crate::services::IpcError> {
    use crate::services::{IpcError, Role};
    let name = control_service_name(names);
    let err = |what: &'static str| {
        let name = name.clone();
        move |e: &dyn core::fmt::Debug| IpcError::Iceoryx {
            what,
            service: name,
            reason: format!("{e:?}"),
        }
    };
    let sn =
        iceoryx2::prelude::ServiceName::new(&name).map_err(|e| err("invalid service name")(&e))?;
    let builder = node
        .service_builder(&sn)
        .request_response::<ControlRequest, ControlResponse>();
    match role {
        Role::Owner => builder
            .max_servers(1)
            .max_clients(CONTROL_MAX_CLIENTS)
            .max_active_requests_per_client(CONTROL_MAX_ACTIVE_REQUESTS)
            .max_response_buffer_size(CONTROL_MAX_ACTIVE_REQUESTS)
            .enable_safe_overflow_for_requests(true)
            .enable_safe_overflow_for_responses(true)
            .open_or_create()
            .map_err(|e| err("create service")(&e)),
        Role::Client => builder.open().map_err(|e| err("open service")(&e)),
    }
}

/// What can go wrong asking the daemon.
#[derive(Debug, thiserror::Error)]
pub enum ControlError {
    /// Opening the service or creating the client failed (the daemon is not running with this
    /// prefix, or the service has [`CONTROL_MAX_CLIENTS`] clients already).
    #[error(transparent)]
    Ipc(#[from] crate::services::IpcError),
    /// The request was sent but no answer came in time.
    #[error("no answer on {service:?} within {waited:?}: is lopd's deformation process running?")]
    NoAnswer {
        /// The service name.
        service: String,
        /// How long we waited.
        waited: std::time::Duration,
    },
}

/// A client of `PREFIX/control` (used by `lopd ctl` and `lop-view`).
pub struct ControlClient {
    service_name: String,
    client: iceoryx2::port::client::Client<
        iceoryx2::service::ipc::Service,
        ControlRequest,
        (),
        ControlResponse,
        (),
    >,
}

impl ControlClient {
    /// Opens `PREFIX/control` on `node`, retrying until `timeout` while the daemon starts.
    pub fn open(
        node: &iceoryx2::node::Node<iceoryx2::service::ipc::Service>,
        names: &crate::ServiceNames,
        timeout: std::time::Duration,
    ) -> Result<ControlClient, ControlError> {
        use crate::services::{open_retry, IpcError, Role};
        let service_name = control_service_name(names);
        let service = open_retry(&service_name, timeout, || {
            control_service(node, names, Role::Client)
        })?;
        let client = service.client_builder().create().map_err(|e| match e {
            iceoryx2::service::port_factory::client::ClientCreateError::ExceedsMaxSupportedClients => {
                IpcError::Full {
                    service: service_name.clone(),
                    port: "client",
                    limit: CONTROL_MAX_CLIENTS,
                    constant: "CONTROL_MAX_CLIENTS",
                }
            }
            other => IpcError::Iceoryx {
                what: "create client for",
                service: service_name.clone(),
                reason: format!("{other:?}"),
            },
        })?;
        Ok(ControlClient {
            service_name,
            client,
        })
    }

    /// Sends `req` and waits up to `timeout` for the answer.
    pub fn request(
        &self,
        req: &ControlRequest,
        timeout: std::time::Duration,
    ) -> Result<ControlResponse, ControlError> {
        let start = std::time::Instant::now();
        let no_answer = || ControlError::NoAnswer {
            service: self.service_name.clone(),
            waited: timeout,
        };
        // A request that reached no server is never answered: there is none yet (the daemon
        // between creating the service and its server port), or one is listed but the
        // client's connection to it is not usable yet. Such a request is sent again; it reached
        // nobody, so nothing acts on it twice.
        let pending = loop {
            let pending =
                self.client
                    .send_copy(*req)
                    .map_err(|e| crate::services::IpcError::Iceoryx {
                        what: "send request on",
                        service: self.service_name.clone(),
                        reason: format!("{e:?}"),
                    })?;
            if pending.number_of_server_connections() > 0 {
                break pending;
            }
            drop(pending);
            if start.elapsed() >= timeout {
                return Err(no_answer());
            }
            std::thread::sleep(std::time::Duration::from_millis(1));
        };
        loop {
            if let Ok(Some(r)) = pending.receive() {
                return Ok(*r.payload());
            }
            if start.elapsed() >= timeout {
                return Err(no_answer());
            }
            std::thread::sleep(std::time::Duration::from_millis(1));
        }
    }
}
